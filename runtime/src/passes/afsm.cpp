#include "passes/afsm.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <string>
#include <tuple>

#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include "config.h"
#include "light_space.h"
#include "passes/pass.h"

namespace penumbra::passes {

namespace {

constexpr uint32_t kScanBlock = PENUMBRA_AFSM_SCAN_GROUP * 16; // afsm_scan.comp.glsl: AFSM_SCAN_BLOCK
constexpr VkPipelineStageFlags2 kFragment = VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT;
constexpr VkPipelineStageFlags2 kGeometry = VK_PIPELINE_STAGE_2_GEOMETRY_SHADER_BIT;
constexpr VkBufferUsageFlags kStorageDst = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;

std::vector<VkDescriptorType> castersBindingTypes()
{
    using namespace vk;
    return {kUniform, kTexels, kTexels, kStorage, kStorage, kTexels, kStorage, kStorage, kStorage, kTexels};
}

std::vector<VkDescriptorType> binBindingTypes()
{
    using namespace vk;
    return {kUniform, kTexels, kTexels, kStorage, kStorage, kTexels, kStorage, kStorage, kStorage, kStorage, kTexels, kTexels, kTexels, kTexels, kTexels};
}

// A perspective frustum from eye along forward with a square field of view
// (half-angle tangent halfTan), its square's sides along up (0: an axis not
// along forward); y is not flipped (culling only).
glm::mat4 cullFrustum(glm::vec3 eye, glm::vec3 forward, float halfTan, float nearPlane, float farPlane, glm::vec3 up = glm::vec3(0.0f))
{
    const glm::vec3 f = glm::normalize(forward);
    if (glm::length(up) == 0.0f)
        up = std::abs(f.y) < 0.9f ? glm::vec3(0, 1, 0) : glm::vec3(1, 0, 0);
    return glm::perspectiveRH_ZO(2.0f * std::atan(halfTan), 1.0f, nearPlane, farPlane) * glm::lookAtRH(eye, eye + f, up);
}

// The frustum from `centre` along `forward` (half-angle tangent halfTan, far
// plane farPlane) pulled back along its axis until every point within
// `radius` of the centre lies inside: it then holds every segment from a point
// of the light to a point of the original frustum (both convex), so every
// caster between the light and a sample of the layer.
// up: the original frustum's (its square's sides; 0: cullFrustum's choice).
glm::mat4 pulledBackFrustum(glm::vec3 centre, glm::vec3 forward, float halfTan, float radius, float farPlane, glm::vec3 up = glm::vec3(0.0f))
{
    const float pull = radius * std::sqrt(1.0f + halfTan * halfTan) / halfTan * 1.001f + 1e-6f * farPlane;
    const float far = (farPlane + pull) * 1.001f;
    return cullFrustum(centre - glm::normalize(forward) * pull, forward, halfTan, far * 1e-6f, far, up);
}

} // namespace

uint64_t afsmBinIterations(uint32_t leafTriangles, uint32_t leafBytes)
{
    // Per caster (afsm_bin.comp.glsl, binCaster): the cells' samples within the budget, which counts 1 + n (soft:
    // 1 + n (1 + quads)) for a cell of n samples while the loops take 1 + n (soft: 1 + n (2 + quads)): at most 3/2
    // of it, at one quad; the rows and columns of a rectangle of at most 16 cells (17 + 32); a loop of 4 per cell's
    // edge test (afsmCellMayMeetTriangle); 16 for the rectangle's own loops over the vertices. Hard shadows go row
    // by row: the budget counts a row's cells and samples while the loops take one per row, three per row's edges
    // (afsmRowCells) and one per sample, which this bounds as well.
    // lavapipe counts the loop iterations of a subgroup (all its loops together, each as long as its longest lane).
    // An invocation walks up to 4 leaves one triangle a step (main's outer loop: a step per triangle, one more per
    // leaf and one to end), each step's caster loops as long as its longest lane's; the inner loop reads strip bytes,
    // at most its 8 lanes' bytes added (each lane's leaves' bytes and a step per leaf's end).
    const uint64_t perCaster = uint64_t(PENUMBRA_AFSM_COMPUTE_BUDGET) * 3 / 2 + 49 + 16 * 4 + 16;
    const uint64_t leaves = 4, lanes = 8;
    const uint64_t steps = leaves * (uint64_t(leafTriangles) + 1) + 1;
    return 16 + steps * (1 + perCaster) + lanes * leaves * (uint64_t(leafBytes) + 1);
}

uint32_t afsmGridSize(uint32_t width, uint32_t height, bool soft)
{
    // A multiple of 16 cells per side: a power of two above the image (512 cells for 320 pixels) spent 2.6 cells
    // per pixel, most of them empty, and the casters' raster cost grows with their area. Fewer, fuller cells cost
    // fewer fragments and more samples per fragment, which suits hard shadows (a sample's test is one ray/triangle
    // test); a soft sample's test is four table lookups, so soft shadows want finer cells. 250 k suite scenes at
    // 640^2, process CPU ms per frame: hard afsm (medians of 3 interleaved runs) with one cell per pixel / 3 per 4 /
    // 5 per 8 (half: the compute path's cells fill past its budget, afsm_bin doubled on the interior): city 208 /
    // 200 / 183, interior 666 / 617 / 632, plant 923 / 791 / 763, scan 363 / 333 / 359; soft (a sphere light, 128
    // samples) with one cell per pixel / 3 per 4 / 5 per 4: city 2823-2891 / 3024-3057 / 2802, scan 7018-7127 /
    // 8057-8085 / 6380.
    const uint32_t side = std::max(width, height);
    const uint32_t cells = soft ? side * 5 / 4 : side * 3 / 4;
    return std::clamp((cells + 15) / 16 * 16, 16u, uint32_t(PENUMBRA_AFSM_MAX_GRID));
}

AfsmTableSize afsmTableSize(uint32_t samples)
{
    AfsmTableSize size;
    size.words = (samples + 127) / 128 * 4; // whole 128-bit quads (afsm.glsli)
    const uint64_t entries = PENUMBRA_AFSM_TABLE_WORDS / std::max(size.words, 1u);
    size.distances = 1;
    while (uint64_t(size.distances) * 2 * size.distances * 2 <= entries)
        size.distances *= 2;
    size.angles = size.distances;
    while (uint64_t(size.angles) * 2 * size.distances <= entries)
        size.angles *= 2;
    return size;
}

double AfsmTableSize::lineError(bool rectangle) const
{
    const double rho = rectangle ? std::sqrt(2.0) : 1.0;
    const double pi = 3.14159265358979;
    return rho / double(distances) + rho * 0.5 * pi / double(angles);
}

uint64_t afsmLargestBuffer(uint32_t width, uint32_t height, uint32_t samples, bool soft)
{
    const uint64_t pixels = uint64_t(width) * height;
    return std::max<uint64_t>(soft ? pixels * afsmTableSize(samples).words * 4 : 0, pixels * 48);
}

uint32_t afsmSliceSamples(uint32_t samples)
{
    // afsm.glsli: afsmSliceSamples (a loop of n rounds takes n + 1 iterations; soft: each sample's loop over its quads).
    const uint32_t quads = (samples + 127) / 128;
    return samples == 0 ? PENUMBRA_AFSM_FRAGMENT_ITERATIONS - 1 : (PENUMBRA_AFSM_FRAGMENT_ITERATIONS - 1) / (quads + 2);
}

std::vector<AfsmLayer> afsmAreaLayers(const Light& light, const Bounds& bounds, bool& cube, const ViewClip* viewClip, uint32_t gridSize)
{
    const bool oneSided = light.type != LightType::Sphere;
    glm::vec3 u, v;
    areaLightAxes(light, u, v);
    const float radius = light.type == LightType::Rectangle ? glm::length(u + v) : light.radius;
    glm::vec3 axis = oneSided ? glm::normalize(light.direction) : bounds.center() - light.position;
    axis = glm::length(axis) > 0.0f ? glm::normalize(axis) : glm::vec3(0, -1, 0);
    const AreaMapProjection model = areaMapProjection(light.position, axis, light.up, bounds);
    AreaMapProjection map = model;
    if (viewClip && viewClip->valid)
        map = fitAreaMapToView(model, light.position, light.up, bounds, glm::vec2(viewClip->min), glm::vec2(viewClip->max), 0.0f,
                               std::max(gridSize, 16u));
    const bool fitted = map.footprint != model.footprint || map.viewProj != model.viewProj;
    std::vector<AfsmLayer> layers;
    cube = model.capped && !fitted;
    if (!cube) {
        // The cull frustum's square turned as the grid's (its view's x and y axes), so that it holds the grid's corners.
        const glm::vec3 forward = -glm::vec3(map.view[0][2], map.view[1][2], map.view[2][2]);
        const glm::vec3 up = glm::vec3(map.view[0][1], map.view[1][1], map.view[2][1]);
        layers.push_back({map.viewProj, pulledBackFrustum(light.position, forward, 0.5f * map.footprint, radius, map.farPlane, up), 0});
        return layers;
    }
    // Six faces of a cube around the centre (the point light's, same order and matrices).
    Light point = light;
    point.type = LightType::Point;
    const LightProjection faces = lightProjection(point, bounds);
    static const glm::vec3 axes[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    for (uint32_t face = 0; face < 6; ++face) {
        if (oneSided) {
            // Left out when every direction of the face points behind the emitter (no sample there).
            const glm::vec3 a = axes[face], s = axes[(face + 2) % 6], t = axes[(face + 4) % 6];
            bool front = false;
            for (float i : {-1.0f, 1.0f})
                for (float j : {-1.0f, 1.0f})
                    front = front || glm::dot(a + i * s + j * t, axis) > 0.0f;
            if (!front)
                continue;
        }
        layers.push_back({faces.viewProj[face], pulledBackFrustum(light.position, axes[face], 1.0f, radius, faces.farPlane), face});
    }
    return layers;
}

namespace {

bool rayHitsBox(const glm::dvec3& origin, const glm::dvec3& inverse, glm::dvec3 lo, glm::dvec3 hi)
{
    const glm::dvec3 t0 = (lo - origin) * inverse, t1 = (hi - origin) * inverse;
    const glm::dvec3 near = glm::min(t0, t1), far = glm::max(t0, t1);
    const double enter = std::max({near.x, near.y, near.z, 0.0}), leave = std::min({far.x, far.y, far.z});
    return enter <= leave;
}

// Closed triangles left minus entered along the ray from origin to infinity.
int closedCrossings(const CompressedModel& model, const CullModel& cull, const glm::dvec3& origin, const glm::dvec3& direction)
{
    const glm::dvec3 inverse = 1.0 / direction;
    const glm::dvec3 margin(cull.boxMargin + 1e-6);
    int balance = 0;
    std::vector<uint32_t> stack{0};
    while (!stack.empty()) {
        const CullModel::TopNode& node = cull.topNodes[stack.back()];
        stack.pop_back();
        if (!rayHitsBox(origin, inverse, glm::dvec3(node.min) - margin, glm::dvec3(node.max) + margin))
            continue;
        if (node.childCount) {
            for (uint32_t c = 0; c < node.childCount; ++c)
                stack.push_back(node.firstChild + c);
            continue;
        }
        const model::ClusterRecord& cluster = model.clusters[node.cluster];
        if (!(cluster.flags & model::kClusterClosed))
            continue;
        const uint8_t* begin = model.indices.data() + cluster.firstIndex;
        forEachStripTriangle(begin, begin + cluster.indexBytes, [&](uint32_t a, uint32_t b, uint32_t c) {
            const glm::dvec3 v0(decodePosition(cluster, model.vertices[cluster.firstVertex + a]));
            const glm::dvec3 v1(decodePosition(cluster, model.vertices[cluster.firstVertex + b]));
            const glm::dvec3 v2(decodePosition(cluster, model.vertices[cluster.firstVertex + c]));
            // Moller-Trumbore.
            const glm::dvec3 e1 = v1 - v0, e2 = v2 - v0, p = glm::cross(direction, e2);
            const double det = glm::dot(e1, p);
            if (std::abs(det) < 1e-300)
                return;
            const glm::dvec3 s = origin - v0, q = glm::cross(s, e1);
            const double u = glm::dot(s, p) / det, v = glm::dot(direction, q) / det, t = glm::dot(e2, q) / det;
            if (u < 0.0 || v < 0.0 || u + v > 1.0 || t <= 0.0)
                return;
            balance += glm::dot(glm::cross(e1, e2), direction) > 0.0 ? 1 : -1;
        });
    }
    return balance;
}

} // namespace

bool afsmSeesInsideClosed(const CompressedModel& model, const CullModel& cull, glm::vec3 eye, const glm::mat4& cameraViewProj)
{
    if (cull.topNodes.empty())
        return false;
    std::vector<glm::dvec3> origins{glm::dvec3(eye)};
    const glm::dmat4 inverse = glm::inverse(glm::dmat4(cameraViewProj));
    for (int y = -1; y <= 1; ++y)
        for (int x = -1; x <= 1; ++x) {
            const glm::dvec4 p = inverse * glm::dvec4(0.999 * x, 0.999 * y, 0.0, 1.0); // the near plane (Vulkan depth 0)
            origins.push_back(glm::dvec3(p) / p.w);
        }
    const glm::dvec3 direction = glm::normalize(glm::dvec3(0.3141593, 0.8660254, 0.3891902));
    for (const glm::dvec3& origin : origins)
        if (closedCrossings(model, cull, origin, direction) > 0)
            return true;
    return false;
}

void AfsmPass::create(vk::Device& device)
{
    using namespace vk;
    std::vector<VkDescriptorType> sampleTypes = pixelBindingTypes();
    sampleTypes.insert(sampleTypes.end(), {kStorage, kStorage, kStorage, kStorage, kStorage, kStorage, kStorage});
    samples.create(device, "afsm_samples.comp", sampleTypes, sizeof(AfsmSamplesPush));
    samplesSoft.create(device, "afsm_samples.comp.soft", sampleTypes, sizeof(AfsmSamplesPush));
    scan.create(device, "afsm_scan.comp", {kStorage, kStorage}, sizeof(AfsmScanPush));
    table.create(device, "afsm_table.comp", {kStorage}, sizeof(AfsmTablePush));
    bin.create(device, "afsm_bin.comp", binBindingTypes(), sizeof(AfsmBinPush));
    binSoft.create(device, "afsm_bin.comp.soft", binBindingTypes(), sizeof(AfsmBinPush));
    wide.create(device, "afsm_wide.comp", binBindingTypes(), sizeof(AfsmWidePush));
    // Test and measurement switches: the row pass off, or its list and loop budget smaller (the raster path's fallback).
    if (const char* env = std::getenv("PENUMBRA_AFSM_WIDE"))
        wideOn = std::string(env) != "0";
    if (const char* env = std::getenv("PENUMBRA_AFSM_WIDE_CAPACITY"))
        wideCapacityLimit = std::clamp(uint32_t(std::strtoul(env, nullptr, 10)), 1u, uint32_t(PENUMBRA_AFSM_WIDE_CAPACITY));
    if (const char* env = std::getenv("PENUMBRA_AFSM_WIDE_ITERATIONS"))
        wideIterations = std::clamp(uint32_t(std::strtoul(env, nullptr, 10)), 1u, uint32_t(PENUMBRA_AFSM_WIDE_ITERATIONS));
    // And the two passes of a directional light's hard casters: off, or split and refreshed elsewhere.
    if (const char* env = std::getenv("PENUMBRA_AFSM_TWO_PASS"))
        twoPass = std::string(env) != "0";
    if (const char* env = std::getenv("PENUMBRA_AFSM_NEAR_DEPTH"))
        nearDepth = std::clamp(std::strtof(env, nullptr), 0.0f, 1.0f);
    if (const char* env = std::getenv("PENUMBRA_AFSM_REFRESH_SHARE"))
        refreshShare = std::clamp(std::strtod(env, nullptr), 0.0, 1.0);
    params = createBuffer(device, sizeof(AfsmParams), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, MemoryUse::Upload);
    cellMostReadback = createBuffer(device, 16, VK_BUFFER_USAGE_TRANSFER_DST_BIT, MemoryUse::Readback);
    closedBits = createBuffer(device, 16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, MemoryUse::Upload, Addressable::Yes);
    std::memset(closedBits.mapped, 0, 16);
    if (!device.aliasFree)
        return;
    castersSetLayout = createSetLayout(device, castersBindingTypes(), VK_SHADER_STAGE_GEOMETRY_BIT | VK_SHADER_STAGE_FRAGMENT_BIT);
    castersSet = allocateSet(device, castersSetLayout, castersBindingTypes(), castersPool);
    GraphicsPipelineDesc desc;
    desc.vertexShader = "world_casters.vert";
    desc.geometryShader = "afsm_casters.geom";
    desc.fragmentShader = "afsm_casters.frag";
    desc.depthFormat = VK_FORMAT_D32_SFLOAT;
    desc.depthWrite = false;
    desc.depthCompare = VK_COMPARE_OP_LESS;
    desc.depthClamp = true;
    desc.pushBytes = sizeof(AfsmCastersPush);
    casters.create(device, desc, VK_SHADER_STAGE_GEOMETRY_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, castersSetLayout);
    desc.geometryShader = "afsm_soft.geom";
    desc.fragmentShader = "afsm_soft.frag";
    desc.pushBytes = sizeof(AfsmSoftPush);
    softCasters.create(device, desc, VK_SHADER_STAGE_GEOMETRY_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, castersSetLayout);
}

void AfsmPass::destroy(vk::Device& device)
{
    for (vk::ComputeKernel* kernel : {&samples, &samplesSoft, &scan, &table, &bin, &binSoft, &wide})
        kernel->destroy(device);
    casters.destroy(device);
    softCasters.destroy(device);
    if (castersPool)
        vkDestroyDescriptorPool(device.device, castersPool, nullptr);
    if (castersSetLayout)
        vkDestroyDescriptorSetLayout(device.device, castersSetLayout, nullptr);
    castersPool = VK_NULL_HANDLE;
    castersSetLayout = VK_NULL_HANDLE;
    castersSet = VK_NULL_HANDLE;
    for (vk::Buffer* buffer : {&tables[0], &tables[1], &tableSamples, &masks, &params, &clusterMasks, &closedBits, &cellMostReadback, &wideList, &wideReadback})
        vk::destroyBuffer(device, *buffer);
    tableCounts[0] = tableCounts[1] = 0;
    maskWords = maskPixels = clusterMaskWords = wideWords = wideCapacity = 0;
    closedModel = insideModel = nullptr;
    closedCount = 0;
    modelTexels = {};
    modelTexelsComplete = modelVertexTexelsSplit = targetsBound = false;
}

void AfsmPass::bind(vk::Device& device, const AfsmTargets& t)
{
    targets = t;
    slotsAddress = vk::bufferAddress(device, *t.slots);
    std::vector<vk::Binding> bindings = pixelBindings(t.pixels);
    bindings.insert(bindings.end(), {vk::storageBuffer(t.cellFirst->buffer), vk::storageBuffer(t.cellCount->buffer),
                                     vk::storageBuffer(t.shadowed->buffer), vk::storageBuffer(t.far->buffer),
                                     vk::storageBuffer(t.cellDepth->buffer), vk::storageBuffer(t.slotShadowed->buffer),
                                     vk::storageBuffer(t.cellAlive->buffer)});
    samples.write(device, bindings);
    samplesSoft.write(device, bindings);
    scan.write(device, {vk::storageBuffer(t.cellFirst->buffer), vk::storageBuffer(t.blockSums->buffer)});
    targetsBound = true;
    writeBinSets(device);
    std::vector<vk::Binding> casterBindings = castersCommonBindings();
    casterBindings.push_back(vk::storageBuffer(closedBits.buffer));
    casterBindings.push_back(vk::texelBuffer(t.slotTexels));
    if (castersSet)
        vk::writeSet(device, castersSet, casterBindings);
    writeParams();
}

void AfsmPass::bindModel(vk::Device& device, const GpuGeometry& geometry)
{
    const bool compressed = geometry.encoding == GeometryEncoding::Compressed;
    modelTexels = compressed ? geometry.texels : GpuGeometry::TexelViews{};
    modelTexelsComplete = compressed && geometry.texelsComplete;
    modelVertexTexelsSplit = geometry.vertexTexelsSplit;
    writeBinSets(device);
}

// The bindings the casters' sets (raster path) and the compute path's begin with: AfsmCastersBinding's and
// AfsmBinBinding's first eight.
std::vector<vk::Binding> AfsmPass::castersCommonBindings() const
{
    const AfsmTargets& t = targets;
    return {vk::uniformBuffer(t.pixels.frame), vk::texelBuffer(t.cellFirstTexels),
            vk::texelBuffer(t.cellCountTexels), vk::storageBuffer(t.shadowed->buffer),
            vk::storageBuffer(t.far->buffer), vk::texelBuffer(t.cellDepthTexels),
            vk::storageBuffer(t.slotShadowed->buffer), vk::storageBuffer(t.cellAlive->buffer)};
}

// The compute path's sets (afsm_bin, afsm_wide: one layout), once both the targets and a model are bound.
void AfsmPass::writeBinSets(vk::Device& device) const
{
    if (!targetsBound || !modelTexels.nodes)
        return;
    std::vector<vk::Binding> bindings = castersCommonBindings();
    bindings.insert(bindings.end(), {vk::storageBuffer(params.buffer), vk::storageBuffer(closedBits.buffer), vk::texelBuffer(targets.slotTexels),
                                     vk::texelBuffer(modelTexels.nodes), vk::texelBuffer(modelTexels.clusters),
                                     vk::texelBuffer(modelTexels.vertices), vk::texelBuffer(modelTexels.strips)});
    bin.write(device, bindings);
    binSoft.write(device, bindings);
    wide.write(device, bindings);
}

void AfsmPass::writeParams() const
{
    const AfsmParams values{masksAddress, tableAddress, softSamples, softTable.packed(),
                            wideOn ? wideAddress : 0, wideCastersOffset(), wideCapacity};
    std::memcpy(params.mapped, &values, sizeof(values));
}

void AfsmPass::prepareSoft(vk::Device& device, VkCommandBuffer cmd, uint32_t lightSamples, bool rectangle)
{
    const AfsmTableSize size = afsmTableSize(lightSamples);
    const uint32_t pixels = targets.width * targets.height;
    // Masks for the image: they must start at zero (each resolve clears what it read).
    if (maskPixels != pixels || maskWords < size.words) {
        vkDeviceWaitIdle(device.device);
        vk::destroyBuffer(device, masks);
        maskPixels = maskWords = 0;
        masks = vk::createBuffer(device, VkDeviceSize(pixels) * size.words * 4, kStorageDst, vk::MemoryUse::DeviceLocal, vk::Addressable::Yes);
        masksAddress = vk::bufferAddress(device, masks);
        vk::memoryBarrier(cmd, kCompute | kFragment, kStorageRW, kClear, kTransferWrite);
        vkCmdFillBuffer(cmd, masks.buffer, 0, VK_WHOLE_SIZE, 0);
        vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute | kFragment, kStorageRW);
        maskPixels = pixels;
        maskWords = size.words;
    }
    const int shape = rectangle ? 0 : 1;
    if (tableCounts[shape] != lightSamples) {
        if (tables[shape].size < size.bytes()) {
            vkDeviceWaitIdle(device.device);
            vk::destroyBuffer(device, tables[shape]);
            tables[shape] = vk::createBuffer(device, size.bytes(), kStorageDst, vk::MemoryUse::DeviceLocal, vk::Addressable::Yes);
        }
        if (!tableSamples.buffer) {
            tableSamples = vk::createBuffer(device, VkDeviceSize(PENUMBRA_AFSM_MAX_SAMPLES) * 8, kStorageDst, vk::MemoryUse::DeviceLocal);
            table.write(device, {vk::storageBuffer(tableSamples.buffer)});
        }
        AfsmTablePush push{vk::bufferAddress(device, tables[shape]), PENUMBRA_AFSM_TABLE_SAMPLES,
                           rectangle ? uint32_t(PENUMBRA_LIGHT_RECTANGLE) : uint32_t(PENUMBRA_LIGHT_DISK), lightSamples, size.packed()};
        vk::memoryBarrier(cmd, kCompute | kFragment, kStorageRead, kCompute, kStorageRW);
        table.bind(cmd);
        table.push(cmd, push);
        vkCmdDispatch(cmd, groupCount(lightSamples, PENUMBRA_AFSM_TABLE_GROUP), 1, 1);
        vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRead);
        push.phase = PENUMBRA_AFSM_TABLE_MASKS;
        table.push(cmd, push);
        vkCmdDispatch(cmd, groupCount(size.angles * size.distances, PENUMBRA_AFSM_TABLE_GROUP), size.words, 1);
        vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute | kFragment, kStorageRead);
        tableCounts[shape] = lightSamples;
    }
    tableAddress = vk::bufferAddress(device, tables[shape]);
    softSamples = lightSamples;
    softTable = size;
    writeParams();
}

uint64_t AfsmPass::prepareModel(vk::Device& device, const CompressedModel* model)
{
    const void* key = model ? static_cast<const void*>(model->clusters.data()) : nullptr;
    if (closedBits.buffer && key == closedModel)
        return closedCount;
    const size_t clusters = model ? model->clusters.size() : 0;
    const VkDeviceSize bytes = std::max<VkDeviceSize>((clusters + 31) / 32 * 4, 16);
    if (closedBits.size < bytes) {
        vkDeviceWaitIdle(device.device);
        vk::destroyBuffer(device, closedBits);
        closedBits = vk::createBuffer(device, bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryUse::Upload, vk::Addressable::Yes);
        if (targets.cellFirst)
            bind(device, targets);
    }
    std::vector<uint32_t> bits(closedBits.size / 4, 0u);
    closedCount = 0;
    for (size_t c = 0; c < clusters; ++c)
        if (model->clusters[c].flags & model::kClusterClosed) {
            bits[c >> 5] |= 1u << (c & 31);
            ++closedCount;
        }
    vk::writeMapped(closedBits, bits.data(), bits.size() * sizeof(uint32_t));
    maxLeafTriangles = maxLeafBytes = 0;
    if (model)
        for (const model::Node& node : model->nodes)
            for (uint32_t c = 0; c < 4; ++c) {
                if (model::childKind(node, c) != model::ChildKind::Leaf)
                    continue;
                const uint8_t* strips = model->indices.data() + model->clusters[node.cluster].firstIndex + (node.child[c] & 0xFFFF);
                uint32_t triangles = 0;
                forEachStripTriangle(strips, strips + (node.child[c] >> 16), [&](uint32_t, uint32_t, uint32_t) { ++triangles; });
                maxLeafTriangles = std::max(maxLeafTriangles, triangles);
                maxLeafBytes = std::max(maxLeafBytes, node.child[c] >> 16);
            }
    closedModel = key;
    insideModel = nullptr;
    return closedCount;
}

bool AfsmPass::computePathFits() const
{
    return afsmBinIterations(maxLeafTriangles, maxLeafBytes) <= PENUMBRA_AFSM_FRAGMENT_ITERATIONS;
}

bool AfsmPass::closedBackFaces(const CompressedModel& model, const CullModel& cull, glm::vec3 eye, const glm::mat4& cameraViewProj)
{
    if (!closedCount)
        return false;
    if (insideModel != closedModel || insideCamera != cameraViewProj || insideEye != eye) {
        insideAnswer = afsmSeesInsideClosed(model, cull, eye, cameraViewProj);
        insideModel = closedModel;
        insideCamera = cameraViewProj;
        insideEye = eye;
    }
    return !insideAnswer;
}

void AfsmPass::clear(VkCommandBuffer cmd) const
{
    vk::memoryBarrier(cmd, kCompute | kFragment, kStorageRead, kClear, kTransferWrite);
    vkCmdFillBuffer(cmd, targets.shadowed->buffer, 0, VK_WHOLE_SIZE, 0);
    vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute | kFragment, kStorageRW);
}

AfsmSamplesPush AfsmPass::samplesPush(uint32_t lightIndex, uint32_t mode, uint32_t layer, const glm::mat4& viewProj, bool cube,
                                      float originOffset, bool soft) const
{
    AfsmSamplesPush push{viewProj, slotsAddress, 0, 0, lightIndex, mode, layer, layerGrid(soft), originOffset, cube ? 1u : 0u, 0, 0,
                         afsmSliceSamples(soft ? softSamples : 0), 0};
    if (soft) {
        push.masks = masksAddress;
        push.table = tableAddress;
        push.samples = softSamples;
        push.tableSize = softTable.packed();
    }
    return push;
}

void AfsmPass::dispatchPixels(VkCommandBuffer cmd, const AfsmSamplesPush& push, bool soft, bool parallel) const
{
    const vk::ComputeKernel& kernel = soft ? samplesSoft : samples;
    // afsm_samples' mode, and whether the list writes sheared slots, are specialization constants.
    kernel.bind(cmd, vk::Specialization{push.mode, parallel && !soft ? 1u : 0u});
    kernel.push(cmd, push);
    vkCmdDispatch(cmd, groupCount(targets.width, PENUMBRA_SHADE_GROUP_SIZE), groupCount(targets.height, PENUMBRA_SHADE_GROUP_SIZE), 1);
}

void AfsmPass::dispatchBlocks(VkCommandBuffer cmd, const AfsmSamplesPush& push, bool soft) const
{
    // One invocation per block of 8x8 cells (afsm_samples.comp.glsl: blockDepth), then a barrier for what reads them.
    const vk::ComputeKernel& kernel = soft ? samplesSoft : samples;
    kernel.bind(cmd, vk::Specialization{PENUMBRA_AFSM_BLOCKS, 0u});
    kernel.push(cmd, push);
    const uint32_t blocks = (push.gridSize + 7) / 8;
    vkCmdDispatch(cmd, groupCount(blocks, PENUMBRA_SHADE_GROUP_SIZE), groupCount(blocks, PENUMBRA_SHADE_GROUP_SIZE), 1);
    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
}

void AfsmPass::recordSamples(VkCommandBuffer cmd, uint32_t lightIndex, uint32_t layer, const glm::mat4& viewProj, bool cube, float originOffset,
                             bool soft, bool parallel) const
{
    const uint32_t grid = layerGrid(soft), cells = grid * grid;
    // The previous layer's casters read the lists, and its copy read the cells' depths.
    vk::memoryBarrier(cmd, kFragment | kGeometry | kCompute | kCopy, kStorageRead | kTransferRead, kClear, kTransferWrite);
    vkCmdFillBuffer(cmd, targets.cellFirst->buffer, 0, VkDeviceSize(cells + 1) * 4, 0);
    vkCmdFillBuffer(cmd, targets.cellCount->buffer, 0, VkDeviceSize(cells) * 4, 0);
    vkCmdFillBuffer(cmd, targets.far->buffer, 0, offsetof(AfsmFar, crowded), 0);
    vkCmdFillBuffer(cmd, targets.far->buffer, offsetof(AfsmFar, crowded), 2 * sizeof(uint32_t), ~0u); // the crowded cells' minima
    vkCmdFillBuffer(cmd, targets.far->buffer, offsetof(AfsmFar, crowded) + 8, 2 * sizeof(uint32_t), 0);
    vkCmdFillBuffer(cmd, targets.far->buffer, offsetof(AfsmFar, parallel), sizeof(AfsmFar::parallel), 0); // the list writes it (parallel)
    vkCmdFillBuffer(cmd, targets.cellDepth->buffer, 0, VkDeviceSize(cells + afsmBlockCount(grid)) * 4, 0);
    vkCmdFillBuffer(cmd, targets.slotShadowed->buffer, 0, VK_WHOLE_SIZE, 0); // no slot shadowed yet
    vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute, kStorageRW);
    dispatchPixels(cmd, samplesPush(lightIndex, PENUMBRA_AFSM_COUNT, layer, viewProj, cube, originOffset, soft), soft);
    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
    dispatchBlocks(cmd, samplesPush(lightIndex, PENUMBRA_AFSM_BLOCKS, layer, viewProj, cube, originOffset, soft), soft);

    // Counts to offsets: block scans, the blocks' totals, then each block's prefix added.
    const uint32_t blocks = groupCount(cells, kScanBlock);
    scan.bind(cmd);
    for (uint32_t phase = 0; phase < 3; ++phase) {
        scan.push(cmd, AfsmScanPush{cells, phase});
        vkCmdDispatch(cmd, phase == 1 ? 1 : blocks, 1, 1);
        vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
    }
    dispatchPixels(cmd, samplesPush(lightIndex, PENUMBRA_AFSM_LIST, layer, viewProj, cube, originOffset, soft), soft, parallel);
    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kFragment | kGeometry | kCompute | kCopy,
                      kStorageRW | kTransferRead | VK_ACCESS_2_SHADER_SAMPLED_READ_BIT); // the slots and the cells: texel fetches too
    // Every listed sample is alive (not shadowed) until the casters run: the cells' counts, as the list filled them
    // (a copy instead of an atomic per sample in the list pass).
    const VkBufferCopy counts{0, 0, VkDeviceSize(cells) * 4};
    vkCmdCopyBuffer(cmd, targets.cellCount->buffer, targets.cellAlive->buffer, 1, &counts);
    vk::memoryBarrier(cmd, kCopy, kTransferWrite, kFragment | kCompute, kStorageRW);

    // The cells' farthest sample depths into the depth image the casters are tested against.
    const vk::Image& depth = *targets.depth;
    vk::transition(cmd, depth, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, kDepthTests,
                   VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT, kCopy, kTransferWrite);
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_DEPTH_BIT, 0, 0, 1};
    region.imageExtent = {grid, grid, 1};
    vkCmdCopyBufferToImage(cmd, targets.cellDepth->buffer, depth.image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &region);
    vk::transition(cmd, depth, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL, kCopy, kTransferWrite,
                   kDepthTests, VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT);
}

bool AfsmPass::computePathOn(const Culling& culling, const GpuGeometry& geometry, VkDeviceAddress modelTable) const
{
    // (modelTexels: bindModel wrote the compute path's sets.)
    return geometry.encoding == GeometryEncoding::Compressed && modelTable && culling.model && geometry.nodeCount && computePathFits() &&
           modelTexels.nodes != VK_NULL_HANDLE;
}

bool AfsmPass::rowPassUsed(const Culling& culling, const GpuGeometry& geometry, VkDeviceAddress modelTable) const
{
    return !geometry.paged() && wideOn && computePathOn(culling, geometry, modelTable);
}

bool AfsmPass::nearCoverPays(const Culling& culling, uint32_t view, const glm::mat4& viewProj) const
{
    const CullModel& model = *culling.model;
    // The grid is orthographic (a directional light's): each clip coordinate is affine in the point, its range over
    // a box the centre's value plus or minus the half extents' absolute weights (afsm_bin.comp: afsmLeafRect).
    const glm::mat3 weights(glm::abs(glm::vec3(viewProj[0])), glm::abs(glm::vec3(viewProj[1])), glm::abs(glm::vec3(viewProj[2])));
    double covered = 0.0; // of the grid's [-1, 1]^2
    for (uint32_t c : culling.viewClusters(view)) {
        const glm::vec3 centre = glm::vec3(viewProj * glm::vec4(0.5f * (model.clusterMin[c] + model.clusterMax[c]), 1.0f));
        const glm::vec3 reach = weights * (0.5f * (model.clusterMax[c] - model.clusterMin[c]));
        const glm::vec2 lo = glm::max(glm::vec2(centre - reach), glm::vec2(-1.0f)), hi = glm::min(glm::vec2(centre + reach), glm::vec2(1.0f));
        if (centre.z - reach.z < nearDepth && hi.x > lo.x && hi.y > lo.y)
            covered += double(hi.x - lo.x) * double(hi.y - lo.y);
    }
    return covered >= refreshShare * 4.0;
}

void AfsmPass::recordRefresh(VkCommandBuffer cmd, uint32_t lightIndex, uint32_t layer, const glm::mat4& viewProj, float originOffset)
{
    ++refreshedLayers;
    const uint32_t grid = layerGrid(false);
    // The first pass's tests read the depths (afsmBlocksBehind).
    vk::memoryBarrier(cmd, kCompute | kFragment, kStorageRead | VK_ACCESS_2_SHADER_SAMPLED_READ_BIT, kClear, kTransferWrite);
    vkCmdFillBuffer(cmd, targets.cellDepth->buffer, 0, VkDeviceSize(grid * grid + afsmBlockCount(grid)) * 4, 0);
    vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute, kStorageRW);
    dispatchPixels(cmd, samplesPush(lightIndex, PENUMBRA_AFSM_REFRESH, layer, viewProj, false, originOffset, false), false);
    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
    dispatchBlocks(cmd, samplesPush(lightIndex, PENUMBRA_AFSM_BLOCKS, layer, viewProj, false, originOffset, false), false);
    // The depth image of the raster path keeps the first counts: farther, so still conservative.
    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute | kFragment | kGeometry, kStorageRW | VK_ACCESS_2_SHADER_SAMPLED_READ_BIT);
}

void AfsmPass::recordCasters(VkCommandBuffer cmd, vk::Device& device, Culling& culling, const GpuGeometry& geometry,
                             VkDeviceAddress modelTable, const CasterLayer& layer, const std::function<void()>& afterCompute,
                             const PagedCasters* paged, const std::function<void()>& afterRows)
{
    if (geometry.paged() && !paged)
        fail("afsm", "paged geometry needs the casters' ranges");
    if (!castersSet)
        fail("afsm", "this device lacks geometry shaders or fragment-shader stores (needed to rasterize the casters)");
    const uint32_t grid = layerGrid(layer.soft);
    const uint32_t parallel = layer.parallel && !layer.soft ? 1u : 0u; // sheared slots (afsm_bin's and afsm_wide's kParallel)
    const uint32_t split = modelVertexTexelsSplit ? 1u : 0u;          // afsm_bin's kSplitVertexTexels
    const uint32_t trim = layer.trimRows && !layer.soft ? 1u : 0u;    // afsm_bin's and afsm_wide's kTrimRows
    // The compute path: the small casters of the view's clusters (compressed model only).
    // (modelTexels: bindModel wrote the compute path's sets.)
    const bool compute = computePathOn(culling, geometry, modelTable);
    computeUsed = compute;
    // afsm_wide.comp takes the hard casters the compute path leaves.
    const bool useWide = compute && wideOn && !layer.soft && afterRows;
    if (compute) {
        const uint32_t clusters = uint32_t(culling.model->clusterMin.size());
        const uint32_t words = (clusters + 31) / 32;
        if (clusterMaskWords < words) {
            vkDeviceWaitIdle(device.device);
            vk::destroyBuffer(device, clusterMasks);
            clusterMaskWords = 0;
            clusterMasks = vk::createBuffer(device, VkDeviceSize(words) * 4 * 6 * PENUMBRA_MAX_LIGHTS, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                            vk::MemoryUse::Upload, vk::Addressable::Yes);
            clusterMaskWords = words;
        }
        // The list holds every triangle of the model, up to PENUMBRA_AFSM_WIDE_CAPACITY (or the environment's smaller one).
        const uint32_t capacity = uint32_t(std::min<uint64_t>(wideCapacityLimit, std::max<uint64_t>(culling.model->totalTriangles, 1)));
        if (wideWords < words || wideCapacity != capacity) {
            vkDeviceWaitIdle(device.device);
            vk::destroyBuffer(device, wideList);
            wideWords = std::max(wideWords, words);
            wideCapacity = capacity;
            wideList = vk::createBuffer(device, wideCastersOffset() + VkDeviceSize(wideCapacity) * sizeof(AfsmWideCaster),
                                        VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT |
                                            VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                                        vk::MemoryUse::DeviceLocal, vk::Addressable::Yes);
            wideAddress = vk::bufferAddress(device, wideList);
            vk::destroyBuffer(device, wideReadback);
            wideReadback = vk::createBuffer(device, 12 + VkDeviceSize(wideWords) * 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::MemoryUse::Readback);
            writeParams();
        }
        std::vector<uint32_t> bits(clusterMaskWords, 0u);
        for (uint32_t c : culling.viewClusters(layer.view))
            bits[c >> 5] |= 1u << (c & 31);
        vk::writeMapped(clusterMasks, bits.data(), bits.size() * sizeof(uint32_t), size_t(layer.maskSlot) * clusterMaskWords * 4);
        AfsmBinPush push{layer.viewProj,
                         modelTable,
                         vk::bufferAddress(device, clusterMasks) + VkDeviceSize(layer.maskSlot) * clusterMaskWords * 4,
                         geometry.nodeCount,
                         layer.lightIndex,
                         grid,
                         layer.originOffset,
                         float(PENUMBRA_AFSM_COMPUTE_CELLS),
                         0,
                         0,
                         layer.closedBackFaces ? 1u : 0u,
                         0,
                         0};
        std::memcpy(&push.rangeBegin, &layer.nearFrom, 4); // in core: this pass's leaves (paged: the ranges below)
        std::memcpy(&push.rangeEnd, &layer.nearTo, 4);
        if (useWide) { // an empty list, no cluster marked
            vkCmdFillBuffer(cmd, wideList.buffer, 0, wideCastersOffset(), 0);
            vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute, kStorageRW);
        }
        const vk::ComputeKernel& kernel = layer.soft ? binSoft : bin;
        const Groups2D groups = spreadGroups(groupCount(geometry.nodeCount, PENUMBRA_AFSM_BIN_GROUP), device.properties.limits.maxComputeWorkGroupCount[0]);
        if (geometry.paged()) {
            // One dispatch per range, resident in turn (the nodes through the node table, kGeometryBudget).
            push.nodeTable = vk::bufferAddress(device, geometry.nodeTable);
            push.nodeRecords = vk::bufferAddress(device, geometry.pool);
            for (size_t j = 0; j < paged->ranges.size(); ++j) {
                if (paged->ranges[j].empty())
                    continue;
                paged->makeResident(paged->ranges[j]);
                push.rangeBegin = paged->ranges[j].front();
                push.rangeEnd = paged->ranges[j].back() + 1;
                kernel.bind(cmd, vk::Specialization{1u, parallel, 0u, split, 0u});
                kernel.push(cmd, push);
                vkCmdDispatch(cmd, groups.x, groups.y, 1);
                vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
            }
        } else {
            kernel.bind(cmd, vk::Specialization{0u, parallel, modelTexelsComplete ? 1u : 0u, split, trim});
            kernel.push(cmd, push);
            vkCmdDispatch(cmd, groups.x, groups.y, 1);
        }
        vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
        afterCompute();
        if (useWide) { // the casters binned to the list: its dispatch, then the tests
            const AfsmWidePush widePush{layer.viewProj, wideAddress, grid, layer.lightIndex, wideCapacity, wideCastersOffset(), wideIterations, 0};
            // Two passes, each after its indirect dispatch is written: the list, then the casters its subgroups
            // reached past their loop budget, one a subgroup.
            for (const auto& [writeDispatch, test, dispatch] :
                 {std::tuple{PENUMBRA_AFSM_WIDE_DISPATCH, PENUMBRA_AFSM_WIDE_TEST, offsetof(AfsmWideHeader, dispatch)},
                  std::tuple{PENUMBRA_AFSM_WIDE_ALONE_DISPATCH, PENUMBRA_AFSM_WIDE_TEST_ALONE, offsetof(AfsmWideHeader, aloneDispatch)}}) {
                wide.bind(cmd, vk::Specialization{uint32_t(writeDispatch), parallel});
                wide.push(cmd, widePush);
                vkCmdDispatch(cmd, 1, 1, 1);
                vk::memoryBarrier(cmd, kCompute, kStorageWrite, VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT | kCompute,
                                  VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT | kStorageRW);
                wide.bind(cmd, vk::Specialization{uint32_t(test), parallel, trim});
                wide.push(cmd, widePush);
                vkCmdDispatchIndirect(cmd, wideList.buffer, dispatch);
                vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
            }
            if (layer.countShadowed) { // the pixels shadowed so far: four an invocation
                ++twoPassLayers;
                wide.bind(cmd, vk::Specialization{uint32_t(PENUMBRA_AFSM_WIDE_COUNT_SHADOWED), parallel});
                wide.push(cmd, widePush);
                vkCmdDispatch(cmd, groupCount(groupCount(targets.width * targets.height, 4), PENUMBRA_AFSM_WIDE_GROUP), 1, 1);
            }
            // Whether it left clusters to the raster path: read back once the commands ran (afterRows).
            vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCopy, kTransferRead);
            const VkBufferCopy regions[4] = {{offsetof(AfsmWideHeader, count), 0, 4},
                                             {offsetof(AfsmWideHeader, marked), 4, 4},
                                             {offsetof(AfsmWideHeader, shadowedPixels), 8, 4},
                                             {sizeof(AfsmWideHeader), 12, VkDeviceSize(wideWords) * 4}};
            vkCmdCopyBuffer(cmd, wideList.buffer, wideReadback.buffer, 4, regions);
            vk::memoryBarrier(cmd, kCopy, kTransferWrite, kHost, VK_ACCESS_2_HOST_READ_BIT);
        }
        vk::memoryBarrier(cmd, kCompute, kStorageWrite, kFragment | kGeometry, kStorageRW);
    } else {
        afterCompute();
    }
    wideMarked.clear();
    if (useWide) {
        // The marks, read back: no cluster marked (every caster tested) and there is no raster path.
        afterRows();
        const uint32_t* header = static_cast<const uint32_t*>(wideReadback.mapped);
        wideCasters += header[0];
        lastShadowed = header[2];
        if (header[1] == 0) {
            culling.markView(cmd, layer.view, false); // the view's timestamps, as its draws would have written
            culling.markView(cmd, layer.view, true);
            return;
        }
        ++wideRasterLayers;
        // The marked clusters (in core: drawn alone, below; paged: the whole view, the geometry shader keeping theirs).
        const uint32_t* bits = header + 3;
        for (uint32_t word = 0; word < wideWords && !geometry.paged(); ++word)
            for (uint32_t b = bits[word]; b; b &= b - 1)
                wideMarked.push_back(32 * word + uint32_t(std::countr_zero(b)));
    }
    // The raster path: the other casters (all of them without the compute path).
    VkRenderingAttachmentInfo depthAttachment{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    depthAttachment.imageView = targets.depth->view;
    depthAttachment.imageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
    depthAttachment.loadOp = VK_ATTACHMENT_LOAD_OP_LOAD;
    depthAttachment.storeOp = VK_ATTACHMENT_STORE_OP_NONE;
    VkRenderingInfo rendering{VK_STRUCTURE_TYPE_RENDERING_INFO};
    rendering.renderArea = {{0, 0}, {grid, grid}};
    rendering.layerCount = 1;
    rendering.pDepthAttachment = &depthAttachment;
    const float computeCells = compute ? float(PENUMBRA_AFSM_COMPUTE_CELLS) : 0.0f;
    const uint32_t closed = layer.closedBackFaces ? 1u : 0u;
    AfsmCastersPush hardPush{layer.viewProj, layer.lightIndex, grid, layer.originOffset, computeCells, closed, 0, useWide ? wideAddress : 0};
    AfsmSoftPush softPush{layer.viewProj, masksAddress, tableAddress, layer.lightIndex, grid, layer.originOffset,
                          softSamples,   softTable.packed(), computeCells, closed, 0};
    const vk::RasterPipelines& pipelines = layer.soft ? softCasters : casters;
    const VkPipeline pipeline = pipelines[geometry.encoding];
    const VkDescriptorSet set = castersSet;
    auto begin = [&](bool) {
        vkCmdBeginRendering(cmd, &rendering);
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline);
        vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipelines.layout, 0, 1, &set, 0, nullptr);
        vk::setViewport(cmd, grid, grid);
        const VkShaderStageFlags stages = VK_SHADER_STAGE_GEOMETRY_BIT | VK_SHADER_STAGE_FRAGMENT_BIT;
        if (layer.soft)
            vkCmdPushConstants(cmd, pipelines.layout, stages, 0, sizeof(softPush), &softPush);
        else
            vkCmdPushConstants(cmd, pipelines.layout, stages, 0, sizeof(hardPush), &hardPush);
    };
    auto end = [&] { vkCmdEndRendering(cmd); };
    // afsm_wide.comp left only the marked clusters: those alone (in core), else the view's.
    const bool markedOnly = useWide && !geometry.paged() && culling.model;
    auto draw = [&](bool again) {
        if (!markedOnly) {
            if (again)
                culling.recordViewAgain(cmd, layer.view, geometry, begin, end);
            else
                culling.recordView(cmd, layer.view, geometry, begin, end);
            return;
        }
        if (!again)
            culling.markView(cmd, layer.view, false);
        begin(false);
        drawClusters(cmd, geometry, *culling.model, wideMarked.data(), wideMarked.size());
        end();
        if (!again)
            culling.markView(cmd, layer.view, true);
    };
    draw(false);
    // Crowded cells (more samples than one fragment may loop over, afsmSliceSamples): the casters again over those
    // cells, once per further slice of their lists (afsm_casters.geom.glsl, afsm_soft.geom.glsl). The compute path
    // takes no caster of a crowded cell (its work budget is far smaller than a slice).
    const uint32_t slice = afsmSliceSamples(layer.soft ? softSamples : 0);
    for (uint32_t first = slice; first < layer.cellMost; first += slice) {
        vk::memoryBarrier(cmd, kFragment, kStorageWrite, kFragment, kStorageRW);
        hardPush.sliceBegin = softPush.sliceBegin = first;
        draw(true);
        ++sliceDraws;
    }
    vk::memoryBarrier(cmd, kFragment, kStorageWrite, kCompute | kClear, kStorageRW | kTransferWrite);
}

bool AfsmPass::mayCrowd(bool soft) const
{
    return uint64_t(targets.width) * targets.height > afsmSliceSamples(soft ? softSamples : 0);
}

void AfsmPass::recordCellMostReadback(VkCommandBuffer cmd) const
{
    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCopy, kTransferRead);
    const VkBufferCopy region{offsetof(AfsmFar, cellMost), 0, sizeof(uint32_t)};
    vkCmdCopyBuffer(cmd, targets.far->buffer, cellMostReadback.buffer, 1, &region);
    vk::memoryBarrier(cmd, kCopy, kTransferWrite, kHost, VK_ACCESS_2_HOST_READ_BIT);
}

uint32_t AfsmPass::cellMost() const
{
    return *static_cast<const uint32_t*>(cellMostReadback.mapped);
}

void AfsmPass::takeWideStats(uint32_t& casters, uint32_t& rasterLayers, uint32_t& twoPass, uint32_t& refreshed)
{
    casters = wideCasters;
    rasterLayers = wideRasterLayers;
    twoPass = twoPassLayers;
    refreshed = refreshedLayers;
    wideCasters = wideRasterLayers = twoPassLayers = refreshedLayers = 0;
}

uint32_t AfsmPass::takeSliceDraws()
{
    const uint32_t draws = sliceDraws;
    sliceDraws = 0;
    return draws;
}

void AfsmPass::recordResolve(VkCommandBuffer cmd, uint32_t lightIndex, float originOffset, bool soft) const
{
    dispatchPixels(cmd, samplesPush(lightIndex, PENUMBRA_AFSM_RESOLVE, 0, glm::mat4(1.0f), false, originOffset, soft), soft);
    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute | kFragment, kStorageRW);
}

} // namespace penumbra::passes
