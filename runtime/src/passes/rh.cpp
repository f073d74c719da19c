#include "passes/rh.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include <glm/geometric.hpp>

#include "config.h"
#include "passes/pass.h"
#include "penumbra/model_format.h"

namespace penumbra::passes {

namespace {

constexpr VkBufferUsageFlags kTexelUsage = VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT; // rh_traverse.comp reads them as texels
constexpr VkAccessFlags2 kSampledRead = VK_ACCESS_2_SHADER_SAMPLED_READ_BIT;          // ... a texel fetch's access

constexpr VkBufferUsageFlags kStorageDst = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
constexpr VkAccessFlags2 kUniformRead = VK_ACCESS_2_UNIFORM_READ_BIT;
constexpr uint32_t kScanBlock = 2048; // rh_scan.comp's RH_SCAN_BLOCK
constexpr VkPipelineStageFlags2 kGeometry = VK_PIPELINE_STAGE_2_GEOMETRY_SHADER_BIT;
constexpr uint32_t kClosedBit = 1u << 8; // rh_casters.geom: the cluster casts only light-back-facing triangles
constexpr uint32_t RH_GRID_NONE_HOST = 0; // rh.glsli's RH_GRID_NONE

std::vector<VkDescriptorType> castersBindingTypes() { return {vk::kStorage, vk::kStorage, vk::kStorage, vk::kStorage, vk::kStorage, vk::kUniform}; }

// Cells of the receivers' depth grid of `faces` faces and 2^order cells a side, all pyramid levels.
uint32_t gridCells(uint32_t faces, uint32_t order)
{
    uint32_t cells = 0;
    for (uint32_t level = 0; level <= order; ++level)
        cells += faces << (2 * (order - level));
    return cells;
}

// Ray list entries for a width x height image: every pixel, plus the padding: up to 3 per 8x8 tile
// (by pixel), or up to 5 faces' alignment, each at most a 24th of the rays (sorted; rh_build.comp).
uint32_t rayCapacity(uint32_t width, uint32_t height)
{
    const uint32_t pixels = width * height;
    return (pixels + std::max(3 * groupCount(width, 8) * groupCount(height, 8), pixels / 4) + 3) & ~3u;
}

// Counts for rh_scan.comp: `count` of them, rounded up to whole blocks, then one block of block totals.
VkDeviceSize scanBytes(uint32_t count) { return VkDeviceSize(groupCount(count, kScanBlock) + 1) * kScanBlock * 4; }

// The three phases of rh_scan.comp over `count` values (direct dispatches).
void recordScan(VkCommandBuffer cmd, const vk::ComputeKernel& scan, uint32_t count)
{
    const uint32_t blocks = groupCount(count, kScanBlock);
    scan.bind(cmd);
    for (uint32_t phase = 0; phase < 3; ++phase) {
        scan.push(cmd, RhScanPush{count, blocks * kScanBlock, phase, 0});
        vkCmdDispatch(cmd, phase == 1 ? 1 : blocks, 1, 1);
        vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW | kSampledRead);
    }
}

} // namespace

bool closedCullingExact(const CompressedModel& model, const glm::vec3& eye, const glm::vec3& light, bool directional)
{
    // The segment (ray) in double precision; `light` is the direction toward a directional light.
    const glm::dvec3 origin(eye);
    const glm::dvec3 direction = directional ? glm::dvec3(light) : glm::dvec3(light) - origin;
    const double tMax = directional ? std::numeric_limits<double>::infinity() : 1.0;
    for (const model::ClusterRecord& cluster : model.clusters) {
        if (!(cluster.flags & model::kClusterClosed))
            continue;
        // The cluster's box (its quantization range), a little wider.
        double enter = 0.0, leave = tMax;
        for (int a = 0; a < 3; ++a) {
            const double lo = double(cluster.boxMin[a]), hi = lo + double(cluster.step[a]) * 65535.0;
            const double pad = 1e-6 * (std::abs(lo) + std::abs(hi)) + 1e-12;
            if (direction[a] == 0.0) {
                if (origin[a] < lo - pad || origin[a] > hi + pad)
                    leave = -1.0;
                continue;
            }
            double t0 = (lo - pad - origin[a]) / direction[a], t1 = (hi + pad - origin[a]) / direction[a];
            if (t0 > t1)
                std::swap(t0, t1);
            enter = std::max(enter, t0);
            leave = std::min(leave, t1);
        }
        if (enter > leave)
            continue;
        const model::QuantizedVertex* vertices = model.vertices.data() + cluster.firstVertex;
        const uint8_t* strips = model.indices.data() + cluster.firstIndex;
        bool along = false;
        forEachStripTriangle(strips, strips + cluster.indexBytes, [&](uint32_t i, uint32_t j, uint32_t k) {
            const glm::dvec3 a(decodePosition(cluster, vertices[i])), b(decodePosition(cluster, vertices[j])), c(decodePosition(cluster, vertices[k]));
            const glm::dvec3 normal = glm::cross(b - a, c - a);
            if (glm::dot(normal, direction) <= 0.0)
                return; // crossed against the winding, or edge-on: never a failing crossing
            // Moller-Trumbore, inclusive of edges (a crossing on an edge counts).
            const glm::dvec3 e1 = b - a, e2 = c - a, p = glm::cross(direction, e2);
            const double det = glm::dot(e1, p);
            if (det == 0.0)
                return;
            const glm::dvec3 s = origin - a;
            const double u = glm::dot(s, p) / det, eps = 1e-9;
            const glm::dvec3 q = glm::cross(s, e1);
            const double v = glm::dot(direction, q) / det, t = glm::dot(e2, q) / det;
            if (u >= -eps && v >= -eps && u + v <= 1.0 + eps && t >= -eps && t <= tMax + eps)
                along = true;
        });
        if (along)
            return false;
    }
    return true;
}

void RhPass::create(vk::Device& device)
{
    using namespace vk;
    rays.create(device, "rh_rays.comp", {kStorageImage, kStorageImage, kUniform, kStorage, kStorage, kStorage, kStorage, kStorage},
                sizeof(RhRaysPush));
    scanTiles.create(device, "rh_scan.comp", {kStorage}, sizeof(RhScanPush));
    scanKeys.create(device, "rh_scan.comp", {kStorage}, sizeof(RhScanPush));
    const std::vector<VkDescriptorType> buildBindings = {kStorageImage, kStorageImage, kUniform, kStorage, kStorage, kStorage, kStorage, kStorage};
    build.create(device, "rh_build.comp", buildBindings, sizeof(RhBuildPush));
    buildParallel.create(device, "rh_build.comp.parallel", buildBindings, sizeof(RhBuildPush));
    step.create(device, "rh_step.comp", {kStorage}, sizeof(RhStepPush));
    const std::vector<VkDescriptorType> traverseBindings = {kStorageImage, kStorageImage, kUniform, kStorage, kStorage, kStorage,
                                                            kStorage,      kStorage,      kStorage, kStorage, kUniform, kTexels,
                                                            kTexels,       kTexels,       kTexels,  kTexels};
    static_assert(kRhTraverseBindingCount == 16);
    traverse.create(device, "rh_traverse.comp", traverseBindings, sizeof(RhTraversePush));
    traverseParallel.create(device, "rh_traverse.comp.parallel", traverseBindings, sizeof(RhTraversePush));
    if (!device.rayHierarchy)
        return;
    castersSetLayout = createSetLayout(device, castersBindingTypes(), VK_SHADER_STAGE_GEOMETRY_BIT);
    castersSet = allocateSet(device, castersSetLayout, castersBindingTypes(), castersPool);
    GraphicsPipelineDesc desc;
    desc.vertexShader = "world_casters.vert";
    desc.geometryShader = "rh_casters.geom";
    desc.depthWrite = false;
    desc.rasterizerDiscard = true;
    desc.pushBytes = sizeof(RhCastersPush);
    casters.create(device, desc, VK_SHADER_STAGE_GEOMETRY_BIT, castersSetLayout);
}

void RhPass::destroy(vk::Device& device)
{
    for (vk::ComputeKernel* kernel : {&rays, &scanTiles, &scanKeys, &build, &buildParallel, &step, &traverse, &traverseParallel})
        kernel->destroy(device);
    casters.destroy(device);
    if (castersPool)
        vkDestroyDescriptorPool(device.device, castersPool, nullptr);
    if (castersSetLayout)
        vkDestroyDescriptorSetLayout(device.device, castersSetLayout, nullptr);
    castersPool = VK_NULL_HANDLE;
    castersSetLayout = VK_NULL_HANDLE;
    castersSet = VK_NULL_HANDLE;
    destroyTexelViews(device);
    for (vk::Buffer* buffer : {&rayList, &nodes, &trianglesA, &trianglesB, &records, &state, &tileCounts, &keyCounts, &clusterFaces, &depthGrid})
        vk::destroyBuffer(device, *buffer);
    maxRays = maxNodes = mortonTiles = keyCapacity = 0;
}

void RhPass::destroyTexelViews(vk::Device& device)
{
    for (VkBufferView* view : {&rayTexels, &nodeTexels, &triangleTexelsA, &triangleTexelsB, &recordTexels}) {
        if (*view)
            vkDestroyBufferView(device.device, *view, nullptr);
        *view = VK_NULL_HANDLE;
    }
    texelAccess = false;
}

bool RhPass::bound(const RhTargets& t) const
{
    return state.buffer && t.surface == targets.surface && t.shadowed == targets.shadowed && t.shadowed->buffer == shadowedBuffer &&
           t.width == targets.width && t.height == targets.height && t.clusters == targets.clusters;
}

// Hilbert order of the direction keys: about two cells per pixel's ray over
// the faces (a point light's rays spread over six), at most
// PENUMBRA_RH_MAX_SORT_ORDER and what rh_scan.comp takes (2048^2 keys). The
// counting sort's cost grows with the cells; on the interior (320^2, 63 k
// rays) orders 7, 8 and 9 gave the same cone tests within 1%: the rays of one
// cell keep their pixel order (rh_rays.comp), which serves as finer keys.
uint32_t RhPass::sortOrder(uint32_t faces) const
{
    const double cellsPerFace = 2.0 * double(targets.width) * double(targets.height) / double(faces);
    uint32_t order = uint32_t(std::clamp(int(std::lround(std::log2(std::max(cellsPerFace, 1.0)) / 2.0)), 4, int(PENUMBRA_RH_MAX_SORT_ORDER)));
    while ((uint64_t(faces) << (2 * order)) > uint64_t(kScanBlock) * kScanBlock) // rh_scan.comp: one level of block totals
        --order;
    return order;
}

void RhPass::bind(vk::Device& device, const RhTargets& t)
{
    targets = t;
    shadowedBuffer = t.shadowed->buffer;
    if (!state.buffer) {
        // Fixed sizes, made on the first rh frame. The state is host-visible: the frame script reads `done` after each wait.
        records = vk::createBuffer(device, VkDeviceSize(kPairCapacity) * 8, kStorageDst | kTexelUsage, vk::MemoryUse::DeviceLocal);
        trianglesA = vk::createBuffer(device, VkDeviceSize(kTriangleCapacity) * 32, kStorageDst | kTexelUsage, vk::MemoryUse::DeviceLocal);
        trianglesB = vk::createBuffer(device, VkDeviceSize(kTriangleCapacity) * 8, kStorageDst | kTexelUsage, vk::MemoryUse::DeviceLocal);
        state = vk::createBuffer(device, sizeof(RhState),
                                 kStorageDst | VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT, vk::MemoryUse::Readback);
    }
    if (clusterFaces.size < VkDeviceSize(std::max(t.clusters, 1u)) * 4) {
        vk::destroyBuffer(device, clusterFaces);
        clusterFaces = vk::createBuffer(device, VkDeviceSize(std::max(t.clusters, 1u)) * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                        vk::MemoryUse::Upload);
    }
    const uint32_t gridBytes = gridCells(6, gridOrder(6)) * 4;
    if (depthGrid.size < gridBytes) {
        vk::destroyBuffer(device, depthGrid);
        depthGrid = vk::createBuffer(device, gridBytes, kStorageDst, vk::MemoryUse::DeviceLocal);
    }
    if (castersSet)
        vk::writeSet(device, castersSet, {vk::storageBuffer(state.buffer), vk::storageBuffer(trianglesA.buffer),
                                          vk::storageBuffer(trianglesB.buffer), vk::storageBuffer(clusterFaces.buffer),
                                          vk::storageBuffer(depthGrid.buffer), vk::uniformBuffer(t.frame)});
    const uint32_t capacity = rayCapacity(t.width, t.height);
    if (capacity != maxRays) {
        for (vk::Buffer* buffer : {&rayList, &nodes, &tileCounts, &keyCounts})
            vk::destroyBuffer(device, *buffer);
        maxRays = 0;
        uint32_t side = 1;
        while (side < std::max(groupCount(t.width, 8), groupCount(t.height, 8)))
            side *= 2;
        mortonTiles = side * side;
        tileCounts = vk::createBuffer(device, scanBytes(mortonTiles), kStorageDst, vk::MemoryUse::DeviceLocal);
        keyCapacity = std::max(6u << (2 * sortOrder(6)), 1u << (2 * sortOrder(1)));
        keyCounts = vk::createBuffer(device, scanBytes(keyCapacity), kStorageDst, vk::MemoryUse::DeviceLocal);
        uint32_t count = capacity / 4, total = 0;
        for (;;) {
            total += count;
            if (count <= 1)
                break;
            count = (count + 3) / 4;
        }
        rayList = vk::createBuffer(device, VkDeviceSize(capacity) * 4, kStorageDst | kTexelUsage, vk::MemoryUse::DeviceLocal);
        nodes = vk::createBuffer(device, VkDeviceSize(total) * 32, kStorageDst | kTexelUsage, vk::MemoryUse::DeviceLocal);
        maxRays = capacity;
        maxNodes = total;
    }
    destroyTexelViews(device);
    rayTexels = vk::createTexelView(device, rayList, VK_FORMAT_R32G32B32A32_UINT, 16);
    nodeTexels = vk::createTexelView(device, nodes, VK_FORMAT_R32G32B32A32_UINT, 16);
    triangleTexelsA = vk::createTexelView(device, trianglesA, VK_FORMAT_R32G32B32A32_UINT, 16);
    triangleTexelsB = vk::createTexelView(device, trianglesB, VK_FORMAT_R32G32_UINT, 8);
    recordTexels = vk::createTexelView(device, records, VK_FORMAT_R32G32_UINT, 8);
    const VkDeviceSize maxTexels = device.properties.limits.maxTexelBufferElements;
    texelAccess = rayList.size / 16 <= maxTexels && nodes.size / 16 <= maxTexels && trianglesA.size / 16 <= maxTexels &&
                  trianglesB.size / 8 <= maxTexels && records.size / 8 <= maxTexels;
    using namespace vk;
    rays.write(device, {storageImage(t.surface), storageImage(t.albedo), uniformBuffer(t.frame), storageBuffer(rayList.buffer),
                        storageBuffer(state.buffer), storageBuffer(tileCounts.buffer), storageBuffer(keyCounts.buffer),
                        storageBuffer(depthGrid.buffer)});
    scanTiles.write(device, {storageBuffer(tileCounts.buffer)});
    scanKeys.write(device, {storageBuffer(keyCounts.buffer)});
    for (const ComputeKernel* kernel : {&build, &buildParallel})
        kernel->write(device, {storageImage(t.surface), storageImage(t.albedo), uniformBuffer(t.frame), storageBuffer(rayList.buffer),
                               storageBuffer(nodes.buffer), storageBuffer(state.buffer), storageBuffer(t.shadowed->buffer),
                               storageBuffer(depthGrid.buffer)});
    step.write(device, {storageBuffer(state.buffer)});
    for (const ComputeKernel* kernel : {&traverse, &traverseParallel})
        kernel->write(device, {storageImage(t.surface), storageImage(t.albedo), uniformBuffer(t.frame), storageBuffer(rayList.buffer),
                               storageBuffer(nodes.buffer), storageBuffer(trianglesA.buffer), storageBuffer(trianglesB.buffer),
                               storageBuffer(records.buffer), storageBuffer(t.shadowed->buffer), storageBuffer(state.buffer),
                               uniformBuffer(state.buffer), texelBuffer(rayTexels), texelBuffer(nodeTexels), texelBuffer(triangleTexelsA),
                               texelBuffer(triangleTexelsB), texelBuffer(recordTexels)});
}

// The receivers' depth grid: about 4 cells per pixel's ray over the faces, at most
// 2^PENUMBRA_RH_MAX_DEPTH_ORDER a side (interior 250k, 320^2, 256 cells a side: 187 k
// casters left at 64, 141 k at 256, 128 k at 512).
uint32_t RhPass::gridOrder(uint32_t faces) const
{
    const double cellsPerFace = 4.0 * double(targets.width) * double(targets.height) / double(faces);
    return uint32_t(std::clamp(int(std::lround(std::log2(std::max(cellsPerFace, 1.0)) / 2.0)), 4, int(PENUMBRA_RH_MAX_DEPTH_ORDER)));
}

uint32_t RhPass::maxLevels() const
{
    uint32_t count = maxRays / 4, levels = 1;
    while (count > 1) {
        count = (count + 3) / 4;
        ++levels;
    }
    return levels;
}

void RhPass::beginFrame(VkCommandBuffer cmd)
{
    stats = {};
    for (double& ms : profileMs)
        ms = 0.0;
    for (double& ms : profileDepthMs)
        ms = 0.0;
    vk::memoryBarrier(cmd, kCompute | kIndirect | kGeometry, kStorageRW | kIndirectRead | kUniformRead, kClear, kTransferWrite);
    vkCmdFillBuffer(cmd, state.buffer, 0, VK_WHOLE_SIZE, 0);
    vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute, kStorageRW | kSampledRead);
}

void RhPass::recordLight(VkCommandBuffer cmd, uint32_t lightIndex, const Light& light, float originOffset,
                         const RhOptions& options, const GpuGeometry& geometry, const CullModel& model,
                         const std::vector<std::vector<uint32_t>>& viewClusters, const std::function<bool(uint32_t)>& closed,
                         const Mark& built, const Submit& submit, const RhPaging& paging)
{
    if (!castersSet)
        fail("rh", "this device lacks geometry shaders or vertex-stage stores (needed to gather the casters)");
    const uint32_t type = light.type == LightType::Point ? PENUMBRA_LIGHT_POINT : light.type == LightType::Spot ? PENUMBRA_LIGHT_SPOT
                                                                                                                : PENUMBRA_LIGHT_DIRECTIONAL;
    const glm::vec3 lightPosition = light.position;
    // The casters: every view's clusters, each once, with the faces whose views kept it (the
    // cube's layers +x, -x, +y, -y, +z, -z are the list's faces 0, 3, 1, 4, 2, 5: rh_rays.comp).
    static constexpr uint32_t kLayerFace[6] = {0, 3, 1, 4, 2, 5};
    std::vector<uint32_t> clusters;
    for (const std::vector<uint32_t>& view : viewClusters)
        clusters.insert(clusters.end(), view.begin(), view.end());
    std::sort(clusters.begin(), clusters.end());
    clusters.erase(std::unique(clusters.begin(), clusters.end()), clusters.end());
    if (!clusters.empty() && clusters.back() >= targets.clusters)
        fail("rh", "a view's cluster " + std::to_string(clusters.back()) + " is beyond the model's " + std::to_string(targets.clusters));
    uint64_t casterTriangles = 0;
    for (uint32_t cluster : clusters)
        casterTriangles += model.clusterTriangles[cluster];
    faceBits.resize(targets.clusters);
    for (uint32_t cluster : clusters)
        faceBits[cluster] = options.closedCulling && closed(cluster) ? kClosedBit : 0u;
    stats.closedCulled += options.closedCulling ? 1 : 0;
    for (size_t view = 0; view < viewClusters.size(); ++view)
        for (uint32_t cluster : viewClusters[view])
            faceBits[cluster] |= type == PENUMBRA_LIGHT_POINT ? 1u << kLayerFace[std::min<size_t>(view, 5)] : 0x3Fu;
    // Only the listed clusters' words are read: the touched span goes over whole.
    if (!clusters.empty())
        vk::writeMapped(clusterFaces, faceBits.data() + clusters.front(), (clusters.back() - clusters.front() + 1) * sizeof(uint32_t),
                        size_t(clusters.front()) * sizeof(uint32_t));
    static const bool profiling = std::getenv("PENUMBRA_RH_PROFILE") != nullptr;
    auto last = std::chrono::steady_clock::now();
    auto lap = [&](int stage) {
        auto now = std::chrono::steady_clock::now();
        profileMs[stage] += std::chrono::duration<double, std::milli>(now - last).count();
        last = now;
    };
    auto checkpoint = [&](int stage) { // PENUMBRA_RH_PROFILE: a wait after each stage, host-timed
        if (profiling) {
            submit();
            lap(stage);
        }
    };
    const bool parallel = type == PENUMBRA_LIGHT_DIRECTIONAL;
    const vk::ComputeKernel& builder = parallel ? buildParallel : build;
    auto buildStep = [&](const RhBuildPush& push) { // rh_build's mode is a specialization constant
        builder.bind(cmd, vk::Specialization{push.mode});
        builder.push(cmd, push);
    };
    const vk::ComputeKernel& traverser = parallel ? traverseParallel : traverse;
    const uint32_t faces = type == PENUMBRA_LIGHT_POINT ? 6 : 1;
    const uint32_t order = sortOrder(faces);
    const uint32_t keys = faces << (2 * order);
    const uint32_t tilesX = groupCount(targets.width, 8), tilesY = groupCount(targets.height, 8);
    const uint32_t sortMode = options.sort == RhSort::Off ? PENUMBRA_RH_SORT_OFF : options.sort == RhSort::On ? PENUMBRA_RH_SORT_ON
                                                                                                            : PENUMBRA_RH_SORT_AUTO;
    stats.lights++;

    // The light's rays: the tiles' counts (and incoherence), the choice of order, the keys' counts when sorting, the scans, the list.
    vk::memoryBarrier(cmd, kCompute | kIndirect | kGeometry, kStorageRW | kIndirectRead | kUniformRead, kClear, kTransferWrite);
    vkCmdFillBuffer(cmd, state.buffer, 0, offsetof(RhState, peakPairs), 0);
    vkCmdFillBuffer(cmd, tileCounts.buffer, 0, VK_WHOLE_SIZE, 0);
    const uint32_t gridFaces = type == PENUMBRA_LIGHT_POINT ? 6 : type == PENUMBRA_LIGHT_DIRECTIONAL ? 1 : 0;
    const uint32_t depthOrder = gridOrder(std::max(gridFaces, 1u));
    if (gridFaces)
        vkCmdFillBuffer(cmd, depthGrid.buffer, 0, VkDeviceSize(gridCells(gridFaces, depthOrder)) * 4, RH_GRID_NONE_HOST);
    if (sortMode != PENUMBRA_RH_SORT_OFF) {
        vkCmdFillBuffer(cmd, keyCounts.buffer, 0, scanBytes(keys), 0);
        vkCmdFillBuffer(cmd, rayList.buffer, 0, VK_WHOLE_SIZE, 0xFFFFFFFFu); // RH_NO_RAY between the faces
    }
    vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute, kStorageRW | kSampledRead);
    auto raysPass = [&](uint32_t mode, bool indirect) {
        rays.bind(cmd, vk::Specialization{mode}); // the mode is a specialization constant
        rays.push(cmd, RhRaysPush{lightIndex, mode, originOffset, order, sortMode == PENUMBRA_RH_SORT_AUTO ? 1u : 0u, gridFaces, depthOrder, 0});
        if (indirect)
            vkCmdDispatchIndirect(cmd, state.buffer, offsetof(RhState, keyDispatch));
        else
            vkCmdDispatch(cmd, tilesX, tilesY, 1);
        vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW | kSampledRead);
    };
    raysPass(PENUMBRA_RH_RAYS_COUNT, false);
    for (uint32_t level = 1; gridFaces && level <= depthOrder; ++level) {
        const uint32_t side = 1u << (depthOrder - level);
        buildStep(RhBuildPush{lightIndex, PENUMBRA_RH_BUILD_GRID, level, 0, originOffset, depthOrder, 0, 0, 0, gridFaces, 0, 0});
        vkCmdDispatch(cmd, groupCount(gridFaces * side * side, PENUMBRA_RH_GROUP_SIZE), 1, 1);
        vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW | kSampledRead);
    }
    buildStep(RhBuildPush{lightIndex, PENUMBRA_RH_BUILD_DECIDE, 0, 0, originOffset, sortMode, tilesX, tilesY,
                                  groupCount(keys, kScanBlock), faces, uint32_t(std::min<uint64_t>(casterTriangles, UINT32_MAX)), 0});
    vkCmdDispatch(cmd, 1, 1, 1);
    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute | kIndirect, kStorageRW | kSampledRead | kIndirectRead);
    if (sortMode != PENUMBRA_RH_SORT_ON)
        recordScan(cmd, scanTiles, mortonTiles);
    if (sortMode != PENUMBRA_RH_SORT_OFF) {
        raysPass(PENUMBRA_RH_RAYS_KEYS, true);
        const uint32_t blocks = groupCount(keys, kScanBlock);
        scanKeys.bind(cmd);
        for (uint32_t phase = 0; phase < 3; ++phase) {
            scanKeys.push(cmd, RhScanPush{keys, blocks * kScanBlock, phase, 0});
            vkCmdDispatchIndirect(cmd, state.buffer, phase == 1 ? offsetof(RhState, scanPhase1) : offsetof(RhState, scanDispatch));
            vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW | kSampledRead);
        }
        // Each face on whole subtrees; the slots between them stay RH_NO_RAY.
        buildStep(RhBuildPush{lightIndex, PENUMBRA_RH_BUILD_FACES, 0, 0, originOffset, sortMode, 0, 0, 0, faces, 0, 0});
        vkCmdDispatch(cmd, 1, 1, 1);
        vk::memoryBarrier(cmd, kCompute | kClear, kStorageWrite | kTransferWrite, kCompute, kStorageRW | kSampledRead);
    }
    raysPass(PENUMBRA_RH_RAYS_LIST, false);
    checkpoint(0);

    // The hierarchy, bottom-up: every level dispatched for its largest size, idle beyond the light's.
    const uint32_t levels = maxLevels();
    auto buildHierarchy = [&](bool skipShadowed) {
        buildStep(RhBuildPush{lightIndex, PENUMBRA_RH_BUILD_INIT, 0, 0, originOffset, 0, 0, 0, 0, faces, 0, 0});
        vkCmdDispatch(cmd, 1, 1, 1);
        vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW | kSampledRead);
        uint32_t count = maxRays / 4;
        for (uint32_t level = 0; level < levels; ++level) {
            buildStep(RhBuildPush{lightIndex, level == 0 ? PENUMBRA_RH_BUILD_LEAVES : PENUMBRA_RH_BUILD_LEVEL, level,
                                          skipShadowed ? 1u : 0u, originOffset, 0, 0, 0, 0, faces, 0, 0});
            const Groups2D groups = spreadGroups(groupCount(count, PENUMBRA_RH_GROUP_SIZE), 65535u);
            vkCmdDispatch(cmd, groups.x, groups.y, 1);
            vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW | kSampledRead | kUniformRead);
            count = (count + 3) / 4;
        }
    };
    // Early accept: the rays under the nodes found covered since the last resolve are shadowed.
    const auto* hostState = static_cast<const RhState*>(state.mapped);
    uint32_t acceptedResolved = 0; // lightAccepted is reset with the light's words (read only after a wait)
    auto resolveAccepted = [&] {
        if (!options.earlyAccept || hostState->lightAccepted == acceptedResolved)
            return;
        acceptedResolved = hostState->lightAccepted;
        buildStep(RhBuildPush{lightIndex, PENUMBRA_RH_BUILD_RESOLVE, 0, 0, originOffset, 0, 0, 0, 0, faces, 0, 0});
        const Groups2D groups = spreadGroups(groupCount(maxRays / 4, PENUMBRA_RH_GROUP_SIZE), 65535u);
        vkCmdDispatch(cmd, groups.x, groups.y, 1);
        vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW | kSampledRead);
        if (profiling) {
            submit();
            lap(4);
        }
    };
    // The casters, in batches that fit the triangle list, each traversing the hierarchy until done.
    // Paged geometry: where each range of resident clusters ends (batches stay within one).
    std::vector<std::vector<uint32_t>> ranges;
    if (paging.cut)
        ranges = paging.cut(clusters);
    std::vector<size_t> rangeEnds;
    for (const std::vector<uint32_t>& range : ranges)
        rangeEnds.push_back((rangeEnds.empty() ? 0 : rangeEnds.back()) + range.size());
    auto traverseCasters = [&](uint32_t select) {
        size_t begin = 0, range = 0, limit = clusters.size();
        while (begin < clusters.size()) {
            if (!rangeEnds.empty() && begin == (range == 0 ? 0 : rangeEnds[range - 1])) {
                while (ranges[range].empty())
                    ++range;
                paging.makeResident(ranges[range]);
                limit = rangeEnds[range++];
            }
            size_t end = begin;
            uint64_t batchTriangles = 0;
            while (end < limit && (end == begin || batchTriangles + model.clusterTriangles[clusters[end]] <= kTriangleCapacity))
                batchTriangles += model.clusterTriangles[clusters[end++]];
            if (batchTriangles > kTriangleCapacity)
                fail("rh", "a cluster of " + std::to_string(batchTriangles) + " triangles exceeds the caster list");
            // Reset the batch's words: done .. rootCursor (the grid, written by compute, read by the casters).
            vk::memoryBarrier(cmd, kCompute, kStorageWrite, kGeometry, kStorageRead);
            vk::memoryBarrier(cmd, kCompute | kIndirect | kGeometry, kStorageRW | kIndirectRead | kUniformRead, kClear, kTransferWrite);
            vkCmdFillBuffer(cmd, state.buffer, offsetof(RhState, done), offsetof(RhState, sorted) - offsetof(RhState, done), 0);
            vk::memoryBarrier(cmd, kClear, kTransferWrite, kGeometry | kCompute, kStorageRW | kSampledRead);
            VkRenderingInfo rendering{VK_STRUCTURE_TYPE_RENDERING_INFO};
            rendering.renderArea = {{0, 0}, {1, 1}};
            rendering.layerCount = 1;
            vkCmdBeginRendering(cmd, &rendering);
            vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, casters[geometry.encoding]);
            vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, casters.layout, 0, 1, &castersSet, 0, nullptr);
            vk::setViewport(cmd, 1, 1);
            const RhCastersPush castersPush{glm::vec4(lightPosition, float(PENUMBRA_RH_LARGE_ANGLE)),
                                            glm::vec4(-glm::normalize(light.direction), originOffset),
                                            kTriangleCapacity,
                                            select,
                                            type == PENUMBRA_LIGHT_POINT ? 1u : 0u,
                                            type == PENUMBRA_LIGHT_SPOT ? 1u : 0u,
                                            lightIndex,
                                            options.cullBehindReceivers ? gridFaces : 0u,
                                            depthOrder,
                                            0};
            vkCmdPushConstants(cmd, casters.layout, VK_SHADER_STAGE_GEOMETRY_BIT, 0, sizeof(castersPush), &castersPush);
            drawClusters(cmd, geometry, model, clusters.data() + begin, end - begin);
            vkCmdEndRendering(cmd);
            vk::memoryBarrier(cmd, kGeometry, kStorageWrite, kCompute, kStorageRW | kSampledRead);
            checkpoint(2);
            stats.batches++;
            // Traversal steps until the batch is done; one wait per round, each round twice the steps of the last.
            for (uint32_t steps = profiling ? 1 : levels + 1;; steps = profiling ? 1 : std::min(2 * steps, 8 * (levels + 1))) {
                for (uint32_t s = 0; s < steps; ++s) {
                    step.bind(cmd);
                    step.push(cmd, RhStepPush{kPairCapacity, kTriangleCapacity, {}});
                    vkCmdDispatch(cmd, 1, 1, 1);
                    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute | kIndirect, kStorageRW | kSampledRead | kIndirectRead | kUniformRead);
                    // The step's records go to the inner levels' pipeline or the leaves' (rh_step.comp empties the other dispatch).
                    for (uint32_t leaf = 0; leaf < 2; ++leaf) {
                        if (leaf) // for the validation layers, which cannot know that one of the two is empty
                            vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW | kSampledRead | kUniformRead);
                        traverser.bind(cmd, vk::Specialization{texelAccess ? 1u : 0u, options.test, options.earlyAccept ? 1u : 0u, leaf});
                        traverser.push(cmd, RhTraversePush{lightIndex, originOffset, faces, 0});
                        vkCmdDispatchIndirect(cmd, state.buffer, leaf ? offsetof(RhState, leafDispatch) : offsetof(RhState, dispatch));
                    }
                    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW | kSampledRead | kUniformRead);
                }
                vk::memoryBarrier(cmd, kCompute, kStorageWrite, kHost, VK_ACCESS_2_HOST_READ_BIT);
                submit();
                if (profiling) {
                    const double before = profileMs[3];
                    lap(3);
                    profileDepthMs[std::min<uint32_t>(hostState->stepDepth, PENUMBRA_RH_MAX_LEVELS - 1)] += profileMs[3] - before;
                }
                stats.rounds++;
                if (hostState->overflow != 0)
                    fail("rh", std::string("the traversal ran out of room (") + (hostState->overflow & 1 ? "records" : "casters") + ")");
                if (hostState->done != 0) {
                    stats.casters += std::min(hostState->triangleCount, kTriangleCapacity);
                    break;
                }
            }
            begin = end;
        }
    };
    buildHierarchy(false);
    checkpoint(1);
    built();
    if (!options.twoPass) {
        traverseCasters(PENUMBRA_RH_CASTERS_ALL);
        resolveAccepted();
        return;
    }
    // Two-pass traversal (section 3.4): the large casters first, then the
    // hierarchy rebuilt without the rays they shadowed, then the others.
    traverseCasters(PENUMBRA_RH_CASTERS_LARGE);
    resolveAccepted();
    buildHierarchy(true);
    traverseCasters(PENUMBRA_RH_CASTERS_SMALL);
    resolveAccepted();
}

RhFrameStats RhPass::frameStats() const
{
    RhFrameStats out = stats;
    if (!state.mapped)
        return out;
    const auto* s = static_cast<const RhState*>(state.mapped);
    out.rays = s->raysListed;
    out.pairsTested = s->pairsTested;
    out.rayTests = s->rayTests;
    out.rayHits = s->rayHits;
    out.accepted = s->accepted;
    out.sortedLights = s->sortedLights;
    out.incoherence = s->coherenceRays ? double(s->incoherence) / 256.0 / double(s->coherenceRays) : 0.0;
    out.peakPairBytes = uint64_t(s->peakPairs) * 8;
    out.memoryBytes = rayList.size + nodes.size + trianglesA.size + trianglesB.size + records.size + state.size + tileCounts.size + keyCounts.size +
                      clusterFaces.size;
    if (std::getenv("PENUMBRA_RH_PROFILE")) {
        std::fprintf(stderr, "rh profile (host ms): rays %.1f build %.1f casters %.1f traverse %.1f resolve %.1f; steps %u rounds %u; ray hits %llu; tests by depth:",
                     profileMs[0], profileMs[1], profileMs[2], profileMs[3], profileMs[4], s->steps, stats.rounds, (unsigned long long)s->rayHits);
        for (uint32_t d = 0; d < PENUMBRA_RH_MAX_LEVELS && s->depthTests[d]; ++d)
            std::fprintf(stderr, " %u (%.0f ms)", s->depthTests[d], profileDepthMs[d]);
        std::fprintf(stderr, "\n");
    }
    return out;
}

} // namespace penumbra::passes
