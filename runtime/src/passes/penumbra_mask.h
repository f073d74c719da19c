// Penumbra mask of an area light's shadow map (shaders/penumbra_mask.comp.glsl,
// penumbra_mask.glsli; srt soft shadows): the map's edge texels (depth
// discontinuities, thin triangles) splatted with the light's projected shape
// into a mask over every level of the map, so that classify_soft traces
// light samples only for the pixels inside it. Needs the deepest receivers
// per tile first (ClassifyPass::recordSoft with PENUMBRA_SOFT_RECEIVERS,
// between clear() and record()).
#pragma once

#include <glm/mat4x4.hpp>

#include "pipelines.h"

namespace penumbra::passes {

// Levels of the mask over an S x S map: 0 .. top, where the level is 1 texel.
uint32_t maskTopLevel(uint32_t size);
// Texels of levels 0 .. top together.
uint64_t maskTexels(uint32_t size);

enum PenumbraMaskBinding : uint32_t {
    kMaskShadowMap, // sampler2DArray: the map (SHADER_READ_ONLY)
    kMaskThinMap,   // the thin map; its last layer: per-texel sliver depths
    kMaskFrame,     // gpu::FrameData
    kMaskPyramid,   // nearest edge depth per block, levels 1..top, per edge kind
    kMaskMask,      // word 0: flags; then per texel of every level the nearest receiver depth reached
    kMaskReceivers, // per tile: the deepest camera pixel; then of those the map does not hide
    kMaskJobs,      // splat jobs and their indirect dispatch
    kMaskThinMask,  // the mask of thin triangles' splats
    kMaskBindingCount
};

struct PenumbraMaskTargets {
    VkImageView shadowMap = VK_NULL_HANDLE;
    VkSampler sampler = VK_NULL_HANDLE;
    VkImageView thinMap = VK_NULL_HANDLE;
    VkBuffer frame = VK_NULL_HANDLE;
    const vk::Buffer* pyramid = nullptr;
    const vk::Buffer* mask = nullptr;
    const vk::Buffer* receivers = nullptr;
    const vk::Buffer* jobs = nullptr;
    const vk::Buffer* thinMask = nullptr;
    uint32_t maxJobs = 0;
};

struct PenumbraMaskPush {
    glm::mat4 invViewProj;
    uint32_t lightIndex;
    uint32_t slot;
    uint32_t level; // the edge stage's or a reduction's source level
    uint32_t mapSize;
    uint32_t topLevel;
    uint32_t useThin;
    float edgeDelta;
    uint32_t maxJobs;
};
static_assert(sizeof(PenumbraMaskPush) == 96);

class PenumbraMaskPass {
  public:
    void create(vk::Device& device);
    void destroy(vk::Device& device);
    void bind(vk::Device& device, const PenumbraMaskTargets& targets);
    // Clears the masks, the receivers and the job list after the passes that read them.
    void clear(VkCommandBuffer cmd) const;
    // The edge pass, one reduction per level, the splats of the listed jobs,
    // then each level's minimum pushed down to level 0; each stage a pipeline of its own (specialized also by the light's
    // type, PENUMBRA_LIGHT_*, and push.useThin). push.level and push.maxJobs
    // are filled in.
    void record(VkCommandBuffer cmd, PenumbraMaskPush push, uint32_t lightType) const;

  private:
    vk::ComputeKernel kernel;
    PenumbraMaskTargets targets;
};

} // namespace penumbra::passes
