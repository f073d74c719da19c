// Trace (shaders/trace.comp.glsl): the compute-shader shadow ray tracer over the preprocessed model: stack-based
// traversal of the shared BVH (8-bit parent-relative node boxes) down to
// strip-range leaves, watertight ray/triangle test on the dequantized
// vertices, any-hit with early exit. Reads the model through buffer device
// addresses, so no 128 MiB storage-buffer binding limit applies. Runs on
// lavapipe and, unchanged, on NVIDIA GPUs (no ray-tracing extensions).
#pragma once

#include "config.h"
#include "model_geometry.h"
#include "pipelines.h"

namespace penumbra::passes {

enum TraceBinding : uint32_t {
    kTraceSurface, kTraceAlbedo, kTraceVisibility, kTraceFrame, kTraceRayList, kTraceStats,
    kTraceNodes, kTraceClusters, kTraceVertices, kTraceStrips, kTraceNodeTable, // GpuGeometry::texels
    kTraceHints,
    kTraceBindingCount
};

struct TraceTargets {
    VkImageView surface = VK_NULL_HANDLE;    // rgba32ui G-buffer surface: position and normal facing the camera (surface.glsli; GENERAL)
    VkImageView albedo = VK_NULL_HANDLE;     // the G-buffer's albedo: not read (the G-buffer keeps bindings 0 and 1 in every pass)
    VkImageView visibility = VK_NULL_HANDLE; // r32f: the tracer writes the visibility of every listed pixel (GENERAL)
    VkBuffer frame = VK_NULL_HANDLE;         // gpu::FrameData (lights)
    VkBuffer rayList = VK_NULL_HANDLE;       // PENUMBRA_RAY_LIST_HEADER_UINTS header + pixel indices
    VkBuffer stats = VK_NULL_HANDLE;         // uint64_t[PENUMBRA_STAT_COUNT], accumulated
    VkBuffer hints = VK_NULL_HANDLE;         // hard shadows in rounds: TracePass::hintBytes(pixels), the tracer's own between dispatches
};

struct TracePush {
    VkDeviceAddress modelTable;
    uint32_t lightIndex;
    float originOffset;
    uint32_t samples; // area lights: light samples per pixel; 0: hard shadows
    uint32_t clusterWords;      // paged geometry: words of the parking buffer's visited bits
    VkDeviceAddress parking;    // paged geometry: GeometryPages' parking buffer (0: no budget)
    float boundsMin[4]; // the root node's box
    float boundsMax[4];
    uint32_t sampleBegin = 0, sampleEnd = 0; // area lights: this dispatch's light samples (TracePass::record)
    uint32_t roundBegin = 0; // hard shadows in rounds: this dispatch's first round
    uint32_t pad1 = 0;
};
static_assert(sizeof(TracePush) == 80);

class TracePass {
  public:
    void create(vk::Device& device);
    void destroy(vk::Device& device);
    // Points the tracer at a (new) model; call after every model upload.
    void bindModel(vk::Device& device, const GpuGeometry& geometry);
    // The targets it reads and writes (call when any of them changes).
    void bind(vk::Device& device, const TraceTargets& targets);
    // Records the trace of every ray in the list toward light lightIndex
    // (vkCmdDispatchIndirect on the list header). Shadow-ray origins are moved
    // originOffset along the normal turned toward the light. The caller orders
    // the writes of the ray list and G-buffer before, and the visibility reads after.
    // samples > 0 (area lights): that many light samples per pixel, visibility is
    // the unblocked fraction (soft shadows). lightType (PENUMBRA_LIGHT_*) and
    // samples > 0 pick a pipeline specialized for them.
    // parking != 0 (paged geometry, geometry_pages.h): rays that reach a cluster that is not resident
    // are parked in that buffer (clusterWords: its visited bits), the pipeline specialized for it.
    void record(VkCommandBuffer cmd, uint32_t lightIndex, uint32_t lightType, float originOffset, uint32_t samples = 0,
                VkDeviceAddress parking = 0, uint32_t clusterWords = 0) const;
    // Device address of the model table (bvh_traversal.glsli), 0 before bindModel.
    VkDeviceAddress modelTableAddress() const { return tableAddress; }
    // List entries one invocation traces in rounds on this device, hard shadows (PENUMBRA_TRACE_RAYS_CPU or
    // _GPU), and those one workgroup then takes: the list header's roundsDispatch counts workgroups of
    // entriesPerGroup(device) entries, its dispatch workgroups of PENUMBRA_TRACE_GROUP_SIZE (soft shadows, paged geometry).
    static uint32_t raysPerInvocation(const vk::Device& device);
    static uint32_t entriesPerGroup(const vk::Device& device) { return PENUMBRA_TRACE_GROUP_SIZE * raysPerInvocation(device); }
    // Bytes of TraceTargets::hints for a list of up to `pixels` entries: two counts, then a hint per invocation
    // whose first entry is listed (trace.comp.glsl: traceHardRounds).
    static VkDeviceSize hintBytes(VkDeviceSize pixels) { return 16 + (pixels / PENUMBRA_TRACE_RAYS_CPU + PENUMBRA_TRACE_GROUP_SIZE) * 8; }
    // A ray list's header (PENUMBRA_RAY_LIST_HEADER_UINTS) for count entries, as compaction writes it on the device.
    static void writeListHeader(const vk::Device& device, uint32_t count, uint32_t* header);

  private:
    // Writes the descriptor set once both the targets and the model are known.
    void writeSet(vk::Device& device) const;

    vk::ComputeKernel kernel;
    TraceTargets targets;
    vk::Buffer modelTable;          // device addresses of the model's buffers (see trace.cpp)
    VkDeviceAddress tableAddress = 0;
    GpuGeometry::TexelViews texels;  // the model's texel views, bound in bind()
    bool texelsComplete = false;     // the tracer reads them (else by device address)
    bool vertexTexelsSplit = false;  // GpuGeometry::vertexTexelsSplit
    uint32_t roundsPerInvocation = 1; // raysPerInvocation(device)
    float boundsMin[4] = {}, boundsMax[4] = {};
    VkBuffer rayList = VK_NULL_HANDLE; // its header holds the indirect dispatch
};

} // namespace penumbra::passes
