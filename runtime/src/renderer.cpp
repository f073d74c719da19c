// Renderer: camera G-buffer pass, per-light shadow-map pass with slope-scaled
// depth bias, compute shade pass, readback. One command buffer per frame.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <glm/gtc/matrix_transform.hpp>

#include "config.h"
#include "device.h"
#include "light_space.h"
#include "model_geometry.h"
#include "penumbra/preprocess.h"
#include "penumbra/penumbra.h"
#include "penumbra/shaders/registry.h"
#include "resources.h"

namespace penumbra {

namespace {

constexpr VkFormat kPositionFormat = VK_FORMAT_R32G32B32A32_SFLOAT;
constexpr VkFormat kNormalFormat = VK_FORMAT_R32G32B32A32_SFLOAT;
constexpr VkFormat kColorFormat = VK_FORMAT_R32G32B32A32_SFLOAT;
constexpr VkFormat kVisibilityFormat = VK_FORMAT_R32_SFLOAT;
constexpr VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT;
constexpr uint32_t kMaxTimestamps = 64;

// Named passes, in the order stats report them.
enum Pass : uint32_t { PassCamera, PassShadowMap, PassShade, PassReadback, PassCount };
constexpr const char* kPassNames[PassCount] = {"camera", "shadow_map", "shade", "readback"};

VkShaderModule createShaderModule(vk::Device& device, const char* name)
{
    for (const shaders::Embedded& shader : shaders::kAll)
        if (std::strcmp(shader.name, name) == 0) {
            VkShaderModuleCreateInfo info{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
            info.codeSize = shader.size;
            info.pCode = shader.code;
            VkShaderModule module;
            VK_CHECK(vkCreateShaderModule(device.device, &info, nullptr, &module));
            return module;
        }
    fail("shaders", std::string("no embedded shader named ") + name);
}

struct GraphicsPipelineDesc {
    std::string vertexShader;                 // registry name; ".float" is appended for the reference encoding
    const char* fragmentShader = nullptr;     // null: depth only
    std::vector<VkFormat> colorFormats;
    bool depthBias = false;
    bool depthAttachment = true;
    bool rasterizerDiscard = false;
    GeometryEncoding encoding = GeometryEncoding::Compressed;
    VkPipelineLayout layout = VK_NULL_HANDLE;
};

VkPipeline createGraphicsPipeline(vk::Device& device, const GraphicsPipelineDesc& desc)
{
    std::string vertexName = desc.vertexShader + (desc.encoding == GeometryEncoding::UncompressedReference ? ".float" : "");
    VkShaderModule vertex = createShaderModule(device, vertexName.c_str());
    VkShaderModule fragment = desc.fragmentShader ? createShaderModule(device, desc.fragmentShader) : VK_NULL_HANDLE;
    VkPipelineShaderStageCreateInfo stages[2] = {{VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO},
                                                 {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO}};
    stages[0].stage = VK_SHADER_STAGE_VERTEX_BIT;
    stages[0].module = vertex;
    stages[0].pName = "main";
    stages[1].stage = VK_SHADER_STAGE_FRAGMENT_BIT;
    stages[1].module = fragment;
    stages[1].pName = "main";

    GeometryInputState input = geometryInputState(desc.encoding);
    VkPipelineVertexInputStateCreateInfo vertexInput{VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
    vertexInput.vertexBindingDescriptionCount = input.bindingCount;
    vertexInput.pVertexBindingDescriptions = input.bindings;
    vertexInput.vertexAttributeDescriptionCount = input.attributeCount;
    vertexInput.pVertexAttributeDescriptions = input.attributes;

    VkPipelineInputAssemblyStateCreateInfo assembly{VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO};
    assembly.topology = input.topology;
    assembly.primitiveRestartEnable = input.primitiveRestart;
    VkPipelineViewportStateCreateInfo viewport{VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO};
    viewport.viewportCount = 1;
    viewport.scissorCount = 1;
    VkPipelineRasterizationStateCreateInfo raster{VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO};
    raster.polygonMode = VK_POLYGON_MODE_FILL;
    raster.cullMode = VK_CULL_MODE_NONE;   // CAD and scanned models are often open or two-sided
    raster.frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE;
    raster.depthBiasEnable = desc.depthBias;
    raster.rasterizerDiscardEnable = desc.rasterizerDiscard;
    raster.lineWidth = 1.0f;
    VkPipelineMultisampleStateCreateInfo multisample{VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO};
    multisample.rasterizationSamples = VK_SAMPLE_COUNT_1_BIT;
    VkPipelineDepthStencilStateCreateInfo depth{VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO};
    depth.depthTestEnable = VK_TRUE;
    depth.depthWriteEnable = VK_TRUE;
    depth.depthCompareOp = VK_COMPARE_OP_LESS_OR_EQUAL;
    std::vector<VkPipelineColorBlendAttachmentState> blends(desc.colorFormats.size());
    for (auto& blend : blends)
        blend.colorWriteMask = 0xf;
    VkPipelineColorBlendStateCreateInfo blend{VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO};
    blend.attachmentCount = uint32_t(blends.size());
    blend.pAttachments = blends.data();
    std::vector<VkDynamicState> dynamicStates = {VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR};
    if (desc.depthBias)
        dynamicStates.push_back(VK_DYNAMIC_STATE_DEPTH_BIAS);
    VkPipelineDynamicStateCreateInfo dynamic{VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO};
    dynamic.dynamicStateCount = uint32_t(dynamicStates.size());
    dynamic.pDynamicStates = dynamicStates.data();

    VkPipelineRenderingCreateInfo rendering{VK_STRUCTURE_TYPE_PIPELINE_RENDERING_CREATE_INFO};
    rendering.colorAttachmentCount = uint32_t(desc.colorFormats.size());
    rendering.pColorAttachmentFormats = desc.colorFormats.data();
    rendering.depthAttachmentFormat = desc.depthAttachment ? kDepthFormat : VK_FORMAT_UNDEFINED;

    VkGraphicsPipelineCreateInfo info{VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO, &rendering};
    info.stageCount = fragment ? 2 : 1;
    info.pStages = stages;
    info.pVertexInputState = &vertexInput;
    info.pInputAssemblyState = &assembly;
    info.pViewportState = &viewport;
    info.pRasterizationState = &raster;
    info.pMultisampleState = &multisample;
    info.pDepthStencilState = desc.depthAttachment ? &depth : nullptr;
    info.pColorBlendState = &blend;
    info.pDynamicState = &dynamic;
    info.layout = desc.layout;
    VkPipeline pipeline;
    VkResult result = vkCreateGraphicsPipelines(device.device, VK_NULL_HANDLE, 1, &info, nullptr, &pipeline);
    vkDestroyShaderModule(device.device, vertex, nullptr);
    if (fragment)
        vkDestroyShaderModule(device.device, fragment, nullptr);
    VK_CHECK(result);
    return pipeline;
}

VkPipelineLayout createPipelineLayout(vk::Device& device, VkDescriptorSetLayout setLayout, uint32_t pushBytes, VkShaderStageFlags stages)
{
    VkPushConstantRange range{stages, 0, pushBytes};
    VkPipelineLayoutCreateInfo info{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    info.setLayoutCount = setLayout ? 1 : 0;
    info.pSetLayouts = &setLayout;
    info.pushConstantRangeCount = 1;
    info.pPushConstantRanges = &range;
    VkPipelineLayout layout;
    VK_CHECK(vkCreatePipelineLayout(device.device, &info, nullptr, &layout));
    return layout;
}

struct CameraPush {
    glm::mat4 viewProj;
    glm::vec4 cameraPosition;
};

struct ShadePush {
    uint32_t lightIndex;
    uint32_t firstLight;
    uint32_t writeVisibility;
    uint32_t pad;
};

gpu::LightData packLight(const Light& light, const Bounds& bounds)
{
    gpu::LightData data{};
    uint32_t layers = lightViewProjections(light, bounds, data.viewProj);
    uint32_t type = 0;
    switch (light.type) {
    case LightType::Point: type = PENUMBRA_LIGHT_POINT; break;
    case LightType::Spot: type = PENUMBRA_LIGHT_SPOT; break;
    case LightType::Directional: type = PENUMBRA_LIGHT_DIRECTIONAL; break;
    // Area lights are point-shadowed from their centre until soft shadows land.
    case LightType::Rectangle: case LightType::Disk: case LightType::Sphere: type = PENUMBRA_LIGHT_POINT; break;
    }
    data.positionType = glm::vec4(light.position, float(type));
    glm::vec3 direction = glm::length(light.direction) > 0.0f ? glm::normalize(light.direction) : glm::vec3(0, -1, 0);
    data.directionRange = glm::vec4(direction, light.range);
    data.colorIntensity = glm::vec4(light.color, light.intensity);
    data.spotCosLayers = glm::vec4(std::cos(glm::radians(light.innerConeDegrees)), std::cos(glm::radians(light.outerConeDegrees)),
                                   float(layers), 0.0f);
    return data;
}

} // namespace

struct Renderer::Impl {
    vk::Device device;
    // Model
    GpuGeometry geometry;
    std::optional<Camera> camera;
    std::vector<Light> lights;
    // Pipelines
    VkDescriptorSetLayout shadeSetLayout = VK_NULL_HANDLE;
    VkPipelineLayout gbufferLayout = VK_NULL_HANDLE, shadowLayout = VK_NULL_HANDLE, shadeLayout = VK_NULL_HANDLE;
    // Raster pipelines per geometry encoding (index: GeometryEncoding).
    VkPipeline gbufferPipelines[2] = {}, shadowPipelines[2] = {};
    VkPipeline shadePipeline = VK_NULL_HANDLE;
    VkSampler nearestSampler = VK_NULL_HANDLE;
    VkDescriptorPool descriptorPool = VK_NULL_HANDLE;
    VkDescriptorSet shadeSet = VK_NULL_HANDLE;
    VkQueryPool queryPool = VK_NULL_HANDLE;
    VkCommandBuffer commandBuffer = VK_NULL_HANDLE;
    VkFence fence = VK_NULL_HANDLE;
    // Targets, recreated when the size changes
    uint32_t width = 0, height = 0, shadowSize = 0, shadowLayers = 0;
    vk::Image position, normal, depth, color, visibility, shadowMap;
    vk::Buffer frameUniforms, readbackColor, readbackPosition, readbackNormal, readbackVisibility;

    explicit Impl(const RendererOptions& options)
    {
        try {
            vk::createDevice(device, options);
            createPipelines();
        } catch (...) {
            destroy();
            throw;
        }
    }
    ~Impl() { destroy(); }

    void createPipelines()
    {
        VkDescriptorSetLayoutBinding bindings[6] = {
            {0, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr},
            {1, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr},
            {2, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr},
            {3, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr},
            {4, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr},
            {5, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr},
        };
        VkDescriptorSetLayoutCreateInfo setInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
        setInfo.bindingCount = 6;
        setInfo.pBindings = bindings;
        VK_CHECK(vkCreateDescriptorSetLayout(device.device, &setInfo, nullptr, &shadeSetLayout));

        gbufferLayout = createPipelineLayout(device, VK_NULL_HANDLE, sizeof(CameraPush), VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT);
        shadowLayout = createPipelineLayout(device, VK_NULL_HANDLE, sizeof(glm::mat4), VK_SHADER_STAGE_VERTEX_BIT);
        shadeLayout = createPipelineLayout(device, shadeSetLayout, sizeof(ShadePush), VK_SHADER_STAGE_COMPUTE_BIT);

        for (GeometryEncoding encoding : {GeometryEncoding::Compressed, GeometryEncoding::UncompressedReference}) {
            GraphicsPipelineDesc gbuffer;
            gbuffer.vertexShader = "gbuffer.vert";
            gbuffer.fragmentShader = "gbuffer.frag";
            gbuffer.colorFormats = {kPositionFormat, kNormalFormat};
            gbuffer.layout = gbufferLayout;
            gbuffer.encoding = encoding;
            gbufferPipelines[int(encoding)] = createGraphicsPipeline(device, gbuffer);

            GraphicsPipelineDesc shadow;
            shadow.vertexShader = "shadow_map.vert";
            shadow.depthBias = true;
            shadow.layout = shadowLayout;
            shadow.encoding = encoding;
            shadowPipelines[int(encoding)] = createGraphicsPipeline(device, shadow);
        }

        VkShaderModule shade = createShaderModule(device, "shade.comp");
        VkComputePipelineCreateInfo computeInfo{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
        computeInfo.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
        computeInfo.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
        computeInfo.stage.module = shade;
        computeInfo.stage.pName = "main";
        computeInfo.layout = shadeLayout;
        VkResult result = vkCreateComputePipelines(device.device, VK_NULL_HANDLE, 1, &computeInfo, nullptr, &shadePipeline);
        vkDestroyShaderModule(device.device, shade, nullptr);
        VK_CHECK(result);

        VkSamplerCreateInfo samplerInfo{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
        samplerInfo.magFilter = samplerInfo.minFilter = VK_FILTER_NEAREST;
        samplerInfo.addressModeU = samplerInfo.addressModeV = samplerInfo.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
        VK_CHECK(vkCreateSampler(device.device, &samplerInfo, nullptr, &nearestSampler));

        VkDescriptorPoolSize poolSizes[3] = {{VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 4},
                                             {VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1},
                                             {VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1}};
        VkDescriptorPoolCreateInfo poolInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
        poolInfo.maxSets = 1;
        poolInfo.poolSizeCount = 3;
        poolInfo.pPoolSizes = poolSizes;
        VK_CHECK(vkCreateDescriptorPool(device.device, &poolInfo, nullptr, &descriptorPool));
        VkDescriptorSetAllocateInfo allocInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
        allocInfo.descriptorPool = descriptorPool;
        allocInfo.descriptorSetCount = 1;
        allocInfo.pSetLayouts = &shadeSetLayout;
        VK_CHECK(vkAllocateDescriptorSets(device.device, &allocInfo, &shadeSet));

        VkQueryPoolCreateInfo queryInfo{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
        queryInfo.queryType = VK_QUERY_TYPE_TIMESTAMP;
        queryInfo.queryCount = kMaxTimestamps;
        VK_CHECK(vkCreateQueryPool(device.device, &queryInfo, nullptr, &queryPool));

        VkCommandBufferAllocateInfo cmdInfo{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
        cmdInfo.commandPool = device.commandPool;
        cmdInfo.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
        cmdInfo.commandBufferCount = 1;
        VK_CHECK(vkAllocateCommandBuffers(device.device, &cmdInfo, &commandBuffer));
        VkFenceCreateInfo fenceInfo{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
        VK_CHECK(vkCreateFence(device.device, &fenceInfo, nullptr, &fence));

        frameUniforms = vk::createBuffer(device, sizeof(gpu::FrameData), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, vk::MemoryUse::Upload);
    }

    void destroyTargets()
    {
        for (vk::Image* image : {&position, &normal, &depth, &color, &visibility})
            vk::destroyImage(device, *image);
        for (vk::Buffer* buffer : {&readbackColor, &readbackPosition, &readbackNormal, &readbackVisibility})
            vk::destroyBuffer(device, *buffer);
        width = height = 0;
    }

    void destroy()
    {
        if (!device.device) {
            vk::destroyDevice(device);
            return;
        }
        vkDeviceWaitIdle(device.device);
        destroyTargets();
        vk::destroyImage(device, shadowMap);
        destroyGeometry(device, geometry);
        vk::destroyBuffer(device, frameUniforms);
        VkDevice d = device.device;
        if (fence) vkDestroyFence(d, fence, nullptr);
        if (queryPool) vkDestroyQueryPool(d, queryPool, nullptr);
        if (descriptorPool) vkDestroyDescriptorPool(d, descriptorPool, nullptr);
        if (nearestSampler) vkDestroySampler(d, nearestSampler, nullptr);
        for (VkPipeline p : {gbufferPipelines[0], gbufferPipelines[1], shadowPipelines[0], shadowPipelines[1], shadePipeline})
            if (p) vkDestroyPipeline(d, p, nullptr);
        for (VkPipelineLayout l : {gbufferLayout, shadowLayout, shadeLayout})
            if (l) vkDestroyPipelineLayout(d, l, nullptr);
        if (shadeSetLayout) vkDestroyDescriptorSetLayout(d, shadeSetLayout, nullptr);
        vk::destroyDevice(device);
    }

    void ensureTargets(uint32_t w, uint32_t h, uint32_t smSize, uint32_t smLayers)
    {
        bool resized = w != width || h != height;
        bool shadowResized = smSize != shadowSize || smLayers != shadowLayers;
        if (!resized && !shadowResized)
            return;
        vkDeviceWaitIdle(device.device);
        if (resized) {
            destroyTargets();
            VkImageUsageFlags storage = VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
            position = vk::createImage(device, w, h, 1, kPositionFormat, VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | storage);
            normal = vk::createImage(device, w, h, 1, kNormalFormat, VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | storage);
            depth = vk::createImage(device, w, h, 1, kDepthFormat, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT);
            color = vk::createImage(device, w, h, 1, kColorFormat, storage);
            visibility = vk::createImage(device, w, h, 1, kVisibilityFormat, storage);
            VkBufferUsageFlags dst = VK_BUFFER_USAGE_TRANSFER_DST_BIT;
            readbackColor = vk::createBuffer(device, VkDeviceSize(w) * h * 16, dst, vk::MemoryUse::Readback);
            readbackPosition = vk::createBuffer(device, VkDeviceSize(w) * h * 16, dst, vk::MemoryUse::Readback);
            readbackNormal = vk::createBuffer(device, VkDeviceSize(w) * h * 16, dst, vk::MemoryUse::Readback);
            readbackVisibility = vk::createBuffer(device, VkDeviceSize(w) * h * 4, dst, vk::MemoryUse::Readback);
            width = w;
            height = h;
        }
        if (shadowResized) {
            vk::destroyImage(device, shadowMap);
            shadowMap = vk::createImage(device, smSize, smSize, smLayers, kDepthFormat,
                                        VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT);
            shadowSize = smSize;
            shadowLayers = smLayers;
        }
        VkDescriptorImageInfo images[5] = {
            {VK_NULL_HANDLE, position.view, VK_IMAGE_LAYOUT_GENERAL},
            {VK_NULL_HANDLE, normal.view, VK_IMAGE_LAYOUT_GENERAL},
            {nearestSampler, shadowMap.view, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL},
            {VK_NULL_HANDLE, color.view, VK_IMAGE_LAYOUT_GENERAL},
            {VK_NULL_HANDLE, visibility.view, VK_IMAGE_LAYOUT_GENERAL},
        };
        VkDescriptorBufferInfo uniforms{frameUniforms.buffer, 0, sizeof(gpu::FrameData)};
        VkWriteDescriptorSet writes[6];
        for (uint32_t i = 0; i < 6; ++i) {
            writes[i] = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
            writes[i].dstSet = shadeSet;
            writes[i].dstBinding = i;
            writes[i].descriptorCount = 1;
            writes[i].descriptorType = i == 2 ? VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER
                                       : i == 5 ? VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER
                                                : VK_DESCRIPTOR_TYPE_STORAGE_IMAGE;
            if (i < 5)
                writes[i].pImageInfo = &images[i];
            else
                writes[i].pBufferInfo = &uniforms;
        }
        vkUpdateDescriptorSets(device.device, 6, writes, 0, nullptr);
    }

    void setGeometry(GpuGeometry uploaded)
    {
        vkDeviceWaitIdle(device.device);
        destroyGeometry(device, geometry);
        geometry = std::move(uploaded);
    }

    std::vector<float> decodeVerticesOnGpu();

    static void setViewport(VkCommandBuffer cmd, uint32_t w, uint32_t h)
    {
        VkViewport viewport{0, 0, float(w), float(h), 0.0f, 1.0f};
        VkRect2D scissor{{0, 0}, {w, h}};
        vkCmdSetViewport(cmd, 0, 1, &viewport);
        vkCmdSetScissor(cmd, 0, 1, &scissor);
    }

    Frame render(const RenderSettings& settings);
};

Frame Renderer::Impl::render(const RenderSettings& settings)
{
    if (!geometry.triangles)
        fail("render", "no model loaded");
    const Bounds& bounds = geometry.bounds;
    if (settings.width == 0 || settings.height == 0 || settings.width > 16384 || settings.height > 16384)
        fail("render", "image size must be 1..16384 pixels per side");
    if (settings.shadowMapSize < 16 || settings.shadowMapSize > device.properties.limits.maxImageDimension2D)
        fail("render", "shadow-map size must be 16.." + std::to_string(device.properties.limits.maxImageDimension2D));
    auto cpuStart = std::chrono::steady_clock::now();

    std::vector<Light> frameLights = lights.empty() ? std::vector<Light>{defaultLight()} : lights;
    Camera frameCamera = camera ? *camera : defaultCamera(bounds);
    ViewProjection view = cameraViewProjection(frameCamera, bounds, float(settings.width) / float(settings.height));

    // Frame constants.
    gpu::FrameData frameData{};
    frameData.cameraPosition = glm::vec4(view.eye, 1.0f);
    frameData.shading = glm::vec4(settings.ambient, settings.albedo, 0.0f, 0.0f);
    frameData.background = glm::vec4(settings.background[0], settings.background[1], settings.background[2], 1.0f);
    uint32_t maxLayers = 1;
    for (size_t i = 0; i < frameLights.size(); ++i) {
        frameData.lights[i] = packLight(frameLights[i], bounds);
        maxLayers = std::max(maxLayers, uint32_t(frameData.lights[i].spotCosLayers.z));
    }
    ensureTargets(settings.width, settings.height, settings.shadowMapSize, maxLayers);
    std::memcpy(frameUniforms.mapped, &frameData, sizeof(frameData));

    VkCommandBuffer cmd = commandBuffer;
    VK_CHECK(vkResetCommandBuffer(cmd, 0));
    VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    VK_CHECK(vkBeginCommandBuffer(cmd, &begin));
    vkCmdResetQueryPool(cmd, queryPool, 0, kMaxTimestamps);

    std::vector<Pass> timestampPass;   // pass of the interval ending at timestamp i
    auto timestamp = [&](Pass endedPass) {
        timestampPass.push_back(endedPass);
        vkCmdWriteTimestamp2(cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, queryPool, uint32_t(timestampPass.size() - 1));
    };
    timestamp(PassCount);

    // Camera pass: G-buffer.
    using vk::transition;
    constexpr VkPipelineStageFlags2 kNone = VK_PIPELINE_STAGE_2_NONE;
    constexpr VkPipelineStageFlags2 kColorOut = VK_PIPELINE_STAGE_2_COLOR_ATTACHMENT_OUTPUT_BIT;
    constexpr VkPipelineStageFlags2 kDepthTests = VK_PIPELINE_STAGE_2_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_2_LATE_FRAGMENT_TESTS_BIT;
    constexpr VkPipelineStageFlags2 kCompute = VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT;
    constexpr VkPipelineStageFlags2 kCopy = VK_PIPELINE_STAGE_2_COPY_BIT;
    for (vk::Image* image : {&position, &normal})
        transition(cmd, *image, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, kNone, 0, kColorOut,
                   VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT);
    transition(cmd, depth, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL, kNone, 0, kDepthTests,
               VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);
    {
        VkRenderingAttachmentInfo colors[2] = {{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO},
                                               {VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO}};
        for (int i = 0; i < 2; ++i) {
            colors[i].imageView = i == 0 ? position.view : normal.view;
            colors[i].imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
            colors[i].loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
            colors[i].storeOp = VK_ATTACHMENT_STORE_OP_STORE;
            colors[i].clearValue.color = {{0.0f, 0.0f, 0.0f, 0.0f}};
        }
        VkRenderingAttachmentInfo depthAttachment{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
        depthAttachment.imageView = depth.view;
        depthAttachment.imageLayout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL;
        depthAttachment.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
        depthAttachment.storeOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
        depthAttachment.clearValue.depthStencil = {1.0f, 0};
        VkRenderingInfo rendering{VK_STRUCTURE_TYPE_RENDERING_INFO};
        rendering.renderArea = {{0, 0}, {width, height}};
        rendering.layerCount = 1;
        rendering.colorAttachmentCount = 2;
        rendering.pColorAttachments = colors;
        rendering.pDepthAttachment = &depthAttachment;
        vkCmdBeginRendering(cmd, &rendering);
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, gbufferPipelines[int(geometry.encoding)]);
        setViewport(cmd, width, height);
        CameraPush push{view.viewProj, glm::vec4(view.eye, 1.0f)};
        vkCmdPushConstants(cmd, gbufferLayout, VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0, sizeof(push), &push);
        drawGeometry(cmd, geometry);
        vkCmdEndRendering(cmd);
    }
    timestamp(PassCamera);
    for (vk::Image* image : {&position, &normal})
        transition(cmd, *image, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL, kColorOut,
                   VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT, kCompute | kCopy, VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_TRANSFER_READ_BIT);
    for (vk::Image* image : {&color, &visibility})
        transition(cmd, *image, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL, kNone, 0, kCompute,
                   VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);

    // Per light: shadow map (moving light: re-rendered every frame), then shade.
    VkImageLayout shadowMapLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    for (uint32_t lightIndex = 0; lightIndex < frameLights.size(); ++lightIndex) {
        const gpu::LightData& light = frameData.lights[lightIndex];
        uint32_t layers = uint32_t(light.spotCosLayers.z);
        transition(cmd, shadowMap, shadowMapLayout, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL, kCompute, 0, kDepthTests,
                   VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);
        for (uint32_t layer = 0; layer < layers; ++layer) {
            VkRenderingAttachmentInfo depthAttachment{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
            depthAttachment.imageView = shadowMap.layerViews[layer];
            depthAttachment.imageLayout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL;
            depthAttachment.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
            depthAttachment.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
            depthAttachment.clearValue.depthStencil = {1.0f, 0};
            VkRenderingInfo rendering{VK_STRUCTURE_TYPE_RENDERING_INFO};
            rendering.renderArea = {{0, 0}, {shadowSize, shadowSize}};
            rendering.layerCount = 1;
            rendering.pDepthAttachment = &depthAttachment;
            vkCmdBeginRendering(cmd, &rendering);
            vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, shadowPipelines[int(geometry.encoding)]);
            setViewport(cmd, shadowSize, shadowSize);
            vkCmdSetDepthBias(cmd, settings.depthBiasConstant, 0.0f, settings.depthBiasSlope);
            vkCmdPushConstants(cmd, shadowLayout, VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof(glm::mat4), &light.viewProj[layer]);
            drawGeometry(cmd, geometry);
            vkCmdEndRendering(cmd);
        }
        timestamp(PassShadowMap);
        transition(cmd, shadowMap, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, kDepthTests,
                   VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT, kCompute, VK_ACCESS_2_SHADER_SAMPLED_READ_BIT);
        shadowMapLayout = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;

        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, shadePipeline);
        vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, shadeLayout, 0, 1, &shadeSet, 0, nullptr);
        ShadePush push{lightIndex, lightIndex == 0 ? 1u : 0u, lightIndex == 0 ? 1u : 0u, 0u};
        vkCmdPushConstants(cmd, shadeLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
        vkCmdDispatch(cmd, (width + PENUMBRA_SHADE_GROUP_SIZE - 1) / PENUMBRA_SHADE_GROUP_SIZE,
                      (height + PENUMBRA_SHADE_GROUP_SIZE - 1) / PENUMBRA_SHADE_GROUP_SIZE, 1);
        // Next light's shade reads the accumulated colour.
        vk::memoryBarrier(cmd, kCompute, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, kCompute | kCopy,
                          VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT | VK_ACCESS_2_TRANSFER_READ_BIT);
        timestamp(PassShade);
    }

    // Readback.
    auto copyImage = [&](vk::Image& image, vk::Buffer& buffer) {
        transition(cmd, image, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, kCompute | kColorOut,
                   VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT | VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT, kCopy, VK_ACCESS_2_TRANSFER_READ_BIT);
        VkBufferImageCopy region{};
        region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
        region.imageExtent = {width, height, 1};
        vkCmdCopyImageToBuffer(cmd, image.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, buffer.buffer, 1, &region);
    };
    copyImage(color, readbackColor);
    if (settings.readbackGBuffer) {
        copyImage(position, readbackPosition);
        copyImage(normal, readbackNormal);
        copyImage(visibility, readbackVisibility);
    }
    vk::memoryBarrier(cmd, kCopy, VK_ACCESS_2_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_READ_BIT);
    timestamp(PassReadback);
    VK_CHECK(vkEndCommandBuffer(cmd));

    VkSubmitInfo submit{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    submit.commandBufferCount = 1;
    submit.pCommandBuffers = &cmd;
    VK_CHECK(vkResetFences(device.device, 1, &fence));
    VK_CHECK(vkQueueSubmit(device.queue, 1, &submit, fence));
    VK_CHECK(vkWaitForFences(device.device, 1, &fence, VK_TRUE, UINT64_MAX));

    Frame frame;
    frame.color.width = width;
    frame.color.height = height;
    size_t pixels = size_t(width) * height;
    frame.color.rgba.assign(static_cast<const float*>(readbackColor.mapped), static_cast<const float*>(readbackColor.mapped) + pixels * 4);
    if (settings.readbackGBuffer) {
        frame.positions.assign(static_cast<const float*>(readbackPosition.mapped),
                               static_cast<const float*>(readbackPosition.mapped) + pixels * 4);
        frame.normals.assign(static_cast<const float*>(readbackNormal.mapped),
                             static_cast<const float*>(readbackNormal.mapped) + pixels * 4);
        frame.visibility.assign(static_cast<const float*>(readbackVisibility.mapped),
                                static_cast<const float*>(readbackVisibility.mapped) + pixels);
    }

    // Timings.
    std::vector<uint64_t> ticks(timestampPass.size());
    VK_CHECK(vkGetQueryPoolResults(device.device, queryPool, 0, uint32_t(ticks.size()), ticks.size() * sizeof(uint64_t), ticks.data(),
                                   sizeof(uint64_t), VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
    double period = device.properties.limits.timestampPeriod * 1e-6; // ms per tick
    double passMs[PassCount] = {};
    for (size_t i = 1; i < ticks.size(); ++i)
        passMs[timestampPass[i]] += double(ticks[i] - ticks[i - 1]) * period;
    FrameStats& stats = frame.stats;
    stats.triangles = geometry.triangles;
    stats.width = width;
    stats.height = height;
    stats.lights = uint32_t(frameLights.size());
    stats.device = device.info;
    for (uint32_t pass = 0; pass < PassCount; ++pass)
        stats.passes.push_back({kPassNames[pass], passMs[pass]});
    stats.gpuMs = double(ticks.back() - ticks.front()) * period;
    stats.cpuMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - cpuStart).count();
    return frame;
}

std::vector<float> Renderer::Impl::decodeVerticesOnGpu()
{
    if (geometry.encoding != GeometryEncoding::Compressed || geometry.triangles == 0)
        fail("decode check", "no compressed model loaded");
    if (!device.vertexStores)
        fail("decode check", device.info.name + " lacks vertexPipelineStoresAndAtomics");
    VkDeviceSize bytes = geometry.vertexCount * 3 * sizeof(float);
    if (bytes > device.properties.limits.maxStorageBufferRange)
        fail("decode check", "model too large for one storage buffer");

    // Resources of this check only; created and destroyed here.
    VkDescriptorSetLayoutBinding binding{0, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_VERTEX_BIT, nullptr};
    VkDescriptorSetLayoutCreateInfo setInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    setInfo.bindingCount = 1;
    setInfo.pBindings = &binding;
    VkDescriptorSetLayout setLayout = VK_NULL_HANDLE;
    VkPipelineLayout layout = VK_NULL_HANDLE;
    VkPipeline pipeline = VK_NULL_HANDLE;
    VkDescriptorPool pool = VK_NULL_HANDLE;
    vk::Buffer output;
    auto cleanup = [&] {
        vk::destroyBuffer(device, output);
        if (pipeline) vkDestroyPipeline(device.device, pipeline, nullptr);
        if (layout) vkDestroyPipelineLayout(device.device, layout, nullptr);
        if (pool) vkDestroyDescriptorPool(device.device, pool, nullptr);
        if (setLayout) vkDestroyDescriptorSetLayout(device.device, setLayout, nullptr);
    };
    try {
        VK_CHECK(vkCreateDescriptorSetLayout(device.device, &setInfo, nullptr, &setLayout));
        layout = createPipelineLayout(device, setLayout, sizeof(uint32_t), VK_SHADER_STAGE_VERTEX_BIT);
        GraphicsPipelineDesc desc;
        desc.vertexShader = "decode_check.vert";
        desc.depthAttachment = false;
        desc.rasterizerDiscard = true;
        desc.layout = layout;
        pipeline = createGraphicsPipeline(device, desc);

        VkDescriptorPoolSize poolSize{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1};
        VkDescriptorPoolCreateInfo poolInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
        poolInfo.maxSets = 1;
        poolInfo.poolSizeCount = 1;
        poolInfo.pPoolSizes = &poolSize;
        VK_CHECK(vkCreateDescriptorPool(device.device, &poolInfo, nullptr, &pool));
        VkDescriptorSetAllocateInfo allocInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
        allocInfo.descriptorPool = pool;
        allocInfo.descriptorSetCount = 1;
        allocInfo.pSetLayouts = &setLayout;
        VkDescriptorSet set;
        VK_CHECK(vkAllocateDescriptorSets(device.device, &allocInfo, &set));
        output = vk::createBuffer(device, bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryUse::Readback);
        std::fill_n(static_cast<float*>(output.mapped), geometry.vertexCount * 3, std::numeric_limits<float>::quiet_NaN());
        VkDescriptorBufferInfo bufferInfo{output.buffer, 0, bytes};
        VkWriteDescriptorSet write{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
        write.dstSet = set;
        write.descriptorCount = 1;
        write.descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
        write.pBufferInfo = &bufferInfo;
        vkUpdateDescriptorSets(device.device, 1, &write, 0, nullptr);

        vk::immediateSubmit(device, [&](VkCommandBuffer cmd) {
            VkRenderingInfo rendering{VK_STRUCTURE_TYPE_RENDERING_INFO};
            rendering.renderArea = {{0, 0}, {1, 1}};
            rendering.layerCount = 1;
            vkCmdBeginRendering(cmd, &rendering);
            vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline);
            vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout, 0, 1, &set, 0, nullptr);
            setViewport(cmd, 1, 1);
            drawGeometry(cmd, geometry, [&](uint64_t vertexBase) {
                uint32_t base = uint32_t(vertexBase);
                vkCmdPushConstants(cmd, layout, VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof(base), &base);
            });
            vkCmdEndRendering(cmd);
            vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_VERTEX_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                              VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_READ_BIT);
        });
        const float* decoded = static_cast<const float*>(output.mapped);
        std::vector<float> result(decoded, decoded + geometry.vertexCount * 3);
        cleanup();
        return result;
    } catch (...) {
        cleanup();
        throw;
    }
}

Renderer::Renderer(const RendererOptions& options) : impl(std::make_unique<Impl>(options)) {}
Renderer::~Renderer() = default;

const DeviceInfo& Renderer::device() const { return impl->device.info; }

void Renderer::loadModel(const CompressedModel& model)
{
    impl->setGeometry(uploadCompressed(impl->device, model));
}

void Renderer::loadModel(const Mesh& mesh)
{
    if (mesh.triangleCount() == 0)
        fail("model", "has no triangles");
    loadModel(buildCompressedModel(mesh, PreprocessOptions{}));
}

void Renderer::loadUncompressedReference(const Mesh& mesh)
{
    impl->setGeometry(uploadReference(impl->device, mesh));
}

uint64_t Renderer::modelDeviceBytes() const { return impl->geometry.deviceBytes; }

std::vector<float> Renderer::decodeVerticesOnGpu() { return impl->decodeVerticesOnGpu(); }

void Renderer::setCamera(const Camera& camera) { impl->camera = camera; }

void Renderer::setLights(const std::vector<Light>& lights)
{
    if (lights.size() > PENUMBRA_MAX_LIGHTS)
        fail("lights", "at most " + std::to_string(PENUMBRA_MAX_LIGHTS) + " lights are supported, got " + std::to_string(lights.size()));
    impl->lights = lights;
}

Frame Renderer::render(const RenderSettings& settings) { return impl->render(settings); }

uint32_t Renderer::validationMessageCount() const { return impl->device.validationMessages.load(); }

std::vector<DeviceInfo> listDevices() { return vk::enumerateDevices(); }

uint32_t validationMessagesInProcess() { return vk::totalValidationMessages(); }

} // namespace penumbra
