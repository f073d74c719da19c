// Import throughput measurement (disabled by default; run with
// --gtest_also_run_disabled_tests --gtest_filter='*Throughput*').
// Exports a 1600 x 1600 grid (5.12M triangles) in each format and prints the
// best-of-3 import time and triangles per second.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>

#include "penumbra/io.h"
#include "test_helpers.h"

namespace penumbra::test {
namespace {

TEST(Throughput, DISABLED_ImportLargeGrid)
{
    Scene scene;
    scene.mesh = makeGrid(1600);
    struct Case {
        const char* name;
        bool binary;
        bool draco;
    };
    for (Case c : {Case{"big.ply", true, false}, Case{"big.glb", true, false}, Case{"big.obj", true, false},
                   Case{"big.stl", true, false}, Case{"big_draco.glb", true, true}}) {
        std::string path = tempPath(c.name);
        ExportOptions options;
        options.binary = c.binary;
        options.draco = c.draco;
        auto exportStart = std::chrono::steady_clock::now();
        exportScene(scene, path, options);
        double exportSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - exportStart).count();
        double best = 1e30;
        size_t triangles = 0;
        for (int run = 0; run < 3; ++run) {
            auto start = std::chrono::steady_clock::now();
            Scene loaded = importScene(path);
            best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
            triangles = loaded.mesh.triangleCount();
        }
        EXPECT_EQ(triangles, scene.mesh.triangleCount());
        std::printf("%-14s %10zu bytes  export %.3f s  import best-of-3 %.3f s  %.2f M triangles/s\n", c.name,
                    size_t(std::filesystem::file_size(path)), exportSeconds, best, double(triangles) / best / 1e6);
        std::filesystem::remove(path);
    }
}

} // namespace
} // namespace penumbra::test
