// Alias-free shadow maps, hard shadows (Sintorn, Eisemann, Assarsson 2008,
// section 3; shaders afsm_samples.comp, afsm_scan.comp, afsm_casters.vert/
// geom/frag, afsm.glsli): per layer of the light, the camera's samples are
// counted per grid cell, the counts turned into offsets by a prefix sum and
// the samples listed per cell; then every caster of the layer's culled view
// is rasterized conservatively over the grid and tests the samples of each
// cell it covers exactly. Resolve writes the light's visibility.
#pragma once

#include <glm/mat4x4.hpp>

#include "culling.h"
#include "model_geometry.h"
#include "passes/pixel_bindings.h"

namespace penumbra::passes {

enum AfsmSamplesBinding : uint32_t {
    kAfsmCellFirst = kPixelBindingCount, // per cell: samples, then (after the scan) the first slot
    kAfsmCellCount,                      // per cell: slots taken while listing (= samples)
    kAfsmSamples,                        // pixel index per slot
    kAfsmShadowed,                       // per pixel: 1 when a caster blocks its ray
    kAfsmSamplesBindingCount
};
enum AfsmScanBinding : uint32_t { kAfsmScanCounts, kAfsmScanBlockSums, kAfsmScanBindingCount };
enum AfsmCastersBinding : uint32_t {
    kAfsmCastersPosition, kAfsmCastersNormal, kAfsmCastersFrame, kAfsmCastersCellFirst, kAfsmCastersCellCount, kAfsmCastersSamples,
    kAfsmCastersShadowed, kAfsmCastersBindingCount
};

struct AfsmSamplesPush {
    uint32_t lightIndex;
    uint32_t mode; // PENUMBRA_AFSM_COUNT, _LIST, _RESOLVE
    uint32_t layer;
    uint32_t gridSize;
    float originOffset;
    uint32_t pad[3];
};
static_assert(sizeof(AfsmSamplesPush) == 32);

struct AfsmScanPush {
    uint32_t count;
    uint32_t phase;
};
static_assert(sizeof(AfsmScanPush) == 8);

struct AfsmCastersPush {
    glm::mat4 viewProj;
    uint32_t lightIndex;
    uint32_t gridSize;
    float originOffset;
    uint32_t pad;
};
static_assert(sizeof(AfsmCastersPush) == 80);

struct AfsmTargets {
    PixelTargets pixels;
    const vk::Buffer* cellFirst = nullptr;
    const vk::Buffer* cellCount = nullptr;
    const vk::Buffer* blockSums = nullptr;
    const vk::Buffer* samples = nullptr;
    const vk::Buffer* shadowed = nullptr;
    uint32_t width = 0, height = 0, gridSize = 0;
};

// Cells per side of the grid for a width x height view: one cell per pixel of
// the longer side, a power of two (the paper fits one sample per texel).
uint32_t afsmGridSize(uint32_t width, uint32_t height);

class AfsmPass {
  public:
    // The casters' pipelines need geometry shaders and fragment stores
    // (vk::Device::aliasFree); without them only the error is left.
    void create(vk::Device& device);
    void destroy(vk::Device& device);
    void bind(vk::Device& device, const AfsmTargets& targets);
    // Clears the samples' shadow flags (before a light's layers).
    void clear(VkCommandBuffer cmd) const;
    // Counts, offsets and lists the samples of layer `layer` of the light.
    void recordSamples(VkCommandBuffer cmd, uint32_t lightIndex, uint32_t layer, float originOffset) const;
    // The casters of view `view` of `culling`, over the grid of viewProj.
    void recordCasters(VkCommandBuffer cmd, Culling& culling, uint32_t view, const GpuGeometry& geometry, const glm::mat4& viewProj,
                       uint32_t lightIndex, float originOffset) const;
    // The light's visibility (and cleared marks, counted pixels).
    void recordResolve(VkCommandBuffer cmd, uint32_t lightIndex, float originOffset) const;

  private:
    void dispatchPixels(VkCommandBuffer cmd, const AfsmSamplesPush& push) const;
    vk::ComputeKernel samples, scan;
    VkDescriptorSetLayout castersSetLayout = VK_NULL_HANDLE;
    VkDescriptorPool castersPool = VK_NULL_HANDLE;
    VkDescriptorSet castersSet = VK_NULL_HANDLE;
    vk::RasterPipelines casters;
    AfsmTargets targets;
};

} // namespace penumbra::passes
