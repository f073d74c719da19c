#include "passes/classify.h"

#include "config.h"
#include "frame_targets.h"
#include "passes/pass.h"

namespace penumbra::passes {

namespace {

std::vector<VkDescriptorType> classifyBindingTypes()
{
    std::vector<VkDescriptorType> types = pixelBindingTypes();
    types.insert(types.end(), {vk::kSampled, vk::kStorageImage, vk::kStorage, vk::kStorage, vk::kStorage});
    return types;
}

void dispatchPixels(VkCommandBuffer cmd, uint32_t width, uint32_t height)
{
    vkCmdDispatch(cmd, groupCount(width, PENUMBRA_SHADE_GROUP_SIZE), groupCount(height, PENUMBRA_SHADE_GROUP_SIZE), 1);
    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
}

} // namespace

void ClassifyPass::create(vk::Device& device)
{
    hard.create(device, "classify.comp", classifyBindingTypes(), sizeof(ClassifyPush));
    soft.create(device, "classify_soft.comp", classifyBindingTypes(), sizeof(ClassifySoftPush));
}

void ClassifyPass::destroy(vk::Device& device)
{
    hard.destroy(device);
    soft.destroy(device);
}

void ClassifyPass::bind(vk::Device& device, const ClassifyTargets& t)
{
    std::vector<vk::Binding> bindings = pixelBindings(t.pixels);
    bindings.insert(bindings.end(), {vk::sampledImage(t.shadowMap, t.sampler, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL),
                                     vk::storageImage(t.thinMap),
                                     vk::storageBuffer(t.mask->buffer, FrameTargets::storageRange(device, *t.mask)),
                                     vk::storageBuffer(t.receivers->buffer),
                                     vk::storageBuffer(t.thinMask->buffer, FrameTargets::storageRange(device, *t.thinMask))});
    hard.write(device, bindings);
    soft.write(device, bindings);
}

void ClassifyPass::createFloor(vk::Device& device)
{
    hard.createFloor(device);
    soft.createFloor(device);
}

void ClassifyPass::record(VkCommandBuffer cmd, const ClassifyPush& push, uint32_t lightType, uint32_t width, uint32_t height,
                          bool floor) const
{
    hard.bind(cmd, vk::Specialization{push.mode, lightType}, floor);
    hard.push(cmd, push);
    dispatchPixels(cmd, width, height);
}

void ClassifyPass::recordSoft(VkCommandBuffer cmd, const ClassifySoftPush& push, uint32_t lightType, uint32_t width, uint32_t height,
                              bool floor) const
{
    soft.bind(cmd, vk::Specialization{push.mode, lightType}, floor);
    soft.push(cmd, push);
    dispatchPixels(cmd, width, height);
}

} // namespace penumbra::passes
