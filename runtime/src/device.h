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

// Test-only failure injection, from the environment variable
// PENUMBRA_FAULT=<kind>:<n> when the device is created: the n-th call (from 1)
// of that kind on this device fails as a real device would.
//   allocate    vkAllocateMemory returns VK_ERROR_OUT_OF_DEVICE_MEMORY
//   submit      vkQueueSubmit returns VK_ERROR_DEVICE_LOST (the work is not submitted)
//   wait        a fence wait returns VK_TIMEOUT at once (the work still runs)
//   validation  the n-th submission also sends one validation error to the debug messenger
struct FaultInjection {
    enum class Kind { None, Allocate, Submit, Wait, Validation } kind = Kind::None;
    uint32_t n = 0;
};

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
    bool aliasFree = false;                      // geometryShader, fragmentStoresAndAtomics and depthClamp (afsm casters)
    bool rayHierarchy = false;                   // geometryShader and vertexPipelineStoresAndAtomics (rh casters)
    VkDeviceSize maxModelBufferBytes = 0;        // RendererOptions::maxModelBufferBytes
    RasterIndices rasterIndices = RasterIndices::Strips; // RendererOptions::rasterIndices, Auto resolved by the device type
    std::atomic<uint32_t> validationMessages{0};
    double timeoutSeconds = 300.0;               // RendererOptions::deviceTimeoutSeconds
    FaultInjection fault;
    uint32_t allocations = 0, submissions = 0, waits = 0; // calls so far (fault injection counts them)
    // Set when a submission was lost or timed out: the device takes no more work.
    std::string failed;
    // A timed-out submission never finished: destroying the device would free memory it may still use.
    bool hung = false;
};

// vkAllocateMemory through the fault injection; throws Error (out of memory) on failure.
VkDeviceMemory allocateMemory(Device& device, const VkMemoryAllocateInfo& info);
// Submits one command buffer signalling fence; what names its passes for errors.
// Throws Error on failure (device lost: one clear line) and marks the device failed.
void submit(Device& device, VkCommandBuffer cmd, VkFence fence, const std::string& what);
// Waits at most the device's timeout for fence. Throws "device did not finish <what> in N s",
// or device lost, and marks the device failed.
void waitForFence(Device& device, VkFence fence, const std::string& what);
// After a failed wait: waits for fence once more (at most max(timeout, 10 s)) so the
// objects its work uses can be freed; false, and the device marked hung, when it never signals.
bool drainFence(Device& device, VkFence fence);
// Host read of query results the device has finished (after the fence), polled
// without VK_QUERY_RESULT_WAIT_BIT so a lost or hung device cannot block it.
void readQueryResults(Device& device, VkQueryPool pool, uint32_t first, uint32_t count, size_t bytes, void* data, VkDeviceSize stride,
                      VkQueryResultFlags flags, const std::string& what);
// A pass timer's timestamp: writes `query` (the one read), then `query + 1`
// (never read; the pool holds kTimestampQueries queries per timestamp, both
// reset before). lavapipe (llvmpipe 22.3) bins a timestamp into the
// rasterizer's next scene and takes the time when that scene runs: at the next
// flush, which the next timestamp's write makes. After a timestamp, a pass of
// compute work alone flushes nothing, so its time was counted in the pass
// before it (the frames' compact held the soft trace's seconds, and the trace
// the shade's). The second write flushes the first at once.
constexpr uint32_t kTimestampQueries = 2;
void writeTimestamp(VkCommandBuffer cmd, VkQueryPool pool, uint32_t query);
// Throws when an earlier submission failed: nothing more is recorded on this device.
void checkUsable(const Device& device);

// Creates instance (+ validation when asked) and a logical device with one
// graphics+compute queue. Throws Error when no device matches.
void createDevice(Device& device, const RendererOptions& options);
void destroyDevice(Device& device);

// Validation messages seen by every device of this process.
uint32_t totalValidationMessages();

// Creates an instance with no layers and reports every physical device.
std::vector<DeviceInfo> enumerateDevices();

} // namespace penumbra::vk
