// Classification (shaders/classify.comp.glsl for directional, point and spot
// lights; classify_soft.comp.glsl for an area light's maps): per camera
// pixel, visibility from the shadow map and the marks of the pixels that get
// rays, in the mode the method's sequence gives (PENUMBRA_CLASSIFY_*,
// PENUMBRA_SOFT_*). Both shaders share one set: pixel_bindings.glsli, then
// classify_bindings.glsli.
#pragma once

#include "passes/pixel_bindings.h"

namespace penumbra::passes {

enum ClassifyBinding : uint32_t {
    kClassifyShadowMap = kPixelBindingCount, // sampler2DArray (SHADER_READ_ONLY)
    kClassifyThinMap,                        // float bits of the nearest thin depth per texel
    kClassifyMask,                           // penumbra mask of depth edges (penumbra_mask.h)
    kClassifyReceivers,                      // deepest receivers per tile (written in PENUMBRA_SOFT_RECEIVERS)
    kClassifyThinMask,                       // penumbra mask of thin triangles
    kClassifyBindingCount
};

struct ClassifyTargets {
    PixelTargets pixels;
    VkImageView shadowMap = VK_NULL_HANDLE;
    VkSampler sampler = VK_NULL_HANDLE;
    VkImageView thinMap = VK_NULL_HANDLE;
    const vk::Buffer* mask = nullptr;
    const vk::Buffer* receivers = nullptr;
    const vk::Buffer* thinMask = nullptr;
};

struct ClassifyPush {
    uint32_t lightIndex;
    uint32_t mode; // PENUMBRA_CLASSIFY_*
};
static_assert(sizeof(ClassifyPush) == 8);

struct ClassifySoftPush {
    uint32_t lightIndex;
    uint32_t slot;   // map of the light
    uint32_t mode;   // PENUMBRA_SOFT_*
    uint32_t first;  // PENUMBRA_SOFT_AVERAGE: 1 for the first map (writes instead of adding; counts pixels)
    float weight;    // PENUMBRA_SOFT_AVERAGE: 1 / K
    uint32_t mapSize;
    uint32_t topLevel; // the penumbra mask's top level (maskTopLevel)
    uint32_t pad;
};
static_assert(sizeof(ClassifySoftPush) == 32);

class ClassifyPass {
  public:
    void create(vk::Device& device);
    void destroy(vk::Device& device);
    void bind(vk::Device& device, const ClassifyTargets& targets);
    // One dispatch over a width x height image, then the barrier to the next compute pass.
    // floor: the null twins instead (shaders/floor.glsli), after createFloor.
    // lightType: PENUMBRA_LIGHT_* of frame.lights[push.lightIndex] (the pipeline is specialized for it and push.mode).
    void record(VkCommandBuffer cmd, const ClassifyPush& push, uint32_t lightType, uint32_t width, uint32_t height,
                bool floor = false) const;
    // lightType: PENUMBRA_LIGHT_* of the area light (a specialization constant, as push.mode is).
    void recordSoft(VkCommandBuffer cmd, const ClassifySoftPush& push, uint32_t lightType, uint32_t width, uint32_t height,
                    bool floor = false) const;
    void createFloor(vk::Device& device);

  private:
    vk::ComputeKernel hard, soft;
};

} // namespace penumbra::passes
