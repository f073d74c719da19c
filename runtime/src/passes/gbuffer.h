// Camera pass (shaders/gbuffer.vert.glsl, gbuffer.frag.glsl): the G-buffer,
// world position and a normal turned toward the camera per pixel (its w the
// cluster's packed albedo), drawn from
// the compressed clusters (or the uncompressed reference) through the
// camera's culled view.
#pragma once

#include <glm/mat4x4.hpp>

#include "culling.h"
#include "model_geometry.h"
#include "pipelines.h"

namespace penumbra::passes {

// shaders/gbuffer_push.glsli
struct GBufferPush {
    glm::mat4 viewProj;
    glm::vec4 cameraPosition;
    uint64_t albedoAddress = 0; // GpuGeometry::albedo, 0: none (white)
    // Bit per cluster (AfsmPass::closedBitsAddress), 0: none. When set, the
    // camera never sees the inside of a cluster flagged kClusterClosed: its
    // triangles seen from behind are not drawn (gbuffer.frag.outside).
    uint64_t closedAddress = 0;
};
static_assert(sizeof(GBufferPush) == 96);

// Writes position and normal (left in GENERAL for the compute passes and
// copies) and depth (kept for the culling's second phase).
struct GBufferTargets {
    const vk::Image* position = nullptr;
    const vk::Image* normal = nullptr;
    const vk::Image* depth = nullptr;
};

class GBufferPass {
  public:
    void create(vk::Device& device);
    void destroy(vk::Device& device);
    // Draws view `view` of the camera's culling.
    void record(VkCommandBuffer cmd, Culling& culling, uint32_t view, const GpuGeometry& geometry, const GBufferTargets& targets,
                const GBufferPush& push) const;

  private:
    vk::RasterPipelines pipelines, outsidePipelines;
};

} // namespace penumbra::passes
