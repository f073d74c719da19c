// Culling of the raster passes (camera G-buffer, shadow-map layers) with the
// top of the shared BVH (Lauterbach et al. 2009, section 5.1): view-frustum
// culling of nodes and clusters on the CPU, then occlusion culling with
// Vulkan occlusion queries on node boxes, in two phases per view:
//   1. draw the cells (subtrees of <= PENUMBRA_CULL_CELL_CLUSTERS clusters)
//      this view found visible last frame, and the cells at the near plane;
//      then query, against that depth, the boxes of the other frustum-visible
//      subtrees (<= PENUMBRA_CULL_GROUP_CLUSTERS clusters, no history below);
//   2. a compute pass turns the query results into the instance counts of a
//      multi-draw-indirect list, drawn with the same pipeline state; then the
//      phase-1 cells due for a retest (each every PENUMBRA_CULL_RETEST_FRAMES
//      frames, staggered; kept visible in between) are queried against the
//      final depth, which gives next frame's history.
// With RenderSettings::adaptiveOcclusion, a view whose frustum holds fewer than
// PENUMBRA_CULL_MIN_TRIANGLES triangles is planned by its frustum only (its
// queries would cost more than they can save), and a view whose queries cull
// little goes frustum-only for PENUMBRA_CULL_RETRY_FRAMES frames.
// Exactness. A shadow map keeps the minimum depth whatever the order, so its
// phase 2 draws only the clusters whose box passed. The G-buffer keeps the
// last of equally deep fragments (LESS_OR_EQUAL), so without culling a pixel
// shows the last cluster, in ascending order, with a fragment at the minimum
// depth m. Phase 2 of the camera draws, in ascending order, the passed
// clusters and the phase-1 clusters after the first passed one, over phase
// 1's colour and depth: if that last cluster is in phase 1 and before every
// passed cluster, phase 1 already left it on top and nothing later reaches m;
// otherwise phase 2 redraws it, after everything else at depth m. A cluster
// that can reach a pixel at depth <= phase 1's depth there has a box that
// passes its query (boxes are grown by a margin, drawn with the same depth
// test, and a box crossing the near plane is never queried), so nothing
// visible is dropped, with or without history (first frame, jumps).
// Query results for the history are read on the CPU after the frame's fence
// (no extra sync). The ray tracer never sees any of this.
// Receiver masks (directional, point and spot lights): a caster can change
// only the texels its projection covers, and the frame reads such a map only
// at the texel of a camera pixel's point and its 8 neighbours, in the layer
// the point is looked up in (classify.comp.glsl, shadow_common.glsli). So a
// box whose footprint in a layer, grown by 2 texels, holds no visible point
// cannot change a texel that is read: it is culled before the occlusion
// tests, and the image stays the same.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include <glm/mat4x4.hpp>

#include "model_geometry.h"
#include "penumbra/penumbra.h"
#include "resources.h"

namespace penumbra {

// Where the camera's visible points are looked up in one shadow-map layer of
// a directional, point or spot light: the cells of a grid over the layer's
// clip x, y in [-1, 1] (a directional light's model-fitted map) that hold one
// (view_fit.comp.glsl), as a summed-area table.
struct ReceiverMask {
    glm::dmat4 viewProj{1.0}; // the grid's clip space
    uint32_t resolution = 0;  // cells a side
    glm::dvec2 margin{0.0};   // clip units added to a footprint on each side
    std::vector<uint32_t> prefix; // (resolution + 1)^2: set cells below and left of each corner

    // bits: resolution^2 bits, row y, bit x (view_fit.comp.glsl).
    void build(const uint32_t* bits, uint32_t cellsPerSide);
    // False when the box's footprint, grown by margin, holds no set cell.
    bool mayCover(const glm::vec3& lo, const glm::vec3& hi) const;
};

// The model as the culling sees it, built once per model and shared by every
// Culling of a renderer (camera, shadow views): CPU copies of the cluster
// boxes, triangle counts and draw commands, and the BVH top (every node down
// to the Cluster nodes).
struct CullModel {
    struct TopNode {
        glm::vec3 min, max;        // union of the boxes below (cluster quantization boxes)
        uint32_t firstChild = 0;   // index in topNodes; Interior only
        uint32_t childCount = 0;   // 0: a Cluster node
        uint32_t cluster = 0;      // Cluster nodes: cluster index
        uint32_t clusterCount = 0; // clusters in the subtree
    };
    std::vector<TopNode> topNodes;                 // index 0: root
    std::vector<glm::vec3> clusterMin, clusterMax; // quantization boxes
    std::vector<uint32_t> clusterTriangles;
    std::vector<VkDrawIndexedIndirectCommand> commands; // per cluster, as in GpuGeometry::indirect
    std::vector<uint32_t> clusterChunk;                 // chunk of each cluster
    uint64_t totalTriangles = 0;
    float boxMargin = 0; // added to every queried box (model units)

    CullModel(const CompressedModel& model, const GpuGeometry& geometry);
};

// One raster view of a frame.
struct CullView {
    std::string name;         // stats name: "camera", "light0", "light0.face3"
    uint32_t slot = 0;        // key of the view's persistent history (camera 0, light i layer l: 1 + 6 i + l)
    glm::mat4 viewProj{1.0f}; // clip = viewProj * world, Vulkan depth 0..1
    bool camera = false;      // G-buffer target (its surface, and its albedo with `albedo`) and order-preserving second phase
    bool occlusion = false;   // occlusion queries allowed (CullMode::All; shadow maps need a non-negative depth bias)
    std::shared_ptr<const ReceiverMask> receivers; // shadow views: the casters beside them are culled (null: none)
    bool albedo = false;      // camera: the G-buffer's albedo target is drawn too (passes::GBufferPush::albedoAddress)
};

struct Culling {
    // Begins the view's rendering: clear (first phase) or load (second phase)
    // the depth, then binds the view's geometry pipeline and sets all of its
    // state (viewport, depth bias, push constants).
    using BeginRendering = std::function<void(bool clear)>;
    using EndRendering = std::function<void()>;

    // Creates the box pipelines (camera: colour formats of the G-buffer, the
    // surface's then the albedo's, writes masked, one pipeline for the surface
    // alone and one for both; shadow: depth only) and the predicate compute pass.
    void create(vk::Device& device, const std::vector<VkFormat>& cameraColorFormats, VkFormat depthFormat);
    void destroy(vk::Device& device);

    // The model just uploaded; clears every view's history. clearModel: the
    // uncompressed reference (no culling).
    void setModel(std::shared_ptr<const CullModel> model);
    void clearModel();

    // Plans every view of the frame on the CPU (frustum traversal, draw lists,
    // query boxes) and writes them into host-visible buffers; the previous
    // frame must be finished. Then resetQueries outside any rendering.
    void beginFrame(vk::Device& device, CullMode mode, bool adaptive, std::vector<CullView> views);
    void resetQueries(VkCommandBuffer cmd);
    // Paged geometry (geometry_pages.h): rewrites the index count, first index
    // and vertex offset of every planned draw from commands (GpuGeometry::commands
    // after pages moved); the device must be idle.
    void refreshCommands(const std::vector<VkDrawIndexedIndirectCommand>& commands);
    // Records view `view` of beginFrame's list (with CullMode::None or no model: the whole geometry).
    void recordView(VkCommandBuffer cmd, uint32_t view, const GpuGeometry& geometry, const BeginRendering& begin,
                    const EndRendering& end);
    // The same view's draws once more, after recordView, untimed (afsm's
    // slices of crowded cells); only for views without occlusion queries.
    void recordViewAgain(VkCommandBuffer cmd, uint32_t view, const GpuGeometry& geometry, const BeginRendering& begin,
                         const EndRendering& end);
    // After the frame's fence: reads the queries, updates the histories and
    // returns per-view stats (empty without a compressed model).
    std::vector<ViewCullStats> endFrame(vk::Device& device);
    // Sets bit c of bits ((clusters + 31) / 32 words, cleared by the caller)
    // for every cluster whose footprint may cover a cell of the mask (a BVH
    // traversal with mask.mayCover; no frustum test). The thin-triangle pass
    // skips the others: their conservative rectangles reach at most 0.71
    // texel beyond the footprint, and a receiver reads the thin map at its own
    // texel only.
    void markClustersNearReceivers(const ReceiverMask& mask, uint32_t* bits) const;

    // Paged geometry (geometry_pages.h). A list a view draws (its clusters in
    // draw order, kNoQuery for entries that draw nothing) is cut into ranges
    // drawn one after another in the same order, so the image is the same:
    // cutRanges returns the ascending cut points (none: one range), and
    // ensureRange makes range r of the last cut resident before it is drawn;
    // queriesAnswered runs between the phases (after phase 1's rendering
    // ended) and returns finalDrawn once the queries can be read. Each may submit the command
    // buffer, wait and begin it again (the same handle).
    std::function<std::vector<uint32_t>(const std::vector<uint32_t>& clusters)> cutRanges;
    std::function<void(uint32_t view, size_t range)> ensureRange;
    std::function<std::vector<uint32_t>(uint32_t view)> queriesAnswered;
    // After phase 1 ran (device idle): per entry of phase 2's list, its
    // cluster if phase 2 may draw it (its query passed, or a repeat of a
    // phase-1 cluster), else kNoQuery.
    std::vector<uint32_t> finalDrawn(vk::Device& device, uint32_t view) const;
    const std::string& viewName(uint32_t view) const { return plans.at(view).view.name; }

    // The clusters view `view` draws, ascending, for a view planned without
    // occlusion queries (its frustum and receiver mask only); every cluster
    // with CullMode::None. Needs the compressed model.
    std::vector<uint32_t> viewClusters(uint32_t view) const;
    // A view whose clusters a pass draws itself (viewClusters): the view's
    // timestamp before (end = false) or after its draws, so its stats are
    // complete. Every planned view gets both, through recordView or this.
    void markView(VkCommandBuffer cmd, uint32_t view, bool end) const;
    // Before a view's timestamps are written a second time in a frame (a
    // pass that draws or marks the view twice; outside rendering): resets
    // them, so that the second pair stands.
    void resetViewTimestamps(VkCommandBuffer cmd, uint32_t view) const;

    struct Entry {
        uint32_t cluster;
        uint32_t query; // kNoQuery: drawn unconditionally
    };
    struct ViewPlan {
        CullView view;
        std::vector<uint32_t> firstPhase;        // clusters of the history and near-plane cells, ascending
        std::vector<Entry> finalPhase;           // ascending by cluster
        std::vector<uint32_t> groupQueryBegin;   // per group query: first index in groupClusters
        std::vector<uint32_t> groupClusters;     // clusters of each group query, in query order
        std::vector<uint32_t> historyQueryBegin; // per history-cell query: first index in historyClusters
        std::vector<uint32_t> historyClusters;   // clusters of each history cell, in query order
        std::vector<uint32_t> keptVisible;       // drawn in phase 1 and kept visible untested (near plane, or not due)
        uint32_t firstQuery = 0;                 // group queries, then history tests
        uint32_t firstCommand = 0;               // first-phase commands, then final-phase commands
        uint64_t nodesTested = 0;
        uint64_t clustersBesideReceivers = 0; // culled by the receiver mask
        double cpuMs = 0;
    };
    static constexpr uint32_t kNoQuery = ~0u;

    // Model
    std::shared_ptr<const CullModel> model; // null: no culling
    struct History {
        std::vector<uint8_t> visible;   // per cluster: visible last frame
        uint32_t frustumOnlyFrames = 0; // occlusion did not pay in this view: frames left culled by the frustum only
        uint32_t frame = 0;             // frames planned with occlusion (staggers the retests of visible cells)
    };
    std::unordered_map<uint32_t, History> history; // per view slot
    // Frame
    CullMode mode = CullMode::None;
    bool adaptive = true; // RenderSettings::adaptiveOcclusion
    std::vector<ViewPlan> plans;
    std::vector<glm::vec3> queryBoxes; // min, max per query of the frame
    uint32_t queryCount = 0;
    // GPU
    VkPipelineLayout boxLayout = VK_NULL_HANDLE, predicateLayout = VK_NULL_HANDLE;
    VkPipeline cameraBoxPipelines[2] = {}, shadowBoxPipeline = VK_NULL_HANDLE, // camera: [albedo], the G-buffer's surface (and albedo)
               predicatePipeline = VK_NULL_HANDLE;
    VkQueryPool queryPool = VK_NULL_HANDLE;
    uint32_t queryCapacity = 0;
    VkQueryPool timestampPool = VK_NULL_HANDLE; // per view: before and after its passes, each twice (vk::writeTimestamp)
    uint32_t timestampCapacity = 0;
    float timestampPeriodNs = 1.0f;
    vk::Buffer
        drawCommands; // VkDrawIndexedIndirectCommand[]: all views' lists (host-visible; compute writes instanceCount)
    vk::Buffer commandQueries; // uint per command: its query, or kNoQuery
    vk::Buffer boxes;          // vec4 min, vec4 max per query
    vk::Buffer queryResults;   // uint per query, copied by vkCmdCopyQueryPoolResults
    VkDeviceAddress drawCommandsAddress = 0, commandQueriesAddress = 0, boxesAddress = 0, queryResultsAddress = 0;

  private:
    void planView(ViewPlan& plan);
    void recordPhases(VkCommandBuffer cmd, uint32_t view, const GpuGeometry& geometry, const BeginRendering& begin,
                      const EndRendering& end);
    void drawList(VkCommandBuffer cmd, const GpuGeometry& geometry, uint32_t firstCommand,
                  const std::vector<uint32_t>& clusters);
    // drawList of `clusters` in ranges (cutRanges on `drawn`), each in its own rendering: the first
    // begun with begin(clear), the others loading; last() runs inside the last one.
    void drawInRanges(VkCommandBuffer cmd, uint32_t view, const GpuGeometry& geometry, uint32_t firstCommand,
                      const std::vector<uint32_t>& clusters, const std::vector<uint32_t>& drawn, bool clear,
                      const BeginRendering& begin, const EndRendering& end, const std::function<void()>& last);
};

// Draws clusters[0 .. count) (ascending) of the compressed model with its own
// per-cluster draw commands (GpuGeometry::indirect): one multi-draw per run of
// consecutive clusters in one chunk. The caller has begun the rendering and
// bound a pipeline of the model's vertex input.
void drawClusters(VkCommandBuffer cmd, const GpuGeometry& geometry, const CullModel& model, const uint32_t* clusters, size_t count);

} // namespace penumbra
