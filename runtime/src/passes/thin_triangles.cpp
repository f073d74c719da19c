#include "passes/thin_triangles.h"

#include <algorithm>
#include <vector>

#include "config.h"
#include "passes/pass.h"

namespace penumbra::passes {

// The fill reads the list phase's rectangles through a texel view (and every phase's pipeline declares it).
constexpr VkAccessFlags2 kRectRead = VK_ACCESS_2_SHADER_SAMPLED_READ_BIT;

void ThinTrianglesPass::create(vk::Device& device)
{
    kernel.create(device, "thin_triangles.comp",
                  {vk::kStorageImage, vk::kTexels, vk::kTexels, vk::kTexels, vk::kTexels, vk::kStorage, vk::kTexels, vk::kStorage, vk::kTexels},
                  sizeof(ThinTrianglesPush));
}

void ThinTrianglesPass::destroy(vk::Device& device)
{
    kernel.destroy(device);
    vk::destroyBuffer(device, list);
    destroyRects(device);
    thinMapView = VK_NULL_HANDLE;
    texels = {};
    texelsComplete = false;
}

void ThinTrianglesPass::bind(vk::Device& device, const vk::Image& thinMap)
{
    thinMapView = thinMap.view;
    writeSet(device);
}

void ThinTrianglesPass::bindModel(vk::Device& device, const GpuGeometry& geometry)
{
    texels = geometry.texels;
    texelsComplete = geometry.texelsComplete;
    vertexTexelsSplit = geometry.vertexTexelsSplit;
    // Every triangle of the model could be a sliver of one view: the list holds them all, up to PENUMBRA_THIN_LIST_MAX.
    const uint32_t capacity = uint32_t(std::min<uint64_t>(std::max<uint64_t>(geometry.triangles, 1), PENUMBRA_THIN_LIST_MAX));
    vk::destroyBuffer(device, list);
    destroyRects(device);
    // The first entries' rectangles, kept for the fill of hard maps (32 bytes each: two texels of the view;
    // a buffer of the model's, so within RendererOptions::maxModelBufferBytes, which tests set small to
    // have the fill decode the later entries again).
    uint32_t rectCapacity = std::min({capacity, PENUMBRA_THIN_RECTS_MAX, device.properties.limits.maxTexelBufferElements / 2});
    if (device.maxModelBufferBytes)
        rectCapacity = uint32_t(std::min<VkDeviceSize>(rectCapacity, device.maxModelBufferBytes / 32));
    rectCapacity = std::max(rectCapacity, 1u);
    rects = vk::createBuffer(device, VkDeviceSize(rectCapacity) * 32,
                             VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT, vk::MemoryUse::DeviceLocal);
    rectTexels = vk::createTexelView(device, rects, VK_FORMAT_R32G32B32A32_SFLOAT, 16);
    std::vector<uint32_t> header(PENUMBRA_THIN_LIST_HEADER_UINTS, 0);
    header[4] = capacity;
    header[5] = rectCapacity;
    list = vk::createBufferWithData(device, header.data(), header.size() * sizeof(uint32_t),
                                    VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                    vk::Addressable::No, header.size() * sizeof(uint32_t) + VkDeviceSize(capacity) * 8);
    writeSet(device);
}

void ThinTrianglesPass::destroyRects(vk::Device& device)
{
    if (rectTexels)
        vkDestroyBufferView(device.device, rectTexels, nullptr);
    rectTexels = VK_NULL_HANDLE;
    vk::destroyBuffer(device, rects);
}

void ThinTrianglesPass::writeSet(vk::Device& device) const
{
    if (!thinMapView || !texels.nodes)
        return;
    kernel.write(device, {vk::storageImage(thinMapView), vk::texelBuffer(texels.nodes), vk::texelBuffer(texels.clusters),
                          vk::texelBuffer(texels.vertices), vk::texelBuffer(texels.strips), vk::storageBuffer(list.buffer),
                          vk::texelBuffer(texels.nodeTable), vk::storageBuffer(rects.buffer), vk::texelBuffer(rectTexels)});
}

void clearThinMap(VkCommandBuffer cmd, const vk::Image& thinMap)
{
    VkClearColorValue far{};
    far.uint32[0] = 0x3F800000u;
    VkImageSubresourceRange range{VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, thinMap.layers};
    vkCmdClearColorImage(cmd, thinMap.image, VK_IMAGE_LAYOUT_GENERAL, &far, 1, &range);
}

void ThinTrianglesPass::clear(VkCommandBuffer cmd, const vk::Image& thinMap, uint32_t mapSize, uint32_t hardLayers, bool areaLight) const
{
    if (areaLight) {
        vk::memoryBarrier(cmd, kCompute, kStorageRead, kClear, kTransferWrite);
        clearThinMap(cmd, thinMap);
        vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute, kStorageRW);
        return;
    }
    constexpr VkAccessFlags2 kColorWrite = VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT;
    vk::memoryBarrier(cmd, kCompute, kStorageRead, kColorOut, kColorWrite);
    const uint32_t size = (mapSize + PENUMBRA_THIN_HARD_SCALE - 1) / PENUMBRA_THIN_HARD_SCALE;
    for (uint32_t layer = 0; layer < hardLayers && layer < 6; ++layer) {
        VkRenderingAttachmentInfo color{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
        color.imageView = thinMap.layerViews[layer];
        color.imageLayout = VK_IMAGE_LAYOUT_GENERAL;
        color.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
        color.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
        color.clearValue.color.uint32[0] = 0x3F800000u; // 1.0f: nothing thin
        VkRenderingInfo rendering{VK_STRUCTURE_TYPE_RENDERING_INFO};
        rendering.renderArea = {{0, 0}, {size, size}};
        rendering.layerCount = 1;
        rendering.colorAttachmentCount = 1;
        rendering.pColorAttachments = &color;
        vkCmdBeginRendering(cmd, &rendering);
        vkCmdEndRendering(cmd);
    }
    vk::memoryBarrier(cmd, kColorOut, kColorWrite, kCompute, kStorageRW);
}

void ThinTrianglesPass::record(VkCommandBuffer cmd, const vk::Device& device, const GpuGeometry& geometry, VkDeviceAddress modelTable,
                               uint32_t mapSize, uint32_t thinLayers, const ThinView& view) const
{
    const uint32_t texels = texelsComplete ? 1u : 0u, local = view.areaLight ? 1u : 0u, split = vertexTexelsSplit ? 1u : 0u;
    const uint32_t paged = geometry.paged() ? 1u : 0u;
    // An orthographic view's clip w is exactly 1: its vertices are projected without the division (kAffine).
    const glm::mat4& m = view.viewProj;
    const uint32_t affine = m[0][3] == 0.0f && m[1][3] == 0.0f && m[2][3] == 0.0f && m[3][3] == 1.0f ? 1u : 0u;
    // The list's count, cleared for this view.
    vk::memoryBarrier(cmd, kCompute | kIndirect, kStorageRW | kIndirectRead, kClear, kTransferWrite);
    vkCmdFillBuffer(cmd, list.buffer, 0, sizeof(uint32_t), 0);
    vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute, kStorageRW | kRectRead);
    kernel.bind(cmd, vk::Specialization{texels, local, PENUMBRA_THIN_LIST, split, paged, affine});
    // One invocation per node, then per leaf of the workgroup's nodes.
    const uint32_t groups = std::max(groupCount(geometry.nodeCount, PENUMBRA_THIN_TRIANGLES_GROUP_SIZE), 1u);
    const Groups2D dispatch = spreadGroups(groups, device.properties.limits.maxComputeWorkGroupCount[0]);
    ThinTrianglesPush push{view.viewProj,
                           glm::vec2(float(mapSize)),
                           geometry.nodeCount,
                           view.layer,
                           modelTable,
                           geometry.paged() ? (geometry.pagedAltitudes ? 1u : 0u) // 1: in the pool's node records
                           : geometry.leafAltitudes.buffer ? vk::bufferAddress(device, geometry.leafAltitudes) : 0,
                           glm::vec4(view.eye, view.perspective ? view.depthPerDistance : 0.0f),
                           view.footprint / float(mapSize),
                           view.areaLight ? thinLayers - 1 : ~0u,
                           view.clusterMask};
    kernel.push(cmd, push);
    vkCmdDispatch(cmd, dispatch.x, dispatch.y, 1);
    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW | kRectRead);
    kernel.bind(cmd, vk::Specialization{texels, local, PENUMBRA_THIN_DISPATCH, split});
    vkCmdDispatch(cmd, 1, 1, 1);
    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute | kIndirect, kStorageRW | kIndirectRead | kRectRead);
    kernel.bind(cmd, vk::Specialization{texels, local, PENUMBRA_THIN_FILL, split, 0u, affine}); // the fill decodes runs past the rectangles' capacity
    vkCmdDispatchIndirect(cmd, list.buffer, sizeof(uint32_t));
}

} // namespace penumbra::passes
