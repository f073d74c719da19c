// Thin triangles (shaders/thin_triangles.comp.glsl; srt): lavapipe has no
// conservative rasterization, so a compute pass over the BVH's leaves finds
// the slivers of a light's view (under PENUMBRA_THIN_TEXELS texels wide) and
// lists them, then a second dispatch over the list writes their conservative
// rectangles' nearest depths into one layer of the thin map with
// imageAtomicMin (on lavapipe a fill in the decoding pass would run, masked,
// for every triangle: 195 of 222 ms on a 250 k city at 1024^2).
#pragma once

#include <glm/mat4x4.hpp>

#include "config.h"
#include "model_geometry.h"
#include "pipelines.h"

namespace penumbra::passes {

struct ThinTrianglesPush {
    glm::mat4 viewProj;
    glm::vec2 mapSize;             // texels
    uint32_t nodeCount;
    uint32_t layer;                // thin-map layer written
    VkDeviceAddress modelTable;
    VkDeviceAddress leafAltitudes; // 0: skip no leaf
    glm::vec4 light;               // xyz light position; w: 0 orthographic, else a lower bound of light-view depth / distance
    float texelSize;               // orthographic: texel size; perspective: texel size per unit of light-view depth
    uint32_t localLayer;           // also write each texel's own depth of the sliver here (area lights); ~0u: no
    VkDeviceAddress clusterMask;   // bit per cluster: may reach a receiver (Culling::markClustersNearReceivers); 0: all may
};
static_assert(sizeof(ThinTrianglesPush) == 128);

// One layer of a light's view. Texel size at depth z: orthographic
// footprint / size; perspective footprint * z / size, with z >= distance *
// depthPerDistance (the cosine of half the frustum's diagonal angle: 1/sqrt(3)
// for cube faces, cos(outer) for spots).
struct ThinView {
    glm::mat4 viewProj{1.0f};
    uint32_t layer = 0;
    glm::vec3 eye{0.0f};
    bool perspective = false;
    float depthPerDistance = 0.0f;
    float footprint = 1.0f;
    VkDeviceAddress clusterMask = 0; // 0: every cluster
    bool areaLight = false;          // also the per-texel depths, into the map's last layer (penumbra mask)
};

// How much wider than the receiver masks' margin (2 texels: the classification's 3x3 texels) the
// clusters the pass decodes must reach (Culling::markClustersNearReceivers): a sliver's rectangle
// holds texel centres up to 1 texel (in x or y) beyond its footprint, and a hard thin texel
// (PENUMBRA_THIN_HARD_SCALE map texels a side) is read by points up to scale - 0.5 texels from such
// a centre, so the margin grows to scale + 1 texels.
constexpr double kThinMaskMarginScale = 0.5 * double(PENUMBRA_THIN_HARD_SCALE + 1);

// Every layer of the thin map (GENERAL) to "nothing thin": the bits of 1.0f (the far plane).
void clearThinMap(VkCommandBuffer cmd, const vk::Image& thinMap);

class ThinTrianglesPass {
  public:
    void create(vk::Device& device);
    void destroy(vk::Device& device);
    void bind(vk::Device& device, const vk::Image& thinMap);
    // The model's texel views (GpuGeometry::texels) and a sliver list sized for
    // it; call after every model upload.
    void bindModel(vk::Device& device, const GpuGeometry& geometry);
    // Clears the thin map after the passes that read it, before this one writes it: an area light's
    // map all of it; a hard light's only what its views write and classify reads, the
    // ceil(mapSize / PENUMBRA_THIN_HARD_SCALE)^2 corner of its first hardLayers layers (render-pass
    // clears: clearing whole 2048^2 layers cost about 4 of city's 17 ms at 640^2 on lavapipe).
    void clear(VkCommandBuffer cmd, const vk::Image& thinMap, uint32_t mapSize, uint32_t hardLayers, bool areaLight) const;
    // modelTable: the tracer's (TracePass::modelTableAddress).
    void record(VkCommandBuffer cmd, const vk::Device& device, const GpuGeometry& geometry, VkDeviceAddress modelTable, uint32_t mapSize,
                uint32_t thinLayers, const ThinView& view) const;

  private:
    // Writes the descriptor set once both the thin map and the model are known.
    void writeSet(vk::Device& device) const;
    void destroyRects(vk::Device& device);

    vk::ComputeKernel kernel;
    VkImageView thinMapView = VK_NULL_HANDLE;
    vk::Buffer list;                 // PENUMBRA_THIN_LIST_HEADER_UINTS header, then the slivers of a view (sized by the model)
    vk::Buffer rects;                // the first entries' rectangles (hard maps), up to PENUMBRA_THIN_RECTS_MAX
    VkBufferView rectTexels = VK_NULL_HANDLE; // RGBA32F view of rects, read by the fill
    GpuGeometry::TexelViews texels;
    bool texelsComplete = false;
    bool vertexTexelsSplit = false;
};

} // namespace penumbra::passes
