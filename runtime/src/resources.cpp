#include "resources.h"

#include <algorithm>
#include <cstring>

#include "penumbra/shaders/registry.h"

namespace penumbra::vk {

namespace {

uint32_t findMemoryType(const Device& device, uint32_t typeBits, VkMemoryPropertyFlags required, VkMemoryPropertyFlags preferred)
{
    for (VkMemoryPropertyFlags want : {required | preferred, required})
        for (uint32_t i = 0; i < device.memory.memoryTypeCount; ++i)
            if ((typeBits & (1u << i)) && (device.memory.memoryTypes[i].propertyFlags & want) == want)
                return i;
    fail("vulkan", "no memory type with the required properties");
}

VkDeviceMemory allocate(Device& device, VkMemoryRequirements requirements, VkMemoryPropertyFlags required, VkMemoryPropertyFlags preferred,
                        Addressable addressable = Addressable::No)
{
    VkMemoryAllocateFlagsInfo flags{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_FLAGS_INFO};
    flags.flags = VK_MEMORY_ALLOCATE_DEVICE_ADDRESS_BIT;
    VkMemoryAllocateInfo info{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    if (addressable == Addressable::Yes)
        info.pNext = &flags;
    info.allocationSize = requirements.size;
    info.memoryTypeIndex = findMemoryType(device, requirements.memoryTypeBits, required, preferred);
    return allocateMemory(device, info);
}

bool deviceLocalIsHostVisible(const Device& device)
{
    for (uint32_t i = 0; i < device.memory.memoryTypeCount; ++i) {
        VkMemoryPropertyFlags f = device.memory.memoryTypes[i].propertyFlags;
        VkMemoryPropertyFlags want = VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT | VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT |
                                     VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
        // Large host-visible device-local heaps only (a 256 MiB BAR window is not enough for models).
        if ((f & want) == want && device.memory.memoryHeaps[device.memory.memoryTypes[i].heapIndex].size > (1ull << 30))
            return true;
    }
    return false;
}

} // namespace

Buffer createBuffer(Device& device, VkDeviceSize size, VkBufferUsageFlags usage, MemoryUse use, Addressable addressable)
{
    Buffer buffer;
    buffer.size = size;
    VkBufferCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    info.size = size;
    info.usage = usage;
    if (addressable == Addressable::Yes)
        info.usage |= VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT | VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
    VK_CHECK(vkCreateBuffer(device.device, &info, nullptr, &buffer.buffer));
    VkMemoryRequirements requirements;
    vkGetBufferMemoryRequirements(device.device, buffer.buffer, &requirements);

    VkMemoryPropertyFlags required = 0, preferred = 0;
    switch (use) {
    case MemoryUse::DeviceLocal: preferred = VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT; break;
    case MemoryUse::Upload:
        required = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
        preferred = VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
        break;
    case MemoryUse::Readback:
        required = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
        preferred = VK_MEMORY_PROPERTY_HOST_CACHED_BIT;
        break;
    }
    try {
        buffer.memory = allocate(device, requirements, required, preferred, addressable);
        VK_CHECK(vkBindBufferMemory(device.device, buffer.buffer, buffer.memory, 0));
        if (required & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT)
            VK_CHECK(vkMapMemory(device.device, buffer.memory, 0, VK_WHOLE_SIZE, 0, &buffer.mapped));
    } catch (...) {
        destroyBuffer(device, buffer);
        throw;
    }
    return buffer;
}

VkBufferView createTexelView(Device& device, const Buffer& buffer, VkFormat format, VkDeviceSize texelBytes)
{
    const VkDeviceSize limit = VkDeviceSize(device.properties.limits.maxTexelBufferElements) * texelBytes;
    VkBufferViewCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_VIEW_CREATE_INFO};
    info.buffer = buffer.buffer;
    info.format = format;
    info.range = std::min(buffer.size / texelBytes * texelBytes, limit);
    VkBufferView view = VK_NULL_HANDLE;
    VK_CHECK(vkCreateBufferView(device.device, &info, nullptr, &view));
    return view;
}

void destroyBuffer(Device& device, Buffer& buffer)
{
    if (buffer.buffer)
        vkDestroyBuffer(device.device, buffer.buffer, nullptr);
    if (buffer.memory)
        vkFreeMemory(device.device, buffer.memory, nullptr);
    buffer = {};
}

void writeMapped(Buffer& buffer, const void* data, size_t bytes, size_t offset)
{
    if (!buffer.mapped || offset + bytes > buffer.size)
        fail("vulkan", "a write of " + std::to_string(bytes) + " bytes at " + std::to_string(offset) + " does not fit a mapped buffer of " +
                           std::to_string(buffer.size));
    std::memcpy(static_cast<char*>(buffer.mapped) + offset, data, bytes);
}

Buffer createBufferWithData(Device& device, const void* data, VkDeviceSize size, VkBufferUsageFlags usage, Addressable addressable,
                            VkDeviceSize capacity)
{
    capacity = std::max(capacity, size);
    if (deviceLocalIsHostVisible(device)) {
        Buffer buffer = createBuffer(device, capacity, usage, MemoryUse::Upload, addressable);
        std::memcpy(buffer.mapped, data, size);
        std::memset(static_cast<char*>(buffer.mapped) + size, 0, capacity - size);
        return buffer;
    }
    Buffer buffer = createBuffer(device, capacity, usage | VK_BUFFER_USAGE_TRANSFER_DST_BIT, MemoryUse::DeviceLocal, addressable);
    const VkDeviceSize chunk = 64ull << 20;
    Buffer staging;
    try {
        staging = createBuffer(device, std::min(capacity, chunk), VK_BUFFER_USAGE_TRANSFER_SRC_BIT, MemoryUse::Upload);
        for (VkDeviceSize offset = 0; offset < capacity; offset += chunk) {
            VkDeviceSize bytes = std::min(chunk, capacity - offset);
            VkDeviceSize fromData = offset < size ? std::min(bytes, size - offset) : 0;
            if (fromData > 0)
                std::memcpy(staging.mapped, static_cast<const char*>(data) + offset, fromData);
            std::memset(static_cast<char*>(staging.mapped) + fromData, 0, bytes - fromData);
            immediateSubmit(device, [&](VkCommandBuffer cmd) {
                VkBufferCopy region{0, offset, bytes};
                vkCmdCopyBuffer(cmd, staging.buffer, buffer.buffer, 1, &region);
            });
        }
    } catch (...) {
        if (!device.hung) {
            destroyBuffer(device, staging);
            destroyBuffer(device, buffer);
        }
        throw;
    }
    destroyBuffer(device, staging);
    return buffer;
}

VkDeviceAddress bufferAddress(const Device& device, const Buffer& buffer)
{
    VkBufferDeviceAddressInfo info{VK_STRUCTURE_TYPE_BUFFER_DEVICE_ADDRESS_INFO};
    info.buffer = buffer.buffer;
    return vkGetBufferDeviceAddress(device.device, &info);
}

Image createImage(Device& device, uint32_t width, uint32_t height, uint32_t layers, VkFormat format, VkImageUsageFlags usage,
                  bool arrayView)
{
    Image image;
    image.format = format;
    image.width = width;
    image.height = height;
    image.layers = layers;
    VkImageCreateInfo info{VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO};
    info.imageType = VK_IMAGE_TYPE_2D;
    info.format = format;
    info.extent = {width, height, 1};
    info.mipLevels = 1;
    info.arrayLayers = layers;
    info.samples = VK_SAMPLE_COUNT_1_BIT;
    info.tiling = VK_IMAGE_TILING_OPTIMAL;
    info.usage = usage;
    info.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    VK_CHECK(vkCreateImage(device.device, &info, nullptr, &image.image));
    try {
        VkMemoryRequirements requirements;
        vkGetImageMemoryRequirements(device.device, image.image, &requirements);
        image.memory = allocate(device, requirements, 0, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
        VK_CHECK(vkBindImageMemory(device.device, image.image, image.memory, 0));
    } catch (...) {
        destroyImage(device, image);
        throw;
    }

    bool depth = format == VK_FORMAT_D32_SFLOAT;
    VkImageViewCreateInfo viewInfo{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
    viewInfo.image = image.image;
    viewInfo.viewType = layers > 1 || arrayView ? VK_IMAGE_VIEW_TYPE_2D_ARRAY : VK_IMAGE_VIEW_TYPE_2D;
    viewInfo.format = format;
    viewInfo.subresourceRange = {VkImageAspectFlags(depth ? VK_IMAGE_ASPECT_DEPTH_BIT : VK_IMAGE_ASPECT_COLOR_BIT), 0, 1, 0, layers};
    VK_CHECK(vkCreateImageView(device.device, &viewInfo, nullptr, &image.view));
    if (layers > 1 || viewInfo.viewType == VK_IMAGE_VIEW_TYPE_2D_ARRAY)
        for (uint32_t layer = 0; layer < layers && layer < 6; ++layer) {
            viewInfo.viewType = VK_IMAGE_VIEW_TYPE_2D;
            viewInfo.subresourceRange.baseArrayLayer = layer;
            viewInfo.subresourceRange.layerCount = 1;
            VK_CHECK(vkCreateImageView(device.device, &viewInfo, nullptr, &image.layerViews[layer]));
        }
    return image;
}

void destroyImage(Device& device, Image& image)
{
    for (VkImageView view : image.layerViews)
        if (view)
            vkDestroyImageView(device.device, view, nullptr);
    if (image.view)
        vkDestroyImageView(device.device, image.view, nullptr);
    if (image.image)
        vkDestroyImage(device.device, image.image, nullptr);
    if (image.memory)
        vkFreeMemory(device.device, image.memory, nullptr);
    image = {};
}

VkShaderModule createShaderModule(Device& device, const char* name)
{
    for (const shaders::Embedded& shader : shaders::kAll)
        if (std::strcmp(shader.name, name) == 0) {
            VkShaderModuleCreateInfo info{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
            info.codeSize = shader.size;
            info.pCode = shader.code;
            VkShaderModule module;
            VK_CHECK(vkCreateShaderModule(device.device, &info, nullptr, &module));
            return module;
        }
    fail("shaders", std::string("no embedded shader named ") + name);
}

VkCommandBuffer beginOneTime(Device& device)
{
    checkUsable(device);
    VkCommandBufferAllocateInfo info{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    info.commandPool = device.commandPool;
    info.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    info.commandBufferCount = 1;
    VkCommandBuffer cmd;
    VK_CHECK(vkAllocateCommandBuffers(device.device, &info, &cmd));
    VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    VkResult result = vkBeginCommandBuffer(cmd, &begin);
    if (result != VK_SUCCESS)
        vkFreeCommandBuffers(device.device, device.commandPool, 1, &cmd);
    VK_CHECK(result);
    return cmd;
}

void endOneTime(Device& device, VkCommandBuffer cmd, const char* what)
{
    VkFence fence = VK_NULL_HANDLE;
    bool submitted = false;
    try {
        VK_CHECK(vkEndCommandBuffer(cmd));
        VkFenceCreateInfo fenceInfo{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
        VK_CHECK(vkCreateFence(device.device, &fenceInfo, nullptr, &fence));
        submit(device, cmd, fence, what);
        submitted = true;
        waitForFence(device, fence, what);
    } catch (...) {
        // Free the fence and the command buffer once the device is done with them; a hung device keeps them.
        if (!submitted || drainFence(device, fence)) {
            if (fence)
                vkDestroyFence(device.device, fence, nullptr);
            vkFreeCommandBuffers(device.device, device.commandPool, 1, &cmd);
        }
        throw;
    }
    vkDestroyFence(device.device, fence, nullptr);
    vkFreeCommandBuffers(device.device, device.commandPool, 1, &cmd);
}

void memoryBarrier(VkCommandBuffer cmd, VkPipelineStageFlags2 srcStage, VkAccessFlags2 srcAccess, VkPipelineStageFlags2 dstStage,
                   VkAccessFlags2 dstAccess)
{
    VkMemoryBarrier2 barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER_2};
    barrier.srcStageMask = srcStage;
    barrier.srcAccessMask = srcAccess;
    barrier.dstStageMask = dstStage;
    barrier.dstAccessMask = dstAccess;
    VkDependencyInfo dependency{VK_STRUCTURE_TYPE_DEPENDENCY_INFO};
    dependency.memoryBarrierCount = 1;
    dependency.pMemoryBarriers = &barrier;
    vkCmdPipelineBarrier2(cmd, &dependency);
}

void transition(VkCommandBuffer cmd, const Image& image, VkImageLayout from, VkImageLayout to,
                VkPipelineStageFlags2 srcStage, VkAccessFlags2 srcAccess, VkPipelineStageFlags2 dstStage,
                VkAccessFlags2 dstAccess)
{
    VkImageMemoryBarrier2 barrier{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER_2};
    barrier.srcStageMask = srcStage;
    barrier.srcAccessMask = srcAccess;
    barrier.dstStageMask = dstStage;
    barrier.dstAccessMask = dstAccess;
    barrier.oldLayout = from;
    barrier.newLayout = to;
    barrier.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    barrier.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    barrier.image = image.image;
    bool depth = image.format == VK_FORMAT_D32_SFLOAT;
    barrier.subresourceRange = {VkImageAspectFlags(depth ? VK_IMAGE_ASPECT_DEPTH_BIT : VK_IMAGE_ASPECT_COLOR_BIT), 0, 1, 0, image.layers};
    VkDependencyInfo dependency{VK_STRUCTURE_TYPE_DEPENDENCY_INFO};
    dependency.imageMemoryBarrierCount = 1;
    dependency.pImageMemoryBarriers = &barrier;
    vkCmdPipelineBarrier2(cmd, &dependency);
}

} // namespace penumbra::vk
