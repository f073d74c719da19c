// Decode check (shaders/decode_check.vert.glsl): every vertex of the
// compressed model dequantized by the vertex shader the raster passes use,
// written to a buffer with vertex-pipeline stores (tests compare it with the
// CPU decoder). Not part of the frame.
#include "passes/decode_check.h"

#include <limits>

#include "pipelines.h"

namespace penumbra::passes {

std::vector<float> decodeVerticesOnGpu(vk::Device& device, const GpuGeometry& geometry)
{
    if (geometry.encoding != GeometryEncoding::Compressed || geometry.triangles == 0)
        fail("decode check", "no compressed model loaded");
    if (!device.vertexStores)
        fail("decode check", device.info.name + " lacks vertexPipelineStoresAndAtomics");
    VkDeviceSize bytes = geometry.vertexCount * 3 * sizeof(float);
    if (bytes > device.properties.limits.maxStorageBufferRange)
        fail("decode check", "model too large for one storage buffer");

    // Resources of this check only; created and destroyed here.
    VkDescriptorSetLayoutBinding binding{0, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_VERTEX_BIT, nullptr};
    VkDescriptorSetLayoutCreateInfo setInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    setInfo.bindingCount = 1;
    setInfo.pBindings = &binding;
    VkDescriptorSetLayout setLayout = VK_NULL_HANDLE;
    VkPipelineLayout layout = VK_NULL_HANDLE;
    VkPipeline pipeline = VK_NULL_HANDLE;
    VkDescriptorPool pool = VK_NULL_HANDLE;
    vk::Buffer output;
    auto cleanup = [&] {
        vk::destroyBuffer(device, output);
        if (pipeline) vkDestroyPipeline(device.device, pipeline, nullptr);
        if (layout) vkDestroyPipelineLayout(device.device, layout, nullptr);
        if (pool) vkDestroyDescriptorPool(device.device, pool, nullptr);
        if (setLayout) vkDestroyDescriptorSetLayout(device.device, setLayout, nullptr);
    };
    try {
        VK_CHECK(vkCreateDescriptorSetLayout(device.device, &setInfo, nullptr, &setLayout));
        layout = vk::createPipelineLayout(device, setLayout, sizeof(uint32_t), VK_SHADER_STAGE_VERTEX_BIT);
        vk::GraphicsPipelineDesc desc;
        desc.vertexShader = "decode_check.vert";
        desc.rasterizerDiscard = true;
        desc.layout = layout;
        desc.pushBytes = sizeof(uint32_t);
        pipeline = vk::createGraphicsPipeline(device, desc);

        VkDescriptorPoolSize poolSize{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1};
        VkDescriptorPoolCreateInfo poolInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
        poolInfo.maxSets = 1;
        poolInfo.poolSizeCount = 1;
        poolInfo.pPoolSizes = &poolSize;
        VK_CHECK(vkCreateDescriptorPool(device.device, &poolInfo, nullptr, &pool));
        VkDescriptorSetAllocateInfo allocInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
        allocInfo.descriptorPool = pool;
        allocInfo.descriptorSetCount = 1;
        allocInfo.pSetLayouts = &setLayout;
        VkDescriptorSet set;
        VK_CHECK(vkAllocateDescriptorSets(device.device, &allocInfo, &set));
        output = vk::createBuffer(device, bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryUse::Readback);
        std::fill_n(static_cast<float*>(output.mapped), geometry.vertexCount * 3, std::numeric_limits<float>::quiet_NaN());
        VkDescriptorBufferInfo bufferInfo{output.buffer, 0, bytes};
        VkWriteDescriptorSet write{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
        write.dstSet = set;
        write.descriptorCount = 1;
        write.descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
        write.pBufferInfo = &bufferInfo;
        vkUpdateDescriptorSets(device.device, 1, &write, 0, nullptr);

        vk::immediateSubmit(device, [&](VkCommandBuffer cmd) {
            VkRenderingInfo rendering{VK_STRUCTURE_TYPE_RENDERING_INFO};
            rendering.renderArea = {{0, 0}, {1, 1}};
            rendering.layerCount = 1;
            vkCmdBeginRendering(cmd, &rendering);
            vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline);
            vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout, 0, 1, &set, 0, nullptr);
            vk::setViewport(cmd, 1, 1);
            drawGeometry(cmd, geometry, [&](uint64_t vertexBase) {
                uint32_t base = uint32_t(vertexBase);
                vkCmdPushConstants(cmd, layout, VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof(base), &base);
            });
            vkCmdEndRendering(cmd);
            vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_VERTEX_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                              VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_READ_BIT);
        }, "decode_check");
        const float* decoded = static_cast<const float*>(output.mapped);
        std::vector<float> result(decoded, decoded + geometry.vertexCount * 3);
        cleanup();
        return result;
    } catch (...) {
        cleanup();
        throw;
    }
}

} // namespace penumbra::passes
