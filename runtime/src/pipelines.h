// Small helpers for pipeline layouts, descriptor sets and compute pipelines,
// shared by the renderer's passes and the ray tracer.
#pragma once

#include <vector>

#include "resources.h"

namespace penumbra::vk {

constexpr VkDescriptorType kStorageImage = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE;
constexpr VkDescriptorType kSampled = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
constexpr VkDescriptorType kUniform = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
constexpr VkDescriptorType kStorage = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;

// Pipeline layout with at most one set and one push-constant range of pushBytes.
VkPipelineLayout createPipelineLayout(Device& device, VkDescriptorSetLayout setLayout, uint32_t pushBytes, VkShaderStageFlags stages);

// Set layout whose binding i has types[i], one descriptor each.
VkDescriptorSetLayout createSetLayout(Device& device, const std::vector<VkDescriptorType>& types, VkShaderStageFlags stages);

// One descriptor of a set: an image view (+ sampler) or a whole buffer.
struct Binding {
    VkDescriptorType type;
    VkImageView view = VK_NULL_HANDLE;
    VkSampler sampler = VK_NULL_HANDLE;
    VkBuffer buffer = VK_NULL_HANDLE;
    VkImageLayout layout = VK_IMAGE_LAYOUT_GENERAL;
    VkDeviceSize range = VK_WHOLE_SIZE;
};

// Writes bindings[i] to binding i of set.
void writeSet(Device& device, VkDescriptorSet set, const std::vector<Binding>& bindings);

// Compute pipeline of an embedded shader ("classify.comp").
VkPipeline createComputePipeline(Device& device, const char* shader, VkPipelineLayout layout);

} // namespace penumbra::vk
