// Embree CPU oracle: rtcOccluded1 per pixel over the uncompressed mesh.
#include "penumbra/oracle.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <thread>

#include <embree3/rtcore.h>
#include <glm/geometric.hpp>

#include "penumbra/error.h"
#include "penumbra/light_sampling.h"
#include "penumbra/scene_file.h"

namespace penumbra {

struct EmbreeOracle::Impl {
    RTCDevice device = nullptr;
    RTCScene scene = nullptr;
    ~Impl()
    {
        if (scene) rtcReleaseScene(scene);
        if (device) rtcReleaseDevice(device);
    }
};

EmbreeOracle::EmbreeOracle(const Mesh& mesh) : impl(std::make_unique<Impl>())
{
    impl->device = rtcNewDevice(nullptr);
    if (!impl->device)
        fail("embree", "cannot create a device");
    impl->scene = rtcNewScene(impl->device);
    rtcSetSceneBuildQuality(impl->scene, RTC_BUILD_QUALITY_HIGH);
    RTCGeometry geometry = rtcNewGeometry(impl->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* vertices = static_cast<float*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), mesh.vertexCount()));
    auto* indices = static_cast<uint32_t*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), mesh.triangleCount()));
    if (!vertices || !indices) {
        rtcReleaseGeometry(geometry);
        fail("embree", "out of memory for the geometry buffers");
    }
    std::memcpy(vertices, mesh.positions.data(), mesh.positions.size() * sizeof(float));
    std::memcpy(indices, mesh.indices.data(), mesh.indices.size() * sizeof(uint32_t));
    rtcCommitGeometry(geometry);
    rtcAttachGeometry(impl->scene, geometry);
    rtcReleaseGeometry(geometry);
    rtcCommitScene(impl->scene);
    if (rtcGetDeviceError(impl->device) != RTC_ERROR_NONE)
        fail("embree", "scene build failed");
}

EmbreeOracle::~EmbreeOracle() = default;

namespace {

// Runs fn(i, position, normal, context) for every covered pixel i (position
// w != 0) on all threads; fn returns the rays it traced, summed and returned.
template <typename Fn>
uint64_t forEachCoveredPixel(const std::vector<float>& positions, const std::vector<float>& normals, unsigned threads, Fn fn)
{
    const size_t pixels = positions.size() / 4;
    std::atomic<size_t> next{0};
    std::atomic<uint64_t> traced{0};
    auto worker = [&] {
        RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        uint64_t local = 0;
        const size_t block = 1024;
        for (size_t begin = next.fetch_add(block); begin < pixels; begin = next.fetch_add(block))
            for (size_t i = begin; i < std::min(pixels, begin + block); ++i) {
                const float* p = &positions[i * 4];
                if (p[3] != 0.0f)
                    local += fn(i, glm::vec3(p[0], p[1], p[2]), glm::vec3(normals[i * 4], normals[i * 4 + 1], normals[i * 4 + 2]), context);
            }
        traced += local;
    };
    threads = threads ? threads : std::max(1u, std::thread::hardware_concurrency());
    std::vector<std::thread> pool;
    for (unsigned t = 1; t < threads; ++t)
        pool.emplace_back(worker);
    worker();
    for (std::thread& thread : pool)
        thread.join();
    return traced.load();
}

// True when the segment from origin along dir (unit) up to tfar hits a triangle.
bool occluded(RTCScene scene, RTCIntersectContext& context, glm::vec3 origin, glm::vec3 dir, float tfar)
{
    RTCRay ray{};
    ray.org_x = origin.x;
    ray.org_y = origin.y;
    ray.org_z = origin.z;
    ray.dir_x = dir.x;
    ray.dir_y = dir.y;
    ray.dir_z = dir.z;
    ray.tnear = 0.0f;
    ray.tfar = tfar;
    ray.mask = 0xFFFFFFFFu;
    ray.flags = 0;
    rtcOccluded1(scene, &context, &ray);
    // Embree sets tfar to -inf when the ray is occluded.
    return ray.tfar == -std::numeric_limits<float>::infinity();
}

} // namespace

std::vector<float> EmbreeOracle::hardShadowVisibility(const std::vector<float>& positions, const std::vector<float>& normals,
                                                      const Light& light, const OracleOptions& options) const
{
    if (normals.size() != positions.size())
        fail("oracle", "positions and normals differ in size");
    size_t pixels = positions.size() / 4;
    std::vector<float> visibility(pixels, kVisibilityBackground);
    bool directional = light.type == LightType::Directional;
    glm::vec3 towardLight = directional ? -glm::normalize(light.direction) : glm::vec3(0.0f);
    rays = forEachCoveredPixel(positions, normals, options.threads, [&](size_t i, glm::vec3 position, glm::vec3 n, RTCIntersectContext& context) {
        glm::vec3 dir = directional ? towardLight : light.position - position;
        float distance = directional ? std::numeric_limits<float>::infinity() : glm::length(dir);
        if (!directional)
            dir /= std::max(distance, 1e-30f);
        if (glm::dot(n, dir) <= 0.0f) {
            visibility[i] = kVisibilityBackFacing;
            return uint64_t(0);
        }
        float tfar = directional ? std::numeric_limits<float>::infinity() : distance - options.originOffset;
        visibility[i] = occluded(impl->scene, context, position + n * options.originOffset, dir, tfar) ? 0.0f : 1.0f;
        return uint64_t(1);
    });
    return visibility;
}

std::vector<float> EmbreeOracle::softShadowVisibility(const std::vector<float>& positions, const std::vector<float>& normals, uint32_t width,
                                                      const Light& light, uint32_t lightIndex, uint32_t samples,
                                                      const OracleOptions& options) const
{
    if (normals.size() != positions.size())
        fail("oracle", "positions and normals differ in size");
    if (!isAreaLight(light))
        fail("oracle", "soft shadows need an area light (rectangle, disk or sphere)");
    if (width == 0 || samples == 0)
        fail("oracle", "image width and sample count must be positive");
    size_t pixels = positions.size() / 4;
    std::vector<float> visibility(pixels, kVisibilityBackground);
    glm::vec3 u, v;
    areaLightAxes(light, u, v);
    const uint32_t shape = light.type == LightType::Rectangle ? PENUMBRA_AREA_RECTANGLE
                           : light.type == LightType::Disk    ? PENUMBRA_AREA_DISK
                                                              : PENUMBRA_AREA_SPHERE;
    const bool oneSided = light.type != LightType::Sphere;
    const glm::vec3 facing = oneSided ? glm::normalize(light.direction) : glm::vec3(0.0f);
    rays = forEachCoveredPixel(positions, normals, options.threads, [&](size_t i, glm::vec3 position, glm::vec3 n, RTCIntersectContext& context) {
        if (oneSided && glm::dot(position - light.position, facing) <= 0.0f) {
            visibility[i] = kVisibilityBackFacing;
            return uint64_t(0);
        }
        uint32_t seed = sampling::sampleSeed(uint32_t(i % width), uint32_t(i / width), lightIndex);
        uint32_t visible = 0, above = 0;
        for (uint32_t s = 0; s < samples; ++s) {
            glm::vec3 target = options.afsmSamples ? sampling::afsmLightPoint(shape, light.position, u, v, position, seed, s, samples)
                                                   : sampling::areaLightPoint(shape, light.position, u, v, position,
                                                                              sampling::stratifiedSample(seed, s, samples));
            glm::vec3 dir = target - position;
            float distance = glm::length(dir);
            dir /= std::max(distance, 1e-30f);
            if (glm::dot(n, dir) <= 0.0f)
                continue;
            ++above;
            visible += occluded(impl->scene, context, position + n * options.originOffset, dir, distance - options.originOffset) ? 0 : 1;
        }
        visibility[i] = above == 0 ? kVisibilityBackFacing : float(visible) / float(samples);
        return uint64_t(above);
    });
    return visibility;
}

} // namespace penumbra
