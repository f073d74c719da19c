// Shade (shaders/shade.comp.glsl): one light's contribution, with its
// visibility from classify or the tracer, added to the colour image (the
// first light also writes ambient and background).
#pragma once

#include "passes/pixel_bindings.h"

namespace penumbra::passes {

enum ShadeBinding : uint32_t { kShadeColor = kPixelBindingCount, kShadeBindingCount };

struct ShadePush {
    uint32_t lightIndex;
    uint32_t firstLight; // 1: initialise colour with ambient/background
    uint32_t debugPip;   // 1: tint marked pixels red (--debug-image pip)
    uint32_t pad;
};
static_assert(sizeof(ShadePush) == 16);

class ShadePass {
  public:
    void create(vk::Device& device);
    void destroy(vk::Device& device);
    void bind(vk::Device& device, const PixelTargets& pixels, VkImageView color);
    // Ends with the barrier that lets the next light's passes rewrite
    // visibility, marks and the ray list (also read as indirect arguments).
    // floor: the null twin instead (shaders/floor.glsli), after createFloor.
    // lightType: PENUMBRA_LIGHT_* of frame.lights[push.lightIndex]; the pipeline is
    // specialized for it, push.firstLight and push.debugPip.
    void record(VkCommandBuffer cmd, const ShadePush& push, uint32_t lightType, uint32_t width, uint32_t height,
                bool floor = false) const;
    void createFloor(vk::Device& device) { kernel.createFloor(device); }

  private:
    vk::ComputeKernel kernel;
};

} // namespace penumbra::passes
