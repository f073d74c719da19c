#include "passes/thin_triangles.h"

#include "config.h"
#include "passes/pass.h"

namespace penumbra::passes {

void ThinTrianglesPass::create(vk::Device& device)
{
    kernel.create(device, "thin_triangles.comp", {vk::kStorageImage}, sizeof(ThinTrianglesPush));
}

void ThinTrianglesPass::destroy(vk::Device& device) { kernel.destroy(device); }

void ThinTrianglesPass::bind(vk::Device& device, const vk::Image& thinMap) { kernel.write(device, {vk::storageImage(thinMap.view)}); }

void clearThinMap(VkCommandBuffer cmd, const vk::Image& thinMap)
{
    VkClearColorValue far{};
    far.uint32[0] = 0x3F800000u;
    VkImageSubresourceRange range{VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, thinMap.layers};
    vkCmdClearColorImage(cmd, thinMap.image, VK_IMAGE_LAYOUT_GENERAL, &far, 1, &range);
}

void ThinTrianglesPass::clear(VkCommandBuffer cmd, const vk::Image& thinMap) const
{
    vk::memoryBarrier(cmd, kCompute, kStorageRead, kClear, kTransferWrite);
    clearThinMap(cmd, thinMap);
    vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute, kStorageRW);
}

void ThinTrianglesPass::record(VkCommandBuffer cmd, const vk::Device& device, const GpuGeometry& geometry, VkDeviceAddress modelTable,
                               uint32_t mapSize, uint32_t thinLayers, const ThinView& view) const
{
    kernel.bind(cmd);
    const uint32_t groups = std::max(groupCount(geometry.nodeCount, PENUMBRA_THIN_TRIANGLES_GROUP_SIZE), 1u);
    const Groups2D dispatch = spreadGroups(groups, device.properties.limits.maxComputeWorkGroupCount[0]);
    ThinTrianglesPush push{view.viewProj,
                           glm::vec2(float(mapSize)),
                           geometry.nodeCount,
                           view.layer,
                           modelTable,
                           geometry.leafAltitudes.buffer ? vk::bufferAddress(device, geometry.leafAltitudes) : 0,
                           glm::vec4(view.eye, view.perspective ? view.depthPerDistance : 0.0f),
                           view.footprint / float(mapSize),
                           view.areaLight ? thinLayers - 1 : ~0u,
                           view.clusterMask};
    kernel.push(cmd, push);
    vkCmdDispatch(cmd, dispatch.x, dispatch.y, 1);
}

} // namespace penumbra::passes
