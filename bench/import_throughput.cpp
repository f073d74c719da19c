// Import throughput: best-of-N and median wall time of importScene per file,
// in triangles per second, plus peak RSS. Prints a table and one JSON line per file.
//   bench_import [--runs N] FILE...
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>
#include <sys/resource.h>
#include <vector>

#include "penumbra/error.h"
#include "penumbra/io.h"

int main(int argc, char** argv)
{
    int runs = 3;
    std::vector<std::string> files;
    for (int i = 1; i < argc; ++i) {
        if (std::strcmp(argv[i], "--runs") == 0 && i + 1 < argc)
            runs = std::max(1, std::atoi(argv[++i]));
        else
            files.push_back(argv[i]);
    }
    if (files.empty()) {
        std::fprintf(stderr, "usage: bench_import [--runs N] FILE...\n");
        return 2;
    }
    for (const std::string& file : files) {
        std::vector<double> seconds;
        size_t triangles = 0;
        try {
            for (int run = 0; run < runs; ++run) {
                auto start = std::chrono::steady_clock::now();
                penumbra::Scene scene = penumbra::importScene(file);
                seconds.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
                triangles = scene.mesh.triangleCount();
            }
        } catch (const penumbra::Error& e) {
            std::fprintf(stderr, "bench_import: error: %s\n", e.what());
            return 1;
        }
        std::sort(seconds.begin(), seconds.end());
        double best = seconds.front(), median = seconds[seconds.size() / 2];
        rusage usage{};
        getrusage(RUSAGE_SELF, &usage);
        std::printf("%-40s %12zu tris  best %8.3f s  median %8.3f s  %7.2f Mtris/s  peak RSS %.0f MiB\n", file.c_str(), triangles,
                    best, median, triangles / best * 1e-6, usage.ru_maxrss / 1024.0);
        std::printf("{\"bench\":\"import\",\"file\":\"%s\",\"triangles\":%zu,\"best_s\":%.4f,\"median_s\":%.4f,\"mtris_per_s\":%.3f,"
                    "\"peak_rss_mib\":%.1f}\n",
                    file.c_str(), triangles, best, median, triangles / best * 1e-6, usage.ru_maxrss / 1024.0);
    }
    return 0;
}
