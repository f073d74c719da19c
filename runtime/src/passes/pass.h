// What every pass module shares: pipeline stages and accesses of the
// barriers between passes, and workgroup counts. A pass module
// (runtime/src/passes/<pass>.{h,cpp}, beside shaders/<pass>.<stage>.glsl)
// owns its pipelines, descriptor-set layout (bindings named by an enum that
// matches the shader) and push constants (checked against the shader's
// block when the pipeline is created, pipelines.h), and has
// create / destroy / bind (the frame targets it reads and writes, when they
// change) / record. Passes never see each other; the frame script
// (renderer.cpp) orders them and records the barriers between them.
#pragma once

#include <algorithm>
#include <vulkan/vulkan.h>

namespace penumbra::passes {

constexpr VkPipelineStageFlags2 kNone = VK_PIPELINE_STAGE_2_NONE;
constexpr VkPipelineStageFlags2 kColorOut = VK_PIPELINE_STAGE_2_COLOR_ATTACHMENT_OUTPUT_BIT;
constexpr VkPipelineStageFlags2 kDepthTests = VK_PIPELINE_STAGE_2_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_2_LATE_FRAGMENT_TESTS_BIT;
constexpr VkPipelineStageFlags2 kCompute = VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT;
constexpr VkPipelineStageFlags2 kCopy = VK_PIPELINE_STAGE_2_COPY_BIT;
// vkCmdFillBuffer and vkCmdClearColorImage. The specification puts fills in the clear stage, but
// Debian 12's validation layers (1.3.239) track them as copies (Vulkan-ValidationLayers issue
// 7406, fixed in 2024): with the clear bit alone, synchronization validation reports every
// access after a fill. All transfer stages cover both readings.
constexpr VkPipelineStageFlags2 kClear = VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT;
constexpr VkPipelineStageFlags2 kIndirect = VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT;
constexpr VkPipelineStageFlags2 kHost = VK_PIPELINE_STAGE_2_HOST_BIT;
constexpr VkAccessFlags2 kStorageRead = VK_ACCESS_2_SHADER_STORAGE_READ_BIT;
constexpr VkAccessFlags2 kStorageWrite = VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT;
constexpr VkAccessFlags2 kStorageRW = kStorageRead | kStorageWrite;
constexpr VkAccessFlags2 kTransferWrite = VK_ACCESS_2_TRANSFER_WRITE_BIT;
constexpr VkAccessFlags2 kTransferRead = VK_ACCESS_2_TRANSFER_READ_BIT;
constexpr VkAccessFlags2 kIndirectRead = VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT;

inline uint32_t groupCount(uint32_t items, uint32_t groupSize) { return (items + groupSize - 1) / groupSize; }

// Workgroups of a 1-D dispatch laid out in 2-D (devices may limit each dimension).
struct Groups2D {
    uint32_t x = 1, y = 1;
};
inline Groups2D spreadGroups(uint32_t groups, uint32_t maxPerRow)
{
    const uint32_t x = std::max(std::min(groups, maxPerRow), 1u);
    return {x, (groups + x - 1) / x};
}

} // namespace penumbra::passes
