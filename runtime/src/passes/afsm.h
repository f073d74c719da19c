// Alias-free shadow maps (Sintorn, Eisemann, Assarsson 2008; shaders
// afsm_samples.comp, afsm_scan.comp, world_casters.vert, afsm_casters.geom/frag,
// afsm_soft.geom/frag, afsm_table.comp, afsm.glsli). Per layer of the light,
// the camera's samples are counted per grid cell, the counts turned into
// offsets by a prefix sum and the samples listed per cell; then every caster
// of the layer's culled view is rasterized conservatively over the grid and
// tests the samples of each cell it covers exactly. Resolve writes the
// light's visibility.
//
// Hard shadows (section 3): a caster covers its own footprint in the grid and
// sets a sample's shadow flag when it blocks the sample's ray (the tracer's
// watertight test). Soft shadows (section 4, area lights): a caster covers its
// influence region and ORs the light samples it hides into the sample's
// bitmask, one bit per light sample, by four lookups in a table from a plane
// to a bitmask (built on the GPU per light shape and sample count).
#pragma once

#include <functional>

#include <glm/mat4x4.hpp>

#include "culling.h"
#include "lights.h"
#include "model_geometry.h"
#include "passes/pixel_bindings.h"
#include "penumbra/penumbra.h"

namespace penumbra::gpu {
struct LightData;
}

namespace penumbra::passes {

enum AfsmSamplesBinding : uint32_t {
    kAfsmCellFirst = kPixelBindingCount, // per cell: samples, then (after the scan) the first slot
    kAfsmCellCount,                      // per cell: slots taken while listing (= samples)
    kAfsmShadowed,                       // per pixel: 1 when a caster blocks its ray (soft: every light sample)
    kAfsmFar,                            // the layer's farthest sample depth (afsm.glsli: afsmDepth)
    kAfsmCellDepth,                      // per cell: its farthest sample depth
    kAfsmSlotShadowed,                   // per slot: its pixel's flag (cleared when listed)
    kAfsmCellAlive,                      // per cell: its samples not yet shadowed
    kAfsmSamplesBindingCount
};
enum AfsmScanBinding : uint32_t { kAfsmScanCounts, kAfsmScanBlockSums, kAfsmScanBindingCount };
// The raster path's set (hard and soft pipelines).
enum AfsmCastersBinding : uint32_t {
    kAfsmCastersFrame, kAfsmCastersCellFirst, kAfsmCastersCellCount, kAfsmCastersShadowed, kAfsmCastersFar, kAfsmCastersCellDepth,
    kAfsmCastersSlotShadowed, kAfsmCastersCellAlive, kAfsmCastersClosedBits, kAfsmCastersSlotTexels, kAfsmCastersBindingCount
};
enum AfsmBinBinding : uint32_t {
    kAfsmBinFrame, kAfsmBinCellFirst, kAfsmBinCellCount, kAfsmBinShadowed, kAfsmBinFar, kAfsmBinCellDepth, kAfsmBinSlotShadowed, kAfsmBinCellAlive, kAfsmBinParams,
    kAfsmBinClosedBits, kAfsmBinSlotTexels, kAfsmBinModelNodes, kAfsmBinModelClusters, kAfsmBinModelVertices, kAfsmBinModelStrips, kAfsmBinBindingCount
};

struct AfsmSamplesPush {
    glm::mat4 viewProj; // the layer's grid projection
    uint64_t slots;     // soft: device address of the per-slot data
    uint64_t masks;     // soft: of the per-pixel sample masks
    uint64_t table;     // soft: of the lookup table
    uint32_t lightIndex;
    uint32_t mode; // PENUMBRA_AFSM_COUNT, _LIST, _RESOLVE
    uint32_t layer;
    uint32_t gridSize;
    float originOffset;
    uint32_t cube;      // the layers are the six cube faces around the light's position
    uint32_t samples;   // soft: light samples
    uint32_t tableSize; // soft: angles | distances << 16
    uint32_t sliceSamples; // a cell with more samples is crowded (afsmSliceSamples)
    uint32_t pad;
};
static_assert(sizeof(AfsmSamplesPush) == 128);

// The layer's buffer kAfsmFar (afsm_samples.comp.glsl writes it).
struct AfsmFar {
    uint32_t farBits;    // the farthest sample's clip.w (float bits)
    uint32_t cellMost;   // the most samples in one cell
    uint32_t crowded[4]; // the cells holding more than afsmSliceSamples: min x, min y, max x, max y (~0, ~0, 0, 0: none)
    uint32_t pad[2];
    uint32_t parallel[4]; // hard shadows of a directional light: the layer's shear (afsm.glsli: AfsmParallel; 0: other layers)
};
static_assert(sizeof(AfsmFar) == 48);

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
    float computeCells; // casters of at most this many cells are the compute path's (0: none)
    uint32_t closedBackFaces; // closed clusters cast only light-back-facing triangles
    uint32_t sliceBegin;      // the first sample of each cell's list the draw tests (> 0: a later slice of the crowded cells)
    uint64_t wideList;        // != 0: afsm_wide.comp tested the casters the compute path left but those of the clusters it marked
};
static_assert(sizeof(AfsmCastersPush) == 96);

struct AfsmSoftPush {
    glm::mat4 viewProj;
    uint64_t masks, table;
    uint32_t lightIndex;
    uint32_t gridSize;
    float originOffset;
    uint32_t samples;
    uint32_t tableSize;
    float computeCells;
    uint32_t closedBackFaces;
    uint32_t sliceBegin; // as AfsmCastersPush
};
static_assert(sizeof(AfsmSoftPush) == 112);

struct AfsmBinPush {
    glm::mat4 viewProj;
    uint64_t modelTable;
    uint64_t clusterMask;
    uint32_t nodeCount;
    uint32_t lightIndex;
    uint32_t gridSize;
    float originOffset;
    float computeCells;
    uint32_t rangeBegin, rangeEnd; // paged geometry: the clusters this dispatch bins; in core: its leaves' nearest depths (float bits)
    uint32_t closedBackFaces;      // closed clusters cast only light-back-facing triangles
    uint64_t nodeTable;   // paged geometry: GpuGeometry::nodeTable's device address
    uint64_t nodeRecords; // paged geometry: the pool's (the node records)
};
static_assert(sizeof(AfsmBinPush) == 128);

// afsm_bin.comp's buffers and table (binding kAfsmBinParams).
struct AfsmParams {
    uint64_t masks, table;
    uint32_t samples, tableSize;
    uint64_t wideList;     // hard shadows: the casters left to afsm_wide.comp (afsm_wide.glsli: AfsmWideList); 0: none
    uint32_t wideCasters;  // byte offset of its casters
    uint32_t wideCapacity; // casters it holds
};
static_assert(sizeof(AfsmParams) == 40);

// The head of afsm_wide.comp's list (afsm_wide.glsli: AfsmWideList).
struct AfsmWideHeader {
    uint32_t count;       // casters appended (those past the capacity are not stored)
    uint32_t dispatch[3]; // the tests' indirect dispatch
    uint32_t marked;      // 1: some cluster is marked (its casters left to the raster path)
    uint32_t alone;       // casters the first pass handed to the second (one caster per subgroup)
    uint32_t shadowedPixels; // the pixels shadowed so far (afsm_wide.comp: PENUMBRA_AFSM_WIDE_COUNT_SHADOWED)
    uint32_t pad0;
    uint32_t aloneDispatch[3]; // the second pass's indirect dispatch
    uint32_t pad1;
};
static_assert(sizeof(AfsmWideHeader) == 48);

// A caster of afsm_wide.comp's list (afsm_wide.glsli): its world-space vertices, v0.w its cluster's bits.
struct AfsmWideCaster {
    float v0Cluster[4], v1[4], v2[4];
};
static_assert(sizeof(AfsmWideCaster) == 48);

// afsm_wide.comp's push constants.
struct AfsmWidePush {
    glm::mat4 viewProj;
    uint64_t list;
    uint32_t gridSize;
    uint32_t lightIndex;
    uint32_t capacity;
    uint32_t casters;    // byte offset of the casters in the list
    uint32_t iterations; // most loop iterations a subgroup spends on its caster (PENUMBRA_AFSM_WIDE_ITERATIONS)
    uint32_t pad;
};
static_assert(sizeof(AfsmWidePush) == 96);

struct AfsmTablePush {
    uint64_t table;
    uint32_t phase;
    uint32_t shape;
    uint32_t count;
    uint32_t tableSize;
};
static_assert(sizeof(AfsmTablePush) == 24);

struct AfsmTargets {
    PixelTargets pixels;
    const vk::Buffer* cellFirst = nullptr; // per cell: its samples, then (afsm_scan) its first slot; one more value: the total
    const vk::Buffer* cellCount = nullptr;
    const vk::Buffer* blockSums = nullptr;
    const vk::Buffer* slots = nullptr; // per slot (a pixel's worth): AfsmRaySlot or AfsmSlot (48 bytes), addressable
    const vk::Buffer* shadowed = nullptr;
    const vk::Buffer* far = nullptr;
    const vk::Buffer* cellDepth = nullptr; // per cell, then per block of 8x8 cells (afsmBlockCount): the farthest sample depth
    const vk::Buffer* slotShadowed = nullptr;
    const vk::Buffer* cellAlive = nullptr;
    const vk::Image* depth = nullptr; // D32, grid x grid: each cell's farthest sample depth, for the casters' depth test
    uint32_t width = 0, height = 0, gridSize = 0;
    VkBufferView slotTexels = VK_NULL_HANDLE; // RGBA32UI over slots: the casters' and the binning's reads (afsm_casters.glsli)
    VkBufferView cellFirstTexels = VK_NULL_HANDLE, cellCountTexels = VK_NULL_HANDLE, cellDepthTexels = VK_NULL_HANDLE; // R32UI, the same
};

// The most samples of one cell a fragment of the raster path tests (one
// slice of the cell's list; afsm.glsli, afsmSliceSamples: lavapipe silently
// ends a shader invocation's loops after 65535 iterations in all). A cell
// with more (crowded) is tested in slices: the layer's casters are drawn
// again over the crowded cells once per further slice. samples 0: hard
// shadows; else the light samples of soft shadows.
uint32_t afsmSliceSamples(uint32_t samples);

// The blocks of 8x8 cells of a grid of gridSize^2 cells: the cells' depth
// buffer holds each block's farthest sample depth after the cells' own
// (afsm_casters.glsli: afsmBlocksBehind).
constexpr uint32_t afsmBlockCount(uint32_t gridSize)
{
    return ((gridSize + 7) / 8) * ((gridSize + 7) / 8);
}

// The most loop iterations a subgroup of afsm_bin.comp can take (hard or
// soft) with leaves of at most leafTriangles triangles in leafBytes strip
// bytes: lavapipe silently ends a subgroup's loops after 65535 iterations in
// all, each loop counted as long as its longest lane (afsm.glsli). An
// invocation walks up to 4 leaves (PENUMBRA_AFSM_BIN_GROUP nodes of
// 4 children each per workgroup) one triangle a step, reading its strip
// bytes in an inner loop, and bins each triangle with at most
// PENUMBRA_AFSM_COMPUTE_BUDGET counted work
// (a cell, or a sample times its loop over the soft masks' quads) plus the
// loops the count leaves out (the cell rows and columns, each cell's edge
// tests, the rectangle's construction).
uint64_t afsmBinIterations(uint32_t leafTriangles, uint32_t leafBytes);

// Cells per side of the grid for a width x height view: hard shadows three
// cells per four pixels of the longer side, soft shadows five per four,
// rounded up to a multiple of 16 (the paper fits about one sample per texel;
// on lavapipe fuller cells measured faster for hard shadows, finer ones for
// soft shadows, whose per-sample test costs more).
uint32_t afsmGridSize(uint32_t width, uint32_t height, bool soft);

// The soft-shadow lookup table for n light samples: angles x distances
// entries (powers of two, at most PENUMBRA_AFSM_TABLE_WORDS words in all) of
// 4 ceil(n / 128) words (whole 128-bit quads), and the largest distance of a misclassified light
// sample from the plane's line, in the light's 2-D units (rectangle: half
// its sides; disk, sphere: its radius): half a step of the distance plus
// half a step of the angle at the farthest sample.
struct AfsmTableSize {
    uint32_t angles = 0, distances = 0, words = 0;
    uint64_t bytes() const { return uint64_t(angles) * distances * words * 4; }
    uint32_t packed() const { return angles | distances << 16; }
    double lineError(bool rectangle) const;
};
AfsmTableSize afsmTableSize(uint32_t samples);

// Bytes of afsm's largest buffer for this image (the slots of the sample
// list; soft shadows with n samples: or the per-pixel masks), for the
// settings' check.
uint64_t afsmLargestBuffer(uint32_t width, uint32_t height, uint32_t samples, bool soft);

// One layer of an area light's grid (soft shadows): the grid's projection
// from the light's centre, and the frustum whose casters can shadow its
// samples (the same one pulled back until it holds the whole light).
struct AfsmLayer {
    glm::mat4 grid;
    glm::mat4 cull;
    uint32_t index = 0; // the face for cube layers
};
// The area light's layers: one perspective grid along its axis over the
// model, or, when that would be wider than PENUMBRA_AREA_MAX_HALF_FOV, the six
// faces of a cube around its centre (a one-sided light's faces wholly behind
// it left out). cube: whether the layers are cube faces.
// Fitted to the view (viewClip valid: the bounds of the points the camera
// sees in the clip space of the model-fitted grid's projection, the light's
// map 0 of packLight, view_fit.comp.glsl): one grid around those points
// alone (fitAreaMapToView, no widening: the grid holds the samples, the
// casters are found through the cull frustum; a margin of
// PENUMBRA_VIEW_FIT_MARGIN_TEXELS cells of a gridSize grid), as sm and srt
// fit their area maps, also where the model needed the cube; the model's
// layers when the fit would not narrow the grid. A close-up then spreads its
// samples over the grid instead of crowding a few cells of a grid over the
// whole model (issue 17: cells over afsmSliceSamples are tested in slices).
std::vector<AfsmLayer> afsmAreaLayers(const Light& light, const Bounds& bounds, bool& cube, const ViewClip* viewClip = nullptr,
                                      uint32_t gridSize = 0);

// Whether what the camera of cameraViewProj sees may lie inside a closed mesh
// (clusters flagged kClusterClosed, wound counter-clockwise outside): a point
// it sees lies in the same region as the camera (nothing between them) unless
// the near plane cut a surface away, so rays go from the eye and from 3 x 3
// points of the near plane along one direction; a point lies inside closed
// meshes when the closed triangles it crosses to infinity are more often left
// (the ray along the winding normal) than entered. Host-side, in double
// precision, over the clusters whose boxes the rays cross (the culling BVH).
bool afsmSeesInsideClosed(const CompressedModel& model, const CullModel& cull, glm::vec3 eye, const glm::mat4& cameraViewProj);

class AfsmPass {
  public:
    // The casters' pipelines need geometry shaders and fragment stores
    // (vk::Device::aliasFree); without them only the error is left.
    void create(vk::Device& device);
    void destroy(vk::Device& device);
    void bind(vk::Device& device, const AfsmTargets& targets);
    // The model's texel views (GpuGeometry::texels) for the compute path's decoding (afsm_bin.comp's
    // kTexelAccess), after each upload of a model (the uncompressed reference has none: no compute path).
    void bindModel(vk::Device& device, const GpuGeometry& geometry);
    // Soft shadows: the table for this light shape (rectangle, or disk for
    // disks and spheres) and sample count, built into cmd when it is new, and
    // the masks and per-slot data for the bound image; then the soft passes
    // use them.
    void prepareSoft(vk::Device& device, VkCommandBuffer cmd, uint32_t samples, bool rectangle);
    // The model's closed clusters (kClusterClosed) for the casters, when the
    // model changed (none for the uncompressed reference); returns how many.
    // Also measures its largest leaf for computePathFits.
    uint64_t prepareModel(vk::Device& device, const CompressedModel* model);
    // Whether the compute path (afsm_bin.comp) stays under lavapipe's loop
    // limit with the prepared model's largest leaf (afsmBinIterations); when
    // not, the raster path takes every caster.
    bool computePathFits() const;
    // Whether closed clusters may cast only their light-back-facing triangles
    // in a frame seen through cameraViewProj: not when what the camera sees
    // may lie inside a closed mesh (afsmSeesInsideClosed); cached per camera.
    bool closedBackFaces(const CompressedModel& model, const CullModel& cull, glm::vec3 eye, const glm::mat4& cameraViewProj);
    // The device address of the closed clusters' bits (prepareModel), for
    // the camera pass of a frame whose closed clusters cast only back faces
    // (GBufferPush::closedAddress).
    VkDeviceAddress closedBitsAddress(const vk::Device& device) const { return vk::bufferAddress(device, closedBits); }
    // Clears the samples' shadow flags (before a light's layers).
    void clear(VkCommandBuffer cmd) const;
    // Counts, offsets and lists the samples of layer `layer` of the light in the grid of viewProj. parallel
    // (hard shadows of a directional light): the slots hold the rays' sheared origins (afsm.glsli:
    // AfsmParallel), and the layer's casters must be recorded with CasterLayer::parallel.
    void recordSamples(VkCommandBuffer cmd, uint32_t lightIndex, uint32_t layer, const glm::mat4& viewProj, bool cube, float originOffset,
                       bool soft, bool parallel = false) const;
    // The casters of one layer: view `view` of `culling`, over the grid of
    // viewProj. The small ones are binned in compute (afsm_bin.comp) when the
    // model is compressed (modelTable: the tracer's model table; maskSlot:
    // the layer's cluster mask among PENUMBRA_MAX_LIGHTS x 6), the others drawn.
    struct CasterLayer {
        uint32_t view = 0, maskSlot = 0;
        glm::mat4 viewProj{1.0f};
        uint32_t lightIndex = 0;
        float originOffset = 0;
        bool soft = false;
        bool closedBackFaces = false; // closed clusters cast only light-back-facing triangles
        uint32_t cellMost = 0;        // the layer's most samples in one cell (cellMost; 0: none crowded, mayCrowd false)
        bool parallel = false;        // hard shadows of a directional light: sheared slots (recordSamples' parallel)
        // Two passes (in core, with the compute path and the row pass; see twoPassSplit): only the leaves whose
        // box's nearest depth lies in [nearFrom, nearTo); trimRows: each row narrowed to the cells still holding a
        // sample beyond the caster (after recordRefresh); countShadowed: shadowedPixels() counts the pixels
        // shadowed once the layer's casters ran (needs afterRows).
        float nearFrom = -3.0e38f, nearTo = 3.0e38f;
        bool trimRows = false;
        bool countShadowed = false;
    };
    // Paged geometry (geometry_pages.h): the compute path bins the view's
    // clusters in ranges whose pages fit the pool together (ascending, as
    // GeometryPages::cutIntoRanges cuts the view's sorted list), one dispatch
    // per range after makeResident(range) made it resident (it may submit
    // what is recorded and begin recording again); the raster path draws in
    // ranges through culling (Culling::cutRanges, ensureRange). Shadow flags
    // and masks are ORed, so the result is the unlimited one.
    struct PagedCasters {
        std::vector<std::vector<uint32_t>> ranges;
        std::function<void(const std::vector<uint32_t>&)> makeResident;
    };
    // afterCompute: runs between the two paths (the frame's timestamp).
    // paged: required with paged geometry, ignored otherwise.
    // afterRows: runs after afsm_wide.comp (hard shadows, with the compute
    // path): marks its timestamp, submits what is recorded, waits for it and
    // begins recording again on cmd, so that the raster path is drawn only
    // when afsm_wide.comp left casters to it (AfsmWideHeader::marked). Not
    // given: afsm_wide.comp is not used (the raster path takes those casters).
    void recordCasters(VkCommandBuffer cmd, vk::Device& device, Culling& culling, const GpuGeometry& geometry, VkDeviceAddress modelTable,
                       const CasterLayer& layer, const std::function<void()>& afterCompute, const PagedCasters* paged = nullptr,
                       const std::function<void()>& afterRows = {});
    // Whether recordCasters would take the layer's hard casters in compute,
    // the row pass included (so that two passes split them by depth): in
    // core, compressed, with afterRows given.
    bool rowPassUsed(const Culling& culling, const GpuGeometry& geometry, VkDeviceAddress modelTable) const;
    // The two-pass split of a directional light's hard casters: the nearest
    // depth dividing the first pass's leaves from the second's
    // (PENUMBRA_AFSM_NEAR_DEPTH), and the share of the bound image's pixels
    // the first must shadow for the second to go after a refresh
    // (PENUMBRA_AFSM_REFRESH_SHARE); 0 when off (PENUMBRA_AFSM_TWO_PASS=0).
    float twoPassSplit() const { return twoPass ? nearDepth : 0.0f; }
    bool refreshPays(uint32_t shadowed) const { return double(shadowed) >= refreshShare * double(targets.width) * double(targets.height); }
    // Whether a first pass may pay: the view's clusters whose box's nearest
    // corner lies before the split cover at least that share of the grid
    // (their boxes' rectangles, clipped to it, summed; from the cluster
    // bounds, on the host). Where none lies that near (the city under its
    // sun), a first pass would cost a scan of the nodes and a round trip for
    // nothing. A first pass that then shadows too little (the scan, the
    // plant: a ground plane's near corner, nothing above the samples) leaves
    // the second untrimmed; it cost them 2-4% of afsm_bin at 1024^2.
    bool nearCoverPays(const Culling& culling, uint32_t view, const glm::mat4& viewProj) const;
    // The pixels shadowed after the last recordCasters with countShadowed (read back by afterRows).
    uint32_t shadowedPixels() const { return lastShadowed; }
    // Between the two passes: the cells' and blocks' farthest depths counted
    // again over the samples not yet shadowed (afsm_samples.comp:
    // PENUMBRA_AFSM_REFRESH), so that the second pass's leaves, casters and
    // rows skip what the first already shadowed. Hard shadows only.
    void recordRefresh(VkCommandBuffer cmd, uint32_t lightIndex, uint32_t layer, const glm::mat4& viewProj, float originOffset);
    // Whether a cell of the bound image's grid could hold more than
    // afsmSliceSamples (soft: of the prepared sample count): then the
    // frame reads the layer's cellMost back before its casters.
    bool mayCrowd(bool soft) const;
    // After recordSamples: copies the layer's most samples in one cell
    // where cellMost() reads it once the commands have run.
    void recordCellMostReadback(VkCommandBuffer cmd) const;
    uint32_t cellMost() const;
    // Draws of the casters over crowded cells since the last call (one per slice past the first).
    uint32_t takeSliceDraws();
    // Since the last call: the casters afsm_wide.comp listed, and the layers
    // whose raster path still drew (some cluster marked), when recordCasters
    // was given `submit`; the layers cast in two passes (countShadowed), and
    // those refreshed between them (recordRefresh).
    void takeWideStats(uint32_t& casters, uint32_t& rasterLayers, uint32_t& twoPass, uint32_t& refreshed);
    // Whether the last recordCasters binned casters in compute.
    bool computePathUsed() const { return computeUsed; }
    // The grid of a layer: afsmGridSize for the bound image (the targets hold the larger, soft one).
    uint32_t layerGrid(bool soft) const { return std::min(afsmGridSize(targets.width, targets.height, soft), targets.gridSize); }
    // The light's visibility (and cleared marks, counted pixels; soft: cleared masks).
    void recordResolve(VkCommandBuffer cmd, uint32_t lightIndex, float originOffset, bool soft) const;

  private:
    bool computePathOn(const Culling& culling, const GpuGeometry& geometry, VkDeviceAddress modelTable) const;
    void dispatchPixels(VkCommandBuffer cmd, const AfsmSamplesPush& push, bool soft, bool parallel = false) const;
    void dispatchBlocks(VkCommandBuffer cmd, const AfsmSamplesPush& push, bool soft) const;
    AfsmSamplesPush samplesPush(uint32_t lightIndex, uint32_t mode, uint32_t layer, const glm::mat4& viewProj, bool cube, float originOffset,
                                bool soft) const;
    vk::ComputeKernel samples, samplesSoft, scan, table, bin, binSoft, wide;
    void writeParams() const;
    VkDescriptorSetLayout castersSetLayout = VK_NULL_HANDLE;
    VkDescriptorPool castersPool = VK_NULL_HANDLE;
    VkDescriptorSet castersSet = VK_NULL_HANDLE;
    vk::RasterPipelines casters, softCasters;
    AfsmTargets targets;
    uint64_t slotsAddress = 0;
    // Soft shadows, made on the first soft frame: a table per shape (0:
    // rectangle, 1: disk) with the sample count it holds, its samples' 2-D
    // positions, and per pixel of the bound image the masks.
    vk::Buffer tables[2], tableSamples;
    uint32_t tableCounts[2] = {};
    vk::Buffer masks;
    uint32_t maskWords = 0, maskPixels = 0;
    uint64_t tableAddress = 0, masksAddress = 0;
    uint32_t softSamples = 0;
    AfsmTableSize softTable;
    vk::Buffer params;       // AfsmParams (host-visible)
    vk::Buffer cellMostReadback; // AfsmFar::cellMost of the last layer read back (host-visible)
    uint32_t sliceDraws = 0;
    vk::Buffer closedBits;   // bit per cluster: kClusterClosed (host-visible)
    const void* closedModel = nullptr; // the model closedBits describe (its cluster array)
    uint64_t closedCount = 0;
    uint32_t maxLeafTriangles = 0, maxLeafBytes = 0; // the prepared model's largest leaf
    bool computeUsed = false;
    glm::mat4 insideCamera{0.0f};       // the last camera (view-projection, eye) closedBackFaces answered for, and its answer
    glm::vec3 insideEye{0.0f};
    const void* insideModel = nullptr;
    bool insideAnswer = false;
    vk::Buffer clusterMasks; // per light layer: bit per cluster in its view (host-visible)
    // afsm_wide.comp's list (afsm_wide.glsli: AfsmWideList): head, overflow bits for wideWords * 32 clusters,
    // then PENUMBRA_AFSM_WIDE_CAPACITY casters; wideOn: used (PENUMBRA_AFSM_WIDE=0 turns it off).
    vk::Buffer wideList;
    vk::Buffer wideReadback; // host-visible: the layer's AfsmWideHeader count, marked and shadowedPixels, then its overflow bits
    uint32_t lastShadowed = 0;
    bool twoPass = true;        // PENUMBRA_AFSM_TWO_PASS
    float nearDepth = 0.2f;     // PENUMBRA_AFSM_NEAR_DEPTH
    double refreshShare = 0.25; // PENUMBRA_AFSM_REFRESH_SHARE
    std::vector<uint32_t> wideMarked; // the layer's marked clusters, ascending (the raster path draws them)
    uint32_t wideWords = 0;
    uint64_t wideAddress = 0;
    GpuGeometry::TexelViews modelTexels{}; // bindModel's
    bool modelTexelsComplete = false, modelVertexTexelsSplit = false;
    bool targetsBound = false;
    void writeBinSets(vk::Device& device) const;
    std::vector<vk::Binding> castersCommonBindings() const;
    uint32_t wideCasters = 0, wideRasterLayers = 0, twoPassLayers = 0, refreshedLayers = 0; // since the last takeWideStats
    bool wideOn = true;
    // PENUMBRA_AFSM_WIDE_CAPACITY and _ITERATIONS, or (tests: the raster path's fallback) the environment's.
    uint32_t wideCapacityLimit = PENUMBRA_AFSM_WIDE_CAPACITY, wideIterations = PENUMBRA_AFSM_WIDE_ITERATIONS;
    uint32_t wideCapacity = 0; // the list's: the model's triangles, at most wideCapacityLimit
    uint32_t wideCastersOffset() const { return (sizeof(AfsmWideHeader) + 4 * wideWords + 15) & ~15u; }
    uint32_t clusterMaskWords = 0;
};

} // namespace penumbra::passes
