#include "passes/compact.h"

#include "config.h"
#include "passes/pass.h"
#include "passes/trace.h"

namespace penumbra::passes {

void CompactPass::create(vk::Device& device)
{
    kernel.create(device, "compact.comp", {vk::kStorage, vk::kStorage, vk::kStorage}, sizeof(CompactPush));
    roundEntries = TracePass::entriesPerGroup(device);
}

void CompactPass::destroy(vk::Device& device) { kernel.destroy(device); }

void CompactPass::bind(vk::Device& device, VkBuffer marks, VkBuffer list, VkBuffer stats)
{
    rayList = list;
    kernel.write(device, {vk::storageBuffer(marks), vk::storageBuffer(list), vk::storageBuffer(stats)});
}

void CompactPass::recordFloor(VkCommandBuffer cmd, uint32_t width, uint32_t height) const
{
    const uint32_t pixelCount = width * height;
    kernel.bind(cmd, true);
    kernel.push(cmd, CompactPush{pixelCount, PENUMBRA_COMPACT_LIST, width, height, roundEntries});
    vkCmdDispatch(cmd, groupCount(width, 32), groupCount(height, 32), 1); // the real pass's quads
    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
}

void CompactPass::record(VkCommandBuffer cmd, uint32_t width, uint32_t height) const
{
    const uint32_t pixelCount = width * height;
    vkCmdFillBuffer(cmd, rayList, 0, PENUMBRA_RAY_LIST_HEADER_UINTS * 4, 0);
    vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute, kStorageRW);
    kernel.bind(cmd);
    CompactPush push{pixelCount, PENUMBRA_COMPACT_LIST, width, height, roundEntries};
    kernel.push(cmd, push);
    // One invocation per 2x2 quad of the 8x8 tiles covering the image, 4 x 4
    // tiles a workgroup (compact.comp.glsl: quadPixel).
    static_assert(PENUMBRA_COMPACT_GROUP_SIZE == 16 * 16);
    vkCmdDispatch(cmd, groupCount(width, 32), groupCount(height, 32), 1);
    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
    push.phase = PENUMBRA_COMPACT_DISPATCH;
    kernel.push(cmd, push);
    vkCmdDispatch(cmd, 1, 1, 1);
    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute | kIndirect, kStorageRW | kIndirectRead);
}

} // namespace penumbra::passes
