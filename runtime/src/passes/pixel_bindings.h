// Bindings 0..5 shared by the per-pixel passes (classify, shade), as declared
// by shaders/pixel_bindings.glsli: the G-buffer, the visibility of the light
// being shaded, the frame constants, the per-pixel marks and the counters.
#pragma once

#include <vector>

#include "pipelines.h"

namespace penumbra::passes {

enum PixelBinding : uint32_t {
    kPixelSurface,    // rgba32ui surface texel: position and normal, 0 for background (shaders/surface.glsli; GENERAL)
    kPixelAlbedo,     // r32ui material colour, written when the frame shows colours (GENERAL; shade.comp reads it)
    kPixelVisibility, // r32f visibility of the light being shaded (GENERAL)
    kPixelFrame,      // uniform gpu::FrameData
    kPixelMarks,      // uint per pixel: rays wanted (compact.comp.glsl)
    kPixelStats,      // uint64_t[PENUMBRA_STAT_COUNT] counters
    kPixelBindingCount
};

struct PixelTargets {
    VkImageView surface = VK_NULL_HANDLE, albedo = VK_NULL_HANDLE, visibility = VK_NULL_HANDLE;
    VkBuffer frame = VK_NULL_HANDLE, marks = VK_NULL_HANDLE, stats = VK_NULL_HANDLE;
};

inline std::vector<VkDescriptorType> pixelBindingTypes()
{
    return {vk::kStorageImage, vk::kStorageImage, vk::kStorageImage, vk::kUniform, vk::kStorage, vk::kStorage};
}

inline std::vector<vk::Binding> pixelBindings(const PixelTargets& t)
{
    return {vk::storageImage(t.surface), vk::storageImage(t.albedo), vk::storageImage(t.visibility),
            vk::uniformBuffer(t.frame),   vk::storageBuffer(t.marks),  vk::storageBuffer(t.stats)};
}

} // namespace penumbra::passes
