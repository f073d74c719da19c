// Cone ray hierarchies (Olsson and Assarsson 2011), hard shadows of point
// and spot lights without a projection plane; shaders rh_rays.comp,
// rh_build.comp, rh_casters.vert/geom, rh_step.comp, rh_traverse.comp and
// rh.glsli (which explains the data). Per layer of the light (a point light's
// six cube faces only split the rays by direction; nothing is rasterized
// into a map): the layer's rays are listed, a 4-way cone hierarchy is built
// over them bottom-up, then the casters of the layer's culled view, in
// batches of bounded size, traverse it breadth-first in bounded memory;
// leaves test their rays exactly. The shadow flags are afsm's, resolved by
// its resolve pass.
#pragma once

#include <cstddef>
#include <functional>

#include <glm/vec4.hpp>

#include "config.h"
#include "culling.h"
#include "model_geometry.h"
#include "passes/pixel_bindings.h"

namespace penumbra::passes {

enum RhRaysBinding : uint32_t {
    kRhRaysPosition, kRhRaysNormal, kRhRaysFrame, kRhRaysList, kRhRaysState, kRhRaysTileOffsets, kRhRaysKeySlots, kRhRaysBindingCount
};
enum RhBuildBinding : uint32_t {
    kRhBuildPosition, kRhBuildFrame, kRhBuildRays, kRhBuildNodes, kRhBuildState, kRhBuildShadowed, kRhBuildBindingCount
};
enum RhCastersBinding : uint32_t { kRhCastersState, kRhCastersTriangles, kRhCastersBindingCount };
enum RhStepBinding : uint32_t { kRhStepState, kRhStepBindingCount };
enum RhTraverseBinding : uint32_t {
    kRhTraversePosition, kRhTraverseNormal, kRhTraverseFrame, kRhTraverseRays, kRhTraverseNodes, kRhTraverseTriangles,
    kRhTraversePairs, kRhTraverseShadowed, kRhTraverseState, kRhTraverseBindingCount
};

struct RhRaysPush {
    uint32_t lightIndex, layer;
    float originOffset;
    uint32_t mode; // PENUMBRA_RH_RAYS_*
};
struct RhScanPush { // afsm_scan.comp's
    uint32_t count, phase;
};
struct RhBuildPush {
    uint32_t lightIndex, mode, level, skipShadowed;
};
struct RhCastersPush {
    glm::vec4 lightLarge; // xyz light, w PENUMBRA_RH_LARGE_ANGLE
    uint32_t capacity, select, pad[2];
};
static_assert(sizeof(RhCastersPush) == 32);
struct RhStepPush {
    uint32_t pairCapacity, triangleCapacity, pad[2];
};
struct RhTraversePush {
    uint32_t lightIndex, test;
    float originOffset;
    uint32_t pad;
};

// shaders/rh.glsli, RH_STATE_DECLARE: the same words.
struct RhState {
    uint32_t rayCount, levels, done, deepest;
    uint32_t dispatch[3];
    uint32_t stepDepth, stepBegin, stepCount;
    uint32_t triangleCount, rootCursor;
    uint32_t peakPairs, overflow, steps, raysListed;
    uint64_t pairsTested, rayTests;
    uint32_t levelOffset[PENUMBRA_RH_MAX_LEVELS], levelCount[PENUMBRA_RH_MAX_LEVELS];
    uint32_t segBegin[PENUMBRA_RH_MAX_LEVELS], segEnd[PENUMBRA_RH_MAX_LEVELS], cursor[PENUMBRA_RH_MAX_LEVELS];
};
static_assert(offsetof(RhState, pairsTested) == 64 && sizeof(RhState) == 80 + 5 * 4 * PENUMBRA_RH_MAX_LEVELS);

struct RhTargets {
    VkImageView position = VK_NULL_HANDLE, normal = VK_NULL_HANDLE;
    VkBuffer frame = VK_NULL_HANDLE;
    const vk::Buffer* shadowed = nullptr; // afsm's per-pixel shadow flags
    uint32_t width = 0, height = 0;
};

// What the traversal did in one frame (RhPass::frameStats, after its last wait).
struct RhFrameStats {
    uint64_t rays = 0;          // rays listed (every layer, padding left out)
    uint64_t pairsTested = 0;   // cone/triangle tests (the paper's nodes visited)
    uint64_t rayTests = 0;      // exact ray/triangle tests at the leaves
    uint64_t casters = 0;       // triangles sent through the hierarchies
    uint32_t batches = 0;       // caster batches
    uint32_t rounds = 0;        // submissions of traversal steps
    uint64_t peakPairBytes = 0; // most pair memory in use at once
    uint64_t memoryBytes = 0;   // the pass's buffers (rays, nodes, triangles, pairs, state)
};

class RhPass {
  public:
    // Pair and triangle capacities: fixed, whatever the scene (bounded memory).
    static constexpr uint32_t kPairCapacity = 1u << 22;     // 32 MiB of (triangle, node) pairs
    static constexpr uint32_t kTriangleCapacity = 1u << 20; // 40 MiB of world-space triangles per batch
    static constexpr uint32_t kSortKeys = PENUMBRA_RH_SORT_CELLS * PENUMBRA_RH_SORT_CELLS; // sorted rays: direction keys per layer

    // The casters' pipeline needs geometry shaders and vertex-stage stores
    // (vk::Device::rayHierarchy); without them only the error is left.
    void create(vk::Device& device);
    void destroy(vk::Device& device);
    // The G-buffer and the shadow flags; the pass's own buffers for this size
    // (the fixed-size ones on the first call).
    void bind(vk::Device& device, const RhTargets& targets);
    bool bound(const RhTargets& targets) const; // bind would change nothing
    // Clears the frame's counters (before the frame's first light).
    void beginFrame(VkCommandBuffer cmd);

    using Submit = std::function<void()>; // submits what is recorded, waits, and begins recording again
    using Mark = std::function<void()>;   // the frame script's timestamp after the hierarchy is built
    // One layer of a light: its rays, their hierarchy, then the casters
    // `clusters` (ascending) in batches of at most kTriangleCapacity triangles
    // through it; after each batch `submit` is called until its traversal is done.
    // sorted: the rays ordered by direction (section 3.5), else by pixel (Morton order).
    // twoPass: the large casters first, the hierarchy rebuilt without the rays they shadowed, then the rest (section 3.4).
    void recordLayer(VkCommandBuffer cmd, uint32_t lightIndex, const glm::vec3& lightPosition, uint32_t layer, float originOffset,
                     uint32_t test, bool sorted, bool twoPass,
                     const GpuGeometry& geometry, const CullModel& model, const std::vector<uint32_t>& clusters, const Mark& built,
                     const Submit& submit);
    // After the frame's fence.
    RhFrameStats frameStats() const;

  private:
    uint32_t maxLevels() const;
    vk::ComputeKernel rays, scanTiles, scanKeys, build, step, traverse;
    VkDescriptorSetLayout castersSetLayout = VK_NULL_HANDLE;
    VkDescriptorPool castersPool = VK_NULL_HANDLE;
    VkDescriptorSet castersSet = VK_NULL_HANDLE;
    vk::RasterPipelines casters;
    vk::Buffer rayList, nodes, triangles, pairs, state, tileOffsets, blockSums, keySlots;
    uint32_t mortonTiles = 0; // tiles on the Morton curve over the image's tiles (a power-of-two square)
    RhTargets targets;
    VkBuffer shadowedBuffer = VK_NULL_HANDLE;
    uint32_t maxRays = 0, maxNodes = 0;
    RhFrameStats stats;
};

} // namespace penumbra::passes
