#include "passes/view_fit.h"

#include <cstring>

#include "frame_targets.h"
#include "passes/pass.h"

namespace penumbra::passes {

namespace {

// Pixels a side per invocation (view_fit.comp.glsl: kBlock): on a CPU device
// each invocation's subgroup reductions and atomics are loops over the lanes,
// so fewer, larger blocks; a GPU wants the invocations.
uint32_t blockSize(const vk::Device& device)
{
    return device.properties.deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU ? PENUMBRA_VIEW_FIT_BLOCK_CPU : PENUMBRA_VIEW_FIT_BLOCK_GPU;
}

} // namespace

void ViewFitPass::create(vk::Device& device)
{
    kernel.create(device, "view_fit.comp", {vk::kStorageImage, vk::kUniform}, sizeof(ViewFitPush));
}

void ViewFitPass::destroy(vk::Device& device) { kernel.destroy(device); }

void ViewFitPass::bind(vk::Device& device, const ViewFitTargets& t)
{
    kernel.write(device, {vk::storageImage(t.surface), vk::uniformBuffer(t.frame)});
}

void ViewFitPass::recordFloor(VkCommandBuffer cmd, const vk::Device& device, const vk::Buffer& viewBounds, uint32_t width,
                              uint32_t height) const
{
    const uint32_t block = blockSize(device);
    kernel.bind(cmd, vk::Specialization{0, 0, 0, 0, block}, true);
    kernel.push(cmd, ViewFitPush{vk::bufferAddress(device, viewBounds), 0, 0, 0, 0});
    const uint32_t tile = PENUMBRA_SHADE_GROUP_SIZE * block;
    vkCmdDispatch(cmd, groupCount(width, tile), groupCount(height, tile), 1);
    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
}

void ViewFitPass::record(VkCommandBuffer cmd, const vk::Device& device, const vk::Buffer& viewBounds, const vk::Buffer& receiverGrids,
                         uint32_t fitMask, uint32_t gridMask, uint32_t pointMask, uint32_t directionalMask, const std::vector<uint32_t>& gridLayers, uint32_t width,
                         uint32_t height, VkDeviceAddress covered) const
{
    auto gridRegion = [&](uint32_t light) { // the grids of light `light`: one per layer
        return std::pair<VkDeviceSize, VkDeviceSize>{6 * light * kReceiverGridBytes, gridLayers[light] * kReceiverGridBytes};
    };
    vkCmdFillBuffer(cmd, viewBounds.buffer, 0, kViewBoundsKeyBytes, ~0u);
    for (uint32_t i = 0; i < gridLayers.size(); ++i)
        if (gridMask & (1u << i))
            vkCmdFillBuffer(cmd, receiverGrids.buffer, gridRegion(i).first, gridRegion(i).second, 0u);
    vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute, kStorageRW);
    const uint32_t block = blockSize(device);
    kernel.bind(cmd, vk::Specialization{fitMask, gridMask, pointMask, directionalMask, block, covered != 0 ? 1u : 0u});
    kernel.push(cmd, ViewFitPush{vk::bufferAddress(device, viewBounds), vk::bufferAddress(device, receiverGrids), fitMask, gridMask, covered});
    const uint32_t tile = PENUMBRA_SHADE_GROUP_SIZE * block; // view_fit.comp.glsl: a block of pixels per invocation
    vkCmdDispatch(cmd, groupCount(width, tile), groupCount(height, tile), 1);
    if (gridMask) {
        // The grids are written with many atomics: in device memory, then copied out.
        vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCopy, kTransferRead);
        for (uint32_t i = 0; i < gridLayers.size(); ++i)
            if (gridMask & (1u << i)) {
                VkBufferCopy region{gridRegion(i).first, kViewBoundsKeyBytes + gridRegion(i).first, gridRegion(i).second};
                vkCmdCopyBuffer(cmd, receiverGrids.buffer, viewBounds.buffer, 1, &region);
            }
    }
    vk::memoryBarrier(cmd, kCompute | kCopy, kStorageWrite | kTransferWrite, kHost, VK_ACCESS_2_HOST_READ_BIT);
}

void readViewClips(const vk::Buffer& viewBounds, uint32_t light, ViewClip clips[6])
{
    // Keys back to floats (view_fit.comp.glsl): min x, y, z, then -max x, y, z, then the behind flag.
    const uint32_t* keys = static_cast<const uint32_t*>(viewBounds.mapped);
    auto fromKey = [](uint32_t key) {
        uint32_t bits = key & 0x80000000u ? key & 0x7FFFFFFFu : ~key;
        float f;
        std::memcpy(&f, &bits, sizeof(f));
        return f;
    };
    for (uint32_t map = 0; map < 6; ++map) {
        const uint32_t* k = keys + 8 * (6 * light + map);
        // Nothing covered, or a pixel behind a perspective map's eye: the model-fitted map stays.
        clips[map].valid = k[0] != ~0u && k[6] == ~0u;
        clips[map].min = {fromKey(k[0]), fromKey(k[1]), fromKey(k[2])};
        clips[map].max = {-fromKey(k[3]), -fromKey(k[4]), -fromKey(k[5])};
    }
}

std::shared_ptr<ReceiverMask> readReceiverMask(const vk::Buffer& viewBounds, uint32_t light, uint32_t layer, const glm::mat4& gridViewProj,
                                               const glm::mat4& drawnViewProj, uint32_t mapSize)
{
    // Margin: 2 texels of the map drawn, in the grid's clip units; a
    // directional map fitted to the view is the grid's map scaled and
    // shifted in x and y.
    const uint32_t* grids = static_cast<const uint32_t*>(viewBounds.mapped) + kViewBoundsKeyBytes / sizeof(uint32_t);
    auto mask = std::make_shared<ReceiverMask>();
    mask->viewProj = glm::dmat4(gridViewProj);
    const glm::dmat4 toDrawn = glm::dmat4(drawnViewProj) * glm::inverse(mask->viewProj);
    const glm::dvec2 drawnPerGrid(std::abs(toDrawn[0][0]), std::abs(toDrawn[1][1]));
    mask->margin = 2.0 * (2.0 / double(mapSize)) / drawnPerGrid + 1e-5;
    mask->build(grids + (6 * light + layer) * PENUMBRA_RECEIVER_GRID_WORDS, PENUMBRA_RECEIVER_GRID);
    return mask;
}

} // namespace penumbra::passes
