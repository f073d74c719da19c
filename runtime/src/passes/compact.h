// Compaction (shaders/compact.comp.glsl): the marked pixels into a dense ray
// list (subgroup ballot, one atomic per subgroup), then the tracer's indirect
// dispatch size from its count.
#pragma once

#include "config.h"
#include "pipelines.h"

namespace penumbra::passes {

enum CompactBinding : uint32_t { kCompactMarks, kCompactRayList, kCompactStats, kCompactBindingCount };

struct CompactPush {
    uint32_t pixelCount;
    uint32_t phase; // PENUMBRA_COMPACT_LIST, PENUMBRA_COMPACT_DISPATCH
    uint32_t width; // of the image
    uint32_t height;
    uint32_t roundEntries; // the tracer's list entries per workgroup in rounds (TracePass::entriesPerGroup)
};
static_assert(sizeof(CompactPush) == 20);

class CompactPass {
  public:
    void create(vk::Device& device);
    void destroy(vk::Device& device);
    void bind(vk::Device& device, VkBuffer marks, VkBuffer rayList, VkBuffer stats);
    // Clears the list's header, lists the marked pixels of pixelCount, writes
    // the tracer's dispatch sizes (TracePass::writeListHeader) and adds the list's length to PENUMBRA_STAT_PIP; ends
    // with the barrier to the trace (indirect).
    // The list holds the pixels in 8x8 tiles (coherent rays for the tracer's SIMD registers).
    void record(VkCommandBuffer cmd, uint32_t width, uint32_t height) const;
    // The null twin (shaders/floor.glsli): the marks read, one entry per marked pixel written; after createFloor.
    void recordFloor(VkCommandBuffer cmd, uint32_t width, uint32_t height) const;
    void createFloor(vk::Device& device) { kernel.createFloor(device); }

  private:
    vk::ComputeKernel kernel;
    VkBuffer rayList = VK_NULL_HANDLE;
    uint32_t roundEntries = PENUMBRA_TRACE_GROUP_SIZE; // TracePass::entriesPerGroup
};

} // namespace penumbra::passes
