#include "passes/shade.h"

#include "config.h"
#include "passes/pass.h"

namespace penumbra::passes {

void ShadePass::create(vk::Device& device)
{
    std::vector<VkDescriptorType> types = pixelBindingTypes();
    types.push_back(vk::kStorageImage);
    kernel.create(device, "shade.comp", types, sizeof(ShadePush));
    types.push_back(vk::kSampled);
    lookup.create(device, "shade.comp.lookup", types, sizeof(ShadePush));
}

void ShadePass::destroy(vk::Device& device)
{
    kernel.destroy(device);
    lookup.destroy(device);
}

void ShadePass::bind(vk::Device& device, const PixelTargets& pixels, VkImageView color, VkImageView shadowMap, VkSampler sampler)
{
    std::vector<vk::Binding> bindings = pixelBindings(pixels);
    bindings.push_back(vk::storageImage(color));
    kernel.write(device, bindings);
    bindings.push_back(vk::sampledImage(shadowMap, sampler, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL));
    lookup.write(device, bindings);
}

void ShadePass::record(VkCommandBuffer cmd, const ShadePush& push, uint32_t lightType, uint32_t width, uint32_t height, bool floor,
                       bool lookupMap, bool storeVisibility) const
{
    const vk::ComputeKernel& k = lookupMap ? lookup : kernel;
    k.bind(cmd, lookupMap ? vk::Specialization{lightType, push.firstLight, push.debugPip, push.countCovered, push.colours, storeVisibility ? 1u : 0u}
                          : vk::Specialization{lightType, push.firstLight, push.debugPip, push.countCovered, push.colours},
           floor);
    k.push(cmd, push);
    vkCmdDispatch(cmd, groupCount(width, PENUMBRA_SHADE_GROUP_SIZE), groupCount(height, PENUMBRA_SHADE_GROUP_SIZE), 1);
    vk::memoryBarrier(cmd, kCompute | kIndirect, kStorageRW | kIndirectRead, kCompute | kClear, kStorageRW | kTransferWrite);
}

} // namespace penumbra::passes
