// Renderer::Impl: the renderer's device, model, passes, culling and frame
// targets. Their lifetime and the public Renderer methods are in
// renderer_impl.cpp; the frame script that records a frame with them is
// renderer.cpp.
#pragma once

#include <optional>
#include <vector>

#include "culling.h"
#include "device.h"
#include "frame_targets.h"
#include "geometry_pages.h"
#include "model_geometry.h"
#include "passes/afsm.h"
#include "passes/rh.h"
#include "passes/classify.h"
#include "passes/compact.h"
#include "passes/gbuffer.h"
#include "passes/penumbra_mask.h"
#include "passes/shade.h"
#include "passes/shadow_map.h"
#include "passes/thin_triangles.h"
#include "passes/trace.h"
#include "passes/view_fit.h"
#include "penumbra/penumbra.h"
#include "selective_choice.h"

namespace penumbra {

struct Renderer::Impl {
    vk::Device device;
    GpuGeometry geometry;
    // RendererOptions::geometryBudgetBytes: the pages and their residency (inactive without a budget).
    GeometryPages pages;
    uint64_t geometryBudgetBytes = 0, geometryPageBytes = 0;
    // The loaded compressed model (the floors decode their uncompressed copy from it).
    std::optional<CompressedModel> model;
    // RenderSettings::measureFloors: the model as indexed float triangles, made on first use.
    GpuGeometry floorGeometry;
    std::optional<Camera> camera;
    std::vector<Light> lights;
    // The passes, in frame order.
    passes::GBufferPass gbuffer;
    passes::ViewFitPass viewFit;
    passes::ShadowMapPass shadowMap;
    passes::ThinTrianglesPass thinTriangles;
    passes::PenumbraMaskPass penumbraMask;
    passes::AfsmPass afsm;
    passes::RhPass rh;
    passes::ClassifyPass classify;
    passes::CompactPass compact;
    passes::TracePass trace;
    passes::ShadePass shade;
    // Raster culling: the camera's view, and the shadow maps' views (planned
    // later in the frame, once maps are fitted to the view).
    Culling culling, shadowCulling;
    FrameTargets targets;
    VkQueryPool queryPool = VK_NULL_HANDLE;
    VkCommandBuffer commandBuffer = VK_NULL_HANDLE;
    VkFence fence = VK_NULL_HANDLE;
    bool framePending = false; // submitted, and its fence wait failed
    // srt: whether a frame traces every light-facing pixel (RenderSettings::srtTraceAllWhenCheaper).
    SelectiveChoice srtChoice;
    uint64_t modelGeneration = 0; // counts the models loaded (selectiveKey)

    explicit Impl(const RendererOptions& options)
        : geometryBudgetBytes(options.geometryBudgetBytes), geometryPageBytes(options.geometryPageBytes)
    {
        try {
            vk::createDevice(device, options);
            create();
        } catch (...) {
            destroy();
            throw;
        }
    }
    ~Impl() { destroy(); }

    void create();
    void destroy();
    // Every pass's bindings to the frame targets (after they were recreated).
    void bindTargets();
    // The G-buffer, visibility, frame constants, marks and counters of the per-pixel passes.
    passes::PixelTargets pixelTargets() const;
    // The afsm pass's targets, made on the first afsm frame of a size.
    void ensureAfsmTargets();
    // The rh pass's targets (afsm's shadow flags and its own buffers), made on the first rh frame of a size.
    void ensureRhTargets();
    // The floors' null pipelines, uncompressed model and depth targets (RenderSettings::measureFloors).
    void ensureFloors();
    void setGeometry(GpuGeometry uploaded);
    // Ends and submits the frame's command buffer and waits for it (the frame's fence, at most the
    // device's timeout); passes names what it holds in errors ("device did not finish <passes> in N s").
    void submitAndWait(VkCommandBuffer cmd, const std::string& passes);

    void validate(const RenderSettings& settings) const;
    uint64_t selectiveKey(const RenderSettings& settings) const;
    struct FrameScript;
    Frame render(const RenderSettings& settings);
};

} // namespace penumbra
