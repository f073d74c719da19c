// Renderer: one command buffer per frame. Camera G-buffer pass, then per light:
// shadow map (slope-scaled depth bias), thin-triangle detection and thin map
// (srt), classify (shadow-map visibility, PIP marks), compaction and trace
// (srt/frt), shade; then readback. Area lights (soft shadows): per shadow map
// of the light, the map, thin triangles and the penumbra mask (srt), then
// classify_soft; compaction and the trace of the light samples; shade.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <glm/gtc/matrix_transform.hpp>

#include "config.h"
#include "culling.h"
#include "device.h"
#include "light_space.h"
#include "model_geometry.h"
#include "pipelines.h"
#include "penumbra/preprocess.h"
#include "penumbra/light_sampling.h"
#include "penumbra/penumbra.h"
#include "ray_tracer.h"
#include "resources.h"

namespace penumbra {

using vk::Binding;
using vk::createComputePipeline;
using vk::createPipelineLayout;
using vk::createSetLayout;
using vk::kSampled;
using vk::kStorage;
using vk::kStorageImage;
using vk::kUniform;
using vk::writeSet;

namespace {

constexpr VkFormat kPositionFormat = VK_FORMAT_R32G32B32A32_SFLOAT;
constexpr VkFormat kNormalFormat = VK_FORMAT_R32G32B32A32_SFLOAT;
constexpr VkFormat kColorFormat = VK_FORMAT_R32G32B32A32_SFLOAT;
constexpr VkFormat kVisibilityFormat = VK_FORMAT_R32_SFLOAT;
constexpr VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT;
constexpr VkFormat kThinFormat = VK_FORMAT_R32_UINT; // float bits of the nearest thin depth (imageAtomicMin)
constexpr uint32_t kMaxTimestamps = 256;

// Named passes, in the order stats report them.
enum Pass : uint32_t {
    PassCamera, PassViewFit, PassShadowMap, PassThinTriangles, PassPenumbraMask, PassClassify, PassCompact, PassTrace, PassShade,
    PassReadback, PassCount
};
constexpr const char* kPassNames[PassCount] = {"camera",   "view_fit", "shadow_map", "thin_triangles", "penumbra_mask", "classify",
                                               "compact",  "trace",    "shade",      "readback"};

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
    std::string vertexName =
        desc.vertexShader + (desc.encoding == GeometryEncoding::UncompressedReference ? ".float" : "");
    VkShaderModule vertex = vk::createShaderModule(device, vertexName.c_str());
    VkShaderModule fragment = desc.fragmentShader ? vk::createShaderModule(device, desc.fragmentShader) : VK_NULL_HANDLE;
    std::vector<VkPipelineShaderStageCreateInfo> stages;
    for (auto [stage, module] : {std::pair{VK_SHADER_STAGE_VERTEX_BIT, vertex}, std::pair{VK_SHADER_STAGE_FRAGMENT_BIT, fragment}})
        if (module) {
            VkPipelineShaderStageCreateInfo info{VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
            info.stage = stage;
            info.module = module;
            info.pName = "main";
            stages.push_back(info);
        }

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
    info.stageCount = uint32_t(stages.size());
    info.pStages = stages.data();
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
    for (VkShaderModule module : {vertex, fragment})
        if (module)
            vkDestroyShaderModule(device.device, module, nullptr);
    VK_CHECK(result);
    return pipeline;
}

struct CameraPush {
    glm::mat4 viewProj;
    glm::vec4 cameraPosition;
};

// Thin-triangle pass: thin_detect.comp writes the conservative rectangles of
// the thin triangles straight into the thin map with imageAtomicMin.
struct ThinDetectPush {
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
static_assert(sizeof(ThinDetectPush) == 128);

struct ViewBoundsPush {
    VkDeviceAddress keys; // view_bounds.comp.glsl
    VkDeviceAddress grid;
    uint32_t lightMask;
    uint32_t gridMask;
};

// viewBounds (readback): the keys of view_bounds.comp.glsl, then the receiver
// grid of each shadow-map layer (layer k of light l at 6 l + k).
constexpr VkDeviceSize kViewBoundsKeyBytes = PENUMBRA_MAX_LIGHTS * 6 * 8 * sizeof(uint32_t);
constexpr VkDeviceSize kReceiverGridBytes = PENUMBRA_RECEIVER_GRID_WORDS * sizeof(uint32_t);
constexpr VkDeviceSize kReceiverGridsBytes = PENUMBRA_MAX_LIGHTS * 6 * kReceiverGridBytes;

struct ClassifyPush {
    uint32_t lightIndex;
    uint32_t mode; // 0 sm, 1 srt, 2 frt
};

struct ClassifySoftPush {
    uint32_t lightIndex;
    uint32_t slot;
    uint32_t mode;   // 0 sm, 1 corner-map mask, 2 srt, 3 frt (classify_soft.comp.glsl)
    uint32_t first;
    float weight;
    uint32_t mapSize;
    uint32_t topLevel;
    uint32_t pad;
};

struct MaskPush {
    glm::mat4 invViewProj;
    uint32_t lightIndex;
    uint32_t slot;
    uint32_t level;
    uint32_t mapSize;
    uint32_t topLevel;
    uint32_t useThin;
    float edgeDelta;
    uint32_t maxJobs;
};
static_assert(sizeof(MaskPush) == 96);
constexpr uint32_t kMaskWriteDispatch = 0xFFFFFFFEu, kMaskSplatJobs = 0xFFFFFFFFu; // MaskPush::level of the last two passes

// Levels of the penumbra mask over an S x S map: 0 .. top, where the level is 1 texel.
uint32_t maskTopLevel(uint32_t size)
{
    uint32_t top = 0;
    while (((size + (1u << top) - 1u) >> top) > 1u)
        ++top;
    return top;
}

// Texels of levels 0 .. top together.
uint64_t maskTexels(uint32_t size)
{
    uint64_t total = 0;
    for (uint32_t level = 0; level <= maskTopLevel(size); ++level) {
        uint64_t side = (uint64_t(size) + (1u << level) - 1u) >> level;
        total += side * side;
    }
    return total;
}

struct CompactPush {
    uint32_t pixelCount;
    uint32_t phase;
};

struct ShadePush {
    uint32_t lightIndex;
    uint32_t firstLight;
    uint32_t debugPip;
    uint32_t pad;
};

// Area lights: the points their shadow maps are taken from. srt: the centre,
// then (penumbraMaps 5) four points on the rim: the rectangle's corners, the
// ends of the disk's axes, or of the sphere's axes across the map direction.
// frt: the centre (its map is not drawn). sm: the centres of K strata of the
// light (penumbra/light_sampling.h), seen from the middle of the scene.
std::vector<glm::vec3> areaMapEyes(const Light& light, glm::vec3 axis, const Bounds& bounds, const RenderSettings& settings)
{
    glm::vec3 u, v;
    areaLightAxes(light, u, v);
    if (light.type == LightType::Sphere) {
        glm::vec3 side = std::abs(axis.x) < 0.9f ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0);
        u = glm::normalize(glm::cross(axis, side)) * light.radius;
        v = glm::normalize(glm::cross(axis, u)) * light.radius;
    }
    std::vector<glm::vec3> eyes;
    if (settings.shadows == ShadowMethod::ShadowMap) {
        glm::vec3 su, sv;
        areaLightAxes(light, su, sv);
        uint32_t k = settings.softShadowMaps;
        uint32_t columns = uint32_t(std::ceil(std::sqrt(float(k))));
        uint32_t rows = (k + columns - 1) / columns;
        for (uint32_t i = 0; i < k; ++i) {
            glm::vec2 cell((float(i % columns) + 0.5f) / float(columns), (float(i / columns) + 0.5f) / float(rows));
            eyes.push_back(sampling::areaLightPoint(uint32_t(light.type == LightType::Rectangle ? PENUMBRA_LIGHT_RECTANGLE
                                                             : light.type == LightType::Disk ? PENUMBRA_LIGHT_DISK
                                                                                              : PENUMBRA_LIGHT_SPHERE),
                                                    light.position, su, sv, bounds.center(), cell));
        }
        return eyes;
    }
    eyes.push_back(light.position);
    if (settings.shadows == ShadowMethod::Selective && settings.penumbraMaps == 5) {
        if (light.type == LightType::Rectangle)
            for (glm::vec2 c : {glm::vec2(1, 1), glm::vec2(-1, 1), glm::vec2(-1, -1), glm::vec2(1, -1)})
                eyes.push_back(light.position + c.x * u + c.y * v);
        else
            for (glm::vec3 d : {u, -u, v, -v})
                eyes.push_back(light.position + d);
    }
    return eyes;
}

// Bounds of the camera's visible points in the clip space of one model-fitted
// shadow map (view_bounds.comp.glsl); not valid: the map stays model-fitted.
struct ViewClip {
    bool valid = false;
    glm::vec3 min{0.0f}, max{0.0f};
};

// viewClip (RenderSettings::fitShadowMapsToView): per map of the light (a
// directional light's one, an area light's spotCosLayers.w), the bounds its
// map is fitted to.
gpu::LightData packLight(const Light& light, const Bounds& bounds, const RenderSettings& settings, const ViewClip* viewClip = nullptr)
{
    gpu::LightData data{};
    if (isAreaLight(light)) {
        glm::vec3 u, v;
        areaLightAxes(light, u, v);
        bool oneSided = light.type != LightType::Sphere;
        float radius = light.type == LightType::Rectangle ? glm::length(u + v) : light.radius;
        data.areaU = glm::vec4(u, oneSided ? 1.0f : 0.0f);
        data.areaV = glm::vec4(v, radius);
        glm::vec3 axis = oneSided ? glm::normalize(light.direction) : bounds.center() - light.position;
        axis = glm::length(axis) > 0.0f ? glm::normalize(axis) : glm::vec3(0, -1, 0);
        std::vector<glm::vec3> eyes = areaMapEyes(light, axis, bounds, settings);
        for (size_t k = 0; k < eyes.size(); ++k) {
            AreaMapProjection map = areaMapProjection(eyes[k], axis, light.up, bounds);
            if (viewClip && viewClip[k].valid) {
                // srt: an occluder beside the visible points throws penumbra onto them from
                // light points up to Rbig off the eye (penumbra_mask.comp.glsl), so the map
                // widens by that angle seen from the nearest geometry.
                float spreadTan = 0.0f;
                if (settings.shadows == ShadowMethod::Selective) {
                    const float rBig = glm::length(light.position - eyes[k]) + data.areaV.w;
                    const float nearest = glm::length(glm::clamp(eyes[k], bounds.min, bounds.max) - eyes[k]);
                    const float sine = nearest > 0.0f ? 1.05f * rBig / nearest : 1.0f;
                    spreadTan = sine < 0.9f ? sine / std::sqrt(1.0f - sine * sine) : -1.0f; // -1: too near, stays model-fitted
                }
                map = fitAreaMapToView(map, eyes[k], light.up, bounds, glm::vec2(viewClip[k].min), glm::vec2(viewClip[k].max), spreadTan,
                                       settings.shadowMapSize);
            }
            data.viewProj[k] = map.viewProj;
            data.mapEye[k] = glm::vec4(eyes[k], map.nearPlane);
            data.mapRange[k] = glm::vec4(map.farPlane, map.footprint, map.capped ? 1.0f : 0.0f, 0.0f);
            if (k == 0)
                data.shadowParams = glm::vec4(map.nearPlane, map.farPlane, 1.0f, map.footprint);
        }
        data.spotCosLayers = glm::vec4(1.0f, 1.0f, 1.0f, float(eyes.size()));
    } else {
        LightProjection projection = lightProjection(light, bounds);
        const float modelFootprint = projection.footprint;
        if (viewClip && viewClip[0].valid)
            projection = fitDirectionalToView(projection, viewClip[0].min, viewClip[0].max, settings.shadowMapSize);
        std::copy(std::begin(projection.viewProj), std::end(projection.viewProj), std::begin(data.viewProj));
        data.shadowParams = glm::vec4(projection.nearPlane, projection.farPlane, projection.perspective ? 1.0f : 0.0f, projection.footprint);
        data.spotCosLayers = glm::vec4(std::cos(glm::radians(light.innerConeDegrees)), std::cos(glm::radians(light.outerConeDegrees)),
                                       float(projection.layers), projection.footprint / modelFootprint);
    }
    uint32_t type = 0;
    switch (light.type) {
    case LightType::Point: type = PENUMBRA_LIGHT_POINT; break;
    case LightType::Spot: type = PENUMBRA_LIGHT_SPOT; break;
    case LightType::Directional: type = PENUMBRA_LIGHT_DIRECTIONAL; break;
    case LightType::Rectangle: type = PENUMBRA_LIGHT_RECTANGLE; break;
    case LightType::Disk: type = PENUMBRA_LIGHT_DISK; break;
    case LightType::Sphere: type = PENUMBRA_LIGHT_SPHERE; break;
    }
    data.positionType = glm::vec4(light.position, float(type));
    glm::vec3 direction = glm::length(light.direction) > 0.0f ? glm::normalize(light.direction) : glm::vec3(0, -1, 0);
    data.directionRange = glm::vec4(direction, light.range);
    data.colorIntensity = glm::vec4(light.color, light.intensity);
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
    VkDescriptorSetLayout classifySetLayout = VK_NULL_HANDLE, compactSetLayout = VK_NULL_HANDLE, shadeSetLayout = VK_NULL_HANDLE;
    VkDescriptorSetLayout thinDetectSetLayout = VK_NULL_HANDLE, maskSetLayout = VK_NULL_HANDLE;
    VkPipelineLayout classifySoftLayout = VK_NULL_HANDLE, maskLayout = VK_NULL_HANDLE;
    VkPipeline classifySoftPipeline = VK_NULL_HANDLE, maskPipeline = VK_NULL_HANDLE;
    VkDescriptorSet maskSet = VK_NULL_HANDLE;
    VkPipelineLayout gbufferLayout = VK_NULL_HANDLE, shadowLayout = VK_NULL_HANDLE;
    VkPipelineLayout classifyLayout = VK_NULL_HANDLE, compactLayout = VK_NULL_HANDLE, shadeLayout = VK_NULL_HANDLE;
    VkPipelineLayout thinDetectLayout = VK_NULL_HANDLE;
    // Raster pipelines per geometry encoding (index: GeometryEncoding).
    VkPipeline gbufferPipelines[2] = {}, shadowPipelines[2] = {};
    VkPipeline thinDetectPipeline = VK_NULL_HANDLE;
    VkPipeline classifyPipeline = VK_NULL_HANDLE, compactPipeline = VK_NULL_HANDLE, shadePipeline = VK_NULL_HANDLE;
    VkPipelineLayout viewBoundsLayout = VK_NULL_HANDLE;
    VkPipeline viewBoundsPipeline = VK_NULL_HANDLE;
    RayTracer tracer;
    // Raster culling: the camera's view, and the shadow maps' views (planned
    // later in the frame, once directional maps are fitted to the view).
    Culling culling, shadowCulling;
    VkSampler nearestSampler = VK_NULL_HANDLE;
    VkDescriptorPool descriptorPool = VK_NULL_HANDLE;
    VkDescriptorSet classifySet = VK_NULL_HANDLE, compactSet = VK_NULL_HANDLE, shadeSet = VK_NULL_HANDLE, thinDetectSet = VK_NULL_HANDLE;
    VkQueryPool queryPool = VK_NULL_HANDLE;
    VkCommandBuffer commandBuffer = VK_NULL_HANDLE;
    VkFence fence = VK_NULL_HANDLE;
    // Targets, recreated when the size changes
    uint32_t width = 0, height = 0, shadowSize = 0, shadowLayers = 0;
    vk::Image position, normal, depth, color, visibility, shadowMap, thinMap;
    vk::Buffer frameUniforms, stats, readbackStats, marks, rayList;
    vk::Buffer viewBounds; // view_bounds.comp.glsl: light-space bounds of the G-buffer, read before the shadow pass
    vk::Buffer receiverGrids; // view_bounds.comp.glsl: per light, its receiver grid (device-local; copied into viewBounds)
    vk::Buffer thinClusterMasks; // srt: per light layer, the clusters the thin-triangle pass decodes (host-written each frame)
    // Per shadow-map size (penumbra_mask.comp.glsl): penumbra mask, nearest-edge pyramid, deepest camera pixel per tile.
    vk::Buffer penumbraMask, penumbraThinMask, penumbraPyramid, penumbraReceivers, penumbraJobs;
    uint32_t penumbraMaxJobs = 0;
    vk::Buffer readbackColor, readbackPosition, readbackNormal, readbackVisibility;

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
        const VkShaderStageFlags compute = VK_SHADER_STAGE_COMPUTE_BIT;
        classifySetLayout = createSetLayout(device, {kStorageImage, kStorageImage, kSampled, kStorageImage, kStorageImage, kUniform, kStorage, kStorage, kStorage, kStorage, kStorage}, compute);
        maskSetLayout = createSetLayout(device, {kSampled, kStorageImage, kUniform, kStorage, kStorage, kStorage, kStorage, kStorage}, compute);
        thinDetectSetLayout = createSetLayout(device, {kStorageImage}, compute);
        compactSetLayout = createSetLayout(device, {kStorage, kStorage}, compute);
        shadeSetLayout = createSetLayout(device, {kStorageImage, kStorageImage, kStorageImage, kStorageImage, kUniform, kStorage, kStorage}, compute);

        gbufferLayout = createPipelineLayout(device, VK_NULL_HANDLE, sizeof(CameraPush), VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT);
        shadowLayout = createPipelineLayout(device, VK_NULL_HANDLE, sizeof(glm::mat4), VK_SHADER_STAGE_VERTEX_BIT);
        thinDetectLayout = createPipelineLayout(device, thinDetectSetLayout, sizeof(ThinDetectPush), compute);
        classifyLayout = createPipelineLayout(device, classifySetLayout, sizeof(ClassifyPush), compute);
        viewBoundsLayout = createPipelineLayout(device, classifySetLayout, sizeof(ViewBoundsPush), compute);
        classifySoftLayout = createPipelineLayout(device, classifySetLayout, sizeof(ClassifySoftPush), compute);
        maskLayout = createPipelineLayout(device, maskSetLayout, sizeof(MaskPush), compute);
        compactLayout = createPipelineLayout(device, compactSetLayout, sizeof(CompactPush), compute);
        shadeLayout = createPipelineLayout(device, shadeSetLayout, sizeof(ShadePush), compute);

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
        thinDetectPipeline = createComputePipeline(device, "thin_detect.comp", thinDetectLayout);
        classifyPipeline = createComputePipeline(device, "classify.comp", classifyLayout);
        viewBoundsPipeline = createComputePipeline(device, "view_bounds.comp", viewBoundsLayout);
        classifySoftPipeline = createComputePipeline(device, "classify_soft.comp", classifySoftLayout);
        maskPipeline = createComputePipeline(device, "penumbra_mask.comp", maskLayout);
        compactPipeline = createComputePipeline(device, "compact.comp", compactLayout);
        shadePipeline = createComputePipeline(device, "shade.comp", shadeLayout);
        createRayTracer(device, tracer);
        culling.create(device, {kPositionFormat, kNormalFormat}, kDepthFormat);
        shadowCulling.create(device, {kPositionFormat, kNormalFormat}, kDepthFormat);

        VkSamplerCreateInfo samplerInfo{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
        samplerInfo.magFilter = samplerInfo.minFilter = VK_FILTER_NEAREST;
        samplerInfo.addressModeU = samplerInfo.addressModeV = samplerInfo.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
        VK_CHECK(vkCreateSampler(device.device, &samplerInfo, nullptr, &nearestSampler));

        VkDescriptorPoolSize poolSizes[4] = {{kStorageImage, 20}, {kSampled, 4}, {kUniform, 4}, {kStorage, 16}};
        VkDescriptorPoolCreateInfo poolInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
        poolInfo.maxSets = 5;
        poolInfo.poolSizeCount = 4;
        poolInfo.pPoolSizes = poolSizes;
        VK_CHECK(vkCreateDescriptorPool(device.device, &poolInfo, nullptr, &descriptorPool));
        VkDescriptorSetLayout layouts[5] = {classifySetLayout, compactSetLayout, shadeSetLayout, thinDetectSetLayout, maskSetLayout};
        VkDescriptorSet sets[5];
        VkDescriptorSetAllocateInfo allocInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
        allocInfo.descriptorPool = descriptorPool;
        allocInfo.descriptorSetCount = 5;
        allocInfo.pSetLayouts = layouts;
        VK_CHECK(vkAllocateDescriptorSets(device.device, &allocInfo, sets));
        classifySet = sets[0];
        compactSet = sets[1];
        shadeSet = sets[2];
        thinDetectSet = sets[3];
        maskSet = sets[4];

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
        // Counters stay in device memory (GPU atomics) and are copied out once per frame.
        stats = vk::createBuffer(device, PENUMBRA_STAT_COUNT * sizeof(uint64_t),
                                 VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                                 vk::MemoryUse::DeviceLocal);
        readbackStats = vk::createBuffer(device, PENUMBRA_STAT_COUNT * sizeof(uint64_t), VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                         vk::MemoryUse::Readback);
        viewBounds = vk::createBuffer(device, kViewBoundsKeyBytes + kReceiverGridsBytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                      vk::MemoryUse::Readback, vk::Addressable::Yes);
        receiverGrids = vk::createBuffer(device, kReceiverGridsBytes,
                                         VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT, vk::MemoryUse::DeviceLocal,
                                         vk::Addressable::Yes);
    }

    void destroyTargets()
    {
        for (vk::Image* image : {&position, &normal, &depth, &color, &visibility})
            vk::destroyImage(device, *image);
        for (vk::Buffer* buffer : {&marks, &rayList, &readbackColor, &readbackPosition, &readbackNormal, &readbackVisibility})
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
        vk::destroyImage(device, thinMap);
        vk::destroyBuffer(device, penumbraMask);
        vk::destroyBuffer(device, penumbraThinMask);
        vk::destroyBuffer(device, penumbraPyramid);
        vk::destroyBuffer(device, penumbraReceivers);
        vk::destroyBuffer(device, penumbraJobs);
        destroyGeometry(device, geometry);
        destroyRayTracer(device, tracer);
        culling.destroy(device);
        shadowCulling.destroy(device);
        vk::destroyBuffer(device, viewBounds);
        vk::destroyBuffer(device, receiverGrids);
        vk::destroyBuffer(device, thinClusterMasks);
        vk::destroyBuffer(device, frameUniforms);
        vk::destroyBuffer(device, stats);
        vk::destroyBuffer(device, readbackStats);
        VkDevice d = device.device;
        if (fence) vkDestroyFence(d, fence, nullptr);
        if (queryPool) vkDestroyQueryPool(d, queryPool, nullptr);
        if (descriptorPool) vkDestroyDescriptorPool(d, descriptorPool, nullptr);
        if (nearestSampler) vkDestroySampler(d, nearestSampler, nullptr);
        for (VkPipeline p : {gbufferPipelines[0], gbufferPipelines[1], shadowPipelines[0], shadowPipelines[1],
                             thinDetectPipeline, classifyPipeline, compactPipeline, shadePipeline, classifySoftPipeline, maskPipeline,
                             viewBoundsPipeline})
            if (p) vkDestroyPipeline(d, p, nullptr);
        for (VkPipelineLayout l : {gbufferLayout, shadowLayout, thinDetectLayout, classifyLayout, compactLayout, shadeLayout,
                                   classifySoftLayout, maskLayout, viewBoundsLayout})
            if (l) vkDestroyPipelineLayout(d, l, nullptr);
        for (VkDescriptorSetLayout l : {classifySetLayout, compactSetLayout, shadeSetLayout, thinDetectSetLayout, maskSetLayout})
            if (l) vkDestroyDescriptorSetLayout(d, l, nullptr);
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
            VkDeviceSize pixels = VkDeviceSize(w) * h;
            marks = vk::createBuffer(device, pixels * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                     vk::MemoryUse::DeviceLocal);
            rayList = vk::createBuffer(device, (PENUMBRA_RAY_LIST_HEADER_UINTS + pixels) * 4,
                                       VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                       vk::MemoryUse::DeviceLocal);
            VkBufferUsageFlags dst = VK_BUFFER_USAGE_TRANSFER_DST_BIT;
            readbackColor = vk::createBuffer(device, pixels * 16, dst, vk::MemoryUse::Readback);
            readbackPosition = vk::createBuffer(device, pixels * 16, dst, vk::MemoryUse::Readback);
            readbackNormal = vk::createBuffer(device, pixels * 16, dst, vk::MemoryUse::Readback);
            readbackVisibility = vk::createBuffer(device, pixels * 4, dst, vk::MemoryUse::Readback);
            width = w;
            height = h;
        }
        if (shadowResized) {
            vk::destroyImage(device, shadowMap);
            vk::destroyImage(device, thinMap);
            vk::destroyBuffer(device, penumbraMask);
            vk::destroyBuffer(device, penumbraThinMask);
            vk::destroyBuffer(device, penumbraPyramid);
            vk::destroyBuffer(device, penumbraReceivers);
            vk::destroyBuffer(device, penumbraJobs);
            shadowSize = shadowLayers = 0; // stays 0 if a creation below throws
            uint64_t maskLevels = maskTexels(smSize);
            // Two masks and two pyramids: depth discontinuities' splats and thin triangles' (penumbra_mask.glsli).
            penumbraMask = vk::createBuffer(device, (1 + maskLevels) * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                            vk::MemoryUse::DeviceLocal);
            penumbraThinMask = vk::createBuffer(device, maskLevels * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                                vk::MemoryUse::DeviceLocal);
            penumbraPyramid = vk::createBuffer(device, std::max<uint64_t>(maskLevels - uint64_t(smSize) * smSize, 1) * 2 * 4,
                                               VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryUse::DeviceLocal);
            uint64_t tiles = (smSize + PENUMBRA_RECEIVER_TILE - 1) / PENUMBRA_RECEIVER_TILE;
            penumbraReceivers = vk::createBuffer(device, 2 * tiles * tiles * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                                 vk::MemoryUse::DeviceLocal);
            // Splat jobs: at most two per texel of all levels (one per edge kind), 8 bytes each, within one storage binding.
            uint64_t bindingJobs = (std::min<uint64_t>(device.properties.limits.maxStorageBufferRange, device.maxAllocationSize) - 16) / 8;
            penumbraMaxJobs = uint32_t(std::min<uint64_t>({2 * maskLevels, bindingJobs, 1u << 26}));
            penumbraJobs = vk::createBuffer(device, 16 + uint64_t(penumbraMaxJobs) * 8,
                                            VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                            vk::MemoryUse::DeviceLocal);
            shadowMap = vk::createImage(device, smSize, smSize, smLayers, kDepthFormat,
                                        VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT, true);
            // The thin map stays in GENERAL: written in srt frames, read (cleared to "nothing thin") otherwise.
            // Layers: per shadow-map layer the slivers' nearest depths, then one of per-texel depths for
            // the penumbra mask of an area light (thin_detect.comp.glsl).
            thinMap = vk::createImage(device, smSize, smSize, smLayers + 1, kThinFormat,
                                      VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT, true);
            vk::immediateSubmit(device, [&](VkCommandBuffer cmd) {
                vk::transition(cmd, shadowMap, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_PIPELINE_STAGE_2_NONE, 0,
                               VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_SAMPLED_READ_BIT);
                vk::transition(cmd, thinMap, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL, VK_PIPELINE_STAGE_2_NONE, 0,
                               VK_PIPELINE_STAGE_2_CLEAR_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT);
                clearThinMap(cmd);
                vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_CLEAR_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                                  VK_ACCESS_2_SHADER_STORAGE_READ_BIT);
            });
            shadowSize = smSize;
            shadowLayers = smLayers;
        }
        writeSet(device, classifySet, {{kStorageImage, position.view}, {kStorageImage, normal.view},
                                       {kSampled, shadowMap.view, nearestSampler, {}, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL},
                                       {kStorageImage, thinMap.view},
                                       {kStorageImage, visibility.view}, {kUniform, {}, {}, frameUniforms.buffer},
                                       {kStorage, {}, {}, marks.buffer}, {kStorage, {}, {}, stats.buffer},
                                       {kStorage, {}, {}, penumbraMask.buffer, {}, storageRange(penumbraMask)},
                                       {kStorage, {}, {}, penumbraReceivers.buffer},
                                       {kStorage, {}, {}, penumbraThinMask.buffer, {}, storageRange(penumbraThinMask)}});
        writeSet(device, thinDetectSet, {{kStorageImage, thinMap.view}});
        writeSet(device, maskSet, {{kSampled, shadowMap.view, nearestSampler, {}, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL},
                                   {kStorageImage, thinMap.view}, {kUniform, {}, {}, frameUniforms.buffer},
                                   {kStorage, {}, {}, penumbraPyramid.buffer, {}, storageRange(penumbraPyramid)},
                                   {kStorage, {}, {}, penumbraMask.buffer, {}, storageRange(penumbraMask)},
                                   {kStorage, {}, {}, penumbraReceivers.buffer}, {kStorage, {}, {}, penumbraJobs.buffer},
                                   {kStorage, {}, {}, penumbraThinMask.buffer, {}, storageRange(penumbraThinMask)}});
        writeSet(device, compactSet, {{kStorage, {}, {}, marks.buffer}, {kStorage, {}, {}, rayList.buffer}});
        writeSet(device, shadeSet, {{kStorageImage, position.view}, {kStorageImage, normal.view}, {kStorageImage, color.view},
                                    {kStorageImage, visibility.view}, {kUniform, {}, {}, frameUniforms.buffer},
                                    {kStorage, {}, {}, marks.buffer}, {kStorage, {}, {}, stats.buffer}});
        TraceBindings trace;
        trace.position = position.view;
        trace.normal = normal.view;
        trace.visibility = visibility.view;
        trace.frameUniforms = frameUniforms.buffer;
        trace.rayList = rayList.buffer;
        trace.stats = stats.buffer;
        bindRayTracerTargets(device, tracer, trace);
    }

    // A storage binding of the whole buffer, or of as much as the device allows
    // (render() refuses the frames that would need more).
    VkDeviceSize storageRange(const vk::Buffer& buffer) const
    {
        return std::min<VkDeviceSize>(buffer.size, device.properties.limits.maxStorageBufferRange);
    }

    // Every layer of the thin map to "nothing thin": the bits of 1.0f (the far plane).
    void clearThinMap(VkCommandBuffer cmd)
    {
        VkClearColorValue far{};
        far.uint32[0] = 0x3F800000u;
        VkImageSubresourceRange range{VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, thinMap.layers};
        vkCmdClearColorImage(cmd, thinMap.image, VK_IMAGE_LAYOUT_GENERAL, &far, 1, &range);
    }

    void setGeometry(GpuGeometry uploaded)
    {
        vkDeviceWaitIdle(device.device);
        destroyGeometry(device, geometry);
        geometry = std::move(uploaded);
        tracer.modelTableAddress = 0;
        if (geometry.encoding == GeometryEncoding::Compressed)
            bindRayTracerModel(device, tracer, geometry);
    }

    std::vector<float> decodeVerticesOnGpu();

    static void setViewport(VkCommandBuffer cmd, uint32_t w, uint32_t h)
    {
        VkViewport viewport{0, 0, float(w), float(h), 0.0f, 1.0f};
        VkRect2D scissor{{0, 0}, {w, h}};
        vkCmdSetViewport(cmd, 0, 1, &viewport);
        vkCmdSetScissor(cmd, 0, 1, &scissor);
    }

    // Submits the frame's command buffer and waits for it (the frame's fence).
    void submitAndWait(VkCommandBuffer cmd)
    {
        VkSubmitInfo submit{VK_STRUCTURE_TYPE_SUBMIT_INFO};
        submit.commandBufferCount = 1;
        submit.pCommandBuffers = &cmd;
        VK_CHECK(vkResetFences(device.device, 1, &fence));
        VK_CHECK(vkQueueSubmit(device.queue, 1, &submit, fence));
        VK_CHECK(vkWaitForFences(device.device, 1, &fence, VK_TRUE, UINT64_MAX));
    }

    Frame render(const RenderSettings& settings);
};

Frame Renderer::Impl::render(const RenderSettings& settings)
{
    if (!geometry.triangles)
        fail("render", "no model loaded");
    if (settings.width == 0 || settings.height == 0 || settings.width > 16384 || settings.height > 16384)
        fail("render", "image size must be 1..16384 pixels per side");
    if (settings.shadowMapSize < 16 || settings.shadowMapSize > device.properties.limits.maxImageDimension2D)
        fail("render", "shadow-map size must be 16.." + std::to_string(device.properties.limits.maxImageDimension2D));
    const VkDeviceSize pixelBytes = VkDeviceSize(settings.width) * settings.height * 16;
    if (pixelBytes > device.maxAllocationSize || pixelBytes / 4 + 16 > device.properties.limits.maxStorageBufferRange)
        fail("render", std::to_string(settings.width) + "x" + std::to_string(settings.height) +
                           " exceeds this device's buffer limits (one RGBA32F image must fit one allocation and the ray list one storage binding)");
    if (settings.lightSamples < 4 || settings.lightSamples > PENUMBRA_MAX_SAMPLES)
        fail("render", "light samples must be 4.." + std::to_string(PENUMBRA_MAX_SAMPLES));
    if (settings.penumbraMaps != 1 && settings.penumbraMaps != 5)
        fail("render", "penumbra maps must be 1 (the light's centre) or 5 (centre and corners)");
    if (settings.softShadowMaps < 1 || settings.softShadowMaps > 6)
        fail("render", "soft shadow maps (sm) must be 1..6");
    // srt soft shadows bind a penumbra mask of every level of the map (4/3 x 4 bytes per texel) as one storage buffer.
    const uint64_t maskBytes = (1 + maskTexels(settings.shadowMapSize)) * 4;
    if (settings.shadows == ShadowMethod::Selective && maskBytes > device.properties.limits.maxStorageBufferRange &&
        std::any_of(lights.begin(), lights.end(), [](const Light& l) { return isAreaLight(l); })) {
        uint32_t largest = settings.shadowMapSize;
        while (largest > 16 && (1 + maskTexels(largest)) * 4 > device.properties.limits.maxStorageBufferRange)
            largest /= 2;
        fail("render", "shadow-map size " + std::to_string(settings.shadowMapSize) + " is too large for srt soft shadows on this device: the penumbra mask (" +
                           std::to_string(maskBytes >> 20) + " MiB) exceeds its storage-buffer limit (" +
                           std::to_string(device.properties.limits.maxStorageBufferRange >> 20) + " MiB); use " + std::to_string(largest) +
                           " or less");
    }
    if (settings.shadows != ShadowMethod::ShadowMap && geometry.encoding != GeometryEncoding::Compressed)
        fail("render", "ray-traced shadows need the compressed model (the uncompressed reference is for raster benchmarks)");
    auto cpuStart = std::chrono::steady_clock::now();
    const Bounds& bounds = geometry.bounds;
    const bool traced = settings.shadows != ShadowMethod::ShadowMap;
    const bool selective = settings.shadows == ShadowMethod::Selective;
    const float rayOffset = settings.rayOffset > 0.0f ? settings.rayOffset : shadowRayOffset(bounds, geometry.maxPositionError);

    std::vector<Light> frameLights = lights.empty() ? std::vector<Light>{defaultLight()} : lights;
    Camera frameCamera = camera ? *camera : defaultCamera(bounds);
    ViewProjection view = cameraViewProjection(frameCamera, bounds, float(settings.width) / float(settings.height));

    // Frame constants.
    gpu::FrameData frameData{};
    frameData.cameraPosition = glm::vec4(view.eye, 1.0f);
    frameData.shading = glm::vec4(settings.ambient, settings.albedo, 0.0f, 0.0f);
    frameData.background = glm::vec4(settings.background[0], settings.background[1], settings.background[2], 1.0f);
    frameData.pip = glm::vec4(float(PENUMBRA_PIP_DELTA_FRACTION), 0.0f, 0.0f, 0.0f);
    uint32_t maxLayers = 1;
    for (size_t i = 0; i < frameLights.size(); ++i) {
        frameData.lights[i] = packLight(frameLights[i], bounds, settings);
        maxLayers = std::max(maxLayers, uint32_t(frameData.lights[i].spotCosLayers.z));
    }
    ensureTargets(settings.width, settings.height, settings.shadowMapSize, maxLayers);
    std::memcpy(frameUniforms.mapped, &frameData, sizeof(frameData));

    // Raster views planned by the culling: the camera's now; every light's
    // shadow-map layers once the directional maps are fitted to the view.
    culling.beginFrame(device, settings.cull, settings.adaptiveOcclusion, {{"camera", 0, view.viewProj, true, true}});
    std::vector<uint32_t> lightFirstView(frameLights.size());
    std::vector<std::shared_ptr<const ReceiverMask>> receiverMasks(6 * frameLights.size()); // layer k of light i at 6 i + k
    std::vector<VkDeviceAddress> thinClusterMask(6 * frameLights.size(), 0);              // the same layers; 0: every cluster
    auto planShadowViews = [&] {
        std::vector<CullView> cullViews;
        const bool shadowOcclusion = settings.depthBiasConstant >= 0.0f && settings.depthBiasSlope >= 0.0f;
        for (uint32_t i = 0; i < frameLights.size(); ++i) {
            lightFirstView[i] = uint32_t(cullViews.size());
            // Shadow maps drawn for the light: its layers, or an area light's maps (none for soft frt).
            const bool area = isAreaLight(frameLights[i]);
            const uint32_t maps = area ? (settings.shadows == ShadowMethod::FullRayTrace ? 0u : uint32_t(frameData.lights[i].spotCosLayers.w))
                                       : uint32_t(frameData.lights[i].spotCosLayers.z);
            for (uint32_t k = 0; k < maps; ++k)
                cullViews.push_back({"light" + std::to_string(i) + (maps > 1 ? (area ? ".map" : ".face") + std::to_string(k) : ""),
                                     1 + 6 * i + k, frameData.lights[i].viewProj[k], false, shadowOcclusion,
                                     area ? nullptr : receiverMasks[6 * i + k]});
        }
        shadowCulling.beginFrame(device, settings.cull, settings.adaptiveOcclusion, std::move(cullViews));
    };
    // Lights whose maps are fitted to what the camera sees: directional lights,
    // and area lights whose maps are drawn (not soft frt).
    uint32_t viewFitMask = 0;
    if (settings.fitShadowMapsToView)
        for (uint32_t i = 0; i < frameLights.size(); ++i)
            if (frameLights[i].type == LightType::Directional ||
                (isAreaLight(frameLights[i]) && settings.shadows != ShadowMethod::FullRayTrace))
                viewFitMask |= 1u << i;
    // Lights whose shadow views cull the casters beside the points the camera
    // sees (receiver grids, read back with the fit): every light but area lights.
    uint32_t receiverGridMask = 0;
    if (settings.cullBesideReceivers && settings.cull != CullMode::None && geometry.encoding == GeometryEncoding::Compressed)
        for (uint32_t i = 0; i < frameLights.size(); ++i)
            if (!isAreaLight(frameLights[i]))
                receiverGridMask |= 1u << i;
    const bool readBack = viewFitMask || receiverGridMask;
    if (!readBack)
        planShadowViews();

    VkCommandBuffer cmd = commandBuffer;
    VK_CHECK(vkResetCommandBuffer(cmd, 0));
    VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    VK_CHECK(vkBeginCommandBuffer(cmd, &begin));
    vkCmdResetQueryPool(cmd, queryPool, 0, kMaxTimestamps);
    culling.resetQueries(cmd);
    if (!readBack)
        shadowCulling.resetQueries(cmd);

    std::vector<Pass> timestampPass;   // pass of the interval ending at timestamp i
    auto timestamp = [&](Pass endedPass) {
        if (timestampPass.size() >= kMaxTimestamps)
            fail("render", "too many timestamps");
        timestampPass.push_back(endedPass);
        vkCmdWriteTimestamp2(cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, queryPool, uint32_t(timestampPass.size() - 1));
    };
    timestamp(PassCount);

    using vk::transition;
    constexpr VkPipelineStageFlags2 kNone = VK_PIPELINE_STAGE_2_NONE;
    constexpr VkPipelineStageFlags2 kColorOut = VK_PIPELINE_STAGE_2_COLOR_ATTACHMENT_OUTPUT_BIT;
    constexpr VkPipelineStageFlags2 kDepthTests = VK_PIPELINE_STAGE_2_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_2_LATE_FRAGMENT_TESTS_BIT;
    constexpr VkPipelineStageFlags2 kCompute = VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT;
    constexpr VkPipelineStageFlags2 kCopy = VK_PIPELINE_STAGE_2_COPY_BIT;
    constexpr VkPipelineStageFlags2 kClear = VK_PIPELINE_STAGE_2_CLEAR_BIT;
    constexpr VkAccessFlags2 kStorageRW = VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT;

    vkCmdFillBuffer(cmd, stats.buffer, 0, VK_WHOLE_SIZE, 0);
    vk::memoryBarrier(cmd, kClear, VK_ACCESS_2_TRANSFER_WRITE_BIT, kCompute, kStorageRW);

    // Camera pass: G-buffer.
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
            colors[i].storeOp = VK_ATTACHMENT_STORE_OP_STORE;
            colors[i].clearValue.color = {{0.0f, 0.0f, 0.0f, 0.0f}};
        }
        VkRenderingAttachmentInfo depthAttachment{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
        depthAttachment.imageView = depth.view;
        depthAttachment.imageLayout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL;
        depthAttachment.storeOp = VK_ATTACHMENT_STORE_OP_STORE; // the culling's second phase loads it
        depthAttachment.clearValue.depthStencil = {1.0f, 0};
        VkRenderingInfo rendering{VK_STRUCTURE_TYPE_RENDERING_INFO};
        rendering.renderArea = {{0, 0}, {width, height}};
        rendering.layerCount = 1;
        rendering.colorAttachmentCount = 2;
        rendering.pColorAttachments = colors;
        rendering.pDepthAttachment = &depthAttachment;
        CameraPush push{view.viewProj, glm::vec4(view.eye, 1.0f)};
        culling.recordView(cmd, 0, geometry, [&](bool clear) {
            for (VkRenderingAttachmentInfo* attachment : {&colors[0], &colors[1], &depthAttachment})
                attachment->loadOp = clear ? VK_ATTACHMENT_LOAD_OP_CLEAR : VK_ATTACHMENT_LOAD_OP_LOAD;
            vkCmdBeginRendering(cmd, &rendering);
            vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, gbufferPipelines[int(geometry.encoding)]);
            setViewport(cmd, width, height);
            vkCmdPushConstants(cmd, gbufferLayout, VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0, sizeof(push), &push);
        }, [&] { vkCmdEndRendering(cmd); });
    }
    timestamp(PassCamera);
    for (vk::Image* image : {&position, &normal})
        transition(cmd, *image, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL, kColorOut,
                   VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT, kCompute | kCopy, VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_TRANSFER_READ_BIT);
    for (vk::Image* image : {&color, &visibility})
        transition(cmd, *image, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL, kNone, 0, kCompute, kStorageRW);

    if (readBack) {
        // Fit the directional and area maps to the view: the light-space bounds
        // of the G-buffer, read back here (the frame's one extra submission),
        // narrow each map before its views are planned and drawn; and where the
        // camera's points lie in each map (receiver grids) for the culling.
        auto gridRegion = [&](uint32_t i) { // light i's grids: one per layer
            return std::pair<VkDeviceSize, VkDeviceSize>{6 * i * kReceiverGridBytes,
                                                         uint32_t(frameData.lights[i].spotCosLayers.z) * kReceiverGridBytes};
        };
        vkCmdFillBuffer(cmd, viewBounds.buffer, 0, kViewBoundsKeyBytes, ~0u);
        for (uint32_t i = 0; i < frameLights.size(); ++i)
            if (receiverGridMask & (1u << i))
                vkCmdFillBuffer(cmd, receiverGrids.buffer, gridRegion(i).first, gridRegion(i).second, 0u);
        vk::memoryBarrier(cmd, kClear, VK_ACCESS_2_TRANSFER_WRITE_BIT, kCompute, kStorageRW);
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, viewBoundsPipeline);
        vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, viewBoundsLayout, 0, 1, &classifySet, 0, nullptr);
        ViewBoundsPush push{vk::bufferAddress(device, viewBounds), vk::bufferAddress(device, receiverGrids), viewFitMask,
                            receiverGridMask};
        vkCmdPushConstants(cmd, viewBoundsLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
        const uint32_t tile = PENUMBRA_SHADE_GROUP_SIZE * 4; // view_bounds.comp.glsl: VIEW_BOUNDS_BLOCK pixels per invocation
        vkCmdDispatch(cmd, (width + tile - 1) / tile, (height + tile - 1) / tile, 1);
        if (receiverGridMask) {
            // The grids are written with many atomics: in device memory, then copied out.
            vk::memoryBarrier(cmd, kCompute, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, kCopy, VK_ACCESS_2_TRANSFER_READ_BIT);
            for (uint32_t i = 0; i < frameLights.size(); ++i)
                if (receiverGridMask & (1u << i)) {
                    VkBufferCopy region{gridRegion(i).first, kViewBoundsKeyBytes + gridRegion(i).first, gridRegion(i).second};
                    vkCmdCopyBuffer(cmd, receiverGrids.buffer, viewBounds.buffer, 1, &region);
                }
        }
        vk::memoryBarrier(cmd, kCompute | kCopy, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT | VK_ACCESS_2_TRANSFER_WRITE_BIT,
                          VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_READ_BIT);
        VK_CHECK(vkEndCommandBuffer(cmd));
        submitAndWait(cmd);

        // Keys back to floats (view_bounds.comp.glsl): min x, y, z, then -max x, y, z, then the behind flag.
        const uint32_t* keys = static_cast<const uint32_t*>(viewBounds.mapped);
        auto fromKey = [](uint32_t key) {
            uint32_t bits = key & 0x80000000u ? key & 0x7FFFFFFFu : ~key;
            float f;
            std::memcpy(&f, &bits, sizeof(f));
            return f;
        };
        const uint32_t* grids = keys + kViewBoundsKeyBytes / sizeof(uint32_t);
        for (uint32_t i = 0; i < frameLights.size(); ++i) {
            const glm::mat4 gridViewProj = frameData.lights[i].viewProj[0]; // a directional light's model-fitted map
            if (viewFitMask & (1u << i)) {
                ViewClip clip[6];
                for (uint32_t map = 0; map < 6; ++map) {
                    const uint32_t* k = keys + 8 * (6 * i + map);
                    // Nothing covered, or a pixel behind a perspective map's eye: the model-fitted map stays.
                    clip[map].valid = k[0] != ~0u && k[6] == ~0u;
                    clip[map].min = {fromKey(k[0]), fromKey(k[1]), fromKey(k[2])};
                    clip[map].max = {-fromKey(k[3]), -fromKey(k[4]), -fromKey(k[5])};
                }
                frameData.lights[i] = packLight(frameLights[i], bounds, settings, clip);
            }
            if (!(receiverGridMask & (1u << i)))
                continue;
            for (uint32_t layer = 0; layer < uint32_t(frameData.lights[i].spotCosLayers.z); ++layer) {
                // Margin: 2 texels of the map drawn (the classification reads the
                // 3x3 texels around a point's), in the grid's clip units; a
                // directional map fitted to the view is the grid's map scaled and
                // shifted in x and y.
                auto mask = std::make_shared<ReceiverMask>();
                mask->viewProj = glm::dmat4(layer == 0 ? gridViewProj : frameData.lights[i].viewProj[layer]);
                const glm::dmat4 toDrawn = glm::dmat4(frameData.lights[i].viewProj[layer]) * glm::inverse(mask->viewProj);
                const glm::dvec2 drawnPerGrid(std::abs(toDrawn[0][0]), std::abs(toDrawn[1][1]));
                mask->margin = 2.0 * (2.0 / double(shadowSize)) / drawnPerGrid + 1e-5;
                mask->build(grids + (6 * i + layer) * PENUMBRA_RECEIVER_GRID_WORDS, PENUMBRA_RECEIVER_GRID);
                receiverMasks[6 * i + layer] = std::move(mask);
            }
        }
        if (selective && receiverGridMask) {
            // The clusters whose thin triangles may reach a receiver's texel, per light layer.
            const size_t words = (shadowCulling.model->clusterMin.size() + 31) / 32;
            const VkDeviceSize bytes = 6 * frameLights.size() * words * sizeof(uint32_t);
            if (thinClusterMasks.size < bytes) {
                vk::destroyBuffer(device, thinClusterMasks);
                thinClusterMasks = vk::createBuffer(device, bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryUse::Upload,
                                                    vk::Addressable::Yes);
            }
            auto* bits = static_cast<uint32_t*>(thinClusterMasks.mapped);
            std::memset(bits, 0, bytes);
            const VkDeviceAddress base = vk::bufferAddress(device, thinClusterMasks);
            for (size_t l = 0; l < receiverMasks.size(); ++l)
                if (receiverMasks[l]) {
                    shadowCulling.markClustersNearReceivers(*receiverMasks[l], bits + l * words);
                    thinClusterMask[l] = base + l * words * sizeof(uint32_t);
                }
        }
        std::memcpy(frameUniforms.mapped, &frameData, sizeof(frameData));
        planShadowViews();

        VK_CHECK(vkResetCommandBuffer(cmd, 0));
        VK_CHECK(vkBeginCommandBuffer(cmd, &begin));
        shadowCulling.resetQueries(cmd);
        timestamp(PassViewFit); // the interval includes the round trip through the host
    }

    const uint32_t groupsX = (width + PENUMBRA_SHADE_GROUP_SIZE - 1) / PENUMBRA_SHADE_GROUP_SIZE;
    const uint32_t groupsY = (height + PENUMBRA_SHADE_GROUP_SIZE - 1) / PENUMBRA_SHADE_GROUP_SIZE;
    const uint32_t pixelCount = width * height;
    // Lights in reverse order, so that the visibility image ends with light 0's (readback).
    // Draws the model into shadow-map layer `layer` from viewProj.
    // Draws the model into shadow-map layer `layer` from viewProj, culled as raster view `cullView`.
    auto drawShadowMap = [&](const glm::mat4& viewProj, uint32_t layer, uint32_t cullView) {
        VkRenderingAttachmentInfo depthAttachment{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
        depthAttachment.imageView = shadowMap.layerViews[layer];
        depthAttachment.imageLayout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL;
        depthAttachment.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
        depthAttachment.clearValue.depthStencil = {1.0f, 0};
        VkRenderingInfo rendering{VK_STRUCTURE_TYPE_RENDERING_INFO};
        rendering.renderArea = {{0, 0}, {shadowSize, shadowSize}};
        rendering.layerCount = 1;
        rendering.pDepthAttachment = &depthAttachment;
        shadowCulling.recordView(cmd, cullView, geometry, [&](bool clear) {
            depthAttachment.loadOp = clear ? VK_ATTACHMENT_LOAD_OP_CLEAR : VK_ATTACHMENT_LOAD_OP_LOAD;
            vkCmdBeginRendering(cmd, &rendering);
            vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, shadowPipelines[int(geometry.encoding)]);
            setViewport(cmd, shadowSize, shadowSize);
            vkCmdSetDepthBias(cmd, settings.depthBiasConstant, 0.0f, settings.depthBiasSlope);
            vkCmdPushConstants(cmd, shadowLayout, VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof(glm::mat4), &viewProj);
        }, [&] { vkCmdEndRendering(cmd); });
    };
    auto beginShadowMaps = [&] {
        transition(cmd, shadowMap, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL, kCompute, 0,
                   kDepthTests, VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);
    };
    auto endShadowMaps = [&] {
        transition(cmd, shadowMap, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, kDepthTests,
                   VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT, kCompute, VK_ACCESS_2_SHADER_SAMPLED_READ_BIT);
        timestamp(PassShadowMap);
    };
    // Thin triangles, rasterized conservatively (srt only): a compute pass over
    // the model's leaves writes the nearest depth of the thin triangles'
    // conservative rectangles into layer `layer` of the thin map. Texel size at
    // depth z: orthographic footprint / size; perspective footprint * z / size,
    // with z >= distance * depthPerDistance (the cosine of half the frustum's
    // diagonal angle: 1/sqrt(3) for cube faces, cos(outer) for spots).
    auto detectThinTriangles = [&](const glm::mat4& viewProj, uint32_t layer, glm::vec3 eye, bool perspective, float depthPerDistance,
                                   float footprint, VkDeviceAddress clusterMask, bool areaLight) {
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, thinDetectPipeline);
        vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, thinDetectLayout, 0, 1, &thinDetectSet, 0, nullptr);
        const uint32_t detectGroups =
            std::max((geometry.nodeCount + PENUMBRA_THIN_DETECT_GROUP_SIZE - 1) / PENUMBRA_THIN_DETECT_GROUP_SIZE, 1u);
        const uint32_t maxGroupsX = device.properties.limits.maxComputeWorkGroupCount[0];
        const uint32_t groupsXDetect = std::min(detectGroups, maxGroupsX), groupsYDetect = (detectGroups + groupsXDetect - 1) / groupsXDetect;
        ThinDetectPush detect{viewProj,
                              glm::vec2(float(shadowSize)),
                              geometry.nodeCount,
                              layer,
                              tracer.modelTableAddress,
                              geometry.leafAltitudes.buffer ? vk::bufferAddress(device, geometry.leafAltitudes) : 0,
                              glm::vec4(eye, perspective ? depthPerDistance : 0.0f),
                              footprint / float(shadowSize),
                              areaLight ? thinMap.layers - 1 : ~0u,
                              clusterMask};
        vkCmdPushConstants(cmd, thinDetectLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(detect), &detect);
        vkCmdDispatch(cmd, groupsXDetect, groupsYDetect, 1);
    };
    auto clearThin = [&] {
        vk::memoryBarrier(cmd, kCompute, VK_ACCESS_2_SHADER_STORAGE_READ_BIT, kClear, VK_ACCESS_2_TRANSFER_WRITE_BIT);
        clearThinMap(cmd);
        vk::memoryBarrier(cmd, kClear, VK_ACCESS_2_TRANSFER_WRITE_BIT, kCompute, kStorageRW);
    };
    // Compaction into a dense ray list, the indirect dispatch size, and the trace.
    auto compactAndTrace = [&](uint32_t lightIndex, uint32_t samples) {
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, compactPipeline);
        vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, compactLayout, 0, 1, &compactSet, 0, nullptr);
        CompactPush compact{pixelCount, 0};
        vkCmdPushConstants(cmd, compactLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(compact), &compact);
        const uint32_t groups = (pixelCount + PENUMBRA_COMPACT_GROUP_SIZE - 1) / PENUMBRA_COMPACT_GROUP_SIZE;
        const uint32_t groupsPerRow = std::min(groups, 65535u);
        vkCmdDispatch(cmd, groupsPerRow, (groups + groupsPerRow - 1) / groupsPerRow, 1);
        vk::memoryBarrier(cmd, kCompute, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, kCompute, kStorageRW);
        compact.phase = 1;
        vkCmdPushConstants(cmd, compactLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(compact), &compact);
        vkCmdDispatch(cmd, 1, 1, 1);
        vk::memoryBarrier(cmd, kCompute, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, kCompute | VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT,
                          kStorageRW | VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT);
        timestamp(PassCompact);

        recordTrace(cmd, tracer, lightIndex, rayOffset, samples);
        vk::memoryBarrier(cmd, kCompute, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, kCompute, kStorageRW);
        timestamp(PassTrace);
    };
    const uint32_t maskTop = maskTopLevel(shadowSize);
    auto classifySoft = [&](uint32_t lightIndex, uint32_t slot, uint32_t mode, bool first, float weight) {
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, classifySoftPipeline);
        vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, classifySoftLayout, 0, 1, &classifySet, 0, nullptr);
        ClassifySoftPush push{lightIndex, slot, mode, first ? 1u : 0u, weight, shadowSize, maskTop, 0};
        vkCmdPushConstants(cmd, classifySoftLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
        vkCmdDispatch(cmd, groupsX, groupsY, 1);
        vk::memoryBarrier(cmd, kCompute, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, kCompute, kStorageRW);
    };
    // Penumbra mask of map `slot` of an area light (penumbra_mask.comp.glsl): the
    // edge pass, then one reduction per level.
    auto buildPenumbraMask = [&](uint32_t lightIndex, uint32_t slot, bool useThin) {
        const gpu::LightData& light = frameData.lights[lightIndex];
        vk::memoryBarrier(cmd, kCompute, VK_ACCESS_2_SHADER_STORAGE_READ_BIT, kClear, VK_ACCESS_2_TRANSFER_WRITE_BIT);
        vkCmdFillBuffer(cmd, penumbraMask.buffer, 0, 4, 0);
        vkCmdFillBuffer(cmd, penumbraMask.buffer, 4, VK_WHOLE_SIZE, 0x7F800000u); // +inf: no receiver depth reached
        vkCmdFillBuffer(cmd, penumbraThinMask.buffer, 0, VK_WHOLE_SIZE, 0x7F800000u);
        vkCmdFillBuffer(cmd, penumbraReceivers.buffer, 0, VK_WHOLE_SIZE, 0);
        vkCmdFillBuffer(cmd, penumbraJobs.buffer, 0, 16, 0);
        vk::memoryBarrier(cmd, kClear, VK_ACCESS_2_TRANSFER_WRITE_BIT, kCompute, kStorageRW);
        classifySoft(lightIndex, slot, 4, false, 1.0f); // where the camera pixels are, per tile of the map
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, maskPipeline);
        vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, maskLayout, 0, 1, &maskSet, 0, nullptr);
        float range = light.mapRange[slot].x - light.mapEye[slot].w;
        MaskPush push{glm::inverse(light.viewProj[slot]), lightIndex, slot, 0, shadowSize, maskTop, useThin ? 1u : 0u,
                      float(PENUMBRA_PIP_DELTA_FRACTION) * range, penumbraMaxJobs};
        for (uint32_t level = 0; level < maskTop; ++level) {
            push.level = level;
            uint32_t parentSize = (shadowSize + (2u << level) - 1u) >> (level + 1);
            uint32_t groups = (parentSize + PENUMBRA_MASK_GROUP_SIZE - 1) / PENUMBRA_MASK_GROUP_SIZE;
            vkCmdPushConstants(cmd, maskLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
            vkCmdDispatch(cmd, groups, groups, 1);
            vk::memoryBarrier(cmd, kCompute, kStorageRW, kCompute, kStorageRW);
        }
        push.level = kMaskWriteDispatch;
        vkCmdPushConstants(cmd, maskLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
        vkCmdDispatch(cmd, 1, 1, 1);
        vk::memoryBarrier(cmd, kCompute, kStorageRW, kCompute | VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT,
                          kStorageRW | VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT);
        push.level = kMaskSplatJobs;
        vkCmdPushConstants(cmd, maskLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
        vkCmdDispatchIndirect(cmd, penumbraJobs.buffer, 4);
        vk::memoryBarrier(cmd, kCompute, kStorageRW, kCompute, kStorageRW);
        timestamp(PassPenumbraMask);
    };

    for (uint32_t step = 0; step < frameLights.size(); ++step) {
        const uint32_t lightIndex = uint32_t(frameLights.size()) - 1 - step;
        const gpu::LightData& light = frameData.lights[lightIndex];
        const uint32_t layers = uint32_t(light.spotCosLayers.z);
        bool lightTraced = traced;

        if (isAreaLight(frameLights[lightIndex])) {
            // Soft shadows: per map of the light, the map (and in srt its thin
            // triangles and penumbra mask), then the pixels' classification.
            const uint32_t maps = uint32_t(light.spotCosLayers.w);
            const bool full = settings.shadows == ShadowMethod::FullRayTrace;
            if (selective) {
                vkCmdFillBuffer(cmd, marks.buffer, 0, VK_WHOLE_SIZE, 0);
                vk::memoryBarrier(cmd, kClear, VK_ACCESS_2_TRANSFER_WRITE_BIT, kCompute, kStorageRW);
            }
            // Corner maps first; the centre map (slot 0) last, its depths decide umbra and lit.
            for (uint32_t m = 0; m < maps; ++m) {
                const uint32_t slot = maps - 1 - m;
                if (!full) {
                    beginShadowMaps();
                    drawShadowMap(light.viewProj[slot], 0, lightFirstView[lightIndex] + slot);
                    endShadowMaps();
                }
                if (selective) {
                    clearThin();
                    float halfTan = 0.5f * light.mapRange[slot].y;
                    detectThinTriangles(light.viewProj[slot], 0, glm::vec3(light.mapEye[slot]), true,
                                        1.0f / std::sqrt(1.0f + 2.0f * halfTan * halfTan), light.mapRange[slot].y, 0, true);
                    vk::memoryBarrier(cmd, kCompute, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, kCompute, VK_ACCESS_2_SHADER_STORAGE_READ_BIT);
                    timestamp(PassThinTriangles);
                    buildPenumbraMask(lightIndex, slot, true);
                }
                if (traced && m == 0) {
                    vkCmdFillBuffer(cmd, rayList.buffer, 0, PENUMBRA_RAY_LIST_HEADER_UINTS * 4, 0);
                    vk::memoryBarrier(cmd, kClear, VK_ACCESS_2_TRANSFER_WRITE_BIT, kCompute, kStorageRW);
                }
                if (settings.shadows == ShadowMethod::ShadowMap)
                    classifySoft(lightIndex, slot, 0, m == 0, 1.0f / float(maps));
                else
                    classifySoft(lightIndex, slot, full ? 3 : slot == 0 ? 2 : 1, false, 1.0f);
                timestamp(PassClassify);
            }
            if (traced)
                compactAndTrace(lightIndex, settings.lightSamples);
        } else {
            // Shadow map from the light, every frame (moving light).
            beginShadowMaps();
            for (uint32_t layer = 0; layer < layers; ++layer)
                drawShadowMap(light.viewProj[layer], layer, lightFirstView[lightIndex] + layer);
            endShadowMaps();

            if (selective) {
                clearThin();
                const bool perspective = light.shadowParams.z != 0.0f;
                const float depthPerDistance = uint32_t(light.positionType.w) == PENUMBRA_LIGHT_SPOT ? light.spotCosLayers.y : 0.57735f;
                for (uint32_t layer = 0; layer < layers; ++layer)
                    detectThinTriangles(light.viewProj[layer], layer, glm::vec3(light.positionType), perspective, depthPerDistance,
                                        light.shadowParams.w, thinClusterMask[6 * lightIndex + layer], false);
                vk::memoryBarrier(cmd, kCompute, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, kCompute, VK_ACCESS_2_SHADER_STORAGE_READ_BIT);
                timestamp(PassThinTriangles);
            }

            // Visibility from the shadow map, and the pixels that get rays.
            if (traced) {
                vkCmdFillBuffer(cmd, rayList.buffer, 0, PENUMBRA_RAY_LIST_HEADER_UINTS * 4, 0);
                vk::memoryBarrier(cmd, kClear, VK_ACCESS_2_TRANSFER_WRITE_BIT, kCompute, kStorageRW);
            }
            vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, classifyPipeline);
            vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, classifyLayout, 0, 1, &classifySet, 0, nullptr);
            ClassifyPush classify{lightIndex, uint32_t(settings.shadows)};
            vkCmdPushConstants(cmd, classifyLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(classify), &classify);
            vkCmdDispatch(cmd, groupsX, groupsY, 1);
            vk::memoryBarrier(cmd, kCompute, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, kCompute, kStorageRW);
            timestamp(PassClassify);

            if (traced)
                compactAndTrace(lightIndex, 0);
        }

        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, shadePipeline);
        vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, shadeLayout, 0, 1, &shadeSet, 0, nullptr);
        ShadePush shade{lightIndex, step == 0 ? 1u : 0u, settings.debugPip && lightTraced ? 1u : 0u, 0u};
        vkCmdPushConstants(cmd, shadeLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(shade), &shade);
        vkCmdDispatch(cmd, groupsX, groupsY, 1);
        // The next light's passes read the accumulated colour, rewrite visibility and marks, and clear
        // the ray-list header that this light's trace read (also as indirect arguments).
        vk::memoryBarrier(cmd, kCompute | VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT, kStorageRW | VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT,
                          kCompute | kClear, kStorageRW | VK_ACCESS_2_TRANSFER_WRITE_BIT);
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
    vk::memoryBarrier(cmd, kCompute, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, kCopy, VK_ACCESS_2_TRANSFER_READ_BIT);
    VkBufferCopy statsRegion{0, 0, PENUMBRA_STAT_COUNT * sizeof(uint64_t)};
    vkCmdCopyBuffer(cmd, stats.buffer, readbackStats.buffer, 1, &statsRegion);
    if (settings.readbackGBuffer) {
        copyImage(position, readbackPosition);
        copyImage(normal, readbackNormal);
        copyImage(visibility, readbackVisibility);
    }
    vk::memoryBarrier(cmd, kCopy | kCompute, VK_ACCESS_2_TRANSFER_WRITE_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                      VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_READ_BIT);
    timestamp(PassReadback);
    VK_CHECK(vkEndCommandBuffer(cmd));

    submitAndWait(cmd);

    Frame frame;
    frame.color.width = width;
    frame.color.height = height;
    size_t pixels = size_t(width) * height;
    auto floats = [](const vk::Buffer& buffer) { return static_cast<const float*>(buffer.mapped); };
    frame.color.rgba.assign(floats(readbackColor), floats(readbackColor) + pixels * 4);
    if (settings.readbackGBuffer) {
        frame.positions.assign(floats(readbackPosition), floats(readbackPosition) + pixels * 4);
        frame.normals.assign(floats(readbackNormal), floats(readbackNormal) + pixels * 4);
        frame.visibility.assign(floats(readbackVisibility), floats(readbackVisibility) + pixels);
    }

    // Timings and counters.
    std::vector<uint64_t> ticks(timestampPass.size());
    VK_CHECK(vkGetQueryPoolResults(device.device, queryPool, 0, uint32_t(ticks.size()), ticks.size() * sizeof(uint64_t), ticks.data(),
                                   sizeof(uint64_t), VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
    double period = device.properties.limits.timestampPeriod * 1e-6; // ms per tick
    double passMs[PassCount] = {};
    bool ran[PassCount] = {};
    for (size_t i = 1; i < ticks.size(); ++i) {
        passMs[timestampPass[i]] += double(ticks[i] - ticks[i - 1]) * period;
        ran[timestampPass[i]] = true;
    }
    const uint64_t* counters = static_cast<const uint64_t*>(readbackStats.mapped);
    FrameStats& out = frame.stats;
    out.triangles = geometry.triangles;
    out.width = width;
    out.height = height;
    out.lights = uint32_t(frameLights.size());
    out.shadows = settings.shadows;
    out.coveredPixels = counters[PENUMBRA_STAT_COVERED] / std::max<uint64_t>(out.lights, 1);
    out.pipPixels = counters[PENUMBRA_STAT_PIP];
    out.pipFraction = out.coveredPixels ? double(out.pipPixels) / (double(out.coveredPixels) * out.lights) : 0.0;
    out.rays = counters[PENUMBRA_STAT_RAYS];
    out.nodesVisited = counters[PENUMBRA_STAT_NODES];
    out.leavesVisited = counters[PENUMBRA_STAT_LEAVES];
    out.triangleTests = counters[PENUMBRA_STAT_TRIANGLES];
    out.penumbraPixels = counters[PENUMBRA_STAT_PENUMBRA];
    uint32_t areaLights = uint32_t(std::count_if(frameLights.begin(), frameLights.end(), [](const Light& l) { return isAreaLight(l); }));
    out.penumbraFraction = out.coveredPixels && areaLights ? double(out.penumbraPixels) / (double(out.coveredPixels) * areaLights) : 0.0;
    out.lightSamples = areaLights && traced ? settings.lightSamples : areaLights ? settings.softShadowMaps : 0;
    out.rayOffset = traced ? rayOffset : 0.0f;
    out.device = device.info;
    for (uint32_t pass = 0; pass < PassCount; ++pass)
        if (ran[pass])
            out.passes.push_back({kPassNames[pass], passMs[pass]});
    out.cull = settings.cull;
    out.views = culling.endFrame(device);
    for (ViewCullStats& shadowView : shadowCulling.endFrame(device))
        out.views.push_back(std::move(shadowView));
    out.gpuMs = double(ticks.back() - ticks.front()) * period;
    out.cpuMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - cpuStart).count();
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
    auto cullModel = std::make_shared<const CullModel>(model, impl->geometry);
    impl->culling.setModel(cullModel);
    impl->shadowCulling.setModel(cullModel);
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
    impl->culling.clearModel();
    impl->shadowCulling.clearModel();
}

uint64_t Renderer::modelDeviceBytes() const { return impl->geometry.deviceBytes; }

std::vector<float> Renderer::decodeVerticesOnGpu() { return impl->decodeVerticesOnGpu(); }

void Renderer::setCamera(const Camera& camera) { impl->camera = camera; }

void Renderer::setLights(const std::vector<Light>& lights)
{
    if (lights.size() > PENUMBRA_MAX_LIGHTS)
        fail("lights", "at most " + std::to_string(PENUMBRA_MAX_LIGHTS) + " lights are supported, got " + std::to_string(lights.size()));
    for (size_t i = 0; i < lights.size(); ++i)
        validateLight(lights[i], "light " + std::to_string(i));
    impl->lights = lights;
}

Frame Renderer::render(const RenderSettings& settings) { return impl->render(settings); }

uint32_t Renderer::validationMessageCount() const { return impl->device.validationMessages.load(); }

std::vector<DeviceInfo> listDevices() { return vk::enumerateDevices(); }

uint32_t validationMessagesInProcess() { return vk::totalValidationMessages(); }

} // namespace penumbra
