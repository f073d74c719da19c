#include "passes/penumbra_mask.h"

#include "config.h"
#include "frame_targets.h"
#include "passes/pass.h"

namespace penumbra::passes {

namespace {

// Specialization of penumbra_mask.comp: the stage, and what only the splats
// (light shape) and the edge stage (thin triangles) read.
vk::Specialization stage(uint32_t stage, uint32_t lightType, uint32_t useThin)
{
    const bool splat = stage == PENUMBRA_MASK_STAGE_SPLAT;
    const bool thin = stage == PENUMBRA_MASK_STAGE_EDGES || stage == PENUMBRA_MASK_STAGE_REDUCE || stage == PENUMBRA_MASK_STAGE_PUSH_DOWN;
    return vk::Specialization{stage, splat ? lightType : uint32_t(PENUMBRA_LIGHT_SPHERE), thin ? useThin : 0u};
}

} // namespace

uint32_t maskTopLevel(uint32_t size)
{
    uint32_t top = 0;
    while (((size + (1u << top) - 1u) >> top) > 1u)
        ++top;
    return top;
}

uint64_t maskTexels(uint32_t size)
{
    uint64_t total = 0;
    for (uint32_t level = 0; level <= maskTopLevel(size); ++level) {
        uint64_t side = (uint64_t(size) + (1u << level) - 1u) >> level;
        total += side * side;
    }
    return total;
}

void PenumbraMaskPass::create(vk::Device& device)
{
    using namespace vk;
    kernel.create(device, "penumbra_mask.comp", {kSampled, kStorageImage, kUniform, kStorage, kStorage, kStorage, kStorage, kStorage},
                  sizeof(PenumbraMaskPush));
}

void PenumbraMaskPass::destroy(vk::Device& device) { kernel.destroy(device); }

void PenumbraMaskPass::bind(vk::Device& device, const PenumbraMaskTargets& t)
{
    targets = t;
    kernel.write(device, {vk::sampledImage(t.shadowMap, t.sampler, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL),
                          vk::storageImage(t.thinMap),
                          vk::uniformBuffer(t.frame),
                          vk::storageBuffer(t.pyramid->buffer, FrameTargets::storageRange(device, *t.pyramid)),
                          vk::storageBuffer(t.mask->buffer, FrameTargets::storageRange(device, *t.mask)),
                          vk::storageBuffer(t.receivers->buffer),
                          vk::storageBuffer(t.jobs->buffer),
                          vk::storageBuffer(t.thinMask->buffer, FrameTargets::storageRange(device, *t.thinMask))});
}

void PenumbraMaskPass::clear(VkCommandBuffer cmd) const
{
    vk::memoryBarrier(cmd, kCompute, kStorageRead, kClear, kTransferWrite);
    vkCmdFillBuffer(cmd, targets.mask->buffer, 0, 4, 0);
    vkCmdFillBuffer(cmd, targets.mask->buffer, 4, VK_WHOLE_SIZE, 0x7F800000u); // +inf: no receiver depth reached
    vkCmdFillBuffer(cmd, targets.thinMask->buffer, 0, VK_WHOLE_SIZE, 0x7F800000u);
    vkCmdFillBuffer(cmd, targets.receivers->buffer, 0, VK_WHOLE_SIZE, 0);
    vkCmdFillBuffer(cmd, targets.jobs->buffer, 0, 16, 0);
    vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute, kStorageRW);
}

void PenumbraMaskPass::record(VkCommandBuffer cmd, PenumbraMaskPush push, uint32_t lightType) const
{
    push.maxJobs = targets.maxJobs;
    for (uint32_t level = 0; level < push.topLevel; ++level) {
        if (level <= 1)
            kernel.bind(cmd, stage(level == 0 ? PENUMBRA_MASK_STAGE_EDGES : PENUMBRA_MASK_STAGE_REDUCE, lightType, push.useThin));
        push.level = level;
        const uint32_t parentSize = (push.mapSize + (2u << level) - 1u) >> (level + 1);
        const uint32_t groups = groupCount(parentSize, PENUMBRA_MASK_GROUP_SIZE);
        kernel.push(cmd, push);
        vkCmdDispatch(cmd, groups, groups, 1);
        vk::memoryBarrier(cmd, kCompute, kStorageRW, kCompute, kStorageRW);
    }
    kernel.bind(cmd, stage(PENUMBRA_MASK_STAGE_WRITE_DISPATCH, lightType, push.useThin));
    kernel.push(cmd, push);
    vkCmdDispatch(cmd, 1, 1, 1);
    vk::memoryBarrier(cmd, kCompute, kStorageRW, kCompute | kIndirect, kStorageRW | kIndirectRead);
    kernel.bind(cmd, stage(PENUMBRA_MASK_STAGE_SPLAT, lightType, push.useThin));
    kernel.push(cmd, push);
    vkCmdDispatchIndirect(cmd, targets.jobs->buffer, 4);
    vk::memoryBarrier(cmd, kCompute, kStorageRW, kCompute, kStorageRW);
    // Each level's values pushed down, coarsest first, as far as level 1: it
    // ends up with the minimum over every level above its texel, so classify
    // reads two values, levels 0 and 1 (pushing into level 0 as well costs
    // three times what the rest does, more than the second read saves).
    kernel.bind(cmd, stage(PENUMBRA_MASK_STAGE_PUSH_DOWN, lightType, push.useThin));
    for (uint32_t level = push.topLevel; level-- > 1;) {
        push.level = level;
        const uint32_t size = (push.mapSize + (1u << level) - 1u) >> level;
        const uint32_t groups = groupCount(size, PENUMBRA_MASK_GROUP_SIZE);
        kernel.push(cmd, push);
        vkCmdDispatch(cmd, groups, groups, 1);
        vk::memoryBarrier(cmd, kCompute, kStorageRW, kCompute, kStorageRW);
    }
}

} // namespace penumbra::passes
