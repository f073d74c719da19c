// Cone ray hierarchies (Olsson and Assarsson 2011), hard shadows of point,
// spot and directional lights without a projection plane; shaders
// rh_rays.comp, rh_scan.comp, rh_build.comp, world_casters.vert, rh_casters.geom,
// rh_step.comp, rh_traverse.comp and rh.glsli (which explains the data). Per
// light, one hierarchy over all its rays: the light-facing pixels' rays are
// listed (by pixel, or sorted by direction), a 4-way hierarchy of cones from
// the light (of slabs across a directional light) is built over them
// bottom-up, then the casters of the light's culled views, in batches of
// bounded size, traverse it breadth-first in bounded memory; leaves test
// their rays exactly. The shadow flags are afsm's, resolved by its resolve
// pass.
#pragma once

#include <cstddef>
#include <functional>

#include <glm/vec3.hpp>

#include "config.h"
#include "culling.h"
#include "model_geometry.h"
#include "passes/pixel_bindings.h"
#include "penumbra/penumbra.h"

namespace penumbra::passes {

enum RhRaysBinding : uint32_t {
    kRhRaysPosition, kRhRaysNormal, kRhRaysFrame, kRhRaysList, kRhRaysState, kRhRaysTileCounts, kRhRaysKeyCounts, kRhRaysDepthGrid,
    kRhRaysBindingCount
};
enum RhScanBinding : uint32_t { kRhScanCounts, kRhScanBindingCount };
enum RhBuildBinding : uint32_t {
    kRhBuildPosition, kRhBuildNormal, kRhBuildFrame, kRhBuildRays, kRhBuildNodes, kRhBuildState, kRhBuildShadowed, kRhBuildDepthGrid,
    kRhBuildBindingCount
};
enum RhCastersBinding : uint32_t {
    kRhCastersState, kRhCastersTrianglesA, kRhCastersTrianglesB, kRhCastersClusterFaces, kRhCastersDepthGrid, kRhCastersFrame, kRhCastersBindingCount
};
enum RhStepBinding : uint32_t { kRhStepState, kRhStepBindingCount };
enum RhTraverseBinding : uint32_t {
    kRhTraversePosition, kRhTraverseNormal, kRhTraverseFrame, kRhTraverseRays, kRhTraverseNodes, kRhTraverseTrianglesA,
    kRhTraverseTrianglesB, kRhTraverseRecords, kRhTraverseShadowed, kRhTraverseState, kRhTraverseStep,
    // The same buffers as uniform texel views (rh_traverse.comp's kTexelAccess): on lavapipe a texel fetch is a
    // gather, any other load that is not uniform a loop over the lanes.
    kRhTraverseRayTexels, kRhTraverseNodeTexels, kRhTraverseTriangleTexelsA, kRhTraverseTriangleTexelsB, kRhTraverseRecordTexels,
    kRhTraverseBindingCount
};

struct RhRaysPush {
    uint32_t lightIndex, mode;
    float originOffset;
    uint32_t order;   // keys: 2^order x 2^order cells per face
    uint32_t measure;   // the tiles' incoherence (the per-frame order)
    uint32_t gridFaces; // the receivers' depth grid (0: none)
    uint32_t gridOrder;
    uint32_t pad;
};
static_assert(sizeof(RhRaysPush) == 32);
struct RhScanPush {
    uint32_t count, sums, phase, pad;
};
struct RhBuildPush {
    uint32_t lightIndex, mode, level, skipShadowed;
    float originOffset;
    uint32_t sort, keyGroupsX, keyGroupsY, scanGroups, faces, casters, pad;
};
static_assert(sizeof(RhBuildPush) == 48);
struct RhCastersPush {
    glm::vec4 lightLarge;    // xyz light, w PENUMBRA_RH_LARGE_ANGLE
    glm::vec4 toLightOffset; // directional lights: toward the light; w: the rays' origin offset
    uint32_t capacity, select, pointLight, spotLight, lightIndex, gridFaces, gridOrder, pad;
};
static_assert(sizeof(RhCastersPush) == 64);
struct RhStepPush {
    uint32_t pairCapacity, triangleCapacity, pad[2];
};
struct RhTraversePush {
    uint32_t lightIndex;
    float originOffset;
    uint32_t faces, pad;
};
static_assert(sizeof(RhTraversePush) == 16);

// shaders/rh.glsli, RH_STATE_WORDS: the same words (std430 and std140 alike).
struct RhState {
    uint32_t rayCount, levels, done, deepest;
    uint32_t dispatch[3];
    uint32_t stepDepth, stepBegin, stepCount, triangleCount, rootCursor;
    uint32_t sorted;
    uint32_t keyDispatch[3], scanDispatch[3], scanPhase1[3];
    uint32_t countedRays, lightAccepted;
    uint64_t incoherence, coherenceRays;
    uint32_t leafDispatch[3], stepPad;
    uint32_t faceCount[8], faceShift[8];
    uint32_t builtLevels, alignmentLevel, treePad[2];
    uint32_t peakPairs, overflow, steps, raysListed, sortedLights, framePad0;
    uint64_t pairsTested, rayTests, accepted, rayHits, framePad2;
    uint32_t levelOffset[PENUMBRA_RH_MAX_LEVELS], levelCount[PENUMBRA_RH_MAX_LEVELS];
    uint32_t segBegin[PENUMBRA_RH_MAX_LEVELS], segEnd[PENUMBRA_RH_MAX_LEVELS], cursor[PENUMBRA_RH_MAX_LEVELS];
    uint32_t depthTests[PENUMBRA_RH_MAX_LEVELS];
};
static_assert(offsetof(RhState, incoherence) == 96 && offsetof(RhState, leafDispatch) == 112 && offsetof(RhState, faceCount) == 128 &&
              offsetof(RhState, peakPairs) == 208 && offsetof(RhState, pairsTested) == 232 && offsetof(RhState, levelOffset) == 272 &&
              sizeof(RhState) == 272 + 6 * 4 * PENUMBRA_RH_MAX_LEVELS);

struct RhTargets {
    // The G-buffer (surface.glsli); the albedo is not read (the G-buffer keeps bindings 0 and 1 in every pass).
    VkImageView surface = VK_NULL_HANDLE, albedo = VK_NULL_HANDLE;
    VkBuffer frame = VK_NULL_HANDLE;
    const vk::Buffer* shadowed = nullptr; // afsm's per-pixel shadow flags
    uint32_t width = 0, height = 0;
    uint32_t clusters = 0; // the model's clusters
};

// What the traversal did in one frame (RhPass::frameStats, after its last wait).
struct RhFrameStats {
    uint64_t rays = 0;          // rays listed (every light, padding left out)
    uint64_t pairsTested = 0;   // cone (slab) tests: the paper's nodes visited
    uint64_t rayTests = 0;      // exact ray/triangle tests at the leaves
    uint64_t rayHits = 0;       // ... that hit
    uint64_t accepted = 0;      // nodes found covered (early accept)
    uint64_t casters = 0;       // triangles sent through the hierarchies
    uint32_t closedCulled = 0;  // lights whose closed clusters cast only light-back-facing triangles (section 3.6)
    uint32_t batches = 0;       // caster batches
    uint32_t rounds = 0;        // submissions of traversal steps
    uint32_t lights = 0;        // hierarchies built
    uint32_t sortedLights = 0;  // of those, over rays sorted by direction
    double incoherence = 0;     // the last light's mean tile incoherence (measured when the order is auto; 0 otherwise)
    uint64_t peakPairBytes = 0; // most record memory in use at once
    uint64_t memoryBytes = 0;   // the pass's buffers (rays, nodes, triangles, records, counts, state)
};

// How one light's rays are shadowed.
struct RhOptions {
    uint32_t test = PENUMBRA_RH_TEST_PRECISE;
    RhSort sort = RhSort::Auto;
    bool twoPass = false;
    bool earlyAccept = true;
    // Section 3.6: the clusters marked closed (model::kClusterClosed) cast
    // only their light-back-facing triangles; closedClusterFlag(cluster) says which.
    bool closedCulling = false;
    // Casters behind every receiver they could shadow (the receivers' depth grid, rh.glsli) left out.
    bool cullBehindReceivers = true;
};

// Section 3.6, front-face culling of closed meshes, and when it is exact. A
// ray from a receiver to the light that passes through a closed, outward-
// oriented component enters it through a light-back-facing triangle, which
// is kept; it misses its shadow only when it starts inside the component and
// the light is outside (it only leaves, through a light-front-facing one).
// An inward-oriented component (consistently oriented too, the format allows
// it) fails the other way round: the light inside, the receiver outside.
// Receivers are inside a component only when the camera is (a camera outside
// sees none of its inside). Along the segment from the eye to the light, a
// failing component is crossed more often with the triangle's winding normal
// along the segment than against it. So culling is exact when no closed
// triangle is crossed that way (this test, on the host, over the closed
// clusters whose boxes the segment meets); otherwise the light's closed
// clusters cast every triangle this frame. `toLight`: for a directional
// light, the segment is the ray from the eye toward it.
bool closedCullingExact(const CompressedModel& model, const glm::vec3& eye, const glm::vec3& light, bool directional);

// Paged geometry (geometry_pages.h): the casters are drawn in ranges whose
// pages fit the pool together (`cut`: GeometryPages::cutIntoRanges), each made
// resident (`makeResident`, which may submit what is recorded and begin again)
// before its first batch; a batch never spans two ranges. The casters are
// copied to the triangle lists in world space when drawn, so the traversal
// needs no page. Rays are shadowed by any caster (an OR), so batches of other
// sizes give the same flags. Empty (no cut) in core.
struct RhPaging {
    std::function<std::vector<std::vector<uint32_t>>(const std::vector<uint32_t>&)> cut;
    std::function<void(const std::vector<uint32_t>&)> makeResident;
};

class RhPass {
  public:
    // Record and triangle capacities: fixed, whatever the scene (bounded memory).
    static constexpr uint32_t kPairCapacity = 1u << 22;     // 32 MiB of (triangle, node) records
    static constexpr uint32_t kTriangleCapacity = 1u << 20; // 36 MiB of world-space triangles per batch

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
    // One light: its rays, their hierarchy, then the casters of its views
    // (`viewClusters`: each view's clusters, ascending; a point light's six
    // cube faces, from +x, -x, +y, -y, +z, -z) in batches of at most
    // kTriangleCapacity triangles through it, each cluster once, carrying the
    // faces whose views kept it; after each batch `submit` is called until
    // its traversal is done. A point, spot or directional light.
    // `closed`: per cluster, whether it is marked closed (with options.closedCulling).
    void recordLight(VkCommandBuffer cmd, uint32_t lightIndex, const Light& light, float originOffset,
                     const RhOptions& options, const GpuGeometry& geometry, const CullModel& model,
                     const std::vector<std::vector<uint32_t>>& viewClusters, const std::function<bool(uint32_t)>& closed,
                     const Mark& built, const Submit& submit, const RhPaging& paging = {});
    // After the frame's fence.
    RhFrameStats frameStats() const;

  private:
    uint32_t maxLevels() const;
    uint32_t sortOrder(uint32_t faces) const; // Hilbert order of the keys per face
    uint32_t gridOrder(uint32_t faces) const; // the receivers' depth grid: 2^order cells a side
    void destroyTexelViews(vk::Device& device);
    vk::ComputeKernel rays, scanTiles, scanKeys, build, buildParallel, step, traverse, traverseParallel;
    VkDescriptorSetLayout castersSetLayout = VK_NULL_HANDLE;
    VkDescriptorPool castersPool = VK_NULL_HANDLE;
    VkDescriptorSet castersSet = VK_NULL_HANDLE;
    vk::RasterPipelines casters;
    vk::Buffer rayList, nodes, trianglesA, trianglesB, records, state, tileCounts, keyCounts;
    // Texel views of rayList (RGBA32UI), nodes (RGBA32UI, two a node), trianglesA (RGBA32UI, two a
    // triangle), trianglesB (RG32UI), records (RG32UI); texelAccess: each holds its whole buffer.
    VkBufferView rayTexels = VK_NULL_HANDLE, nodeTexels = VK_NULL_HANDLE, triangleTexelsA = VK_NULL_HANDLE,
                 triangleTexelsB = VK_NULL_HANDLE, recordTexels = VK_NULL_HANDLE;
    bool texelAccess = false;
    vk::Buffer clusterFaces; // per cluster: the faces whose views kept it (host-written per light)
    std::vector<uint32_t> faceBits; // clusterFaces built on the host (vk::writeMapped)
    vk::Buffer depthGrid;    // the receivers' depth grid (rh.glsli), 6 faces
    uint32_t mortonTiles = 0;  // tiles on the Morton curve over the image's tiles (a power-of-two square)
    uint32_t keyCapacity = 0;  // keys the key counts hold (before their block totals)
    RhTargets targets;
    VkBuffer shadowedBuffer = VK_NULL_HANDLE;
    uint32_t maxRays = 0, maxNodes = 0;
    RhFrameStats stats;
    double profileMs[5] = {}; // PENUMBRA_RH_PROFILE: host-timed rays, build, casters, traverse, resolve
    double profileDepthMs[PENUMBRA_RH_MAX_LEVELS] = {}; // ... the traversal's steps by depth (one step per wait)
};

} // namespace penumbra::passes
