#include "passes/gbuffer.h"

#include "frame_targets.h"
#include "passes/pass.h"

namespace penumbra::passes {

void GBufferPass::create(vk::Device& device)
{
    vk::GraphicsPipelineDesc desc;
    desc.vertexShader = "gbuffer.vert";
    desc.depthFormat = kDepthFormat;
    desc.pushBytes = sizeof(GBufferPush);
    static const char* const names[2][2] = {{"gbuffer.frag", "gbuffer.frag.albedo"}, {"gbuffer.frag.outside", "gbuffer.frag.outside.albedo"}};
    for (int outside = 0; outside < 2; ++outside)
        for (int albedo = 0; albedo < 2; ++albedo) {
            desc.fragmentShader = names[outside][albedo];
            desc.colorFormats = albedo ? std::vector<VkFormat>{kSurfaceFormat, kAlbedoFormat} : std::vector<VkFormat>{kSurfaceFormat};
            pipelines[outside][albedo].create(device, desc, VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT);
        }
}

void GBufferPass::destroy(vk::Device& device)
{
    for (auto& row : pipelines)
        for (vk::RasterPipelines& set : row)
            set.destroy(device);
}

void GBufferPass::record(VkCommandBuffer cmd, Culling& culling, uint32_t view, const GpuGeometry& geometry, const GBufferTargets& t,
                         const GBufferPush& push) const
{
    using vk::transition;
    // The albedo is made ready even when not drawn: shade.comp's layout names it.
    for (const vk::Image* image : {t.surface, t.albedo})
        transition(cmd, *image, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, kNone, 0, kColorOut,
                   VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT);
    transition(cmd, *t.depth, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL, kNone, 0, kDepthTests,
               VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);

    VkRenderingAttachmentInfo colors[2] = {{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO}, {VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO}};
    for (int i = 0; i < 2; ++i) {
        colors[i].imageView = i == 0 ? t.surface->view : t.albedo->view;
        colors[i].imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
        colors[i].storeOp = VK_ATTACHMENT_STORE_OP_STORE;
        colors[i].clearValue.color = {}; // 0: the background (surface.glsli)
    }
    VkRenderingAttachmentInfo depthAttachment{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    depthAttachment.imageView = t.depth->view;
    depthAttachment.imageLayout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL;
    depthAttachment.storeOp = VK_ATTACHMENT_STORE_OP_STORE; // the culling's second phase loads it
    depthAttachment.clearValue.depthStencil = {1.0f, 0};
    VkRenderingInfo rendering{VK_STRUCTURE_TYPE_RENDERING_INFO};
    const bool albedo = push.albedoAddress != 0;
    rendering.renderArea = {{0, 0}, {t.surface->width, t.surface->height}};
    rendering.layerCount = 1;
    rendering.colorAttachmentCount = albedo ? 2 : 1;
    rendering.pColorAttachments = colors;
    rendering.pDepthAttachment = &depthAttachment;
    const vk::RasterPipelines& chosen = pipelines[push.closedAddress != 0][albedo];
    const VkPipeline pipeline = chosen[geometry.encoding];
    culling.recordView(cmd, view, geometry, [&](bool clear) {
        for (VkRenderingAttachmentInfo* attachment : {&colors[0], &colors[1], &depthAttachment})
            attachment->loadOp = clear ? VK_ATTACHMENT_LOAD_OP_CLEAR : VK_ATTACHMENT_LOAD_OP_LOAD;
        vkCmdBeginRendering(cmd, &rendering);
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline);
        vk::setViewport(cmd, t.surface->width, t.surface->height);
        vkCmdPushConstants(cmd, chosen.layout, VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0, sizeof(push), &push);
    }, [&] { vkCmdEndRendering(cmd); });

    for (const vk::Image* image : {t.surface, t.albedo})
        transition(cmd, *image, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL, kColorOut,
                   VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT, kCompute | kCopy, VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_TRANSFER_READ_BIT);
}

} // namespace penumbra::passes
