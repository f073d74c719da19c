// View fit (shaders/view_fit.comp.glsl): after the camera pass, the bounds of
// the visible points in each model-fitted map of the lights fitted to the
// view, and where those points are looked up in each layer of the lights
// whose views cull by receivers (receiver grids). The frame reads both back
// (its one mid-frame submission and fence wait) before it plans and draws
// the shadow maps.
#pragma once

#include <memory>

#include <glm/mat4x4.hpp>

#include "culling.h"
#include "lights.h"
#include "pipelines.h"

namespace penumbra::passes {

enum ViewFitBinding : uint32_t { kViewFitPosition, kViewFitFrame, kViewFitBindingCount };

struct ViewFitPush {
    VkDeviceAddress keys; // viewBounds: PENUMBRA_MAX_LIGHTS * 6 * 8 uints, cleared to 0xFFFFFFFF
    VkDeviceAddress grid; // receiverGrids: PENUMBRA_RECEIVER_GRID_WORDS uints per layer 6 l + k, cleared to 0
    uint32_t lightMask;   // bit l: light l is fitted (directional, area)
    uint32_t gridMask;    // bit l: light l writes its receiver grids (directional, point, spot)
    VkDeviceAddress covered; // 0, or the frame counter PENUMBRA_STAT_COVERED (uint64_t) that the pass adds the covered pixels to
};
static_assert(sizeof(ViewFitPush) == 32);

struct ViewFitTargets {
    VkImageView surface = VK_NULL_HANDLE; // G-buffer surface (surface.glsli; GENERAL)
    VkBuffer frame = VK_NULL_HANDLE;       // gpu::FrameData
};

class ViewFitPass {
  public:
    void create(vk::Device& device);
    void destroy(vk::Device& device);
    void bind(vk::Device& device, const ViewFitTargets& targets);
    // Clears and writes viewBounds (host-visible) for a width x height G-buffer:
    // keys of the lights in fitMask, and through receiverGrids (device-local)
    // the grids of gridLayers[l] layers of each light l in gridMask. Ends with
    // the barrier to the host read. covered: 0, or the address of the frame's
    // PENUMBRA_STAT_COVERED counter, which then gets the covered pixels (the
    // shade pass need not count them).
    void record(VkCommandBuffer cmd, const vk::Device& device, const vk::Buffer& viewBounds, const vk::Buffer& receiverGrids,
                uint32_t fitMask, uint32_t gridMask, uint32_t pointMask, uint32_t directionalMask, const std::vector<uint32_t>& gridLayers,
                uint32_t width, uint32_t height, VkDeviceAddress covered = 0) const;
    // The null twin (shaders/floor.glsli): every G-buffer point read, the bounds left as they are; after createFloor.
    void recordFloor(VkCommandBuffer cmd, const vk::Device& device, const vk::Buffer& viewBounds, uint32_t width, uint32_t height) const;
    void createFloor(vk::Device& device) { kernel.createFloor(device); }

  private:
    vk::ComputeKernel kernel;
};

// After the submission: the clip bounds of each of light `light`'s six possible maps.
void readViewClips(const vk::Buffer& viewBounds, uint32_t light, ViewClip clips[6]);

// After the submission: the receiver mask of layer `layer` of light `light`,
// whose grid lies over gridViewProj's clip space (a directional light's
// model-fitted map, or the layer's own map) and whose map is drawn with
// drawnViewProj at mapSize texels: footprints are grown by 2 texels of the
// drawn map (the classification reads the 3x3 texels around a point's).
std::shared_ptr<ReceiverMask> readReceiverMask(const vk::Buffer& viewBounds, uint32_t light, uint32_t layer, const glm::mat4& gridViewProj,
                                               const glm::mat4& drawnViewProj, uint32_t mapSize);

} // namespace penumbra::passes
