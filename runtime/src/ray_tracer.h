// Compute-shader shadow ray tracer over the preprocessed model: stack-based
// traversal of the shared BVH (8-bit parent-relative node boxes) down to
// strip-range leaves, watertight ray/triangle test on the dequantized
// vertices, any-hit with early exit. Reads the model through buffer device
// addresses, so no 128 MiB storage-buffer binding limit applies. Runs on
// lavapipe and, unchanged, on NVIDIA GPUs (no ray-tracing extensions).
#pragma once

#include "device.h"
#include "model_geometry.h"

namespace penumbra {

struct RayTracer {
    VkDescriptorSetLayout setLayout = VK_NULL_HANDLE;
    VkPipelineLayout layout = VK_NULL_HANDLE;
    VkPipeline pipeline = VK_NULL_HANDLE;
    VkDescriptorPool pool = VK_NULL_HANDLE;
    VkDescriptorSet set = VK_NULL_HANDLE;
    vk::Buffer modelTable;   // device addresses of the model's buffers (see ray_tracer.cpp)
    VkDeviceAddress modelTableAddress = 0; // pushed to trace.comp; 0 until bindRayTracerModel
    VkBuffer rayList = VK_NULL_HANDLE;     // from bindRayTracerTargets: its header holds the indirect dispatch
};

void createRayTracer(vk::Device& device, RayTracer& tracer);
void destroyRayTracer(vk::Device& device, RayTracer& tracer);

// Points the tracer at a (new) model; call after every model upload.
void bindRayTracerModel(vk::Device& device, RayTracer& tracer, const GpuGeometry& geometry);

struct TraceBindings {
    VkImageView position = VK_NULL_HANDLE;   // rgba32f G-buffer world position (GENERAL)
    VkImageView normal = VK_NULL_HANDLE;     // rgba32f G-buffer normal facing the camera (GENERAL)
    VkImageView visibility = VK_NULL_HANDLE; // r32f: the tracer writes the visibility of every listed pixel (GENERAL)
    VkBuffer frameUniforms = VK_NULL_HANDLE; // gpu::FrameData (lights)
    VkBuffer rayList = VK_NULL_HANDLE;       // PENUMBRA_RAY_LIST_HEADER_UINTS header + pixel indices
    VkBuffer stats = VK_NULL_HANDLE;         // uint[PENUMBRA_STAT_COUNT], accumulated
};
// Updates the tracer's descriptor set (call when any view or buffer changes).
void bindRayTracerTargets(vk::Device& device, RayTracer& tracer, const TraceBindings& bindings);

// Records the trace of every ray in the list toward light lightIndex
// (vkCmdDispatchIndirect on the list header). Shadow-ray origins are moved
// originOffset along the normal turned toward the light. The caller orders
// the writes of the ray list and G-buffer before, and the visibility reads after.
// samples > 0 (area lights): that many light samples per pixel, visibility is
// the unblocked fraction (soft shadows).
void recordTrace(VkCommandBuffer cmd, RayTracer& tracer, uint32_t lightIndex, float originOffset, uint32_t samples = 0);

} // namespace penumbra
