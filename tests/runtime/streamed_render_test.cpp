// A streamed build (preprocess --memory-limit: many chunks, merged) renders
// the same model as the in-core build, within the quantization error: its
// clusters differ, so vertices move by up to the models' maxPositionError, and
// the images may differ as much as they do between two in-core builds with
// other clusters (measured here: the plant's 5 mm bars and coplanar gratings
// turn some 900 of 41 k pixels over between 512- and 256-triangle clusters).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "penumbra/generate.h"
#include "penumbra/penumbra.h"
#include "penumbra/streamed.h"

namespace penumbra {
namespace {

struct Difference {
    size_t covered = 0, coverage = 0, visibility = 0;
};

Difference compare(const Frame& a, const Frame& b)
{
    Difference d;
    for (size_t i = 0; i < a.visibility.size(); ++i) {
        const bool ca = a.visibility[i] >= 0.0f, cb = b.visibility[i] >= 0.0f;
        d.covered += ca || cb;
        d.coverage += ca != cb;
        d.visibility += ca && cb && a.visibility[i] != b.visibility[i];
    }
    return d;
}

TEST(StreamedRender, SameImagesAsTheInCoreBuild)
{
    for (const char* name : {"city", "plant"}) {
        SCOPED_TRACE(name);
        GenerateOptions generate;
        generate.triangles = 30'000;
        const Scene scene = generateScene(name, generate);
        const std::string input = std::string(PENUMBRA_TEST_TMP) + "/streamed_render_" + name + ".ply";
        const std::string output = std::string(PENUMBRA_TEST_TMP) + "/streamed_render_" + name + ".penumbra";
        exportScene(scene, input);
        StreamedOptions options;
        options.memoryLimit = uint64_t(64) << 20;
        options.chunkTriangles = 4'000; // about 10 chunks
        options.tempDirectory = PENUMBRA_TEST_TMP;
        const StreamedStats stats = preprocessStreamed(input, output, options);
        EXPECT_GE(stats.chunks, 6u);
        const CompressedModel streamed = openModelFile(output);
        PreprocessOptions build;
        const CompressedModel inCore = buildCompressedModel(scene.mesh, build);
        ASSERT_EQ(streamed.header.triangleCount, inCore.header.triangleCount);
        // The same model quantized in other clusters (in core, smaller clusters): how much the scene's
        // images depend on the quantization alone.
        PreprocessOptions smaller;
        smaller.maxClusterTriangles = 256;
        const CompressedModel requantized = buildCompressedModel(scene.mesh, smaller);

        Renderer renderer;
        renderer.setCamera(scene.cameras[0]);
        renderer.setLights({scene.lights[0]});
        for (ShadowMethod method : {ShadowMethod::FullRayTrace}) {
            RenderSettings settings;
            settings.width = settings.height = 256;
            settings.shadows = method;
            settings.readbackGBuffer = true;
            renderer.loadModel(inCore);
            const Frame a = renderer.render(settings);
            renderer.loadModel(streamed);
            const Frame b = renderer.render(settings);
            renderer.loadModel(requantized);
            const Frame c = renderer.render(settings);
            const Difference d = compare(a, b), q = compare(a, c);
            std::printf("[ streamed ] %s: in core with 256-triangle clusters: coverage differs on %zu, visibility on %zu\n",
                        name, q.coverage, q.visibility);
            std::printf("[ streamed ] %s %s: %zu covered pixels, coverage differs on %zu, light visibility on %zu "
                        "(max position error %.3g / %.3g)\n",
                        name, method == ShadowMethod::FullRayTrace ? "frt" : "srt", d.covered, d.coverage, d.visibility,
                        double(inCore.header.maxPositionError), double(streamed.header.maxPositionError));
            EXPECT_GT(d.covered, 10'000u);
            EXPECT_LE(d.coverage, 2 * q.coverage + d.covered / 1000) << "coverage moves more than requantization moves it";
            EXPECT_LE(d.visibility, 2 * q.visibility + d.covered / 1000) << "shadows move more than requantization moves them";
        }
        EXPECT_EQ(renderer.validationMessageCount(), 0u);
    }
}

} // namespace
} // namespace penumbra
