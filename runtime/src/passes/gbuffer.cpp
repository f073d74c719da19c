#include "passes/gbuffer.h"

#include "frame_targets.h"
#include "passes/pass.h"

namespace penumbra::passes {

void GBufferPass::create(vk::Device& device)
{
    vk::GraphicsPipelineDesc desc;
    desc.vertexShader = "gbuffer.vert";
    desc.fragmentShader = "gbuffer.frag";
    desc.colorFormats = {kPositionFormat, kNormalFormat};
    desc.depthFormat = kDepthFormat;
    desc.pushBytes = sizeof(GBufferPush);
    pipelines.create(device, desc, VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT);
    desc.fragmentShader = "gbuffer.frag.outside";
    outsidePipelines.create(device, desc, VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT);
}

void GBufferPass::destroy(vk::Device& device)
{
    pipelines.destroy(device);
    outsidePipelines.destroy(device);
}

void GBufferPass::record(VkCommandBuffer cmd, Culling& culling, uint32_t view, const GpuGeometry& geometry, const GBufferTargets& t,
                         const GBufferPush& push) const
{
    using vk::transition;
    for (const vk::Image* image : {t.position, t.normal})
        transition(cmd, *image, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, kNone, 0, kColorOut,
                   VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT);
    transition(cmd, *t.depth, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL, kNone, 0, kDepthTests,
               VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);

    VkRenderingAttachmentInfo colors[2] = {{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO}, {VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO}};
    for (int i = 0; i < 2; ++i) {
        colors[i].imageView = i == 0 ? t.position->view : t.normal->view;
        colors[i].imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
        colors[i].storeOp = VK_ATTACHMENT_STORE_OP_STORE;
        colors[i].clearValue.color = {{0.0f, 0.0f, 0.0f, 0.0f}};
    }
    VkRenderingAttachmentInfo depthAttachment{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    depthAttachment.imageView = t.depth->view;
    depthAttachment.imageLayout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL;
    depthAttachment.storeOp = VK_ATTACHMENT_STORE_OP_STORE; // the culling's second phase loads it
    depthAttachment.clearValue.depthStencil = {1.0f, 0};
    VkRenderingInfo rendering{VK_STRUCTURE_TYPE_RENDERING_INFO};
    rendering.renderArea = {{0, 0}, {t.position->width, t.position->height}};
    rendering.layerCount = 1;
    rendering.colorAttachmentCount = 2;
    rendering.pColorAttachments = colors;
    rendering.pDepthAttachment = &depthAttachment;
    const vk::RasterPipelines& chosen = push.closedAddress ? outsidePipelines : pipelines;
    const VkPipeline pipeline = chosen[geometry.encoding];
    culling.recordView(cmd, view, geometry, [&](bool clear) {
        for (VkRenderingAttachmentInfo* attachment : {&colors[0], &colors[1], &depthAttachment})
            attachment->loadOp = clear ? VK_ATTACHMENT_LOAD_OP_CLEAR : VK_ATTACHMENT_LOAD_OP_LOAD;
        vkCmdBeginRendering(cmd, &rendering);
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline);
        vk::setViewport(cmd, t.position->width, t.position->height);
        vkCmdPushConstants(cmd, chosen.layout, VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0, sizeof(push), &push);
    }, [&] { vkCmdEndRendering(cmd); });

    for (const vk::Image* image : {t.position, t.normal})
        transition(cmd, *image, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL, kColorOut,
                   VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT, kCompute | kCopy, VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_TRANSFER_READ_BIT);
}

} // namespace penumbra::passes
