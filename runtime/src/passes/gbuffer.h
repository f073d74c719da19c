// Camera pass (shaders/gbuffer.vert.glsl, gbuffer.frag.glsl): the G-buffer,
// world position and a normal turned toward the camera per pixel in one
// surface texel (shaders/surface.glsli), and the cluster's packed albedo in a
// second target when the frame shows colours, drawn from the compressed
// clusters (or the uncompressed reference) through the camera's culled view.
// On lavapipe each colour target costs the pass about as much as the
// fragments' own work: 20 -> 15 ms at 1024^2 for the second target's move
// from RGBA32F to R32UI, 15 -> 10 ms for leaving it out.
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
    uint64_t albedoAddress = 0; // GpuGeometry::albedo; 0: none (white), and the albedo target is not drawn
    // Bit per cluster (AfsmPass::closedBitsAddress), 0: none. When set, the
    // camera never sees the inside of a cluster flagged kClusterClosed: its
    // triangles seen from behind are not drawn (gbuffer.frag.outside).
    uint64_t closedAddress = 0;
};
static_assert(sizeof(GBufferPush) == 96);

// Writes the surface and (with an albedoAddress) the albedo, both left in
// GENERAL for the compute passes and copies, and depth (kept for the
// culling's second phase).
struct GBufferTargets {
    const vk::Image* surface = nullptr;
    const vk::Image* albedo = nullptr;
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
    vk::RasterPipelines pipelines[2][2]; // [outside][albedo]: gbuffer.frag[.outside][.albedo]
};

} // namespace penumbra::passes
