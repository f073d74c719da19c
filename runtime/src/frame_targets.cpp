#include "frame_targets.h"

#include <algorithm>

#include "passes/afsm.h"
#include "passes/penumbra_mask.h"
#include "passes/thin_triangles.h"
#include "passes/trace.h"

namespace penumbra {

namespace {

constexpr VkBufferUsageFlags kStorageDst = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;

} // namespace

void FrameTargets::create(vk::Device& device)
{
    frameUniforms = vk::createBuffer(device, sizeof(gpu::FrameData), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, vk::MemoryUse::Upload);
    stats = vk::createBuffer(device, PENUMBRA_STAT_COUNT * sizeof(uint64_t), kStorageDst | VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                             vk::MemoryUse::DeviceLocal, vk::Addressable::Yes); // view_fit counts the covered pixels into it
    readbackStats =
        vk::createBuffer(device, PENUMBRA_STAT_COUNT * sizeof(uint64_t), VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::MemoryUse::Readback);
    viewBounds = vk::createBuffer(device, kViewBoundsKeyBytes + kReceiverGridsBytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                  vk::MemoryUse::Readback, vk::Addressable::Yes);
    receiverGrids = vk::createBuffer(device, kReceiverGridsBytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                                     vk::MemoryUse::DeviceLocal, vk::Addressable::Yes);
    VkSamplerCreateInfo samplerInfo{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
    samplerInfo.magFilter = samplerInfo.minFilter = VK_FILTER_NEAREST;
    samplerInfo.addressModeU = samplerInfo.addressModeV = samplerInfo.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
    VK_CHECK(vkCreateSampler(device.device, &samplerInfo, nullptr, &nearestSampler));
}

std::vector<vk::Image*> FrameTargets::imageSized() { return {&surface, &albedo, &depth, &color, &visibility}; }

std::vector<vk::Buffer*> FrameTargets::imageSizedBuffers()
{
    return {&marks, &rayList, &traceHints, &readbackColor, &readbackSurface, &readbackAlbedo, &readbackVisibility};
}

std::vector<vk::Buffer*> FrameTargets::mapSizedBuffers()
{
    return {&penumbraMask, &penumbraThinMask, &penumbraPyramid, &penumbraReceivers, &penumbraJobs};
}

std::vector<vk::Buffer*> FrameTargets::afsmBuffers()
{
    return {&afsmCellFirst, &afsmCellCount, &afsmBlockSums, &afsmSlots, &afsmShadowed, &afsmFar, &afsmCellDepth, &afsmSlotShadowed, &afsmCellAlive};
}

void FrameTargets::destroyAfsmTexelViews(vk::Device& device)
{
    for (VkBufferView* view : {&afsmSlotTexels, &afsmCellFirstTexels, &afsmCellCountTexels, &afsmCellDepthTexels}) {
        if (*view)
            vkDestroyBufferView(device.device, *view, nullptr);
        *view = VK_NULL_HANDLE;
    }
}

void FrameTargets::destroyImageSized(vk::Device& device)
{
    destroyAfsmTexelViews(device);
    for (vk::Buffer* buffer : afsmBuffers()) // afsmSlots and afsmShadowed are per pixel
        vk::destroyBuffer(device, *buffer);
    vk::destroyImage(device, afsmDepth);
    vk::destroyBuffer(device, readbackLightVisibility);
    vk::destroyBuffer(device, readbackLightMarks);
    afsmGrid = 0;
    vk::destroyImage(device, floorDepth);
    for (vk::Image* image : imageSized())
        vk::destroyImage(device, *image);
    for (vk::Buffer* buffer : imageSizedBuffers())
        vk::destroyBuffer(device, *buffer);
    width = height = 0;
}

void FrameTargets::destroyMapSized(vk::Device& device)
{
    vk::destroyImage(device, shadowMap);
    vk::destroyImage(device, thinMap);
    vk::destroyImage(device, floorMapDepth);
    for (vk::Buffer* buffer : mapSizedBuffers())
        vk::destroyBuffer(device, *buffer);
    shadowSize = shadowLayers = 0;
}

void FrameTargets::destroy(vk::Device& device)
{
    destroyImageSized(device);
    destroyMapSized(device);
    for (vk::Buffer* buffer : {&frameUniforms, &stats, &readbackStats, &viewBounds, &receiverGrids, &thinClusterMasks})
        vk::destroyBuffer(device, *buffer);
    if (nearestSampler)
        vkDestroySampler(device.device, nearestSampler, nullptr);
    nearestSampler = VK_NULL_HANDLE;
}

void FrameTargets::ensureFloors(vk::Device& device)
{
    if (!floorDepth.image)
        floorDepth = vk::createImage(device, width, height, 1, kDepthFormat, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT, true);
    if (!floorMapDepth.image)
        floorMapDepth = vk::createImage(device, shadowSize, shadowSize, 1, kDepthFormat, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT, true);
}

bool FrameTargets::ensure(vk::Device& device, uint32_t w, uint32_t h, uint32_t mapSize, uint32_t mapLayers)
{
    const bool resized = w != width || h != height;
    const bool mapResized = mapSize != shadowSize || mapLayers != shadowLayers;
    if (!resized && !mapResized)
        return false;
    vkDeviceWaitIdle(device.device);
    if (resized) {
        destroyImageSized(device);
        const VkImageUsageFlags storage = VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
        surface = vk::createImage(device, w, h, 1, kSurfaceFormat, VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | storage);
        albedo = vk::createImage(device, w, h, 1, kAlbedoFormat, VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | storage);
        depth = vk::createImage(device, w, h, 1, kDepthFormat, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT);
        color = vk::createImage(device, w, h, 1, kColorFormat, storage);
        visibility = vk::createImage(device, w, h, 1, kVisibilityFormat, storage);
        const VkDeviceSize pixels = VkDeviceSize(w) * h;
        marks = vk::createBuffer(device, pixels * 4, kStorageDst | VK_BUFFER_USAGE_TRANSFER_SRC_BIT, vk::MemoryUse::DeviceLocal);
        rayList = vk::createBuffer(device, (PENUMBRA_RAY_LIST_HEADER_UINTS + pixels) * 4, kStorageDst | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT,
                                   vk::MemoryUse::DeviceLocal);
        traceHints = vk::createBuffer(device, passes::TracePass::hintBytes(pixels), kStorageDst, vk::MemoryUse::DeviceLocal);
        const VkBufferUsageFlags dst = VK_BUFFER_USAGE_TRANSFER_DST_BIT;
        readbackColor = vk::createBuffer(device, pixels * 8, dst, vk::MemoryUse::Readback); // RGBA16F
        readbackSurface = vk::createBuffer(device, pixels * 16, dst, vk::MemoryUse::Readback);
        readbackAlbedo = vk::createBuffer(device, pixels * 4, dst, vk::MemoryUse::Readback);
        readbackVisibility = vk::createBuffer(device, pixels * 4, dst, vk::MemoryUse::Readback);
        width = w;
        height = h;
    }
    if (mapResized) {
        destroyMapSized(device); // the sizes stay 0 if a creation below throws
        const uint64_t maskLevels = passes::maskTexels(mapSize);
        // Two masks and two pyramids: depth discontinuities' splats and thin triangles' (penumbra_mask.glsli).
        penumbraMask = vk::createBuffer(device, (1 + maskLevels) * 4, kStorageDst, vk::MemoryUse::DeviceLocal);
        penumbraThinMask = vk::createBuffer(device, maskLevels * 4, kStorageDst, vk::MemoryUse::DeviceLocal);
        penumbraPyramid = vk::createBuffer(device, std::max<uint64_t>(maskLevels - uint64_t(mapSize) * mapSize, 1) * 2 * 4,
                                           VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryUse::DeviceLocal);
        const uint64_t tiles = (mapSize + PENUMBRA_RECEIVER_TILE - 1) / PENUMBRA_RECEIVER_TILE;
        penumbraReceivers = vk::createBuffer(device, 2 * tiles * tiles * 4, kStorageDst, vk::MemoryUse::DeviceLocal);
        // Splat jobs: at most two per texel of all levels (one per edge kind), 8 bytes each, within one storage binding.
        const uint64_t bindingJobs = (std::min<uint64_t>(device.properties.limits.maxStorageBufferRange, device.maxAllocationSize) - 16) / 8;
        penumbraMaxJobs = uint32_t(std::min<uint64_t>({2 * maskLevels, bindingJobs, 1u << 26}));
        penumbraJobs = vk::createBuffer(device, 16 + uint64_t(penumbraMaxJobs) * 8, kStorageDst | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT,
                                        vk::MemoryUse::DeviceLocal);
        shadowMap = vk::createImage(device, mapSize, mapSize, mapLayers, kDepthFormat,
                                    VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT, true);
        // The thin map stays in GENERAL: written in srt frames, read (cleared to "nothing thin") otherwise.
        // Layers: per shadow-map layer the slivers' nearest depths, then one of per-texel depths for
        // the penumbra mask of an area light (thin_triangles.comp.glsl).
        thinMap = vk::createImage(device, mapSize, mapSize, mapLayers + 1, kThinFormat,
                                  VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT | VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT, true);
        vk::immediateSubmit(device, [&](VkCommandBuffer cmd) {
            vk::transition(cmd, shadowMap, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_PIPELINE_STAGE_2_NONE, 0,
                           VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_SAMPLED_READ_BIT);
            vk::transition(cmd, thinMap, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL, VK_PIPELINE_STAGE_2_NONE, 0,
                           VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT);
            passes::clearThinMap(cmd, thinMap);
            vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                              VK_ACCESS_2_SHADER_STORAGE_READ_BIT);
        }, "the shadow map's and thin map's first transitions");
        shadowSize = mapSize;
        shadowLayers = mapLayers;
    }
    return true;
}

bool FrameTargets::ensureAfsm(vk::Device& device, uint32_t gridSize)
{
    if (afsmGrid == gridSize && afsmShadowed.buffer)
        return false;
    vkDeviceWaitIdle(device.device);
    destroyAfsmTexelViews(device);
    for (vk::Buffer* buffer : afsmBuffers())
        vk::destroyBuffer(device, *buffer);
    vk::destroyImage(device, afsmDepth);
    afsmGrid = 0; // stays 0 if a creation below throws
    const VkDeviceSize cells = VkDeviceSize(gridSize) * gridSize, pixels = VkDeviceSize(width) * height;
    // The casters read these three through texel views (afsm_casters.glsli).
    const VkBufferUsageFlags texels = VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT;
    // One more value after the cells' first slots: the total (afsm_scan.comp.glsl).
    afsmCellFirst = vk::createBuffer(device, (cells + 1) * 4, kStorageDst | texels, vk::MemoryUse::DeviceLocal);
    afsmCellCount = vk::createBuffer(device, cells * 4, kStorageDst | texels | VK_BUFFER_USAGE_TRANSFER_SRC_BIT, vk::MemoryUse::DeviceLocal);
    // Also the source of the per-cell depth grid (afsmDepth), copied after the count pass; then per block of 8x8
    // cells, its farthest sample depth (afsm_casters.glsli: afsmBlocksBehind).
    afsmCellDepth = vk::createBuffer(device, (cells + passes::afsmBlockCount(gridSize)) * 4, kStorageDst | texels | VK_BUFFER_USAGE_TRANSFER_SRC_BIT, vk::MemoryUse::DeviceLocal);
    afsmCellFirstTexels = vk::createTexelView(device, afsmCellFirst, VK_FORMAT_R32_UINT, 4);
    afsmCellCountTexels = vk::createTexelView(device, afsmCellCount, VK_FORMAT_R32_UINT, 4);
    afsmCellDepthTexels = vk::createTexelView(device, afsmCellDepth, VK_FORMAT_R32_UINT, 4);
    afsmCellAlive = vk::createBuffer(device, cells * 4, kStorageDst, vk::MemoryUse::DeviceLocal);
    afsmDepth = vk::createImage(device, gridSize, gridSize, 1, kDepthFormat,
                                VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT);
    afsmBlockSums = vk::createBuffer(device, PENUMBRA_AFSM_MAX_GRID * 4, kStorageDst, vk::MemoryUse::DeviceLocal);
    afsmSlots = vk::createBuffer(device, pixels * 48, kStorageDst | VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT, vk::MemoryUse::DeviceLocal,
                                 vk::Addressable::Yes);
    afsmSlotTexels = vk::createTexelView(device, afsmSlots, VK_FORMAT_R32G32B32A32_UINT, 16);
    afsmSlotShadowed = vk::createBuffer(device, pixels * 4, kStorageDst, vk::MemoryUse::DeviceLocal);
    afsmShadowed = vk::createBuffer(device, pixels * 4, kStorageDst, vk::MemoryUse::DeviceLocal);
    afsmFar = vk::createBuffer(device, sizeof(passes::AfsmFar), kStorageDst | VK_BUFFER_USAGE_TRANSFER_SRC_BIT, vk::MemoryUse::DeviceLocal); // passes::AfsmFar
    afsmGrid = gridSize;
    return true;
}

void FrameTargets::ensureLightLayers(vk::Device& device)
{
    const VkDeviceSize bytes = VkDeviceSize(width) * height * 4 * PENUMBRA_MAX_LIGHTS;
    if (readbackLightVisibility.size == bytes && readbackLightMarks.size == bytes)
        return;
    vk::destroyBuffer(device, readbackLightVisibility);
    vk::destroyBuffer(device, readbackLightMarks);
    readbackLightVisibility = vk::createBuffer(device, bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::MemoryUse::Readback);
    readbackLightMarks = vk::createBuffer(device, bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::MemoryUse::Readback);
}

void FrameTargets::ensureThinClusterMasks(vk::Device& device, VkDeviceSize bytes)
{
    if (thinClusterMasks.size >= bytes)
        return;
    vk::destroyBuffer(device, thinClusterMasks);
    thinClusterMasks = vk::createBuffer(device, bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryUse::Upload, vk::Addressable::Yes);
}

VkDeviceSize FrameTargets::storageRange(const vk::Device& device, const vk::Buffer& buffer)
{
    return std::min<VkDeviceSize>(buffer.size, device.properties.limits.maxStorageBufferRange);
}

} // namespace penumbra
