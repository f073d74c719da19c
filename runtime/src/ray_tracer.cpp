// The compute ray tracer of shadow rays (Lauterbach et al. 2009, section 3.1
// and 5.1): pipeline, descriptor set and the model table through which
// shaders/trace.comp.glsl (bvh_traversal.glsli) finds the model's chunks by
// device address.
#include "ray_tracer.h"

#include "pipelines.h"

#include <cstring>
#include <string>
#include <vector>

#include "config.h"
#include "pipelines.h"
#include "resources.h"

namespace penumbra {

namespace {

// Push constants of trace.comp.glsl.
struct TracePush {
    VkDeviceAddress modelTable;
    uint32_t lightIndex;
    float originOffset;
    uint32_t samples; // area lights: light samples per pixel; 0: hard shadows
    uint32_t pad;
};
static_assert(sizeof(TracePush) == 24);

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
    uint32_t vertexBase;
    uint32_t indexBase;
    uint32_t reserved;
    VkDeviceAddress vertices;
    VkDeviceAddress indices;
};
static_assert(sizeof(ModelTableChunk) == 32);

} // namespace

void createRayTracer(vk::Device& device, RayTracer& tracer)
{
    try {
        tracer.setLayout = vk::createSetLayout(device, {vk::kStorageImage, vk::kStorageImage, vk::kStorageImage, vk::kUniform,
                                                        vk::kStorage, vk::kStorage},
                                               VK_SHADER_STAGE_COMPUTE_BIT);
        tracer.layout = vk::createPipelineLayout(device, tracer.setLayout, sizeof(TracePush), VK_SHADER_STAGE_COMPUTE_BIT);
        tracer.pipeline = vk::createComputePipeline(device, "trace.comp", tracer.layout);

        VkDescriptorPoolSize sizes[] = {{VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 3},
                                        {VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1},
                                        {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 2}};
        VkDescriptorPoolCreateInfo poolInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
        poolInfo.maxSets = 1;
        poolInfo.poolSizeCount = 3;
        poolInfo.pPoolSizes = sizes;
        VK_CHECK(vkCreateDescriptorPool(device.device, &poolInfo, nullptr, &tracer.pool));
        VkDescriptorSetAllocateInfo allocInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
        allocInfo.descriptorPool = tracer.pool;
        allocInfo.descriptorSetCount = 1;
        allocInfo.pSetLayouts = &tracer.setLayout;
        VK_CHECK(vkAllocateDescriptorSets(device.device, &allocInfo, &tracer.set));
    } catch (...) {
        destroyRayTracer(device, tracer);
        throw;
    }
}

void destroyRayTracer(vk::Device& device, RayTracer& tracer)
{
    vk::destroyBuffer(device, tracer.modelTable);
    if (tracer.pool)
        vkDestroyDescriptorPool(device.device, tracer.pool, nullptr);
    if (tracer.pipeline)
        vkDestroyPipeline(device.device, tracer.pipeline, nullptr);
    if (tracer.layout)
        vkDestroyPipelineLayout(device.device, tracer.layout, nullptr);
    if (tracer.setLayout)
        vkDestroyDescriptorSetLayout(device.device, tracer.setLayout, nullptr);
    tracer = {};
}

void bindRayTracerModel(vk::Device& device, RayTracer& tracer, const GpuGeometry& geometry)
{
    tracer.modelTableAddress = 0; // nothing traceable until the new table exists
    if (geometry.encoding != GeometryEncoding::Compressed || geometry.nodeChunks.empty() || geometry.chunks.empty())
        fail("ray tracer", "needs a compressed model with its BVH (the uncompressed reference cannot be traced)");
    // Header, node chunk addresses, then the geometry chunks 16-byte aligned.
    const size_t nodeChunkCount = geometry.nodeChunks.size();
    const size_t chunksOffset = (sizeof(ModelTableHeader) + 8 * nodeChunkCount + 15) & ~size_t(15);
    std::vector<uint8_t> table(chunksOffset + geometry.chunks.size() * sizeof(ModelTableChunk), 0);

    ModelTableHeader header{};
    for (int axis = 0; axis < 3; ++axis) {
        header.boundsMin[axis] = geometry.bounds.min[axis];
        header.boundsMax[axis] = geometry.bounds.max[axis];
    }
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
        entry.vertexBase = uint32_t(chunk.vertexBase); // ClusterRecord::firstVertex is 32-bit
        entry.indexBase = uint32_t(chunk.indexBase);   // ClusterRecord::firstIndex is 32-bit
        entry.vertices = vk::bufferAddress(device, chunk.vertices);
        entry.indices = vk::bufferAddress(device, chunk.indices);
        std::memcpy(table.data() + chunksOffset + i * sizeof(entry), &entry, sizeof(entry));
    }
    vk::destroyBuffer(device, tracer.modelTable);
    tracer.modelTable = vk::createBufferWithData(device, table.data(), table.size(), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::Addressable::Yes);
    tracer.modelTableAddress = vk::bufferAddress(device, tracer.modelTable);
}

void bindRayTracerTargets(vk::Device& device, RayTracer& tracer, const TraceBindings& bindings)
{
    // trace.comp's set 0: position, normal, visibility, frame, ray list, stats.
    vk::writeSet(device, tracer.set,
                 {{vk::kStorageImage, bindings.position}, {vk::kStorageImage, bindings.normal}, {vk::kStorageImage, bindings.visibility},
                  {vk::kUniform, {}, {}, bindings.frameUniforms}, {vk::kStorage, {}, {}, bindings.rayList},
                  {vk::kStorage, {}, {}, bindings.stats}});
    tracer.rayList = bindings.rayList;
}

void recordTrace(VkCommandBuffer cmd, RayTracer& tracer, uint32_t lightIndex, float originOffset, uint32_t samples)
{
    if (!tracer.modelTableAddress || !tracer.rayList)
        fail("ray tracer", "recordTrace before bindRayTracerModel and bindRayTracerTargets");
    if (lightIndex >= PENUMBRA_MAX_LIGHTS)
        fail("ray tracer", "light index " + std::to_string(lightIndex) + " out of range (at most " +
                               std::to_string(PENUMBRA_MAX_LIGHTS) + " lights)");
    TracePush push{tracer.modelTableAddress, lightIndex, originOffset, samples, 0};
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, tracer.pipeline);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, tracer.layout, 0, 1, &tracer.set, 0, nullptr);
    vkCmdPushConstants(cmd, tracer.layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
    vkCmdDispatchIndirect(cmd, tracer.rayList, sizeof(uint32_t)); // dispatch[3] follows the count
}

} // namespace penumbra
