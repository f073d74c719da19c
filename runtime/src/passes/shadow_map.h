// Shadow-map pass (shaders/shadow_map.vert.glsl): the depth of the casters
// from a light, one layer of the shadow map (a cube face, or one map of an
// area light) per view of the shadow views' culling, with slope-scaled
// depth bias. Depth only.
#pragma once

#include <glm/mat4x4.hpp>

#include "culling.h"
#include "model_geometry.h"
#include "pipelines.h"

namespace penumbra::passes {

struct ShadowMapPush {
    glm::mat4 viewProj;
};
static_assert(sizeof(ShadowMapPush) == 64);

struct DepthBias {
    float constant = 0.0f, slope = 0.0f;
};

class ShadowMapPass {
  public:
    void create(vk::Device& device);
    void destroy(vk::Device& device);
    // The map goes from SHADER_READ_ONLY to a depth attachment (begin) and
    // back for the compute passes that sample it (end), around the layers drawn.
    void begin(VkCommandBuffer cmd, const vk::Image& shadowMap) const;
    void end(VkCommandBuffer cmd, const vk::Image& shadowMap) const;
    // Draws layer `layer` of the map from viewProj, culled as view `view` of `culling`.
    void record(VkCommandBuffer cmd, Culling& culling, uint32_t view, const GpuGeometry& geometry, const vk::Image& shadowMap,
                uint32_t layer, const ShadowMapPush& push, DepthBias bias) const;

  private:
    vk::RasterPipelines pipelines;
};

} // namespace penumbra::passes
