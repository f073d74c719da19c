#include "pipelines.h"

namespace penumbra::vk {

VkPipelineLayout createPipelineLayout(Device& device, VkDescriptorSetLayout setLayout, uint32_t pushBytes, VkShaderStageFlags stages)
{
    VkPushConstantRange range{stages, 0, pushBytes};
    VkPipelineLayoutCreateInfo info{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    info.setLayoutCount = setLayout ? 1 : 0;
    info.pSetLayouts = &setLayout;
    info.pushConstantRangeCount = 1;
    info.pPushConstantRanges = &range;
    VkPipelineLayout layout;
    VK_CHECK(vkCreatePipelineLayout(device.device, &info, nullptr, &layout));
    return layout;
}

VkDescriptorSetLayout createSetLayout(Device& device, const std::vector<VkDescriptorType>& types, VkShaderStageFlags stages)
{
    std::vector<VkDescriptorSetLayoutBinding> bindings;
    for (uint32_t i = 0; i < types.size(); ++i)
        bindings.push_back({i, types[i], 1, stages, nullptr});
    VkDescriptorSetLayoutCreateInfo info{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    info.bindingCount = uint32_t(bindings.size());
    info.pBindings = bindings.data();
    VkDescriptorSetLayout layout;
    VK_CHECK(vkCreateDescriptorSetLayout(device.device, &info, nullptr, &layout));
    return layout;
}

void writeSet(Device& device, VkDescriptorSet set, const std::vector<Binding>& bindings)
{
    std::vector<VkDescriptorImageInfo> images(bindings.size());
    std::vector<VkDescriptorBufferInfo> buffers(bindings.size());
    std::vector<VkWriteDescriptorSet> writes;
    for (uint32_t i = 0; i < bindings.size(); ++i) {
        const Binding& b = bindings[i];
        VkWriteDescriptorSet write{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
        write.dstSet = set;
        write.dstBinding = i;
        write.descriptorCount = 1;
        write.descriptorType = b.type;
        if (b.buffer) {
            buffers[i] = {b.buffer, 0, b.range};
            write.pBufferInfo = &buffers[i];
        } else {
            images[i] = {b.sampler, b.view, b.layout};
            write.pImageInfo = &images[i];
        }
        writes.push_back(write);
    }
    vkUpdateDescriptorSets(device.device, uint32_t(writes.size()), writes.data(), 0, nullptr);
}

VkPipeline createComputePipeline(Device& device, const char* shader, VkPipelineLayout layout)
{
    VkShaderModule module = createShaderModule(device, shader);
    VkComputePipelineCreateInfo info{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
    info.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
    info.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    info.stage.module = module;
    info.stage.pName = "main";
    info.layout = layout;
    VkPipeline pipeline;
    VkResult result = vkCreateComputePipelines(device.device, VK_NULL_HANDLE, 1, &info, nullptr, &pipeline);
    vkDestroyShaderModule(device.device, module, nullptr);
    VK_CHECK(result);
    return pipeline;
}

} // namespace penumbra::vk
