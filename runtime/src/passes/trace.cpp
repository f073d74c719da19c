// The compute ray tracer of shadow rays (Lauterbach et al. 2009, section 3.1
// and 5.1): pipeline, descriptor set and the model table through which
// shaders/trace.comp.glsl (bvh_traversal.glsli) finds the model's chunks by
// device address.
#include "passes/trace.h"

#include <algorithm>
#include <cstring>
#include <string>
#include <vector>

#include "config.h"
#include "passes/pass.h"

static_assert(PENUMBRA_TRACE_STACK_SIZE >= 3 * penumbra::model::kMaxBvhDepth + 4, "the tracer's stack holds every pending node");

namespace penumbra::passes {

namespace {

// The model table (layout documented in shaders/bvh_traversal.glsli).
struct ModelTableHeader {
    float boundsMin[4];
    float boundsMax[4];
    uint32_t nodeChunkShift;
    uint32_t nodeChunkCount;
    uint32_t geometryChunkCount;
    uint32_t reserved0;
    VkDeviceAddress clusters;
    uint64_t reserved1;
};
static_assert(sizeof(ModelTableHeader) == 64);

struct ModelTableChunk {
    uint32_t firstCluster;
    uint32_t reserved[3];
    VkDeviceAddress vertices; // the chunk's vertex buffer address minus 8 x its first vertex (mod 2^64)
    VkDeviceAddress indices;  // the chunk's strip buffer address minus its first strip byte (mod 2^64)
};
static_assert(sizeof(ModelTableChunk) == 32);

} // namespace

uint32_t TracePass::raysPerInvocation(const vk::Device& device)
{
    return device.properties.deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU ? PENUMBRA_TRACE_RAYS_CPU : PENUMBRA_TRACE_RAYS_GPU;
}

void TracePass::writeListHeader(const vk::Device& device, uint32_t count, uint32_t* header)
{
    std::fill(header, header + PENUMBRA_RAY_LIST_HEADER_UINTS, 0u);
    header[0] = count;
    const uint32_t perGroup[2] = {PENUMBRA_TRACE_GROUP_SIZE, entriesPerGroup(device)};
    for (int i = 0; i < 2; ++i) {
        const Groups2D groups = spreadGroups((count + perGroup[i] - 1) / perGroup[i], device.properties.limits.maxComputeWorkGroupCount[0]);
        header[1 + 3 * i] = groups.x;
        header[2 + 3 * i] = groups.y;
        header[3 + 3 * i] = 1;
    }
}

void TracePass::create(vk::Device& device)
{
    using namespace vk;
    roundsPerInvocation = raysPerInvocation(device);
    kernel.create(device, "trace.comp",
                  {kStorageImage, kStorageImage, kStorageImage, kUniform, kStorage, kStorage, kTexels, kTexels, kTexels, kTexels, kTexels, kStorage},
                  sizeof(TracePush));
}

void TracePass::destroy(vk::Device& device)
{
    vk::destroyBuffer(device, modelTable);
    kernel.destroy(device);
    tableAddress = 0;
    rayList = VK_NULL_HANDLE;
    texels = {};
    texelsComplete = false;
}

void TracePass::bindModel(vk::Device& device, const GpuGeometry& geometry)
{
    tableAddress = 0; // nothing traceable until the new table exists
    if (geometry.encoding != GeometryEncoding::Compressed || (geometry.nodeChunks.empty() && !geometry.paged()) || geometry.chunks.empty())
        fail("ray tracer", "needs a compressed model with its BVH (the uncompressed reference cannot be traced)");
    // Header, node chunk addresses, then the geometry chunks 16-byte aligned.
    const size_t nodeChunkCount = geometry.nodeChunks.size();
    const size_t chunksOffset = (sizeof(ModelTableHeader) + 8 * nodeChunkCount + 15) & ~size_t(15);
    std::vector<uint8_t> table(chunksOffset + geometry.chunks.size() * sizeof(ModelTableChunk), 0);

    ModelTableHeader header{};
    for (int axis = 0; axis < 3; ++axis) {
        header.boundsMin[axis] = boundsMin[axis] = geometry.bounds.min[axis];
        header.boundsMax[axis] = boundsMax[axis] = geometry.bounds.max[axis];
    }
    texels = geometry.texels;
    texelsComplete = geometry.texelsComplete;
    vertexTexelsSplit = geometry.vertexTexelsSplit;
    writeSet(device);
    header.nodeChunkShift = geometry.nodeChunkShift;
    header.nodeChunkCount = uint32_t(nodeChunkCount);
    header.geometryChunkCount = uint32_t(geometry.chunks.size());
    header.clusters = vk::bufferAddress(device, geometry.clusters);
    std::memcpy(table.data(), &header, sizeof(header));
    for (size_t i = 0; i < nodeChunkCount; ++i) {
        VkDeviceAddress address = vk::bufferAddress(device, geometry.nodeChunks[i]);
        std::memcpy(table.data() + sizeof(header) + 8 * i, &address, 8);
    }
    for (size_t i = 0; i < geometry.chunks.size(); ++i) {
        const GpuGeometry::Chunk& chunk = geometry.chunks[i];
        ModelTableChunk entry{};
        entry.firstCluster = chunk.firstCluster;
        // ClusterRecord::firstVertex and firstIndex are 64-bit: the shader adds them to these bases.
        entry.vertices = vk::bufferAddress(device, chunk.vertices) - chunk.vertexBase * sizeof(model::QuantizedVertex);
        entry.indices = vk::bufferAddress(device, chunk.indices) - chunk.indexBase;
        std::memcpy(table.data() + chunksOffset + i * sizeof(entry), &entry, sizeof(entry));
    }
    vk::destroyBuffer(device, modelTable);
    modelTable = vk::createBufferWithData(device, table.data(), table.size(), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::Addressable::Yes);
    tableAddress = vk::bufferAddress(device, modelTable);
}

void TracePass::bind(vk::Device& device, const TraceTargets& t)
{
    targets = t;
    rayList = t.rayList;
    writeSet(device);
}

void TracePass::writeSet(vk::Device& device) const
{
    if (!rayList || !targets.hints || !texels.nodes)
        return; // both the targets and the model are needed
    const TraceTargets& t = targets;
    kernel.write(device, {vk::storageImage(t.surface), vk::storageImage(t.albedo), vk::storageImage(t.visibility),
                          vk::uniformBuffer(t.frame), vk::storageBuffer(t.rayList), vk::storageBuffer(t.stats),
                          vk::texelBuffer(texels.nodes), vk::texelBuffer(texels.clusters), vk::texelBuffer(texels.vertices),
                          vk::texelBuffer(texels.strips), vk::texelBuffer(texels.nodeTable), vk::storageBuffer(t.hints)});
}

void TracePass::record(VkCommandBuffer cmd, uint32_t lightIndex, uint32_t lightType, float originOffset, uint32_t samples,
                       VkDeviceAddress parking, uint32_t clusterWords) const
{
    if (!tableAddress || !rayList)
        fail("ray tracer", "record before bindModel and bind");
    if (lightIndex >= PENUMBRA_MAX_LIGHTS)
        fail("ray tracer", "light index " + std::to_string(lightIndex) + " out of range (at most " +
                               std::to_string(PENUMBRA_MAX_LIGHTS) + " lights)");
    // Hard shadows without paging in rounds (trace.comp.glsl: traceHardRounds), in dispatches of
    // PENUMBRA_TRACE_ROUNDS_PER_DISPATCH rounds; the rest one ray an invocation.
    const uint32_t rounds = samples == 0 && !parking ? roundsPerInvocation : 1u;
    kernel.bind(cmd, vk::Specialization{texelsComplete ? 1u : 0u, vertexTexelsSplit ? 1u : 0u, samples != 0 ? 1u : 0u, lightType,
                                        parking ? 1u : 0u, rounds});
    TracePush push{tableAddress, lightIndex, originOffset, samples, clusterWords, parking, {}, {}};
    std::copy(boundsMin, boundsMin + 4, push.boundsMin);
    std::copy(boundsMax, boundsMax + 4, push.boundsMax);
    if (rounds > 1) {
        vk::memoryBarrier(cmd, kCompute, kStorageRW, kClear, kTransferWrite); // after an earlier trace's use
        vkCmdFillBuffer(cmd, targets.hints, 0, 16, 0);                        // the hints' counts (trace.comp.glsl: Hints)
        vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute, kStorageRW);
        for (uint32_t begin = 0; begin < rounds; begin += PENUMBRA_TRACE_ROUNDS_PER_DISPATCH) {
            push.roundBegin = begin;
            if (begin != 0)
                vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
            kernel.push(cmd, push);
            vkCmdDispatchIndirect(cmd, rayList, 4 * sizeof(uint32_t)); // roundsDispatch[3]
        }
        return;
    }
    // An area light's samples in dispatches of at most PENUMBRA_TRACE_SAMPLES_PER_DISPATCH, each adding
    // its share of the visibility: lavapipe ends every loop of an invocation after 65,535 iterations in
    // all (its loop limiter), and 256 traversals of a large model reach that. Paged geometry keeps one
    // dispatch (a ray parked in one would be listed again by the next).
    const uint32_t rays = std::max(samples, 1u); // per pixel
    const uint32_t perDispatch = samples == 0 || parking ? rays : PENUMBRA_TRACE_SAMPLES_PER_DISPATCH;
    for (uint32_t begin = 0; begin < rays; begin += perDispatch) {
        push.sampleBegin = begin;
        push.sampleEnd = std::min(begin + perDispatch, rays);
        if (begin != 0)
            vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
        kernel.push(cmd, push);
        vkCmdDispatchIndirect(cmd, rayList, sizeof(uint32_t)); // dispatch[3] follows the count
    }
}

} // namespace penumbra::passes
