#include "pipelines.h"

#include <algorithm>
#include <cstring>
#include <unordered_map>

#include "penumbra/shaders/registry.h"

namespace penumbra::vk {

VkPipelineLayout createPipelineLayout(Device& device, VkDescriptorSetLayout setLayout, uint32_t pushBytes, VkShaderStageFlags stages)
{
    VkPushConstantRange range{stages, 0, pushBytes};
    VkPipelineLayoutCreateInfo info{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    info.setLayoutCount = setLayout ? 1 : 0;
    info.pSetLayouts = &setLayout;
    info.pushConstantRangeCount = pushBytes ? 1 : 0;
    info.pPushConstantRanges = &range;
    VkPipelineLayout layout;
    VK_CHECK(vkCreatePipelineLayout(device.device, &info, nullptr, &layout));
    return layout;
}

VkDescriptorSetLayout createSetLayout(Device& device, const std::vector<VkDescriptorType>& types, VkShaderStageFlags stages)
{
    std::vector<VkDescriptorSetLayoutBinding> bindings;
    for (uint32_t i = 0; i < types.size(); ++i)
        bindings.push_back({i, types[i], 1, stages, nullptr});
    VkDescriptorSetLayoutCreateInfo info{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    info.bindingCount = uint32_t(bindings.size());
    info.pBindings = bindings.data();
    VkDescriptorSetLayout layout;
    VK_CHECK(vkCreateDescriptorSetLayout(device.device, &info, nullptr, &layout));
    return layout;
}

void writeSet(Device& device, VkDescriptorSet set, const std::vector<Binding>& bindings)
{
    std::vector<VkDescriptorImageInfo> images(bindings.size());
    std::vector<VkDescriptorBufferInfo> buffers(bindings.size());
    std::vector<VkWriteDescriptorSet> writes;
    for (uint32_t i = 0; i < bindings.size(); ++i) {
        const Binding& b = bindings[i];
        VkWriteDescriptorSet write{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
        write.dstSet = set;
        write.dstBinding = i;
        write.descriptorCount = 1;
        write.descriptorType = b.type;
        if (b.type == kTexels) {
            write.pTexelBufferView = &b.texels;
        } else if (b.buffer) {
            buffers[i] = {b.buffer, 0, b.range};
            write.pBufferInfo = &buffers[i];
        } else {
            images[i] = {b.sampler, b.view, b.layout};
            write.pImageInfo = &images[i];
        }
        writes.push_back(write);
    }
    vkUpdateDescriptorSets(device.device, uint32_t(writes.size()), writes.data(), 0, nullptr);
}

namespace {

const shaders::Embedded& embeddedShader(const char* name)
{
    for (const shaders::Embedded& shader : shaders::kAll)
        if (std::strcmp(shader.name, name) == 0)
            return shader;
    fail("shaders", std::string("no embedded shader named ") + name);
}

// The few SPIR-V opcodes and enumerants the push-constant reflection reads.
enum : uint32_t {
    OpTypeInt = 21, OpTypeFloat = 22, OpTypeVector = 23, OpTypeMatrix = 24, OpTypeArray = 28, OpTypeStruct = 30,
    OpTypePointer = 32, OpConstant = 43, OpVariable = 59, OpDecorate = 71, OpMemberDecorate = 72,
    DecorationArrayStride = 6, DecorationMatrixStride = 7, DecorationOffset = 35,
    StorageClassPushConstant = 9, StorageClassPhysicalStorageBuffer = 5349,
};

struct SpirvTypes {
    std::unordered_map<uint32_t, std::vector<uint32_t>> types; // result id -> the instruction's words from the opcode on
    std::unordered_map<uint32_t, uint32_t> constants, arrayStrides;
    std::unordered_map<uint64_t, uint32_t> memberOffsets, matrixStrides; // (struct << 32 | member)

    uint32_t size(uint32_t id, uint32_t matrixStride = 0) const
    {
        auto it = types.find(id);
        if (it == types.end())
            return 0;
        const std::vector<uint32_t>& t = it->second;
        switch (t[0] & 0xFFFFu) {
        case OpTypeInt:
        case OpTypeFloat: return t[2] / 8;
        case OpTypeVector: return t[3] * size(t[2]);
        case OpTypeMatrix: return t[3] * (matrixStride ? matrixStride : size(t[2]));
        case OpTypeArray: {
            auto stride = arrayStrides.find(id);
            auto length = constants.find(t[3]);
            return (length == constants.end() ? 0 : length->second) * (stride != arrayStrides.end() ? stride->second : size(t[2]));
        }
        case OpTypePointer: return t[2] == StorageClassPhysicalStorageBuffer ? 8 : 0;
        case OpTypeStruct: {
            uint32_t end = 0;
            for (uint32_t m = 0; m + 2 < t.size(); ++m) {
                const uint64_t key = uint64_t(id) << 32 | m;
                auto offset = memberOffsets.find(key);
                auto stride = matrixStrides.find(key);
                end = std::max(end, (offset != memberOffsets.end() ? offset->second : 0) +
                                        size(t[2 + m], stride != matrixStrides.end() ? stride->second : 0));
            }
            return end;
        }
        default: return 0;
        }
    }
};

} // namespace

uint32_t shaderPushConstantBytes(const char* shader)
{
    const shaders::Embedded& embedded = embeddedShader(shader);
    const uint32_t* words = embedded.code;
    const size_t count = embedded.size / 4;
    SpirvTypes spirv;
    uint32_t pushPointerType = 0;
    for (size_t i = 5; i < count;) {
        const uint32_t opcode = words[i] & 0xFFFFu, length = words[i] >> 16;
        if (length == 0 || i + length > count)
            fail("shaders", std::string(shader) + ": malformed SPIR-V");
        const uint32_t* w = words + i;
        switch (opcode) {
        case OpTypeInt: case OpTypeFloat: case OpTypeVector: case OpTypeMatrix: case OpTypeArray: case OpTypeStruct: case OpTypePointer:
            spirv.types[w[1]].assign(w, w + length);
            break;
        case OpConstant: spirv.constants[w[2]] = w[3]; break;
        case OpDecorate:
            if (w[2] == DecorationArrayStride) spirv.arrayStrides[w[1]] = w[3];
            break;
        case OpMemberDecorate:
            if (w[3] == DecorationOffset) spirv.memberOffsets[uint64_t(w[1]) << 32 | w[2]] = w[4];
            if (w[3] == DecorationMatrixStride) spirv.matrixStrides[uint64_t(w[1]) << 32 | w[2]] = w[4];
            break;
        case OpVariable:
            if (w[3] == StorageClassPushConstant) pushPointerType = w[1];
            break;
        default: break;
        }
        i += length;
    }
    if (!pushPointerType)
        return 0;
    auto pointer = spirv.types.find(pushPointerType);
    return pointer == spirv.types.end() ? 0 : spirv.size(pointer->second[3]);
}

void checkPushConstants(const char* shader, uint32_t pushBytes)
{
    const uint32_t shaderBytes = shaderPushConstantBytes(shader);
    if (shaderBytes != 0 && shaderBytes != pushBytes)
        fail("shaders", std::string(shader) + ": its push constants are " + std::to_string(shaderBytes) + " bytes, the pass pushes " +
                            std::to_string(pushBytes));
}

VkPipeline createComputePipeline(Device& device, const char* shader, VkPipelineLayout layout, uint32_t pushBytes,
                                 const Specialization& specialization)
{
    checkPushConstants(shader, pushBytes);
    VkShaderModule module = createShaderModule(device, shader);
    VkComputePipelineCreateInfo info{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
    info.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
    info.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    info.stage.module = module;
    info.stage.pName = "main";
    std::array<VkSpecializationMapEntry, 6> entries{};
    VkSpecializationInfo specializationInfo{};
    if (specialization.count > 0) {
        for (uint32_t i = 0; i < specialization.count; ++i)
            entries[i] = {i, uint32_t(i * sizeof(uint32_t)), sizeof(uint32_t)};
        specializationInfo.mapEntryCount = specialization.count;
        specializationInfo.pMapEntries = entries.data();
        specializationInfo.dataSize = specialization.count * sizeof(uint32_t);
        specializationInfo.pData = specialization.values.data();
        info.stage.pSpecializationInfo = &specializationInfo;
    }
    info.layout = layout;
    VkPipeline pipeline;
    VkResult result = vkCreateComputePipelines(device.device, VK_NULL_HANDLE, 1, &info, nullptr, &pipeline);
    vkDestroyShaderModule(device.device, module, nullptr);
    VK_CHECK(result);
    return pipeline;
}

VkDescriptorSet allocateSet(Device& device, VkDescriptorSetLayout setLayout, const std::vector<VkDescriptorType>& bindings,
                            VkDescriptorPool& pool)
{
    VkDescriptorSet set = VK_NULL_HANDLE;
    std::vector<VkDescriptorPoolSize> sizes;
    for (VkDescriptorType type : bindings) {
        auto it = std::find_if(sizes.begin(), sizes.end(), [&](const VkDescriptorPoolSize& s) { return s.type == type; });
        if (it == sizes.end())
            sizes.push_back({type, 1});
        else
            ++it->descriptorCount;
    }
    VkDescriptorPoolCreateInfo poolInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
    poolInfo.maxSets = 1;
    poolInfo.poolSizeCount = uint32_t(sizes.size());
    poolInfo.pPoolSizes = sizes.data();
    VK_CHECK(vkCreateDescriptorPool(device.device, &poolInfo, nullptr, &pool));
    VkDescriptorSetAllocateInfo allocInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    allocInfo.descriptorPool = pool;
    allocInfo.descriptorSetCount = 1;
    allocInfo.pSetLayouts = &setLayout;
    VK_CHECK(vkAllocateDescriptorSets(device.device, &allocInfo, &set));
    return set;
}

void ComputeKernel::create(Device& device, const char* shader, const std::vector<VkDescriptorType>& bindings, uint32_t pushBytes)
{
    try {
        const VkShaderStageFlags compute = VK_SHADER_STAGE_COMPUTE_BIT;
        setLayout = createSetLayout(device, bindings, compute);
        layout = createPipelineLayout(device, setLayout, pushBytes, compute);
        pipeline = createComputePipeline(device, shader, layout, pushBytes);

        set = allocateSet(device, setLayout, bindings, pool);
        this->shader = shader;
        this->pushBytes = pushBytes;
        this->device = &device;
    } catch (...) {
        destroy(device);
        throw;
    }
}

void ComputeKernel::createFloor(Device& device)
{
    if (!floorPipeline)
        floorPipeline = createComputePipeline(device, (std::string(shader) + ".floor").c_str(), layout, pushBytes);
}

void ComputeKernel::destroy(Device& device)
{
    VkDevice d = device.device;
    if (pool) vkDestroyDescriptorPool(d, pool, nullptr);
    if (pipeline) vkDestroyPipeline(d, pipeline, nullptr);
    for (auto* cache : {&variants, &floorVariants})
        for (auto& [specialization, variant] : *cache)
            vkDestroyPipeline(d, variant, nullptr);
    if (floorPipeline) vkDestroyPipeline(d, floorPipeline, nullptr);
    if (layout) vkDestroyPipelineLayout(d, layout, nullptr);
    if (setLayout) vkDestroyDescriptorSetLayout(d, setLayout, nullptr);
    *this = {};
}

void ComputeKernel::bind(VkCommandBuffer cmd, bool floor) const
{
    if (floor && !floorPipeline)
        fail("renderer", std::string(shader) + ": null pass recorded before createFloor");
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, floor ? floorPipeline : pipeline);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout, 0, 1, &set, 0, nullptr);
}

void ComputeKernel::bind(VkCommandBuffer cmd, const Specialization& specialization, bool floor) const
{
    if (specialization.count == 0) {
        bind(cmd, floor);
        return;
    }
    if (floor && !floorPipeline)
        fail("renderer", std::string(shader) + ": null pass recorded before createFloor");
    // The null twin takes the same constants: those that shape the dispatch (view_fit's block size) must agree.
    auto& cache = floor ? floorVariants : variants;
    auto it = std::find_if(cache.begin(), cache.end(), [&](const auto& v) { return v.first == specialization; });
    if (it == cache.end()) {
        const std::string name = std::string(shader) + (floor ? ".floor" : "");
        cache.emplace_back(specialization, createComputePipeline(*device, name.c_str(), layout, pushBytes, specialization));
        it = cache.end() - 1;
    }
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, it->second);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout, 0, 1, &set, 0, nullptr);
}

VkPipeline createGraphicsPipeline(Device& device, const GraphicsPipelineDesc& desc)
{
    std::string vertexName = desc.vertexShader + (desc.encoding == GeometryEncoding::UncompressedReference ? ".float" : "");
    checkPushConstants(vertexName.c_str(), desc.pushBytes);
    if (desc.fragmentShader)
        checkPushConstants(desc.fragmentShader, desc.pushBytes);
    VkShaderModule vertex = createShaderModule(device, vertexName.c_str());
    if (desc.geometryShader)
        checkPushConstants(desc.geometryShader, desc.pushBytes);
    VkShaderModule fragment = VK_NULL_HANDLE, geometry = VK_NULL_HANDLE;
    try {
        if (desc.fragmentShader)
            fragment = createShaderModule(device, desc.fragmentShader);
        if (desc.geometryShader)
            geometry = createShaderModule(device, desc.geometryShader);
    } catch (...) {
        for (VkShaderModule module : {vertex, fragment})
            if (module)
                vkDestroyShaderModule(device.device, module, nullptr);
        throw;
    }
    std::vector<VkPipelineShaderStageCreateInfo> stages;
    for (auto [stage, module] : {std::pair{VK_SHADER_STAGE_VERTEX_BIT, vertex}, std::pair{VK_SHADER_STAGE_GEOMETRY_BIT, geometry},
                                 std::pair{VK_SHADER_STAGE_FRAGMENT_BIT, fragment}})
        if (module) {
            VkPipelineShaderStageCreateInfo info{VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
            info.stage = stage;
            info.module = module;
            info.pName = "main";
            stages.push_back(info);
        }

    VkPipelineVertexInputStateCreateInfo vertexInput{VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
    VkPipelineInputAssemblyStateCreateInfo assembly{VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO};
    assembly.topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST;
    GeometryInputState input{};
    if (desc.modelGeometry) {
        input = geometryInputState(desc.encoding, device.rasterIndices);
        vertexInput.vertexBindingDescriptionCount = input.bindingCount;
        vertexInput.pVertexBindingDescriptions = input.bindings;
        vertexInput.vertexAttributeDescriptionCount = input.attributeCount;
        vertexInput.pVertexAttributeDescriptions = input.attributes;
        assembly.topology = input.topology;
        assembly.primitiveRestartEnable = input.primitiveRestart;
    }
    VkPipelineViewportStateCreateInfo viewport{VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO};
    viewport.viewportCount = 1;
    viewport.scissorCount = 1;
    VkPipelineRasterizationStateCreateInfo raster{VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO};
    raster.polygonMode = VK_POLYGON_MODE_FILL;
    raster.cullMode = VK_CULL_MODE_NONE; // CAD and scanned models are often open or two-sided
    raster.frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE;
    raster.depthBiasEnable = desc.depthBias;
    raster.depthClampEnable = desc.depthClamp;
    raster.rasterizerDiscardEnable = desc.rasterizerDiscard;
    raster.lineWidth = 1.0f;
    VkPipelineMultisampleStateCreateInfo multisample{VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO};
    multisample.rasterizationSamples = VK_SAMPLE_COUNT_1_BIT;
    VkPipelineDepthStencilStateCreateInfo depth{VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO};
    depth.depthTestEnable = VK_TRUE;
    depth.depthWriteEnable = desc.depthWrite;
    depth.depthCompareOp = desc.depthCompare;
    std::vector<VkPipelineColorBlendAttachmentState> blends(desc.colorFormats.size());
    for (auto& blend : blends)
        blend.colorWriteMask = desc.colorWrite ? 0xf : 0;
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
    rendering.depthAttachmentFormat = desc.depthFormat;

    VkGraphicsPipelineCreateInfo info{VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO, &rendering};
    info.stageCount = uint32_t(stages.size());
    info.pStages = stages.data();
    info.pVertexInputState = &vertexInput;
    info.pInputAssemblyState = &assembly;
    info.pViewportState = &viewport;
    info.pRasterizationState = &raster;
    info.pMultisampleState = &multisample;
    info.pDepthStencilState = desc.depthFormat != VK_FORMAT_UNDEFINED ? &depth : nullptr;
    info.pColorBlendState = &blend;
    info.pDynamicState = &dynamic;
    info.layout = desc.layout;
    VkPipeline pipeline;
    VkResult result = vkCreateGraphicsPipelines(device.device, VK_NULL_HANDLE, 1, &info, nullptr, &pipeline);
    for (VkShaderModule module : {vertex, geometry, fragment})
        if (module)
            vkDestroyShaderModule(device.device, module, nullptr);
    VK_CHECK(result);
    return pipeline;
}

void RasterPipelines::create(Device& device, GraphicsPipelineDesc desc, VkShaderStageFlags pushStages, VkDescriptorSetLayout setLayout)
{
    try {
        layout = createPipelineLayout(device, setLayout, desc.pushBytes, pushStages);
        desc.layout = layout;
        for (GeometryEncoding encoding : {GeometryEncoding::Compressed, GeometryEncoding::UncompressedReference}) {
            desc.encoding = encoding;
            byEncoding[int(encoding)] = createGraphicsPipeline(device, desc);
        }
    } catch (...) {
        destroy(device);
        throw;
    }
}

void RasterPipelines::destroy(Device& device)
{
    for (VkPipeline pipeline : byEncoding)
        if (pipeline)
            vkDestroyPipeline(device.device, pipeline, nullptr);
    if (layout)
        vkDestroyPipelineLayout(device.device, layout, nullptr);
    *this = {};
}

void setViewport(VkCommandBuffer cmd, uint32_t w, uint32_t h)
{
    VkViewport viewport{0, 0, float(w), float(h), 0.0f, 1.0f};
    VkRect2D scissor{{0, 0}, {w, h}};
    vkCmdSetViewport(cmd, 0, 1, &viewport);
    vkCmdSetScissor(cmd, 0, 1, &scissor);
}

} // namespace penumbra::vk
