// Buffers and images: plain structs with create/destroy, one allocation each.
#pragma once

#include <vulkan/vulkan.h>

#include "device.h"

namespace penumbra::vk {

struct Buffer {
    VkBuffer buffer = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    VkDeviceSize size = 0;
    void* mapped = nullptr;   // non-null for host-visible buffers
};

struct Image {
    VkImage image = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    VkImageView view = VK_NULL_HANDLE;       // all layers
    VkImageView layerViews[6] = {};          // one per layer (render targets of layered images)
    VkFormat format = VK_FORMAT_UNDEFINED;
    uint32_t width = 0, height = 0, layers = 1;
};

enum class MemoryUse {
    DeviceLocal,  // GPU only
    Upload,       // host-visible; device-local when the device offers it (lavapipe, ReBAR); see writeMapped
    Readback,     // host-visible, cached where possible
};

// Whether shaders read the buffer through its device address (buffer_reference):
// adds SHADER_DEVICE_ADDRESS and STORAGE_BUFFER usage and allocates the memory
// with VK_MEMORY_ALLOCATE_DEVICE_ADDRESS_BIT.
enum class Addressable { No, Yes };

// Copies bytes into a host-visible buffer's mapping at offset. Upload memory is
// written only, and in one pass: on a discrete GPU it is uncached and
// write-combined, so a host read of it (bits[i] |= ...) waits a round trip over
// the bus. Bit masks are built in host memory and copied here (on an H200, a
// million-triangle model's per-frame cluster masks read-modify-written in place
// took 5-7 ms of the frame's host work).
void writeMapped(Buffer& buffer, const void* data, size_t bytes, size_t offset = 0);
Buffer createBuffer(Device& device, VkDeviceSize size, VkBufferUsageFlags usage, MemoryUse use, Addressable addressable = Addressable::No);
void destroyBuffer(Device& device, Buffer& buffer);

// A uniform texel view of `format` (texelBytes a texel) over the start of
// buffer: as many whole texels as it holds, at most maxTexelBufferElements.
VkBufferView createTexelView(Device& device, const Buffer& buffer, VkFormat format, VkDeviceSize texelBytes);

// Creates a device-local buffer holding data: mapped directly when the
// device-local heap is host-visible, else through a staging copy. capacity
// (>= size; 0: size) sizes the buffer, the bytes after data zero.
Buffer createBufferWithData(Device& device, const void* data, VkDeviceSize size, VkBufferUsageFlags usage,
                            Addressable addressable = Addressable::No, VkDeviceSize capacity = 0);

// Device address of a buffer created with Addressable::Yes.
VkDeviceAddress bufferAddress(const Device& device, const Buffer& buffer);

// arrayView: the view is a 2D array (for sampler2DArray) with one 2D view per layer for rendering.
Image createImage(Device& device, uint32_t width, uint32_t height, uint32_t layers, VkFormat format, VkImageUsageFlags usage,
                  bool arrayView = false);
void destroyImage(Device& device, Image& image);

// Shader module of an embedded SPIR-V shader by registry name ("shade.comp").
VkShaderModule createShaderModule(Device& device, const char* name);

// One-time command buffer: begin, record in fn, submit and wait (bounded: the
// device's timeout). what names the work in errors ("device did not finish <what> ...").
template <typename Fn>
void immediateSubmit(Device& device, Fn&& fn, const char* what = "an upload");

VkCommandBuffer beginOneTime(Device& device);
// Submits, waits and frees cmd (also when it fails, unless the device hung).
void endOneTime(Device& device, VkCommandBuffer cmd, const char* what = "an upload");

template <typename Fn>
void immediateSubmit(Device& device, Fn&& fn, const char* what)
{
    VkCommandBuffer cmd = beginOneTime(device);
    try {
        fn(cmd);
    } catch (...) {
        vkFreeCommandBuffers(device.device, device.commandPool, 1, &cmd);
        throw;
    }
    endOneTime(device, cmd, what);
}

// Global memory barrier (sync2).
void memoryBarrier(VkCommandBuffer cmd, VkPipelineStageFlags2 srcStage, VkAccessFlags2 srcAccess, VkPipelineStageFlags2 dstStage,
                   VkAccessFlags2 dstAccess);

// Full image layout transition with a sync2 barrier.
void transition(VkCommandBuffer cmd, const Image& image, VkImageLayout from, VkImageLayout to,
                VkPipelineStageFlags2 srcStage, VkAccessFlags2 srcAccess, VkPipelineStageFlags2 dstStage,
                VkAccessFlags2 dstAccess);

} // namespace penumbra::vk
