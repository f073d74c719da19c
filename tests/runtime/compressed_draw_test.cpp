// The runtime draws straight from the compressed model: the vertex shader's
// decoded positions equal the CPU decoder's bit for bit, chunked uploads work,
// and images match the uncompressed reference path.
#include <cmath>
#include <cstring>

#include <gtest/gtest.h>

#include "penumbra/generate.h"
#include "penumbra/penumbra.h"
#include "penumbra/preprocess.h"

namespace penumbra {
namespace {

CompressedModel compressedScene(const char* name, uint64_t triangles)
{
    GenerateOptions options;
    options.triangles = triangles;
    return buildCompressedModel(generateScene(name, options).mesh, PreprocessOptions{});
}

void expectGpuDecodeMatchesCpu(const CompressedModel& model, const RendererOptions& options)
{
    Renderer renderer(options);
    renderer.loadModel(model);
    std::vector<float> gpu = renderer.decodeVerticesOnGpu();
    ASSERT_EQ(gpu.size(), model.vertices.size() * 3);
    size_t mismatches = 0;
    for (const model::ClusterRecord& cluster : model.clusters)
        for (uint32_t v = 0; v < cluster.vertexCount; ++v) {
            size_t global = size_t(cluster.firstVertex) + v;
            glm::vec3 cpu = decodePosition(cluster, model.vertices[global]);
            for (int axis = 0; axis < 3; ++axis)
                if (std::memcmp(&gpu[global * 3 + axis], &cpu[axis], sizeof(float)) != 0 && mismatches++ < 5)
                    ADD_FAILURE() << "vertex " << global << " axis " << axis << ": gpu " << gpu[global * 3 + axis] << " cpu " << cpu[axis];
        }
    EXPECT_EQ(mismatches, 0u);
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
}

TEST(CompressedDraw, VertexShaderDecodeEqualsCpuDecoder)
{
    expectGpuDecodeMatchesCpu(compressedScene("scan", 60'000), {});
}

TEST(CompressedDraw, ChunkedUploadDecodesTheSame)
{
    CompressedModel model = compressedScene("plant", 60'000);
    RendererOptions options;
    options.maxModelBufferBytes = 64 * 1024; // forces dozens of chunks
    ASSERT_GT(model.vertices.size_bytes(), 4 * options.maxModelBufferBytes);
    expectGpuDecodeMatchesCpu(model, options);
}

struct Capture {
    std::vector<float> positions, visibility;
    uint64_t deviceBytes = 0;
};

Capture renderCapture(const Scene& scene, bool compressed, uint64_t chunkBytes = 0)
{
    RendererOptions options;
    options.maxModelBufferBytes = chunkBytes;
    Renderer renderer(options);
    if (compressed)
        renderer.loadModel(scene.mesh);
    else
        renderer.loadUncompressedReference(scene.mesh);
    renderer.setCamera(scene.cameras.at(0));
    renderer.setLights(scene.lights);
    RenderSettings settings;
    settings.width = settings.height = 256;
    settings.readbackGBuffer = true;
    Frame frame = renderer.render(settings);
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
    return {frame.positions, frame.visibility, renderer.modelDeviceBytes()};
}

TEST(CompressedDraw, ImageMatchesUncompressedReference)
{
    for (const char* name : {"city", "plant"}) {
        GenerateOptions options;
        options.triangles = 80'000;
        Scene scene = generateScene(name, options);
        Capture reference = renderCapture(scene, false);
        Capture compressed = renderCapture(scene, true);
        Capture chunked = renderCapture(scene, true, 32 * 1024);
        // Geometry + the whole BVH (for the tracer) still take less than the bare float mesh.
        EXPECT_LT(compressed.deviceBytes, reference.deviceBytes) << name;

        size_t pixels = reference.visibility.size(), coverage = 0, shadow = 0, chunkDifferences = 0;
        for (size_t i = 0; i < pixels; ++i) {
            coverage += (reference.positions[i * 4 + 3] != compressed.positions[i * 4 + 3]);
            shadow += (reference.visibility[i] != compressed.visibility[i]);
            chunkDifferences += std::memcmp(&compressed.positions[i * 4], &chunked.positions[i * 4], 16) != 0 ||
                                compressed.visibility[i] != chunked.visibility[i];
        }
        // Quantization moves vertices by < 1e-4 of a cluster: only pixels on silhouettes may flip,
        // and shadow-map texels along shadow edges (plant has thousands of thin bars, so more of those).
        EXPECT_LT(double(coverage) / pixels, 0.002) << name;
        EXPECT_LT(double(shadow) / pixels, 0.005) << name;
        EXPECT_EQ(chunkDifferences, 0u) << name << ": chunking must not change the image";
    }
}

// The raster passes draw either the file's strips (primitive restart) or the
// triangle lists decoded from them at load (RasterIndices): the same triangles
// in the same order with the same vertex order, so every pass that
// rasterizes the model (camera, shadow map, afsm's casters) gives the same
// image bit for bit, chunked or not.
TEST(CompressedDraw, TriangleListsDrawTheSameImagesAsStrips)
{
    struct Case {
        const char* scene;
        ShadowMethod method;
        uint64_t chunkBytes;
    };
    for (const Case& c : {Case{"scan", ShadowMethod::ShadowMap, 0}, Case{"plant", ShadowMethod::ShadowMap, 16 * 1024},
                          Case{"plant", ShadowMethod::AliasFree, 0}}) {
        GenerateOptions generate;
        generate.triangles = 30'000;
        Scene scene = generateScene(c.scene, generate);
        Frame frames[2];
        uint64_t deviceBytes[2] = {};
        for (RasterIndices indices : {RasterIndices::Strips, RasterIndices::Triangles}) {
            RendererOptions options;
            options.maxModelBufferBytes = c.chunkBytes;
            options.rasterIndices = indices;
            Renderer renderer(options);
            renderer.loadModel(scene.mesh);
            renderer.setCamera(scene.cameras.at(0));
            renderer.setLights(scene.lights);
            RenderSettings settings;
            settings.width = settings.height = 256;
            settings.shadows = c.method;
            settings.readbackGBuffer = true;
            const int k = indices == RasterIndices::Triangles;
            renderer.render(settings); // and a second frame: the occlusion culling's history decides its draws
            frames[k] = renderer.render(settings);
            deviceBytes[k] = renderer.modelDeviceBytes();
            EXPECT_EQ(renderer.validationMessageCount(), 0u);
        }
        const std::string what = std::string(c.scene) + ", " + shadowMethodName(c.method) + ", chunk bytes " + std::to_string(c.chunkBytes);
        ASSERT_EQ(frames[0].positions.size(), frames[1].positions.size()) << what;
        EXPECT_EQ(0, std::memcmp(frames[0].positions.data(), frames[1].positions.data(), frames[0].positions.size() * sizeof(float))) << what;
        EXPECT_EQ(0, std::memcmp(frames[0].normals.data(), frames[1].normals.data(), frames[0].normals.size() * sizeof(float))) << what;
        EXPECT_EQ(0, std::memcmp(frames[0].visibility.data(), frames[1].visibility.data(), frames[0].visibility.size() * sizeof(float)))
            << what;
        EXPECT_EQ(frames[0].color.rgba, frames[1].color.rgba) << what;
        // The lists are an addition on the device: 3 bytes per triangle at most (and a few bytes per chunk).
        EXPECT_GT(deviceBytes[1], deviceBytes[0]) << what;
        EXPECT_LE(deviceBytes[1], deviceBytes[0] + 3 * generate.triangles + 4 * 256) << what;
    }
}

TEST(CompressedDraw, RasterIndicesNamesRoundTrip)
{
    for (RasterIndices indices : {RasterIndices::Auto, RasterIndices::Strips, RasterIndices::Triangles})
        EXPECT_EQ(parseRasterIndices(rasterIndicesName(indices)), indices);
    try {
        parseRasterIndices("lines");
        FAIL() << "accepted an unknown form";
    } catch (const Error& e) {
        EXPECT_EQ(std::string(e.what()), "--raster-indices lines: unknown form (expected auto, strips or triangles)");
    }
}

} // namespace
} // namespace penumbra
