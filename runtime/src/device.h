// Vulkan instance/device creation (headless), device selection and validation.
#pragma once

#include <atomic>
#include <string>
#include <vector>

#include <vulkan/vulkan.h>

#include "penumbra/penumbra.h"

namespace penumbra::vk {

const char* resultName(VkResult result);
[[noreturn]] void vulkanFailure(const char* call, VkResult result, const char* file, int line);

// Always-on check of a Vulkan call: throws Error naming the call, the result and the source line.
#define VK_CHECK(call)                                                                     \
    do {                                                                                   \
        VkResult vkCheckResult_ = (call);                                                  \
        if (vkCheckResult_ != VK_SUCCESS)                                                  \
            ::penumbra::vk::vulkanFailure(#call, vkCheckResult_, __FILE__, __LINE__);      \
    } while (0)

struct Device {
    VkInstance instance = VK_NULL_HANDLE;
    VkDebugUtilsMessengerEXT messenger = VK_NULL_HANDLE;
    VkPhysicalDevice physical = VK_NULL_HANDLE;
    VkDevice device = VK_NULL_HANDLE;
    VkQueue queue = VK_NULL_HANDLE;
    uint32_t queueFamily = 0;
    VkCommandPool commandPool = VK_NULL_HANDLE;
    VkPhysicalDeviceProperties properties{};
    VkPhysicalDeviceMemoryProperties memory{};
    DeviceInfo info;
    VkDeviceSize maxAllocationSize = 1ull << 30; // VkPhysicalDeviceMaintenance3Properties
    bool vertexStores = false;                   // vertexPipelineStoresAndAtomics (decode check)
    bool aliasFree = false;                      // geometryShader and fragmentStoresAndAtomics (afsm casters)
    VkDeviceSize maxModelBufferBytes = 0;        // RendererOptions::maxModelBufferBytes
    std::atomic<uint32_t> validationMessages{0};
};

// Creates instance (+ validation when asked) and a logical device with one
// graphics+compute queue. Throws Error when no device matches.
void createDevice(Device& device, const RendererOptions& options);
void destroyDevice(Device& device);

// Validation messages seen by every device of this process.
uint32_t totalValidationMessages();

// Creates an instance with no layers and reports every physical device.
std::vector<DeviceInfo> enumerateDevices();

} // namespace penumbra::vk
