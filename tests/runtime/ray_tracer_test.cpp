// The compute ray tracer (runtime/src/passes/trace.h, shaders/trace.comp.glsl)
// against the Embree oracle: the same G-buffer (rendered by the public
// Renderer), the same shadow rays, one ray per covered pixel. Checked against
// the oracle on the decoded (quantized) triangles, which the tracer must match
// exactly up to rounding, and on the original mesh (>= 99.99% agreement).
// A self-contained harness drives the tracer: its own device, model upload,
// G-buffer images, ray list and frame uniforms.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <cstring>

#include <gtest/gtest.h>

#include "config.h"
#include "device.h"
#include "model_geometry.h"
#include "penumbra/generate.h"
#include "penumbra/oracle.h"
#include "penumbra/penumbra.h"
#include "test_scenes.h"
#include "penumbra/preprocess.h"
#include "passes/trace.h"
#include "resources.h"
#include "surface.h"

namespace penumbra {
namespace {

// The shadow-ray offset the runtime should use: quantization error dominates.
float shadowRayOffset(const CompressedModel& model)
{
    const auto& h = model.header;
    glm::vec3 extent(h.boundsMax[0] - h.boundsMin[0], h.boundsMax[1] - h.boundsMin[1], h.boundsMax[2] - h.boundsMin[2]);
    return std::max(1e-5f * glm::length(extent), 4.0f * h.maxPositionError);
}

struct GBuffer {
    uint32_t width = 0, height = 0;
    std::vector<float> positions, normals;
};

GBuffer renderGBuffer(const CompressedModel& model, const Camera& camera, uint32_t size)
{
    Renderer renderer;
    renderer.loadModel(model);
    renderer.setCamera(camera);
    RenderSettings settings;
    settings.width = settings.height = size;
    settings.readbackGBuffer = true;
    Frame frame = renderer.render(settings);
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
    return {size, size, std::move(frame.positions), std::move(frame.normals)};
}

gpu::LightData packTraceLight(const Light& light)
{
    gpu::LightData data{};
    uint32_t type = light.type == LightType::Directional ? PENUMBRA_LIGHT_DIRECTIONAL
                    : light.type == LightType::Spot      ? PENUMBRA_LIGHT_SPOT
                                                         : PENUMBRA_LIGHT_POINT;
    data.positionType = glm::vec4(light.position, float(type));
    data.directionRange = glm::vec4(glm::normalize(light.direction), light.range);
    return data;
}

struct TraceResult {
    std::vector<float> visibility; // per pixel; -5 where the tracer wrote nothing
    uint64_t stats[PENUMBRA_STAT_COUNT] = {}; // trace.comp adds 64-bit counters
    uint32_t listed = 0;
};

// The tracer on its own device: uploads the model and the G-buffer, lists
// every covered pixel, traces toward each light, reads visibility back.
class TraceHarness {
public:
    TraceHarness(const CompressedModel& model, const GBuffer& gbuffer, uint64_t maxModelBufferBytes = 0) : gbuffer(gbuffer)
    {
        RendererOptions options;
        options.maxModelBufferBytes = maxModelBufferBytes;
        vk::createDevice(device, options);
        geometry = uploadCompressed(device, model);
        tracer.create(device);
        tracer.bindModel(device, geometry);

        const VkImageUsageFlags usage = VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
        surface = vk::createImage(device, gbuffer.width, gbuffer.height, 1, VK_FORMAT_R32G32B32A32_UINT, usage);
        albedo = vk::createImage(device, gbuffer.width, gbuffer.height, 1, VK_FORMAT_R32_UINT, usage); // bound, not read
        visibility = vk::createImage(device, gbuffer.width, gbuffer.height, 1, VK_FORMAT_R32_SFLOAT, usage);
        const VkDeviceSize pixels = VkDeviceSize(gbuffer.width) * gbuffer.height;
        staging = vk::createBuffer(device, pixels * 16, VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                   vk::MemoryUse::Readback);
        frameUniforms = vk::createBuffer(device, sizeof(gpu::FrameData), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, vk::MemoryUse::Upload);
        rayList = vk::createBuffer(device, (PENUMBRA_RAY_LIST_HEADER_UINTS + pixels) * 4,
                                   VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT, vk::MemoryUse::Upload);
        stats = vk::createBuffer(device, PENUMBRA_STAT_COUNT * 8, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryUse::Readback);
        hints = vk::createBuffer(device, passes::TracePass::hintBytes(pixels), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                 vk::MemoryUse::DeviceLocal);

        // Every covered pixel (light-facing or not: the tracer writes 0 for the others).
        auto* list = static_cast<uint32_t*>(rayList.mapped);
        uint32_t count = 0;
        for (uint32_t i = 0; i < pixels; ++i)
            if (gbuffer.positions[size_t(i) * 4 + 3] != 0.0f)
                list[PENUMBRA_RAY_LIST_HEADER_UINTS + count++] = i;
        passes::TracePass::writeListHeader(device, count, list);
        listed = count;

        // The G-buffer as the camera pass writes it (surface.h): the normals
        // read back were decoded from such texels, and encode to them again.
        std::vector<uint32_t> texels(size_t(pixels) * 4, 0u);
        for (size_t i = 0; i < pixels; ++i)
            if (gbuffer.positions[i * 4 + 3] != 0.0f)
                encodeSurface(&gbuffer.positions[i * 4], &gbuffer.normals[i * 4], &texels[i * 4]);
        upload(surface, texels.data(), texels.size() * sizeof(uint32_t));
        const std::vector<uint32_t> white(pixels, kWhiteAlbedo);
        upload(albedo, white.data(), white.size() * sizeof(uint32_t));
        vk::immediateSubmit(device, [&](VkCommandBuffer cmd) {
            vk::transition(cmd, visibility, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL, VK_PIPELINE_STAGE_2_NONE, VK_ACCESS_2_NONE,
                           VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, VK_ACCESS_2_MEMORY_READ_BIT | VK_ACCESS_2_MEMORY_WRITE_BIT);
        });

        tracer.bind(device, {surface.view, albedo.view, visibility.view, frameUniforms.buffer, rayList.buffer, stats.buffer, hints.buffer});
    }

    ~TraceHarness()
    {
        vkDeviceWaitIdle(device.device);
        for (vk::Image* image : {&surface, &albedo, &visibility})
            vk::destroyImage(device, *image);
        for (vk::Buffer* buffer : {&staging, &frameUniforms, &rayList, &stats, &hints})
            vk::destroyBuffer(device, *buffer);
        tracer.destroy(device);
        destroyGeometry(device, geometry);
        EXPECT_EQ(device.validationMessages.load(), 0u);
        vk::destroyDevice(device);
    }

    TraceResult trace(const Light& light, float originOffset)
    {
        gpu::FrameData frame{};
        frame.lights[1] = packTraceLight(light); // not light 0, to check lightIndex
        std::memcpy(frameUniforms.mapped, &frame, sizeof(frame));
        std::memset(stats.mapped, 0, PENUMBRA_STAT_COUNT * 8);
        const uint32_t width = gbuffer.width, height = gbuffer.height;
        vk::immediateSubmit(device, [&](VkCommandBuffer cmd) {
            VkClearColorValue unwritten{};
            unwritten.float32[0] = -5.0f;
            VkImageSubresourceRange range{VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
            vkCmdClearColorImage(cmd, visibility.image, VK_IMAGE_LAYOUT_GENERAL, &unwritten, 1, &range);
            vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT | VK_PIPELINE_STAGE_2_HOST_BIT,
                              VK_ACCESS_2_TRANSFER_WRITE_BIT | VK_ACCESS_2_HOST_WRITE_BIT,
                              VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT,
                              VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT |
                                  VK_ACCESS_2_UNIFORM_READ_BIT | VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT);
            tracer.record(cmd, 1, uint32_t(frame.lights[1].positionType.w), originOffset);
            vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, VK_PIPELINE_STAGE_2_HOST_BIT,
                              VK_ACCESS_2_HOST_READ_BIT);
            vk::transition(cmd, visibility, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                           VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT, VK_ACCESS_2_TRANSFER_READ_BIT);
            VkBufferImageCopy copy{};
            copy.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
            copy.imageExtent = {width, height, 1};
            vkCmdCopyImageToBuffer(cmd, visibility.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, staging.buffer, 1, &copy);
            vk::transition(cmd, visibility, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL, VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT,
                           VK_ACCESS_2_TRANSFER_READ_BIT, VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT);
            vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_2_HOST_BIT,
                              VK_ACCESS_2_HOST_READ_BIT);
        });
        TraceResult result;
        const float* data = static_cast<const float*>(staging.mapped);
        result.visibility.assign(data, data + size_t(width) * height);
        std::memcpy(result.stats, stats.mapped, sizeof(result.stats));
        result.listed = listed;
        return result;
    }

    const GpuGeometry& model() const { return geometry; }
    vk::Device device;

private:
    void upload(vk::Image& image, const void* texels, size_t bytes)
    {
        std::memcpy(staging.mapped, texels, bytes);
        vk::immediateSubmit(device, [&](VkCommandBuffer cmd) {
            vk::transition(cmd, image, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_PIPELINE_STAGE_2_NONE,
                           VK_ACCESS_2_NONE, VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT);
            VkBufferImageCopy copy{};
            copy.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
            copy.imageExtent = {image.width, image.height, 1};
            vkCmdCopyBufferToImage(cmd, staging.buffer, image.image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &copy);
            vk::transition(cmd, image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL, VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT,
                           VK_ACCESS_2_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_READ_BIT);
        });
    }

    const GBuffer& gbuffer;
    GpuGeometry geometry;
    passes::TracePass tracer;
    vk::Image surface, albedo, visibility;
    vk::Buffer staging, frameUniforms, rayList, stats, hints;
    uint32_t listed = 0;
};

struct Agreement {
    size_t traced = 0, differing = 0, shadowed = 0;
    size_t backFacingWrong = 0, unwritten = 0, backgroundWritten = 0;
    double fraction() const { return traced ? double(differing) / double(traced) : 0.0; }
};

Agreement compare(const std::vector<float>& oracle, const TraceResult& gpu)
{
    Agreement a;
    for (size_t i = 0; i < oracle.size(); ++i) {
        float g = gpu.visibility[i];
        if (oracle[i] == kVisibilityBackground) {
            a.backgroundWritten += g != -5.0f;
            continue;
        }
        if (oracle[i] == kVisibilityBackFacing) {
            a.backFacingWrong += g != 0.0f;
            continue;
        }
        a.unwritten += g == -5.0f;
        ++a.traced;
        a.shadowed += oracle[i] == 0.0f;
        a.differing += oracle[i] != g;
    }
    return a;
}

// Of the rays where the tracer and the oracle on the original mesh differ,
// counts those on which the oracle agrees with the tracer once the ray is
// moved by shift: sideways in one of eight directions (rays passing within
// about shift of an occluder's silhouette or corner), or its origin along the
// surface normal (the receiver's own surface, quantized too, lies up to shift
// from the original one).
size_t grazingDisagreements(const EmbreeOracle& oracle, const GBuffer& gbuffer, const Light& light, const OracleOptions& options,
                            const std::vector<float>& reference, const std::vector<float>& traced, float shift)
{
    std::vector<bool> explained(reference.size(), false);
    for (int k = 0; k < 10; ++k) {
        std::vector<float> positions(gbuffer.positions.size(), 0.0f); // w = 0: not traced
        for (size_t i = 0; i < reference.size(); ++i) {
            if (reference[i] < 0.0f || reference[i] == traced[i])
                continue;
            glm::vec3 p(gbuffer.positions[i * 4], gbuffer.positions[i * 4 + 1], gbuffer.positions[i * 4 + 2]);
            glm::vec3 d = light.type == LightType::Directional ? -glm::normalize(light.direction) : glm::normalize(light.position - p);
            glm::vec3 u = glm::normalize(glm::cross(d, std::abs(d.x) < 0.9f ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0)));
            glm::vec3 v = glm::cross(d, u);
            glm::vec3 n(gbuffer.normals[i * 4], gbuffer.normals[i * 4 + 1], gbuffer.normals[i * 4 + 2]);
            n = glm::dot(n, n) > 0.0f ? glm::normalize(n) : d;
            const glm::vec3 moves[10] = {u, -u, v, -v, (u + v) * 0.70710678f, (u - v) * 0.70710678f, (v - u) * 0.70710678f,
                                         -(u + v) * 0.70710678f, n, -n};
            p += moves[k] * shift;
            positions[i * 4] = p.x;
            positions[i * 4 + 1] = p.y;
            positions[i * 4 + 2] = p.z;
            positions[i * 4 + 3] = 1.0f;
        }
        std::vector<float> shifted = oracle.hardShadowVisibility(positions, gbuffer.normals, light, options);
        for (size_t i = 0; i < reference.size(); ++i)
            explained[i] = explained[i] || (positions[i * 4 + 3] != 0.0f && shifted[i] == traced[i]);
    }
    return size_t(std::count(explained.begin(), explained.end(), true));
}

struct LightCase {
    const char* name;
    Light light;
};

std::vector<LightCase> testLights(const CompressedModel& model)
{
    const auto& h = model.header;
    glm::vec3 lo(h.boundsMin[0], h.boundsMin[1], h.boundsMin[2]), hi(h.boundsMax[0], h.boundsMax[1], h.boundsMax[2]);
    Light sun;
    sun.type = LightType::Directional;
    sun.direction = glm::normalize(glm::vec3(-0.35f, -1.0f, -0.25f));
    Light point;
    point.type = LightType::Point;
    point.position = lo + (hi - lo) * glm::vec3(0.3f, 0.8f, 0.6f);
    Light spot = point;
    spot.type = LightType::Spot;
    spot.position = lo + (hi - lo) * glm::vec3(0.7f, 0.9f, 0.35f);
    spot.direction = glm::normalize(glm::vec3(-0.2f, -1.0f, 0.1f));
    return {{"directional", sun}, {"point", point}, {"spot", spot}};
}

void expectTracerMatchesOracle(const Mesh& mesh, const Camera& camera, const char* name, uint64_t maxModelBufferBytes = 0,
                               uint32_t size = 256)
{
    CompressedModel model = buildCompressedModel(mesh, PreprocessOptions{});
    const float offset = shadowRayOffset(model);
    GBuffer gbuffer = renderGBuffer(model, camera, size);
    EmbreeOracle original(mesh), decoded(decodeMesh(model));
    TraceHarness harness(model, gbuffer, maxModelBufferBytes);
    if (maxModelBufferBytes) { // the chunked upload really is chunked
        EXPECT_GT(harness.model().chunks.size(), 2u);
        EXPECT_GT(harness.model().nodeChunks.size(), 2u);
    }
    OracleOptions options;
    options.originOffset = offset;
    for (const LightCase& c : testLights(model)) {
        TraceResult gpu = harness.trace(c.light, offset);
        Agreement exact = compare(decoded.hardShadowVisibility(gbuffer.positions, gbuffer.normals, c.light, options), gpu);
        std::vector<float> reference = original.hardShadowVisibility(gbuffer.positions, gbuffer.normals, c.light, options);
        Agreement source = compare(reference, gpu);
        std::printf("%s %s: offset %g, %zu rays, %.1f%% shadowed; differs from the decoded-mesh oracle on %zu, from the original on %zu; "
                    "%.1f nodes, %.2f leaves, %.1f triangles per ray\n",
                    name, c.name, offset, exact.traced, 100.0 * double(exact.shadowed) / double(std::max<size_t>(1, exact.traced)),
                    exact.differing, source.differing, double(gpu.stats[PENUMBRA_STAT_NODES]) / gpu.stats[PENUMBRA_STAT_RAYS],
                    double(gpu.stats[PENUMBRA_STAT_LEAVES]) / gpu.stats[PENUMBRA_STAT_RAYS],
                    double(gpu.stats[PENUMBRA_STAT_TRIANGLES]) / gpu.stats[PENUMBRA_STAT_RAYS]);
        EXPECT_GT(exact.traced, size_t(size) * size / 8) << name << " " << c.name;
        EXPECT_EQ(exact.unwritten, 0u) << name << " " << c.name;
        EXPECT_EQ(exact.backgroundWritten, 0u) << name << " " << c.name;
        EXPECT_EQ(exact.backFacingWrong, 0u) << name << " " << c.name;
        EXPECT_EQ(gpu.stats[PENUMBRA_STAT_RAYS], exact.traced) << name << " " << c.name;
        // Same triangles: the tracer must agree with Embree up to rounding.
        EXPECT_LE(exact.fraction(), 1e-4) << name << " " << c.name << ": " << exact.differing << " of " << exact.traced;
        // Original triangles: quantization moves silhouettes by up to
        // maxPositionError, so rays grazing an occluder may differ. Every
        // differing ray must be such a grazing ray, and they must be rare.
        size_t grazing = grazingDisagreements(original, gbuffer, c.light, options, reference, gpu.visibility, 2.0f * model.header.maxPositionError);
        EXPECT_EQ(grazing, source.differing) << name << " " << c.name << ": differing rays not explained by quantization";
        EXPECT_LE(source.fraction(), 5e-4) << name << " " << c.name << ": " << source.differing << " of " << source.traced;
    }
}

Scene generated(const char* name, uint64_t triangles)
{
    GenerateOptions options;
    options.triangles = triangles;
    return generateScene(name, options);
}


TEST(RayTracer, CubeOverFloorMatchesOracle)
{
    Camera camera;
    camera.position = {6, 8, 9};
    camera.target = {0, 1, 0};
    expectTracerMatchesOracle(test::cubeOverFloor(0.5f), camera, "cube");
}

TEST(RayTracer, CityMatchesOracle)
{
    Scene scene = generated("city", 100'000);
    expectTracerMatchesOracle(scene.mesh, scene.cameras.at(0), "city");
}

TEST(RayTracer, PlantMatchesOracle)
{
    Scene scene = generated("plant", 100'000);
    expectTracerMatchesOracle(scene.mesh, scene.cameras.at(0), "plant");
}

TEST(RayTracer, InteriorMatchesOracle)
{
    Scene scene = generated("interior", 100'000);
    expectTracerMatchesOracle(scene.mesh, scene.cameras.at(0), "interior");
}

TEST(RayTracer, ChunkedModelMatchesOracle)
{
    Scene scene = generated("plant", 60'000);
    expectTracerMatchesOracle(scene.mesh, scene.cameras.at(0), "plant chunked", 16 * 1024, 128);
}

TEST(RayTracer, RejectsModelsWithoutBvhAndUnboundUse)
{
    vk::Device device;
    vk::createDevice(device, RendererOptions{});
    passes::TracePass tracer;
    tracer.create(device);
    GpuGeometry reference = uploadReference(device, test::cubeOverFloor(0.5f));
    EXPECT_THROW(tracer.bindModel(device, reference), Error);
    vk::immediateSubmit(device, [&](VkCommandBuffer cmd) { EXPECT_THROW(tracer.record(cmd, 0, PENUMBRA_LIGHT_POINT, 0.0f), Error); });
    destroyGeometry(device, reference);
    tracer.destroy(device);
    EXPECT_EQ(device.validationMessages.load(), 0u);
    vk::destroyDevice(device);
}

// Rays per second of a full-frame trace (every covered pixel, directional
// light) on the 1M-triangle city:
// ./build/tests/runtime_tests --gtest_also_run_disabled_tests --gtest_filter='*DISABLED_Throughput*'
TEST(RayTracer, DISABLED_ThroughputCity1M)
{
    Scene scene = generated("city", 1'000'000);
    CompressedModel model = buildCompressedModel(scene.mesh, PreprocessOptions{});
    GBuffer gbuffer = renderGBuffer(model, scene.cameras.at(0), 1024);
    TraceHarness harness(model, gbuffer);
    for (const LightCase& c : testLights(model)) {
        double best = 1e30, bestCpu = 1e30; // wall clock; CPU time of the process (lavapipe's threads included)
        TraceResult result;
        for (int run = 0; run < 3; ++run) {
            auto start = std::chrono::steady_clock::now();
            std::clock_t cpuStart = std::clock();
            result = harness.trace(c.light, shadowRayOffset(model));
            bestCpu = std::min(bestCpu, double(std::clock() - cpuStart) / CLOCKS_PER_SEC);
            best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
        }
        uint64_t rays = result.stats[PENUMBRA_STAT_RAYS];
        std::printf("city 1M %s, %s: %llu rays in %.3f s, %.3f CPU s (best of 3, incl. clear and readback) = %.2f Mrays/s; %.1f nodes, "
                    "%.2f leaves, %.1f triangles per ray\n",
                    c.name, harness.device.info.name.c_str(), (unsigned long long)rays, best, bestCpu, rays / best * 1e-6,
                    double(result.stats[PENUMBRA_STAT_NODES]) / rays, double(result.stats[PENUMBRA_STAT_LEAVES]) / rays,
                    double(result.stats[PENUMBRA_STAT_TRIANGLES]) / rays);
    }
}

} // namespace
} // namespace penumbra
