#include "passes/rh.h"

#include <algorithm>

#include "config.h"
#include "passes/pass.h"

namespace penumbra::passes {

namespace {

constexpr VkBufferUsageFlags kStorageDst = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;

std::vector<VkDescriptorType> castersBindingTypes() { return {vk::kStorage, vk::kStorage}; }

// Ray list entries for a width x height image: every pixel, plus up to 3 of padding per 8x8 tile.
uint32_t rayCapacity(uint32_t width, uint32_t height)
{
    return width * height + 3 * groupCount(width, 8) * groupCount(height, 8);
}

} // namespace

void RhPass::create(vk::Device& device)
{
    using namespace vk;
    rays.create(device, "rh_rays.comp", {kStorageImage, kStorageImage, kUniform, kStorage, kStorage, kStorage, kStorage},
                sizeof(RhRaysPush));
    scanTiles.create(device, "afsm_scan.comp", {kStorage, kStorage}, sizeof(RhScanPush));
    scanKeys.create(device, "afsm_scan.comp", {kStorage, kStorage}, sizeof(RhScanPush));
    build.create(device, "rh_build.comp", {kStorageImage, kUniform, kStorage, kStorage, kStorage, kStorage}, sizeof(RhBuildPush));
    step.create(device, "rh_step.comp", {kStorage}, sizeof(RhStepPush));
    traverse.create(device, "rh_traverse.comp",
                    {kStorageImage, kStorageImage, kUniform, kStorage, kStorage, kStorage, kStorage, kStorage, kStorage},
                    sizeof(RhTraversePush));
    if (!device.rayHierarchy)
        return;
    castersSetLayout = createSetLayout(device, castersBindingTypes(), VK_SHADER_STAGE_GEOMETRY_BIT);
    castersSet = allocateSet(device, castersSetLayout, castersBindingTypes(), castersPool);
    GraphicsPipelineDesc desc;
    desc.vertexShader = "afsm_casters.vert";
    desc.geometryShader = "rh_casters.geom";
    desc.depthWrite = false;
    desc.rasterizerDiscard = true;
    desc.pushBytes = sizeof(RhCastersPush);
    casters.create(device, desc, VK_SHADER_STAGE_GEOMETRY_BIT, castersSetLayout);
}

void RhPass::destroy(vk::Device& device)
{
    rays.destroy(device);
    scanTiles.destroy(device);
    scanKeys.destroy(device);
    build.destroy(device);
    step.destroy(device);
    traverse.destroy(device);
    casters.destroy(device);
    if (castersPool)
        vkDestroyDescriptorPool(device.device, castersPool, nullptr);
    if (castersSetLayout)
        vkDestroyDescriptorSetLayout(device.device, castersSetLayout, nullptr);
    castersPool = VK_NULL_HANDLE;
    castersSetLayout = VK_NULL_HANDLE;
    castersSet = VK_NULL_HANDLE;
    for (vk::Buffer* buffer : {&rayList, &nodes, &triangles, &pairs, &state, &tileOffsets, &blockSums, &keySlots})
        vk::destroyBuffer(device, *buffer);
    maxRays = maxNodes = mortonTiles = 0;
}

bool RhPass::bound(const RhTargets& t) const
{
    return state.buffer && t.position == targets.position && t.shadowed == targets.shadowed && t.shadowed->buffer == shadowedBuffer &&
           t.width == targets.width && t.height == targets.height;
}

void RhPass::bind(vk::Device& device, const RhTargets& t)
{
    targets = t;
    shadowedBuffer = t.shadowed->buffer;
    if (!state.buffer) {
        // Fixed sizes, made on the first rh frame. The state is host-visible: the frame script reads `done` after each wait.
        pairs = vk::createBuffer(device, VkDeviceSize(kPairCapacity) * 8, kStorageDst, vk::MemoryUse::DeviceLocal);
        triangles = vk::createBuffer(device, VkDeviceSize(kTriangleCapacity) * 40, kStorageDst, vk::MemoryUse::DeviceLocal);
        state = vk::createBuffer(device, sizeof(RhState), kStorageDst | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT, vk::MemoryUse::Readback);
        keySlots = vk::createBuffer(device, VkDeviceSize(kSortKeys) * 4, kStorageDst, vk::MemoryUse::DeviceLocal);
        if (castersSet)
            vk::writeSet(device, castersSet, {vk::storageBuffer(state.buffer), vk::storageBuffer(triangles.buffer)});
    }
    const uint32_t capacity = rayCapacity(t.width, t.height);
    if (capacity != maxRays) {
        vk::destroyBuffer(device, rayList);
        vk::destroyBuffer(device, nodes);
        vk::destroyBuffer(device, tileOffsets);
        vk::destroyBuffer(device, blockSums);
        maxRays = 0;
        uint32_t side = 1;
        while (side < std::max(groupCount(t.width, 8), groupCount(t.height, 8)))
            side *= 2;
        mortonTiles = side * side;
        tileOffsets = vk::createBuffer(device, VkDeviceSize(mortonTiles) * 4, kStorageDst, vk::MemoryUse::DeviceLocal);
        blockSums = vk::createBuffer(device, PENUMBRA_AFSM_MAX_GRID * 4, kStorageDst, vk::MemoryUse::DeviceLocal);
        uint32_t count = (capacity + 3) / 4, total = 0;
        for (;;) {
            total += count;
            if (count <= 1)
                break;
            count = (count + 3) / 4;
        }
        rayList = vk::createBuffer(device, VkDeviceSize(capacity) * 4, kStorageDst, vk::MemoryUse::DeviceLocal);
        nodes = vk::createBuffer(device, VkDeviceSize(total) * 32, kStorageDst, vk::MemoryUse::DeviceLocal);
        maxRays = capacity;
        maxNodes = total;
    }
    using namespace vk;
    rays.write(device, {storageImage(t.position), storageImage(t.normal), uniformBuffer(t.frame), storageBuffer(rayList.buffer),
                        storageBuffer(state.buffer), storageBuffer(tileOffsets.buffer), storageBuffer(keySlots.buffer)});
    scanTiles.write(device, {storageBuffer(tileOffsets.buffer), storageBuffer(blockSums.buffer)});
    scanKeys.write(device, {storageBuffer(keySlots.buffer), storageBuffer(blockSums.buffer)});
    build.write(device, {storageImage(t.position), uniformBuffer(t.frame), storageBuffer(rayList.buffer), storageBuffer(nodes.buffer),
                         storageBuffer(state.buffer), storageBuffer(t.shadowed->buffer)});
    step.write(device, {storageBuffer(state.buffer)});
    traverse.write(device, {storageImage(t.position), storageImage(t.normal), uniformBuffer(t.frame), storageBuffer(rayList.buffer),
                            storageBuffer(nodes.buffer), storageBuffer(triangles.buffer), storageBuffer(pairs.buffer),
                            storageBuffer(t.shadowed->buffer), storageBuffer(state.buffer)});
}

uint32_t RhPass::maxLevels() const
{
    uint32_t count = (maxRays + 3) / 4, levels = 1;
    while (count > 1) {
        count = (count + 3) / 4;
        ++levels;
    }
    return levels;
}

void RhPass::beginFrame(VkCommandBuffer cmd)
{
    stats = {};
    vk::memoryBarrier(cmd, kCompute | kIndirect | VK_PIPELINE_STAGE_2_GEOMETRY_SHADER_BIT, kStorageRW | kIndirectRead, kClear,
                      kTransferWrite);
    vkCmdFillBuffer(cmd, state.buffer, 0, VK_WHOLE_SIZE, 0);
    vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute, kStorageRW);
}

void RhPass::recordLayer(VkCommandBuffer cmd, uint32_t lightIndex, const glm::vec3& lightPosition, uint32_t layer, float originOffset,
                         uint32_t test, bool sorted, bool twoPass,
                         const GpuGeometry& geometry, const CullModel& model, const std::vector<uint32_t>& clusters, const Mark& built,
                         const Submit& submit)
{
    if (!castersSet)
        fail("rh", "this device lacks geometry shaders or vertex-stage stores (needed to gather the casters)");
    constexpr VkPipelineStageFlags2 kGeometry = VK_PIPELINE_STAGE_2_GEOMETRY_SHADER_BIT;
    const VkDeviceSize rayCountBytes = 2 * sizeof(uint32_t); // rayCount, levels
    // The layer's rays.
    vk::memoryBarrier(cmd, kCompute | kIndirect | kGeometry, kStorageRW | kIndirectRead, kClear, kTransferWrite);
    vkCmdFillBuffer(cmd, state.buffer, 0, rayCountBytes, 0);
    const vk::Buffer& counts = sorted ? keySlots : tileOffsets;
    const uint32_t countEntries = sorted ? kSortKeys : mortonTiles;
    vkCmdFillBuffer(cmd, counts.buffer, 0, VK_WHOLE_SIZE, 0);
    vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute, kStorageRW);
    // Unsorted: each tile's count at its Morton index, the counts to offsets, then the rays there.
    // Sorted: the rays per direction key, the counts to offsets, then each ray at its key's next slot.
    auto listRays = [&](uint32_t mode) {
        rays.bind(cmd);
        rays.push(cmd, RhRaysPush{lightIndex, layer, originOffset, mode});
        vkCmdDispatch(cmd, groupCount(targets.width, 8), groupCount(targets.height, 8), 1);
        vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
    };
    listRays(sorted ? PENUMBRA_RH_RAYS_SORT_COUNT : PENUMBRA_RH_RAYS_COUNT);
    const vk::ComputeKernel& scan = sorted ? scanKeys : scanTiles;
    scan.bind(cmd);
    for (uint32_t phase = 0; phase < 3; ++phase) {
        scan.push(cmd, RhScanPush{countEntries, phase});
        vkCmdDispatch(cmd, phase == 1 ? 1 : groupCount(countEntries, PENUMBRA_AFSM_SCAN_GROUP * 16), 1, 1);
        vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
    }
    listRays(sorted ? PENUMBRA_RH_RAYS_SORT_LIST : PENUMBRA_RH_RAYS_LIST);
    // The hierarchy, bottom-up: every level dispatched for its largest size, idle beyond the layer's.
    const uint32_t levels = maxLevels();
    auto buildHierarchy = [&](bool skipShadowed) {
        build.bind(cmd);
        build.push(cmd, RhBuildPush{lightIndex, PENUMBRA_RH_BUILD_INIT, 0, 0});
        vkCmdDispatch(cmd, 1, 1, 1);
        vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
        uint32_t count = (maxRays + 3) / 4;
        for (uint32_t level = 0; level < levels; ++level) {
            build.push(cmd, RhBuildPush{lightIndex, level == 0 ? PENUMBRA_RH_BUILD_LEAVES : PENUMBRA_RH_BUILD_LEVEL, level,
                                        skipShadowed ? 1u : 0u});
            const Groups2D groups = spreadGroups(groupCount(count, PENUMBRA_RH_GROUP_SIZE), 65535u);
            vkCmdDispatch(cmd, groups.x, groups.y, 1);
            vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
            count = (count + 3) / 4;
        }
    };
    // The casters, in batches that fit the triangle list, each traversing the hierarchy until done.
    auto traverseCasters = [&](uint32_t select) {
        size_t begin = 0;
        while (begin < clusters.size()) {
            size_t end = begin;
            uint64_t batchTriangles = 0;
            while (end < clusters.size() && (end == begin || batchTriangles + model.clusterTriangles[clusters[end]] <= kTriangleCapacity))
                batchTriangles += model.clusterTriangles[clusters[end++]];
            if (batchTriangles > kTriangleCapacity)
                fail("rh", "a cluster of " + std::to_string(batchTriangles) + " triangles exceeds the caster list");
            // Reset the batch's words: done .. rootCursor.
            vk::memoryBarrier(cmd, kCompute | kIndirect | kGeometry, kStorageRW | kIndirectRead, kClear, kTransferWrite);
            vkCmdFillBuffer(cmd, state.buffer, offsetof(RhState, done), offsetof(RhState, peakPairs) - offsetof(RhState, done), 0);
            vk::memoryBarrier(cmd, kClear, kTransferWrite, kGeometry | kCompute, kStorageRW);
            VkRenderingInfo rendering{VK_STRUCTURE_TYPE_RENDERING_INFO};
            rendering.renderArea = {{0, 0}, {1, 1}};
            rendering.layerCount = 1;
            vkCmdBeginRendering(cmd, &rendering);
            vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, casters[geometry.encoding]);
            vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, casters.layout, 0, 1, &castersSet, 0, nullptr);
            vk::setViewport(cmd, 1, 1);
            const RhCastersPush castersPush{glm::vec4(lightPosition, float(PENUMBRA_RH_LARGE_ANGLE)), kTriangleCapacity, select, {}};
            vkCmdPushConstants(cmd, casters.layout, VK_SHADER_STAGE_GEOMETRY_BIT, 0, sizeof(castersPush), &castersPush);
            drawClusters(cmd, geometry, model, clusters.data() + begin, end - begin);
            vkCmdEndRendering(cmd);
            vk::memoryBarrier(cmd, kGeometry, kStorageWrite, kCompute, kStorageRW);
            stats.batches++;
            // Traversal steps until the batch is done; one wait per round.
            for (;;) {
                for (uint32_t s = 0; s < levels + 1; ++s) {
                    step.bind(cmd);
                    step.push(cmd, RhStepPush{kPairCapacity, kTriangleCapacity, {}});
                    vkCmdDispatch(cmd, 1, 1, 1);
                    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute | kIndirect, kStorageRW | kIndirectRead);
                    traverse.bind(cmd);
                    traverse.push(cmd, RhTraversePush{lightIndex, test, originOffset, 0});
                    vkCmdDispatchIndirect(cmd, state.buffer, offsetof(RhState, dispatch));
                    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
                }
                vk::memoryBarrier(cmd, kCompute, kStorageWrite, kHost, VK_ACCESS_2_HOST_READ_BIT);
                submit();
                stats.rounds++;
                const auto* s = static_cast<const RhState*>(state.mapped);
                if (s->overflow != 0)
                    fail("rh", std::string("the traversal ran out of room (") + (s->overflow & 1 ? "pairs" : "casters") + ")");
                if (s->done != 0) {
                    stats.casters += std::min(s->triangleCount, kTriangleCapacity);
                    break;
                }
            }
            begin = end;
        }
    };
    buildHierarchy(false);
    built();
    if (!twoPass) {
        traverseCasters(PENUMBRA_RH_CASTERS_ALL);
        return;
    }
    // Two-pass traversal (section 3.4): the large casters first, then the
    // hierarchy rebuilt without the rays they shadowed, then the others.
    traverseCasters(PENUMBRA_RH_CASTERS_LARGE);
    buildHierarchy(true);
    traverseCasters(PENUMBRA_RH_CASTERS_SMALL);
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
    out.peakPairBytes = uint64_t(s->peakPairs) * 8;
    out.memoryBytes = rayList.size + nodes.size + triangles.size + pairs.size + state.size + tileOffsets.size + blockSums.size + keySlots.size;
    return out;
}

} // namespace penumbra::passes
