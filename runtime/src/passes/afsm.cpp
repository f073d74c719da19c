#include "passes/afsm.h"

#include <algorithm>

#include "config.h"
#include "passes/pass.h"

namespace penumbra::passes {

namespace {

constexpr uint32_t kScanBlock = PENUMBRA_AFSM_SCAN_GROUP * 16; // afsm_scan.comp.glsl: AFSM_SCAN_BLOCK

std::vector<VkDescriptorType> castersBindingTypes()
{
    using namespace vk;
    return {kStorageImage, kStorageImage, kUniform, kStorage, kStorage, kStorage, kStorage};
}

} // namespace

uint32_t afsmGridSize(uint32_t width, uint32_t height)
{
    uint32_t grid = 16;
    while (grid < std::max(width, height) && grid < PENUMBRA_AFSM_MAX_GRID)
        grid *= 2;
    return grid;
}

void AfsmPass::create(vk::Device& device)
{
    using namespace vk;
    std::vector<VkDescriptorType> sampleTypes = pixelBindingTypes();
    sampleTypes.insert(sampleTypes.end(), {kStorage, kStorage, kStorage, kStorage});
    samples.create(device, "afsm_samples.comp", sampleTypes, sizeof(AfsmSamplesPush));
    scan.create(device, "afsm_scan.comp", {kStorage, kStorage}, sizeof(AfsmScanPush));
    if (!device.aliasFree)
        return;
    castersSetLayout = createSetLayout(device, castersBindingTypes(), VK_SHADER_STAGE_FRAGMENT_BIT);
    castersSet = allocateSet(device, castersSetLayout, castersBindingTypes(), castersPool);
    GraphicsPipelineDesc desc;
    desc.vertexShader = "afsm_casters.vert";
    desc.geometryShader = "afsm_casters.geom";
    desc.fragmentShader = "afsm_casters.frag";
    desc.depthWrite = false;
    desc.pushBytes = sizeof(AfsmCastersPush);
    casters.create(device, desc, VK_SHADER_STAGE_GEOMETRY_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, castersSetLayout);
}

void AfsmPass::destroy(vk::Device& device)
{
    samples.destroy(device);
    scan.destroy(device);
    casters.destroy(device);
    if (castersPool)
        vkDestroyDescriptorPool(device.device, castersPool, nullptr);
    if (castersSetLayout)
        vkDestroyDescriptorSetLayout(device.device, castersSetLayout, nullptr);
    castersPool = VK_NULL_HANDLE;
    castersSetLayout = VK_NULL_HANDLE;
    castersSet = VK_NULL_HANDLE;
}

void AfsmPass::bind(vk::Device& device, const AfsmTargets& t)
{
    targets = t;
    std::vector<vk::Binding> bindings = pixelBindings(t.pixels);
    bindings.insert(bindings.end(), {vk::storageBuffer(t.cellFirst->buffer), vk::storageBuffer(t.cellCount->buffer),
                                     vk::storageBuffer(t.samples->buffer), vk::storageBuffer(t.shadowed->buffer)});
    samples.write(device, bindings);
    scan.write(device, {vk::storageBuffer(t.cellFirst->buffer), vk::storageBuffer(t.blockSums->buffer)});
    if (castersSet)
        vk::writeSet(device, castersSet,
                     {vk::storageImage(t.pixels.position), vk::storageImage(t.pixels.normal), vk::uniformBuffer(t.pixels.frame),
                      vk::storageBuffer(t.cellFirst->buffer), vk::storageBuffer(t.cellCount->buffer), vk::storageBuffer(t.samples->buffer),
                      vk::storageBuffer(t.shadowed->buffer)});
}

void AfsmPass::clear(VkCommandBuffer cmd) const
{
    vk::memoryBarrier(cmd, kCompute, kStorageRead, kClear, kTransferWrite);
    vkCmdFillBuffer(cmd, targets.shadowed->buffer, 0, VK_WHOLE_SIZE, 0);
    vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute | VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT, kStorageRW);
}

void AfsmPass::dispatchPixels(VkCommandBuffer cmd, const AfsmSamplesPush& push) const
{
    samples.bind(cmd);
    samples.push(cmd, push);
    vkCmdDispatch(cmd, groupCount(targets.width, PENUMBRA_SHADE_GROUP_SIZE), groupCount(targets.height, PENUMBRA_SHADE_GROUP_SIZE), 1);
}

void AfsmPass::recordSamples(VkCommandBuffer cmd, uint32_t lightIndex, uint32_t layer, float originOffset) const
{
    const VkPipelineStageFlags2 kFragment = VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT;
    const uint32_t grid = targets.gridSize, cells = grid * grid;
    // The previous layer's casters read the lists.
    vk::memoryBarrier(cmd, kFragment | kCompute, kStorageRead, kClear, kTransferWrite);
    vkCmdFillBuffer(cmd, targets.cellFirst->buffer, 0, VkDeviceSize(cells) * 4, 0);
    vkCmdFillBuffer(cmd, targets.cellCount->buffer, 0, VkDeviceSize(cells) * 4, 0);
    vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute, kStorageRW);
    dispatchPixels(cmd, {lightIndex, PENUMBRA_AFSM_COUNT, layer, grid, originOffset, {}});
    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);

    // Counts to offsets: block scans, the blocks' totals, then each block's prefix added.
    const uint32_t blocks = groupCount(cells, kScanBlock);
    scan.bind(cmd);
    for (uint32_t phase = 0; phase < 3; ++phase) {
        scan.push(cmd, AfsmScanPush{cells, phase});
        vkCmdDispatch(cmd, phase == 1 ? 1 : blocks, 1, 1);
        vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
    }
    dispatchPixels(cmd, {lightIndex, PENUMBRA_AFSM_LIST, layer, grid, originOffset, {}});
    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kFragment | kCompute, kStorageRW);
}

void AfsmPass::recordCasters(VkCommandBuffer cmd, Culling& culling, uint32_t view, const GpuGeometry& geometry, const glm::mat4& viewProj,
                             uint32_t lightIndex, float originOffset) const
{
    if (!castersSet)
        fail("afsm", "this device lacks geometry shaders or fragment-shader stores (needed to rasterize the casters)");
    const uint32_t grid = targets.gridSize;
    VkRenderingInfo rendering{VK_STRUCTURE_TYPE_RENDERING_INFO};
    rendering.renderArea = {{0, 0}, {grid, grid}};
    rendering.layerCount = 1;
    const AfsmCastersPush push{viewProj, lightIndex, grid, originOffset, 0};
    const VkPipeline pipeline = casters[geometry.encoding];
    culling.recordView(cmd, view, geometry, [&](bool) {
        vkCmdBeginRendering(cmd, &rendering);
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline);
        vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, casters.layout, 0, 1, &castersSet, 0, nullptr);
        vk::setViewport(cmd, grid, grid);
        vkCmdPushConstants(cmd, casters.layout, VK_SHADER_STAGE_GEOMETRY_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0, sizeof(push), &push);
    }, [&] { vkCmdEndRendering(cmd); });
    vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT, kStorageWrite, kCompute | kClear, kStorageRW | kTransferWrite);
}

void AfsmPass::recordResolve(VkCommandBuffer cmd, uint32_t lightIndex, float originOffset) const
{
    dispatchPixels(cmd, {lightIndex, PENUMBRA_AFSM_RESOLVE, 0, targets.gridSize, originOffset, {}});
    vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
}

} // namespace penumbra::passes
