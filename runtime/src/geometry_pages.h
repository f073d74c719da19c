// Out-of-core rendering under a geometry budget (RendererOptions::
// geometryBudgetBytes, issue 19). The nodes above the clusters (the BVH's
// top), the cluster table and one word per node (the node table) stay
// resident; everything of a cluster (quantized vertices, 8-bit strips, its
// own BVH nodes with their leaves' smallest altitudes and, on CPU devices, the
// raster passes' triangle lists) lives in pages of pageBytes: consecutive
// clusters packed together (vertices first, then strips, then node records,
// then triangle lists), so a page is the unit of upload and eviction. The
// device holds a pool of budget / pageBytes page slots (GpuGeometry::pool),
// followed by the top nodes' records. Uploading a page rewrites the device
// copies of its clusters' records (firstVertex, firstIndex into the pool),
// draw commands and node-table words (where each node's record now is);
// evicting it sets kNotResident in their firstVertex, empties their draws and
// sets their nodes' words to cluster | kNodeAbsent.
//
// Who asks for pages (renderer.cpp): the camera's culled view before the
// G-buffer; before each light's passes, the clusters of its culled views and
// of its thin-triangle views (clusterMayReachView); afsm's binned casters and
// rh's caster batches, per range of their views' clusters; the tracer, which parks
// rays that reach a cluster that is not resident (trace.comp.glsl) and marks
// every cluster it visits, after which the frame script uploads what they
// need and traces them again (FrameScript::traceParked), until none is left.
// Every change happens with the device idle (a submission and wait before it).
#pragma once

#include <string>
#include <vector>

#include <glm/mat4x4.hpp>

#include "model_geometry.h"

namespace penumbra {

struct GeometryPageStats {
    uint64_t residentPeakBytes = 0; // most page slots in use at once this frame, in bytes
    uint64_t pagesUploaded = 0;
    uint64_t bytesStreamed = 0;     // page contents uploaded (bytes)
    uint32_t parkingRounds = 0;     // re-trace dispatches of parked rays
    uint64_t parkedRays = 0;        // rays parked (summed over rounds)
};

class GeometryPages {
  public:
    // Lays the model's clusters out in pages and sizes the pool for budgetBytes
    // (pageBytes: a multiple of 48; both checked with a one-line error).
    // Afterwards poolBytes() is what uploadCompressed allocates.
    // altitudes: whether node records carry their leaves' smallest altitudes (as
    // GpuGeometry::leafAltitudes would without a budget; zeros otherwise).
    void build(const CompressedModel& model, RasterIndices raster, uint64_t pageBytes, uint64_t budgetBytes, bool altitudes);
    bool active() const { return slotCount != 0; }
    // The pool: the page slots, then the top nodes' records (padded to a multiple of 48).
    uint64_t poolBytes() const { return slotBytes() + ((uint64_t(topNodeCount) * kNodeRecordBytes + 47) / 48 * 48); }
    uint64_t slotBytes() const { return uint64_t(slotCount) * pageBytes; }
    // What uploadCompressed writes once: the top nodes' records and the node table with no cluster resident.
    PagedBvh pagedBvh(const CompressedModel& model) const;
    uint64_t geometryBytes() const { return totalBytes; } // every page's contents
    uint64_t budgetBytes() const { return budget; }
    uint32_t clusterCount() const { return uint32_t(clusterPage.size()); }
    // After a new GpuGeometry: nothing resident.
    void resetResidency();
    void destroy(vk::Device& device);

    // Makes every listed cluster resident, evicting the least recently used
    // pages outside the list; the device must be idle. `what` names the
    // working set in the error when its pages exceed the pool. Returns whether
    // anything changed.
    bool ensure(vk::Device& device, GpuGeometry& geometry, const CompressedModel& model, const std::vector<uint32_t>& clusters,
                const std::string& what);
    // Whether the listed clusters' pages fit the pool together.
    bool fits(const std::vector<uint32_t>& clusters) const;
    bool allResident(const std::vector<uint32_t>& clusters) const;
    bool resident(uint32_t cluster) const { return pageSlot[clusterPage[cluster]] != kNone; }

    // The tracer's parking buffer (made for `pixels` ray entries): header
    // {parked count, 3 pad}, then one bit per cluster (visited), then the
    // parked entries; and the host-visible list of rays to trace again.
    void ensureParking(vk::Device& device, uint64_t pixels);
    VkDeviceAddress parkingAddress(const vk::Device& device) const;
    uint32_t clusterWords() const { return uint32_t((clusterPage.size() + 31) / 32); }
    void clearParking(); // device idle
    uint32_t parkedCount() const;
    const uint32_t* parkedEntries() const;
    std::vector<uint32_t> visitedClusters() const;
    vk::Buffer retraceList; // RayList layout (header + entries), copied into the frame's ray list
    // The thin-triangle pass's cluster masks, one per (range, view) of a step (host-visible, addressable).
    vk::Buffer thinMasks;
    void ensureThinMasks(vk::Device& device, uint64_t bytes);
    // Consecutive ranges of `clusters` (in order) whose pages fit the pool together.
    std::vector<std::vector<uint32_t>> cutIntoRanges(const std::vector<uint32_t>& clusters) const;

    GeometryPageStats frame; // this frame's counters (reset by beginFrame)
    void beginFrame();

    uint64_t pageBytes = 0;

  private:
    static constexpr uint32_t kNone = ~0u;
    struct ClusterPlace {
        uint32_t vertexByte = 0, stripByte = 0, rasterByte = 0, rasterBytes = 0, nodeByte = 0; // within the page
    };
    // Node record (kNodeRecordBytes) of `node` at `out`: the file's node, then its leaves' altitudes.
    void writeNodeRecord(const CompressedModel& model, uint32_t node, uint8_t* out) const;
    uint64_t budget = 0, totalBytes = 0;
    RasterIndices raster = RasterIndices::Strips;
    uint32_t slotCount = 0;
    std::vector<uint32_t> clusterPage;
    std::vector<ClusterPlace> place;
    bool altitudes = false;
    uint32_t topNodeCount = 0;
    std::vector<uint64_t> clusterNodesFirst; // cluster c's nodes: clusterNodes[clusterNodesFirst[c] .. [c + 1]), ascending
    std::vector<uint32_t> clusterNodes;
    std::vector<uint32_t> pageFirstCluster; // page p: clusters [pageFirstCluster[p], pageFirstCluster[p + 1])
    std::vector<uint32_t> pageUsed;         // bytes of contents
    std::vector<uint32_t> pageSlot, slotPage;
    std::vector<uint64_t> slotUse; // LRU stamp
    uint64_t useClock = 0;
    uint32_t residentPages = 0;
    vk::Buffer staging, parking;
    uint64_t parkingCapacity = 0;
};

// Whether a cluster box can reach the map of viewProj in the thin-triangle
// pass (a conservative plane test of its corners: every point of the box
// behind the eye, in front of the near plane, or more than marginTexels of a
// mapSize map beyond a side means no triangle of it writes a texel).
bool clusterMayReachView(const glm::mat4& viewProj, const glm::vec3& lo, const glm::vec3& hi, uint32_t mapSize, float marginTexels);

} // namespace penumbra
