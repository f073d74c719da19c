#include "device.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <thread>

namespace penumbra::vk {

const char* resultName(VkResult result)
{
    switch (result) {
#define NAME(r) case r: return #r
        NAME(VK_NOT_READY); NAME(VK_TIMEOUT); NAME(VK_INCOMPLETE);
        NAME(VK_ERROR_OUT_OF_HOST_MEMORY); NAME(VK_ERROR_OUT_OF_DEVICE_MEMORY);
        NAME(VK_ERROR_INITIALIZATION_FAILED); NAME(VK_ERROR_DEVICE_LOST);
        NAME(VK_ERROR_MEMORY_MAP_FAILED); NAME(VK_ERROR_LAYER_NOT_PRESENT);
        NAME(VK_ERROR_EXTENSION_NOT_PRESENT); NAME(VK_ERROR_FEATURE_NOT_PRESENT);
        NAME(VK_ERROR_INCOMPATIBLE_DRIVER); NAME(VK_ERROR_TOO_MANY_OBJECTS);
        NAME(VK_ERROR_FORMAT_NOT_SUPPORTED); NAME(VK_ERROR_OUT_OF_POOL_MEMORY);
#undef NAME
    default: return "VkResult error";
    }
}

void vulkanFailure(const char* call, VkResult result, const char* file, int line)
{
    const char* base = std::strrchr(file, '/');
    std::string where = std::string(base ? base + 1 : file) + ":" + std::to_string(line);
    if (result == VK_ERROR_OUT_OF_DEVICE_MEMORY || result == VK_ERROR_OUT_OF_HOST_MEMORY)
        fail("vulkan", std::string("out of memory (") + resultName(result) + ") in " + call + " at " + where);
    if (result == VK_ERROR_DEVICE_LOST)
        fail("vulkan", std::string("device lost (VK_ERROR_DEVICE_LOST) in ") + call + " at " + where);
    fail("vulkan", std::string(call) + " failed with " + resultName(result) + " at " + where);
}

namespace {

std::atomic<uint32_t> processValidationMessages{0};

FaultInjection faultFromEnvironment()
{
    FaultInjection fault;
    const char* env = std::getenv("PENUMBRA_FAULT");
    if (!env || !*env)
        return fault;
    std::string text = env;
    size_t colon = text.find(':');
    std::string kind = text.substr(0, colon);
    char* end = nullptr;
    unsigned long n = colon == std::string::npos ? 0 : std::strtoul(text.c_str() + colon + 1, &end, 10);
    if (colon == std::string::npos || *end != '\0' || n == 0)
        fail("PENUMBRA_FAULT=" + text, "expected <kind>:<n> with n >= 1");
    if (kind == "allocate") fault.kind = FaultInjection::Kind::Allocate;
    else if (kind == "submit") fault.kind = FaultInjection::Kind::Submit;
    else if (kind == "wait") fault.kind = FaultInjection::Kind::Wait;
    else if (kind == "validation") fault.kind = FaultInjection::Kind::Validation;
    else fail("PENUMBRA_FAULT=" + text, "kind must be allocate, submit, wait or validation");
    fault.n = uint32_t(n);
    return fault;
}

double timeoutFromEnvironment(double seconds)
{
    const char* env = std::getenv("PENUMBRA_DEVICE_TIMEOUT");
    if (!env || !*env)
        return seconds;
    char* end = nullptr;
    double value = std::strtod(env, &end);
    if (*end != '\0' || !(value > 0.0) || !std::isfinite(value))
        fail(std::string("PENUMBRA_DEVICE_TIMEOUT=") + env, "expected a positive number of seconds");
    return value;
}

std::string secondsText(double seconds)
{
    char text[32];
    std::snprintf(text, sizeof(text), "%g", seconds);
    return text;
}

uint64_t nanoseconds(double seconds) { return seconds >= 1.8e10 ? UINT64_MAX : uint64_t(seconds * 1e9); }

[[noreturn]] void deviceLost(Device& device, const std::string& what)
{
    device.failed = "device lost (VK_ERROR_DEVICE_LOST) in " + what;
    fail("vulkan", device.failed + ": the driver reset the GPU or the GPU failed");
}

} // namespace

VkDeviceMemory allocateMemory(Device& device, const VkMemoryAllocateInfo& info)
{
    const bool inject = device.fault.kind == FaultInjection::Kind::Allocate && ++device.allocations == device.fault.n;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    VkResult result = inject ? VK_ERROR_OUT_OF_DEVICE_MEMORY : vkAllocateMemory(device.device, &info, nullptr, &memory);
    if (result == VK_ERROR_OUT_OF_DEVICE_MEMORY || result == VK_ERROR_OUT_OF_HOST_MEMORY) {
        char size[32];
        std::snprintf(size, sizeof(size), "%.1f MiB", double(info.allocationSize) / double(1 << 20));
        fail("vulkan", std::string(result == VK_ERROR_OUT_OF_DEVICE_MEMORY ? "out of device memory" : "out of host memory") + " (" +
                           resultName(result) + ") allocating " + size + " on " + device.info.name);
    }
    if (result == VK_ERROR_DEVICE_LOST)
        deviceLost(device, "vkAllocateMemory");
    VK_CHECK(result);
    return memory;
}

void checkUsable(const Device& device)
{
    if (!device.failed.empty())
        fail("vulkan", "the device failed earlier (" + device.failed + "); create a new renderer");
}

void submit(Device& device, VkCommandBuffer cmd, VkFence fence, const std::string& what)
{
    checkUsable(device);
    ++device.submissions;
    if (device.fault.kind == FaultInjection::Kind::Validation && device.submissions == device.fault.n && device.messenger) {
        auto message = reinterpret_cast<PFN_vkSubmitDebugUtilsMessageEXT>(vkGetInstanceProcAddr(device.instance, "vkSubmitDebugUtilsMessageEXT"));
        VkDebugUtilsMessengerCallbackDataEXT data{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CALLBACK_DATA_EXT};
        data.pMessageIdName = "PENUMBRA_FAULT";
        data.pMessage = "injected by PENUMBRA_FAULT=validation (test)";
        message(device.instance, VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT, VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT, &data);
    }
    VkSubmitInfo info{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    info.commandBufferCount = 1;
    info.pCommandBuffers = &cmd;
    const bool inject = device.fault.kind == FaultInjection::Kind::Submit && device.submissions == device.fault.n;
    VkResult result = inject ? VK_ERROR_DEVICE_LOST : vkQueueSubmit(device.queue, 1, &info, fence);
    if (result == VK_ERROR_DEVICE_LOST)
        deviceLost(device, what);
    if (result != VK_SUCCESS)
        device.failed = "vkQueueSubmit failed with " + std::string(resultName(result)) + " in " + what;
    VK_CHECK(result);
}

void waitForFence(Device& device, VkFence fence, const std::string& what)
{
    ++device.waits;
    const bool inject = device.fault.kind == FaultInjection::Kind::Wait && device.waits == device.fault.n;
    VkResult result = inject ? VK_TIMEOUT : vkWaitForFences(device.device, 1, &fence, VK_TRUE, nanoseconds(device.timeoutSeconds));
    if (result == VK_SUCCESS)
        return;
    if (result == VK_TIMEOUT) {
        device.failed = "device did not finish " + what + " in " + secondsText(device.timeoutSeconds) + " s";
        fail("vulkan", device.failed);
    }
    if (result == VK_ERROR_DEVICE_LOST)
        deviceLost(device, what);
    device.failed = "waiting for " + what + " failed with " + resultName(result);
    VK_CHECK(result);
}

bool drainFence(Device& device, VkFence fence)
{
    if (device.hung)
        return false;
    VkResult result = vkWaitForFences(device.device, 1, &fence, VK_TRUE, nanoseconds(std::max(device.timeoutSeconds, 10.0)));
    if (result == VK_TIMEOUT)
        device.hung = true;
    return !device.hung; // a lost device's work is over
}

void writeTimestamp(VkCommandBuffer cmd, VkQueryPool pool, uint32_t query)
{
    vkCmdWriteTimestamp2(cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, pool, query);
    vkCmdWriteTimestamp2(cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, pool, query + 1);
}

void readQueryResults(Device& device, VkQueryPool pool, uint32_t first, uint32_t count, size_t bytes, void* data, VkDeviceSize stride,
                      VkQueryResultFlags flags, const std::string& what)
{
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(device.timeoutSeconds);
    for (;;) {
        VkResult result = vkGetQueryPoolResults(device.device, pool, first, count, bytes, data, stride, flags & ~VK_QUERY_RESULT_WAIT_BIT);
        if (result == VK_SUCCESS)
            return;
        if (result == VK_ERROR_DEVICE_LOST)
            deviceLost(device, what + " (query results)");
        if (result != VK_NOT_READY)
            VK_CHECK(result);
        if (std::chrono::steady_clock::now() > deadline) {
            device.failed = "device did not finish " + what + " (query results) in " + secondsText(device.timeoutSeconds) + " s";
            fail("vulkan", device.failed);
        }
        std::this_thread::sleep_for(std::chrono::microseconds(100));
    }
}

uint32_t totalValidationMessages() { return processValidationMessages.load(); }

namespace {

VKAPI_ATTR VkBool32 VKAPI_CALL debugCallback(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                            VkDebugUtilsMessageTypeFlagsEXT, const VkDebugUtilsMessengerCallbackDataEXT* data,
                                            void* user)
{
    auto* device = static_cast<Device*>(user);
    device->validationMessages.fetch_add(1);
    processValidationMessages.fetch_add(1);
    const char* level = severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT ? "error" : "warning";
    std::fprintf(stderr, "penumbra: validation %s: %s\n", level, data->pMessage ? data->pMessage : "");
    return VK_FALSE;
}

bool validationRequested(const RendererOptions& options)
{
    const char* env = std::getenv("PENUMBRA_VALIDATION");
    return options.validation || (env && std::strcmp(env, "0") != 0 && env[0] != '\0');
}

// An environment switch: unset or empty gives fallback, "0" off, anything else on.
bool envFlag(const char* name, bool fallback)
{
    const char* env = std::getenv(name);
    if (!env || !*env)
        return fallback;
    return std::strcmp(env, "0") != 0;
}

bool hasLayer(const char* name)
{
    uint32_t count = 0;
    vkEnumerateInstanceLayerProperties(&count, nullptr);
    std::vector<VkLayerProperties> layers(count);
    vkEnumerateInstanceLayerProperties(&count, layers.data());
    return std::any_of(layers.begin(), layers.end(), [&](const VkLayerProperties& l) { return std::strcmp(l.layerName, name) == 0; });
}

// The loader unloads a driver with the last instance that uses it. NVIDIA's driver holds initial-exec TLS, and
// glibc does not hand static TLS back when a library is unloaded, so after a few dozen renderers in one process
// the driver no longer loads ("cannot allocate memory in static TLS block") and vkCreateInstance finds no driver.
// One bare instance that lives as long as the process keeps every driver loaded once.
void pinDrivers()
{
    static const VkInstance pinned = [] {
        VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
        app.apiVersion = VK_API_VERSION_1_3;
        VkInstanceCreateInfo info{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
        info.pApplicationInfo = &app;
        VkInstance instance = VK_NULL_HANDLE;
        return vkCreateInstance(&info, nullptr, &instance) == VK_SUCCESS ? instance : VK_NULL_HANDLE;
    }();
    (void)pinned;
}

VkInstance createInstance(bool validation, const VkDebugUtilsMessengerCreateInfoEXT* messengerInfo)
{
    pinDrivers();
    VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
    app.pApplicationName = "penumbra";
    app.pEngineName = "penumbra";
    app.apiVersion = VK_API_VERSION_1_3;

    const char* layer = "VK_LAYER_KHRONOS_validation";
    const char* extensions[] = {VK_EXT_DEBUG_UTILS_EXTENSION_NAME, VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME};
    // Synchronization validation (hazards between passes: missing or too weak barriers) is on
    // with the layer; PENUMBRA_VALIDATION_SYNC=0 turns it off. Best practices are opt-in
    // (PENUMBRA_VALIDATION_BEST_PRACTICES=1): on lavapipe they only report performance advice.
    std::vector<VkValidationFeatureEnableEXT> enables;
    if (envFlag("PENUMBRA_VALIDATION_SYNC", true))
        enables.push_back(VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT);
    if (envFlag("PENUMBRA_VALIDATION_BEST_PRACTICES", false))
        enables.push_back(VK_VALIDATION_FEATURE_ENABLE_BEST_PRACTICES_EXT);
    VkValidationFeaturesEXT features{VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT};
    features.enabledValidationFeatureCount = uint32_t(enables.size());
    features.pEnabledValidationFeatures = enables.data();
    features.pNext = messengerInfo;
    VkInstanceCreateInfo info{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
    info.pApplicationInfo = &app;
    if (validation) {
        if (!hasLayer(layer))
            fail("vulkan", "validation requested but VK_LAYER_KHRONOS_validation is not installed (apt-get install vulkan-validationlayers)");
        info.enabledLayerCount = 1;
        info.ppEnabledLayerNames = &layer;
        info.enabledExtensionCount = 2;
        info.ppEnabledExtensionNames = extensions;
        info.pNext = &features;
    }
    VkInstance instance = VK_NULL_HANDLE;
    VkResult result = vkCreateInstance(&info, nullptr, &instance);
    if (result == VK_ERROR_INCOMPATIBLE_DRIVER)
        fail("vulkan", "no Vulkan 1.3 driver found (install mesa-vulkan-drivers for lavapipe)");
    VK_CHECK(result);
    return instance;
}

std::string lower(std::string s)
{
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return s;
}

const char* typeName(VkPhysicalDeviceType type)
{
    switch (type) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return "discrete";
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return "integrated";
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return "virtual";
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return "cpu";
    default: return "other";
    }
}

DeviceInfo describe(VkPhysicalDevice physical, uint32_t index)
{
    VkPhysicalDeviceDriverProperties driver{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DRIVER_PROPERTIES};
    VkPhysicalDeviceProperties2 props{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2, &driver};
    vkGetPhysicalDeviceProperties2(physical, &props);
    DeviceInfo info;
    info.index = index;
    info.name = props.properties.deviceName;
    info.type = typeName(props.properties.deviceType);
    info.driver = std::string(driver.driverName) + " " + driver.driverInfo;
    uint32_t v = props.properties.apiVersion;
    info.apiVersion = std::to_string(VK_API_VERSION_MAJOR(v)) + "." + std::to_string(VK_API_VERSION_MINOR(v)) + "." +
                      std::to_string(VK_API_VERSION_PATCH(v));
    return info;
}

int preference(VkPhysicalDeviceType type)
{
    switch (type) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return 0;
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return 1;
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return 2;
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return 3;
    default: return 4;
    }
}

bool graphicsComputeFamily(VkPhysicalDevice physical, uint32_t& family)
{
    uint32_t count = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(physical, &count, nullptr);
    std::vector<VkQueueFamilyProperties> families(count);
    vkGetPhysicalDeviceQueueFamilyProperties(physical, &count, families.data());
    for (uint32_t i = 0; i < count; ++i) {
        VkQueueFlags need = VK_QUEUE_GRAPHICS_BIT | VK_QUEUE_COMPUTE_BIT;
        if ((families[i].queueFlags & need) == need && families[i].timestampValidBits > 0) {
            family = i;
            return true;
        }
    }
    return false;
}

bool hasDeviceExtension(VkPhysicalDevice physical, const char* name)
{
    uint32_t count = 0;
    vkEnumerateDeviceExtensionProperties(physical, nullptr, &count, nullptr);
    std::vector<VkExtensionProperties> extensions(count);
    vkEnumerateDeviceExtensionProperties(physical, nullptr, &count, extensions.data());
    return std::any_of(extensions.begin(), extensions.end(),
                       [&](const VkExtensionProperties& e) { return std::strcmp(e.extensionName, name) == 0; });
}

std::vector<VkPhysicalDevice> physicalDevices(VkInstance instance)
{
    uint32_t count = 0;
    VK_CHECK(vkEnumeratePhysicalDevices(instance, &count, nullptr));
    std::vector<VkPhysicalDevice> devices(count);
    VK_CHECK(vkEnumeratePhysicalDevices(instance, &count, devices.data()));
    return devices;
}

VkPhysicalDevice choosePhysicalDevice(VkInstance instance, const std::string& request)
{
    std::vector<VkPhysicalDevice> devices = physicalDevices(instance);
    if (devices.empty())
        fail("vulkan", "no Vulkan device found (install mesa-vulkan-drivers for lavapipe)");

    // Vulkan 1.3, a graphics+compute queue with timestamps, and the subgroup operations the compute
    // shaders use (ballot in the penumbra mask, ballot and arithmetic in the thin-triangle pass, vote and
    // shuffle in the tracer's rounds, afsm's row pass and rh's rays).
    auto usable = [](VkPhysicalDevice d) {
        VkPhysicalDeviceSubgroupProperties subgroup{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SUBGROUP_PROPERTIES};
        VkPhysicalDeviceProperties2 p{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
        p.pNext = &subgroup;
        vkGetPhysicalDeviceProperties2(d, &p);
        const VkSubgroupFeatureFlags needed = VK_SUBGROUP_FEATURE_BASIC_BIT | VK_SUBGROUP_FEATURE_BALLOT_BIT |
                                              VK_SUBGROUP_FEATURE_ARITHMETIC_BIT | VK_SUBGROUP_FEATURE_VOTE_BIT |
                                              VK_SUBGROUP_FEATURE_SHUFFLE_BIT;
        uint32_t family;
        return p.properties.apiVersion >= VK_API_VERSION_1_3 && (subgroup.supportedStages & VK_SHADER_STAGE_COMPUTE_BIT) &&
               (subgroup.supportedOperations & needed) == needed && graphicsComputeFamily(d, family);
    };

    if (!request.empty()) {
        char* end = nullptr;
        unsigned long index = std::strtoul(request.c_str(), &end, 10);
        bool numeric = *end == '\0';
        std::string names;
        for (uint32_t i = 0; i < devices.size(); ++i) {
            DeviceInfo info = describe(devices[i], i);
            names += (i ? ", " : "") + std::to_string(i) + ": " + info.name;
            bool match = numeric ? index == i : lower(info.name).find(lower(request)) != std::string::npos;
            if (match) {
                if (!usable(devices[i]))
                    fail("--device " + request, "'" + info.name + "' lacks Vulkan 1.3, compute subgroup operations or a graphics+compute queue with timestamps");
                return devices[i];
            }
        }
        fail("--device " + request, "no such device (available: " + names + ")");
    }

    VkPhysicalDevice best = VK_NULL_HANDLE;
    int bestRank = 1 << 30;
    for (VkPhysicalDevice d : devices) {
        VkPhysicalDeviceProperties p;
        vkGetPhysicalDeviceProperties(d, &p);
        if (usable(d) && preference(p.deviceType) < bestRank) {
            best = d;
            bestRank = preference(p.deviceType);
        }
    }
    if (!best)
        fail("vulkan", "no device supports Vulkan 1.3 with a graphics+compute queue");
    return best;
}

} // namespace

std::vector<DeviceInfo> enumerateDevices()
{
    VkInstance instance = createInstance(false, nullptr);
    std::vector<DeviceInfo> result;
    std::vector<VkPhysicalDevice> devices = physicalDevices(instance);
    for (uint32_t i = 0; i < devices.size(); ++i)
        result.push_back(describe(devices[i], i));
    vkDestroyInstance(instance, nullptr);
    return result;
}

void createDevice(Device& device, const RendererOptions& options)
{
    bool validation = validationRequested(options);
    device.fault = faultFromEnvironment();
    device.timeoutSeconds = timeoutFromEnvironment(options.deviceTimeoutSeconds);
    if (!(device.timeoutSeconds > 0.0))
        fail("renderer", "deviceTimeoutSeconds must be positive");
    VkDebugUtilsMessengerCreateInfoEXT messengerInfo{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
    messengerInfo.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
    messengerInfo.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                                VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
    messengerInfo.pfnUserCallback = debugCallback;
    messengerInfo.pUserData = &device;

    device.instance = createInstance(validation, &messengerInfo);
    if (validation) {
        auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
            vkGetInstanceProcAddr(device.instance, "vkCreateDebugUtilsMessengerEXT"));
        VK_CHECK(create(device.instance, &messengerInfo, nullptr, &device.messenger));
    }

    device.physical = choosePhysicalDevice(device.instance, options.device);
    device.maxModelBufferBytes = options.maxModelBufferBytes;
    vkGetPhysicalDeviceProperties(device.physical, &device.properties);
    device.rasterIndices = options.rasterIndices != RasterIndices::Auto ? options.rasterIndices
                           : device.properties.deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU ? RasterIndices::Triangles
                                                                                          : RasterIndices::Strips;
    vkGetPhysicalDeviceMemoryProperties(device.physical, &device.memory);
    graphicsComputeFamily(device.physical, device.queueFamily);
    {
        std::vector<VkPhysicalDevice> all = physicalDevices(device.instance);
        uint32_t index = uint32_t(std::find(all.begin(), all.end(), device.physical) - all.begin());
        device.info = describe(device.physical, index);
    }

    if (!hasDeviceExtension(device.physical, VK_EXT_INDEX_TYPE_UINT8_EXTENSION_NAME))
        fail("vulkan", device.info.name + " lacks VK_EXT_index_type_uint8 (8-bit strip indices)");
    VkPhysicalDeviceIndexTypeUint8FeaturesEXT uint8Features{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_INDEX_TYPE_UINT8_FEATURES_EXT};
    VkPhysicalDeviceVulkan11Features features11{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_1_FEATURES, &uint8Features};
    VkPhysicalDeviceVulkan12Features features12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES, &features11};
    VkPhysicalDeviceVulkan13Features features13{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES, &features12};
    VkPhysicalDeviceFeatures2 supported{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2, &features13};
    vkGetPhysicalDeviceFeatures2(device.physical, &supported);
    if (!features13.dynamicRendering || !features13.synchronization2 || !features13.maintenance4 || !uint8Features.indexTypeUint8 ||
        !supported.features.multiDrawIndirect || !supported.features.drawIndirectFirstInstance)
        fail("vulkan", device.info.name +
                           " lacks a required feature (dynamicRendering, synchronization2, maintenance4, indexTypeUint8, "
                           "multiDrawIndirect, drawIndirectFirstInstance)");
    // The ray tracer reads the model through buffer device addresses (64-bit
    // pointers, 8-bit strip loads).
    if (!features12.bufferDeviceAddress || !supported.features.shaderInt64 || !features12.storageBuffer8BitAccess ||
        !features11.storageBuffer16BitAccess || !features12.shaderBufferInt64Atomics)
        fail("vulkan", device.info.name +
                           " lacks a feature the ray tracer needs (bufferDeviceAddress, shaderInt64, storageBuffer8BitAccess, "
                           "storageBuffer16BitAccess, shaderBufferInt64Atomics)");
    device.vertexStores = supported.features.vertexPipelineStoresAndAtomics;
    VkPhysicalDeviceMaintenance3Properties maintenance3{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_MAINTENANCE_3_PROPERTIES};
    VkPhysicalDeviceProperties2 properties2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2, &maintenance3};
    vkGetPhysicalDeviceProperties2(device.physical, &properties2);
    device.maxAllocationSize = maintenance3.maxMemoryAllocationSize;

    VkPhysicalDeviceIndexTypeUint8FeaturesEXT enableUint8{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_INDEX_TYPE_UINT8_FEATURES_EXT};
    enableUint8.indexTypeUint8 = VK_TRUE;
    VkPhysicalDeviceVulkan11Features enable11{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_1_FEATURES, &enableUint8};
    enable11.storageBuffer16BitAccess = VK_TRUE; // 6-byte vertices read by device address (three 16-bit loads)
    VkPhysicalDeviceVulkan12Features enable12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES, &enable11};
    enable12.bufferDeviceAddress = VK_TRUE;
    enable12.shaderBufferInt64Atomics = VK_TRUE; // 64-bit frame counters (nodes visited overflow 32 bits at 4K)
    enable12.storageBuffer8BitAccess = VK_TRUE;
    VkPhysicalDeviceVulkan13Features enable13{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES, &enable12};
    enable13.dynamicRendering = VK_TRUE;
    enable13.synchronization2 = VK_TRUE;
    enable13.maintenance4 = VK_TRUE; // glslang emits LocalSizeId for Vulkan 1.3 targets
    VkPhysicalDeviceFeatures2 enable{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2, &enable13};
    enable.features.fullDrawIndexUint32 = supported.features.fullDrawIndexUint32;
    enable.features.multiDrawIndirect = VK_TRUE;
    enable.features.shaderInt64 = VK_TRUE;
    enable.features.drawIndirectFirstInstance = VK_TRUE;
    enable.features.vertexPipelineStoresAndAtomics = supported.features.vertexPipelineStoresAndAtomics;
    // Alias-free shadow maps draw their casters with a geometry shader whose fragments write the samples' flags,
    // depth-tested against the cells' farthest samples with depth clamping (no caster clipped by the grid's depth range).
    device.aliasFree = supported.features.geometryShader && supported.features.fragmentStoresAndAtomics && supported.features.depthClamp;
    // Cone ray hierarchies gather their casters with a geometry shader that stores them.
    device.rayHierarchy = supported.features.geometryShader && supported.features.vertexPipelineStoresAndAtomics;
    enable.features.geometryShader = device.aliasFree || device.rayHierarchy;
    enable.features.fragmentStoresAndAtomics = device.aliasFree;
    enable.features.depthClamp = device.aliasFree;
    const char* extensions[] = {VK_EXT_INDEX_TYPE_UINT8_EXTENSION_NAME};

    float priority = 1.0f;
    VkDeviceQueueCreateInfo queueInfo{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
    queueInfo.queueFamilyIndex = device.queueFamily;
    queueInfo.queueCount = 1;
    queueInfo.pQueuePriorities = &priority;
    VkDeviceCreateInfo info{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO, &enable};
    info.queueCreateInfoCount = 1;
    info.pQueueCreateInfos = &queueInfo;
    info.enabledExtensionCount = 1;
    info.ppEnabledExtensionNames = extensions;
    VK_CHECK(vkCreateDevice(device.physical, &info, nullptr, &device.device));
    vkGetDeviceQueue(device.device, device.queueFamily, 0, &device.queue);

    VkCommandPoolCreateInfo poolInfo{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    poolInfo.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    poolInfo.queueFamilyIndex = device.queueFamily;
    VK_CHECK(vkCreateCommandPool(device.device, &poolInfo, nullptr, &device.commandPool));
}

void destroyDevice(Device& device)
{
    if (device.hung) {
        // Work that never finished may still use the device's memory: leave it to the process's end.
        std::fprintf(stderr, "penumbra: warning: the device never finished its work; it is left undestroyed\n");
        device.device = VK_NULL_HANDLE;
        device.messenger = VK_NULL_HANDLE;
        device.instance = VK_NULL_HANDLE;
        return;
    }
    if (device.device) {
        vkDeviceWaitIdle(device.device);
        vkDestroyCommandPool(device.device, device.commandPool, nullptr);
        vkDestroyDevice(device.device, nullptr);
    }
    if (device.messenger) {
        auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
            vkGetInstanceProcAddr(device.instance, "vkDestroyDebugUtilsMessengerEXT"));
        destroy(device.instance, device.messenger, nullptr);
    }
    if (device.instance)
        vkDestroyInstance(device.instance, nullptr);
    device.device = VK_NULL_HANDLE;
    device.messenger = VK_NULL_HANDLE;
    device.instance = VK_NULL_HANDLE;
}

} // namespace penumbra::vk
