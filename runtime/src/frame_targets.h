// The images and buffers a frame renders into, in one place with one destroy
// list: those sized by the image (G-buffer, colour, visibility, marks, ray
// list, readback), those sized by the shadow map (maps, thin map, penumbra
// masks), and the fixed ones (frame constants, counters, the view fit's
// read-back). Passes get them explicitly through their bind().
#pragma once

#include <cstdint>
#include <vector>

#include "config.h"
#include "resources.h"

namespace penumbra {

// The G-buffer: the surface texel (position and normal, shaders/surface.glsli)
// and the material colour, written only by frames that show colours.
constexpr VkFormat kSurfaceFormat = VK_FORMAT_R32G32B32A32_UINT;
constexpr VkFormat kAlbedoFormat = VK_FORMAT_R32_UINT;
// The shaded colour: half floats, so that the shade pass (lavapipe writes an
// image texel one channel and lane at a time) and the read-back move half the
// bytes; Frame::color gets floats (half_float.h).
constexpr VkFormat kColorFormat = VK_FORMAT_R16G16B16A16_SFLOAT;
constexpr VkFormat kVisibilityFormat = VK_FORMAT_R32_SFLOAT;
constexpr VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT;
constexpr VkFormat kThinFormat = VK_FORMAT_R32_UINT; // float bits of the nearest thin depth (imageAtomicMin)

// viewBounds (host-visible, read back mid-frame): the keys of
// view_fit.comp.glsl, then the receiver grid of each shadow-map layer
// (layer k of light l at 6 l + k).
constexpr VkDeviceSize kViewBoundsKeyBytes = PENUMBRA_MAX_LIGHTS * 6 * 8 * sizeof(uint32_t);
constexpr VkDeviceSize kReceiverGridBytes = PENUMBRA_RECEIVER_GRID_WORDS * sizeof(uint32_t);
constexpr VkDeviceSize kReceiverGridsBytes = PENUMBRA_MAX_LIGHTS * 6 * kReceiverGridBytes;

constexpr uint32_t kMaxTimestamps = 256; // per frame

struct FrameTargets {
    // Sized by the image.
    uint32_t width = 0, height = 0;
    vk::Image surface, albedo, depth, color, visibility;
    vk::Buffer marks;   // uint per pixel (compact.comp.glsl)
    vk::Buffer rayList; // PENUMBRA_RAY_LIST_HEADER_UINTS + a pixel index per pixel
    vk::Buffer traceHints; // TracePass::hintBytes(pixels)
    vk::Buffer readbackColor, readbackSurface, readbackAlbedo, readbackVisibility;
    // Sized by the shadow map.
    uint32_t shadowSize = 0, shadowLayers = 0;
    vk::Image shadowMap; // D32, one layer per cube face (SHADER_READ_ONLY between passes)
    vk::Image thinMap;   // R32_UINT, shadowLayers + 1 layers (GENERAL; thin_triangles.comp.glsl)
    // penumbra_mask.comp.glsl: the masks of depth edges and of thin triangles, the
    // nearest-edge pyramid, the deepest receiver per tile, the splat jobs.
    vk::Buffer penumbraMask, penumbraThinMask, penumbraPyramid, penumbraReceivers, penumbraJobs;
    uint32_t penumbraMaxJobs = 0;
    // afsm only (alias-free shadow maps; passes/afsm.h), made on first use.
    uint32_t afsmGrid = 0;   // cells per side
    vk::Buffer afsmCellFirst, afsmCellCount, afsmBlockSums; // per grid cell
    vk::Buffer afsmSlots, afsmShadowed;                     // per pixel: a slot of the sample list (48 bytes, addressable), a flag
    VkBufferView afsmSlotTexels = VK_NULL_HANDLE;           // RGBA32UI over afsmSlots (the casters read the slots by texel fetches)
    VkBufferView afsmCellFirstTexels = VK_NULL_HANDLE, afsmCellCountTexels = VK_NULL_HANDLE, afsmCellDepthTexels = VK_NULL_HANDLE; // R32UI, the same
    vk::Buffer afsmSlotShadowed;                            // per slot: its pixel's flag
    vk::Buffer afsmFar;                                     // the layer's farthest sample depth, most samples in a cell, crowded cells (passes::AfsmFar)
    vk::Buffer afsmCellDepth, afsmCellAlive;                // per grid cell: its farthest sample depth, its samples not yet shadowed
    vk::Image afsmDepth;                                    // D32 grid: the cells' farthest sample depths (the casters' depth test)
    // RenderSettings::readbackLightLayers only, made on first use: every light's
    // visibility and marks (PENUMBRA_MAX_LIGHTS slices of one image each).
    vk::Buffer readbackLightVisibility, readbackLightMarks;
    // RenderSettings::measureFloors only, made on first use: the depth targets
    // of the raster passes' floors (uncompressed depth-only draws), sized like
    // the camera's depth and one shadow-map layer.
    vk::Image floorDepth, floorMapDepth;
    // Fixed.
    vk::Buffer frameUniforms;    // gpu::FrameData
    vk::Buffer stats;            // uint64_t[PENUMBRA_STAT_COUNT] (device-local, copied out once per frame)
    vk::Buffer readbackStats;
    vk::Buffer viewBounds;       // view_fit.comp.glsl's keys and receiver grids, read back before the shadow maps
    vk::Buffer receiverGrids;    // device-local receiver grids (written with atomics, copied into viewBounds)
    vk::Buffer thinClusterMasks; // srt: per light layer, the clusters the thin-triangle pass decodes (host-written)
    VkSampler nearestSampler = VK_NULL_HANDLE;

    // The fixed targets.
    void create(vk::Device& device);
    // Recreates what the size or the map's size changed; true when anything
    // was (the passes bind again).
    bool ensure(vk::Device& device, uint32_t w, uint32_t h, uint32_t mapSize, uint32_t mapLayers);
    // The afsm buffers for a grid of gridSize^2 cells and this image size;
    // true when they were (re)made (the passes bind again).
    bool ensureAfsm(vk::Device& device, uint32_t gridSize);
    // The floors' depth targets for this image and map size.
    void ensureFloors(vk::Device& device);
    // The per-light read-back buffers for this image size.
    void ensureLightLayers(vk::Device& device);
    // At least `bytes` of host-visible thin cluster masks.
    void ensureThinClusterMasks(vk::Device& device, VkDeviceSize bytes);
    void destroy(vk::Device& device);

    // A storage binding of the whole buffer, or of as much as the device
    // allows (the frame refuses the settings that would need more).
    static VkDeviceSize storageRange(const vk::Device& device, const vk::Buffer& buffer);

  private:
    std::vector<vk::Image*> imageSized();
    std::vector<vk::Buffer*> imageSizedBuffers();
    std::vector<vk::Buffer*> mapSizedBuffers();
    std::vector<vk::Buffer*> afsmBuffers();
    void destroyAfsmTexelViews(vk::Device& device);
    void destroyImageSized(vk::Device& device);
    void destroyMapSized(vk::Device& device);
};

} // namespace penumbra
