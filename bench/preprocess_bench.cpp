// Preprocessing end to end on one input file: import + build + write, as
// `penumbra preprocess` does. Prints time, triangles/s, bytes per triangle per
// section, and peak RSS against the input file size, plus one JSON line.
//   bench_preprocess INPUT [--threads N] [--out MODEL.penumbra]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <sys/resource.h>

#include "penumbra/error.h"
#include "penumbra/io.h"
#include "penumbra/model_format.h"
#include "penumbra/preprocess.h"

int main(int argc, char** argv)
{
    std::string input, output = "/tmp/bench_preprocess.penumbra";
    unsigned threads = 0;
    for (int i = 1; i < argc; ++i) {
        if (std::strcmp(argv[i], "--threads") == 0 && i + 1 < argc)
            threads = unsigned(std::atoi(argv[++i]));
        else if (std::strcmp(argv[i], "--out") == 0 && i + 1 < argc)
            output = argv[++i];
        else
            input = argv[i];
    }
    if (input.empty()) {
        std::fprintf(stderr, "usage: bench_preprocess INPUT [--threads N] [--out MODEL.penumbra]\n");
        return 2;
    }
    try {
        using Clock = std::chrono::steady_clock;
        auto seconds = [](Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double>(b - a).count(); };
        auto t0 = Clock::now();
        penumbra::Scene scene = penumbra::importScene(input);
        auto t1 = Clock::now();
        penumbra::PreprocessOptions options;
        options.threads = threads;
        penumbra::PreprocessStats stats;
        penumbra::CompressedModel model = penumbra::buildCompressedModel(scene.mesh, options, &stats);
        auto t2 = Clock::now();
        penumbra::writeModelFile(model, output);
        auto t3 = Clock::now();

        double total = seconds(t0, t3);
        double triangles = double(scene.mesh.triangleCount());
        double stored = double(model.header.triangleCount);
        rusage usage{};
        getrusage(RUSAGE_SELF, &usage);
        double peakMiB = usage.ru_maxrss / 1024.0;
        double inputMiB = double(std::filesystem::file_size(input)) / (1 << 20);
        double clusters = model.clusters.size_bytes() / stored, nodes = model.nodes.size_bytes() / stored;
        double vertices = model.vertices.size_bytes() / stored, indices = model.indices.size_bytes() / stored;

        // 4-wide nodes (format version 4): every node but the root fills one slot, every leaf one more.
        const double slotsPerNode = double(model.header.nodeCount - 1 + stats.leaves) / model.header.nodeCount;
        std::printf("%s: %.0f triangles in, %.0f stored, %u clusters, %u nodes (%.2f children each), %llu leaves "
                    "(%.1f triangles each), depth %u, %llu widened box coordinates\n",
                    input.c_str(), triangles, stored, model.header.clusterCount, model.header.nodeCount, slotsPerNode,
                    (unsigned long long)stats.leaves, stored / double(std::max<uint64_t>(stats.leaves, 1)), model.header.bvhDepth,
                    (unsigned long long)stats.widenedBounds);
        std::printf("  time      import %.2f s + build %.2f s (filter %.2f incl. closed %.2f, tree %.2f, clusters %.2f, layout %.2f) + write %.2f s = %.2f s -> %.2f M tris/s\n",
                    seconds(t0, t1), seconds(t1, t2), stats.filterSeconds, stats.closedSeconds, stats.treeSeconds,
                    stats.clusterSeconds, stats.layoutSeconds, seconds(t2, t3), total, triangles / total * 1e-6);
        std::printf("  closed    %.1f%% of the triangles in closed clusters, %.1f%% in closed components\n",
                    100.0 * double(stats.closedClusterTriangles) / stored, 100.0 * double(stats.closedTriangles) / stored);
        std::printf("  B/tri     clusters %.3f + nodes %.3f + vertices %.3f + indices %.3f = %.3f\n", clusters, nodes, vertices,
                    indices, clusters + nodes + vertices + indices);
        std::printf("  memory    peak RSS %.0f MiB = %.2fx the input file (%.0f MiB)\n", peakMiB, peakMiB / inputMiB, inputMiB);
        std::printf("  error     max position error %.3g (model units)\n", double(model.header.maxPositionError));
        std::printf("{\"bench\":\"preprocess\",\"input\":\"%s\",\"triangles\":%.0f,\"seconds\":%.3f,\"mtris_per_s\":%.3f,"
                    "\"bytes_per_triangle\":%.3f,\"clusters_bpt\":%.3f,\"nodes_bpt\":%.3f,\"vertices_bpt\":%.3f,\"indices_bpt\":%.3f,"
                    "\"peak_rss_mib\":%.1f,\"input_mib\":%.1f,\"threads\":%u,\"nodes\":%u,\"leaves\":%llu,\"bvh_depth\":%u}\n",
                    input.c_str(), triangles, total, triangles / total * 1e-6, clusters + nodes + vertices + indices, clusters, nodes,
                    vertices, indices, peakMiB, inputMiB, threads, model.header.nodeCount, (unsigned long long)stats.leaves,
                    model.header.bvhDepth);
    } catch (const penumbra::Error& e) {
        std::fprintf(stderr, "bench_preprocess: error: %s\n", e.what());
        return 1;
    }
    return 0;
}
