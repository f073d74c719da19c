// Shade (shaders/shade.comp.glsl): one light's contribution, with its
// visibility from classify or the tracer, added to the colour image (the
// first light also writes ambient and background). Its lookup variant
// (shade.comp.lookup, `sm`'s hard lights) reads the shadow map itself, so
// that an sm light needs no classify pass.
#pragma once

#include "passes/pixel_bindings.h"

namespace penumbra::passes {

enum ShadeBinding : uint32_t { kShadeColor = kPixelBindingCount, kShadeShadowMap, kShadeBindingCount }; // the map: lookup only

struct ShadePush {
    uint32_t lightIndex;
    uint32_t firstLight; // 1: initialise colour with ambient/background
    uint32_t debugPip;   // 1: tint marked pixels red (--debug-image pip)
    uint32_t countCovered; // 1: add the covered pixels to the frame's counter (the first light, when view_fit did not)
    uint32_t colours;      // 1: the albedo times the G-buffer's material colour (the frame shows colours)
};
static_assert(sizeof(ShadePush) == 20);

class ShadePass {
  public:
    void create(vk::Device& device);
    void destroy(vk::Device& device);
    // shadowMap, sampler: the lookup variant's map (nearest filtering).
    void bind(vk::Device& device, const PixelTargets& pixels, VkImageView color, VkImageView shadowMap, VkSampler sampler);
    // Ends with the barrier that lets the next light's passes rewrite
    // visibility, marks and the ray list (also read as indirect arguments).
    // floor: the null twin instead (shaders/floor.glsli), after createFloor.
    // lightType: PENUMBRA_LIGHT_* of frame.lights[push.lightIndex]; the pipeline is
    // specialized for it, push.firstLight, push.debugPip, push.countCovered and push.colours.
    // lookup: the visibility from the light's shadow map (hard lights, in the
    // shader-read layout), stored in the visibility image only if
    // storeVisibility; otherwise read from it.
    void record(VkCommandBuffer cmd, const ShadePush& push, uint32_t lightType, uint32_t width, uint32_t height,
                bool floor = false, bool lookup = false, bool storeVisibility = true) const;
    void createFloor(vk::Device& device)
    {
        kernel.createFloor(device);
        lookup.createFloor(device);
    }

  private:
    vk::ComputeKernel kernel;
    vk::ComputeKernel lookup;
};

} // namespace penumbra::passes
