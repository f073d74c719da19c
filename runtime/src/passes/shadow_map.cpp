#include "passes/shadow_map.h"

#include "frame_targets.h"
#include "passes/pass.h"

namespace penumbra::passes {

void ShadowMapPass::create(vk::Device& device)
{
    vk::GraphicsPipelineDesc desc;
    desc.vertexShader = "shadow_map.vert";
    desc.depthFormat = kDepthFormat;
    desc.depthBias = true;
    desc.pushBytes = sizeof(ShadowMapPush);
    pipelines.create(device, desc, VK_SHADER_STAGE_VERTEX_BIT);
}

void ShadowMapPass::destroy(vk::Device& device) { pipelines.destroy(device); }

void ShadowMapPass::begin(VkCommandBuffer cmd, const vk::Image& shadowMap) const
{
    vk::transition(cmd, shadowMap, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL, kCompute, 0,
                   kDepthTests, VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);
}

void ShadowMapPass::end(VkCommandBuffer cmd, const vk::Image& shadowMap) const
{
    vk::transition(cmd, shadowMap, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, kDepthTests,
                   VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT, kCompute, VK_ACCESS_2_SHADER_SAMPLED_READ_BIT);
}

void ShadowMapPass::record(VkCommandBuffer cmd, Culling& culling, uint32_t view, const GpuGeometry& geometry, const vk::Image& shadowMap,
                           uint32_t layer, const ShadowMapPush& push, DepthBias bias) const
{
    VkRenderingAttachmentInfo depthAttachment{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    depthAttachment.imageView = shadowMap.layerViews[layer];
    depthAttachment.imageLayout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL;
    depthAttachment.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    depthAttachment.clearValue.depthStencil = {1.0f, 0};
    VkRenderingInfo rendering{VK_STRUCTURE_TYPE_RENDERING_INFO};
    rendering.renderArea = {{0, 0}, {shadowMap.width, shadowMap.height}};
    rendering.layerCount = 1;
    rendering.pDepthAttachment = &depthAttachment;
    const VkPipeline pipeline = pipelines[geometry.encoding];
    culling.recordView(cmd, view, geometry, [&](bool clear) {
        depthAttachment.loadOp = clear ? VK_ATTACHMENT_LOAD_OP_CLEAR : VK_ATTACHMENT_LOAD_OP_LOAD;
        vkCmdBeginRendering(cmd, &rendering);
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline);
        vk::setViewport(cmd, shadowMap.width, shadowMap.height);
        vkCmdSetDepthBias(cmd, bias.constant, 0.0f, bias.slope);
        vkCmdPushConstants(cmd, pipelines.layout, VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof(push), &push);
    }, [&] { vkCmdEndRendering(cmd); });
}

} // namespace penumbra::passes
