// Pipelines of the passes: set layouts, descriptor sets, compute kernels and
// the one graphics-pipeline helper (G-buffer, shadow maps, culling boxes,
// decode check). Every pipeline checks its C++ push-constant size against
// the shader's push-constant block, read from the embedded SPIR-V.
#pragma once

#include <array>
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

#include "model_geometry.h"
#include "resources.h"

namespace penumbra::vk {

constexpr VkDescriptorType kStorageImage = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE;
constexpr VkDescriptorType kSampled = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
constexpr VkDescriptorType kUniform = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
constexpr VkDescriptorType kStorage = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
constexpr VkDescriptorType kTexels = VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER;

// Pipeline layout with at most one set and one push-constant range of pushBytes.
VkPipelineLayout createPipelineLayout(Device& device, VkDescriptorSetLayout setLayout, uint32_t pushBytes, VkShaderStageFlags stages);

// Set layout whose binding i has types[i], one descriptor each.
VkDescriptorSetLayout createSetLayout(Device& device, const std::vector<VkDescriptorType>& types, VkShaderStageFlags stages);

// One descriptor of a set: an image view (+ sampler) or a whole buffer.
struct Binding {
    VkDescriptorType type;
    VkImageView view = VK_NULL_HANDLE;
    VkSampler sampler = VK_NULL_HANDLE;
    VkBuffer buffer = VK_NULL_HANDLE;
    VkImageLayout layout = VK_IMAGE_LAYOUT_GENERAL;
    VkDeviceSize range = VK_WHOLE_SIZE;
    VkBufferView texels = VK_NULL_HANDLE; // kTexels
};
inline Binding storageImage(VkImageView view) { return {kStorageImage, view}; }
inline Binding sampledImage(VkImageView view, VkSampler sampler, VkImageLayout layout) { return {kSampled, view, sampler, {}, layout}; }
inline Binding uniformBuffer(VkBuffer buffer) { return {kUniform, {}, {}, buffer}; }
inline Binding storageBuffer(VkBuffer buffer, VkDeviceSize range = VK_WHOLE_SIZE) { return {kStorage, {}, {}, buffer, {}, range}; }
inline Binding texelBuffer(VkBufferView view) { return {kTexels, {}, {}, {}, {}, VK_WHOLE_SIZE, view}; }

// Writes bindings[i] to binding i of set.
void writeSet(Device& device, VkDescriptorSet set, const std::vector<Binding>& bindings);

// Size in bytes of the push-constant block of an embedded shader ("classify.comp"),
// from its SPIR-V: the end of its last member. 0 when it declares none.
uint32_t shaderPushConstantBytes(const char* shader);

// Throws when the shader's push-constant block is not pushBytes long.
void checkPushConstants(const char* shader, uint32_t pushBytes);

// Values of a compute pipeline's specialization constants: constant_id i
// takes values[i] for i < count; the others keep the shader's defaults. On
// lavapipe a shader pays for every instruction it holds, taken or not
// (llvmpipe runs both sides of every if, masked): modes and light types that
// a dispatch knows are specialization constants, so that the compiler drops
// the code of the others.
struct Specialization {
    std::array<uint32_t, 6> values{};
    uint32_t count = 0;

    Specialization() = default;
    Specialization(std::initializer_list<uint32_t> list)
    {
        for (uint32_t v : list)
            values.at(count++) = v;
    }
    bool operator==(const Specialization&) const = default;
};

// Compute pipeline of an embedded shader ("classify.comp"); checks pushBytes against the shader.
VkPipeline createComputePipeline(Device& device, const char* shader, VkPipelineLayout layout, uint32_t pushBytes,
                                 const Specialization& specialization = {});

// One descriptor set of setLayout (binding i of type bindings[i]) from a new
// pool sized for it, returned in `pool` (destroying the pool frees the set).
VkDescriptorSet allocateSet(Device& device, VkDescriptorSetLayout setLayout, const std::vector<VkDescriptorType>& bindings,
                            VkDescriptorPool& pool);

// A compute pass's pipeline with its own set layout (binding i of type
// bindings[i]), one descriptor set from a pool of its own, and push constants.
struct ComputeKernel {
    VkDescriptorSetLayout setLayout = VK_NULL_HANDLE;
    VkPipelineLayout layout = VK_NULL_HANDLE;
    VkPipeline pipeline = VK_NULL_HANDLE;
    VkDescriptorPool pool = VK_NULL_HANDLE;
    VkDescriptorSet set = VK_NULL_HANDLE;
    // The null twin (shaders/floor.glsli, "<shader>.floor"), made by createFloor for `penumbra bench`.
    VkPipeline floorPipeline = VK_NULL_HANDLE;
    const char* shader = nullptr;
    uint32_t pushBytes = 0;
    Device* device = nullptr;
    // Pipelines specialized by bind(cmd, specialization), made on first use (and their null twins').
    mutable std::vector<std::pair<Specialization, VkPipeline>> variants, floorVariants;

    void create(Device& device, const char* shader, const std::vector<VkDescriptorType>& bindings, uint32_t pushBytes);
    // Makes the null twin once (same layout and set).
    void createFloor(Device& device);
    void destroy(Device& device);
    void write(Device& device, const std::vector<Binding>& bindings) const { writeSet(device, set, bindings); }
    // Binds the pipeline (floor: its null twin) and its set.
    void bind(VkCommandBuffer cmd, bool floor = false) const;
    // Binds the pipeline specialized with `specialization` (made on first use;
    // floor: the null twin, with the same constants) and its set.
    void bind(VkCommandBuffer cmd, const Specialization& specialization, bool floor = false) const;
    template <typename Push>
    void push(VkCommandBuffer cmd, const Push& push) const
    {
        vkCmdPushConstants(cmd, layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(Push), &push);
    }
};

struct GraphicsPipelineDesc {
    std::string vertexShader;                 // registry name; ".float" is appended for the reference encoding
    const char* geometryShader = nullptr;     // null: none
    const char* fragmentShader = nullptr;     // null: depth only
    std::vector<VkFormat> colorFormats;
    VkFormat depthFormat = VK_FORMAT_UNDEFINED; // UNDEFINED: no depth attachment
    bool depthWrite = true;
    VkCompareOp depthCompare = VK_COMPARE_OP_LESS_OR_EQUAL;
    bool depthClamp = false;                  // fragment depths clamped instead of primitives clipped (needs the depthClamp feature)
    bool colorWrite = true;                   // false: colour attachments masked (culling boxes)
    bool depthBias = false;
    bool rasterizerDiscard = false;
    bool modelGeometry = true;                // vertex input of the model (geometryInputState); false: none, triangle list
    GeometryEncoding encoding = GeometryEncoding::Compressed;
    VkPipelineLayout layout = VK_NULL_HANDLE;
    uint32_t pushBytes = 0;                   // checked against every stage's push-constant block
};

VkPipeline createGraphicsPipeline(Device& device, const GraphicsPipelineDesc& desc);

// A raster pass's pipelines, one per geometry encoding, with one layout (no set).
struct RasterPipelines {
    VkPipelineLayout layout = VK_NULL_HANDLE;
    VkPipeline byEncoding[2] = {};

    // desc.layout and desc.encoding are filled in; setLayout: the layout's one set, if any.
    void create(Device& device, GraphicsPipelineDesc desc, VkShaderStageFlags pushStages, VkDescriptorSetLayout setLayout = VK_NULL_HANDLE);
    void destroy(Device& device);
    VkPipeline operator[](GeometryEncoding encoding) const { return byEncoding[int(encoding)]; }
};

// Viewport and scissor covering w x h.
void setViewport(VkCommandBuffer cmd, uint32_t w, uint32_t h);

} // namespace penumbra::vk
