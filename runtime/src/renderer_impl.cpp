// The renderer's lifetime: device, passes, culling and frame targets created
// and destroyed, models uploaded; and the public Renderer methods.
#include "renderer_impl.h"

#include "passes/decode_check.h"
#include "penumbra/preprocess.h"

namespace penumbra {

using namespace passes;

void Renderer::Impl::create()
{
    gbuffer.create(device);
    viewFit.create(device);
    shadowMap.create(device);
    thinTriangles.create(device);
    penumbraMask.create(device);
    afsm.create(device);
    rh.create(device);
    classify.create(device);
    compact.create(device);
    trace.create(device);
    shade.create(device);
    culling.create(device, {kSurfaceFormat, kAlbedoFormat}, kDepthFormat);
    shadowCulling.create(device, {kSurfaceFormat, kAlbedoFormat}, kDepthFormat);
    targets.create(device);

    VkQueryPoolCreateInfo queryInfo{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
    queryInfo.queryType = VK_QUERY_TYPE_TIMESTAMP;
    queryInfo.queryCount = vk::kTimestampQueries * kMaxTimestamps;
    VK_CHECK(vkCreateQueryPool(device.device, &queryInfo, nullptr, &queryPool));
    VkCommandBufferAllocateInfo cmdInfo{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    cmdInfo.commandPool = device.commandPool;
    cmdInfo.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    cmdInfo.commandBufferCount = 1;
    VK_CHECK(vkAllocateCommandBuffers(device.device, &cmdInfo, &commandBuffer));
    VkFenceCreateInfo fenceInfo{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    VK_CHECK(vkCreateFence(device.device, &fenceInfo, nullptr, &fence));
}

void Renderer::Impl::destroy()
{
    // After a failed submission, the device may still be running the frame: wait for it (bounded);
    // if it never finishes, nothing it may use is freed.
    if (device.device && framePending)
        vk::drainFence(device, fence);
    if (device.device && !device.hung) {
        vkDeviceWaitIdle(device.device);
        targets.destroy(device);
        destroyGeometry(device, geometry);
        destroyGeometry(device, floorGeometry);
        pages.destroy(device);
        gbuffer.destroy(device);
        viewFit.destroy(device);
        shadowMap.destroy(device);
        thinTriangles.destroy(device);
        penumbraMask.destroy(device);
        afsm.destroy(device);
        rh.destroy(device);
        classify.destroy(device);
        compact.destroy(device);
        trace.destroy(device);
        shade.destroy(device);
        culling.destroy(device);
        shadowCulling.destroy(device);
        if (fence) vkDestroyFence(device.device, fence, nullptr);
        if (queryPool) vkDestroyQueryPool(device.device, queryPool, nullptr);
    }
    vk::destroyDevice(device);
}

PixelTargets Renderer::Impl::pixelTargets() const
{
    const FrameTargets& t = targets;
    return {t.surface.view, t.albedo.view, t.visibility.view, t.frameUniforms.buffer, t.marks.buffer, t.stats.buffer};
}

void Renderer::Impl::bindTargets()
{
    const FrameTargets& t = targets;
    const PixelTargets pixels = pixelTargets();
    viewFit.bind(device, {t.surface.view, t.frameUniforms.buffer});
    thinTriangles.bind(device, t.thinMap);
    penumbraMask.bind(device, {t.shadowMap.view, t.nearestSampler, t.thinMap.view, t.frameUniforms.buffer, &t.penumbraPyramid,
                               &t.penumbraMask, &t.penumbraReceivers, &t.penumbraJobs, &t.penumbraThinMask, t.penumbraMaxJobs});
    classify.bind(device, {pixels, t.shadowMap.view, t.nearestSampler, t.thinMap.view, &t.penumbraMask, &t.penumbraReceivers,
                           &t.penumbraThinMask});
    compact.bind(device, t.marks.buffer, t.rayList.buffer, t.stats.buffer);
    trace.bind(device, {t.surface.view, t.albedo.view, t.visibility.view, t.frameUniforms.buffer, t.rayList.buffer, t.stats.buffer,
                        t.traceHints.buffer});
    shade.bind(device, pixels, t.color.view, t.shadowMap.view, t.nearestSampler);
}

void Renderer::Impl::ensureAfsmTargets()
{
    FrameTargets& t = targets;
    if (!t.ensureAfsm(device, afsmGridSize(t.width, t.height, true))) // the larger grid; hard layers use part of it
        return;
    const PixelTargets pixels = pixelTargets();
    afsm.bind(device, {pixels, &t.afsmCellFirst, &t.afsmCellCount, &t.afsmBlockSums, &t.afsmSlots, &t.afsmShadowed, &t.afsmFar, &t.afsmCellDepth, &t.afsmSlotShadowed, &t.afsmCellAlive, &t.afsmDepth, t.width,
                       t.height, t.afsmGrid, t.afsmSlotTexels, t.afsmCellFirstTexels, t.afsmCellCountTexels, t.afsmCellDepthTexels});
}

void Renderer::Impl::ensureRhTargets()
{
    ensureAfsmTargets();
    FrameTargets& t = targets;
    const RhTargets rhTargets{t.surface.view, t.albedo.view, t.frameUniforms.buffer, &t.afsmShadowed, t.width, t.height,
                              shadowCulling.model ? uint32_t(shadowCulling.model->clusterTriangles.size()) : 0u};
    if (!rh.bound(rhTargets))
        rh.bind(device, rhTargets);
}

void Renderer::Impl::ensureFloors()
{
    if (!model)
        fail("render", "floors are measured on a compressed model (loadModel), not on the uncompressed reference");
    if (floorGeometry.chunks.empty())
        floorGeometry = uploadReference(device, decodeMesh(*model));
    viewFit.createFloor(device);
    classify.createFloor(device);
    compact.createFloor(device);
    shade.createFloor(device);
    targets.ensureFloors(device);
}

void Renderer::Impl::setGeometry(GpuGeometry uploaded)
{
    if (!device.failed.empty()) {
        destroyGeometry(device, uploaded);
        vk::checkUsable(device);
    }
    vkDeviceWaitIdle(device.device);
    destroyGeometry(device, geometry);
    destroyGeometry(device, floorGeometry);
    geometry = std::move(uploaded);
    ++modelGeneration;
    if (geometry.encoding == GeometryEncoding::Compressed) {
        trace.bindModel(device, geometry);
        thinTriangles.bindModel(device, geometry);
    }
    afsm.bindModel(device, geometry); // no texel views for the reference encoding: its casters are rasterized
}

void Renderer::Impl::submitAndWait(VkCommandBuffer cmd, const std::string& passes)
{
    VK_CHECK(vkEndCommandBuffer(cmd));
    VK_CHECK(vkResetFences(device.device, 1, &fence));
    vk::submit(device, cmd, fence, passes);
    framePending = true;
    vk::waitForFence(device, fence, passes);
    framePending = false;
}

Renderer::Renderer(const RendererOptions& options) : impl(std::make_unique<Impl>(options)) {}
Renderer::~Renderer() = default;

const DeviceInfo& Renderer::device() const { return impl->device.info; }

void Renderer::loadModel(const CompressedModel& model)
{
    vk::checkUsable(impl->device);
    Impl& r = *impl;
    if (r.geometryBudgetBytes) {
        r.pages.build(model, r.device.rasterIndices == RasterIndices::Triangles ? RasterIndices::Triangles : RasterIndices::Strips,
                      r.geometryPageBytes, r.geometryBudgetBytes, leafAltitudesFit(r.device, model));
        const PagedBvh bvh = r.pages.pagedBvh(model);
        r.setGeometry(uploadCompressed(r.device, model, &bvh));
        r.pages.resetResidency();
    } else {
        impl->setGeometry(uploadCompressed(impl->device, model));
    }
    impl->model = model;
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
    vk::checkUsable(impl->device);
    if (impl->geometryBudgetBytes)
        fail("--geometry-budget", "the uncompressed reference is drawn in core (no budget)");
    impl->setGeometry(uploadReference(impl->device, mesh));
    impl->model.reset();
    impl->culling.clearModel();
    impl->shadowCulling.clearModel();
}

uint64_t Renderer::modelDeviceBytes() const { return impl->geometry.deviceBytes; }

std::vector<float> Renderer::decodeVerticesOnGpu()
{
    if (impl->geometry.paged())
        fail("decode check", "needs the whole model in core (no geometry budget)");
    return passes::decodeVerticesOnGpu(impl->device, impl->geometry);
}

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
