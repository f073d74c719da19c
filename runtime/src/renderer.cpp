// Renderer: the frame script. One command buffer per frame: the camera's
// G-buffer, the view fit (read back mid-frame: the frame's one extra
// submission), then per light, last light first, the sequence of passes its
// shadow method lists (shadow_methods.cpp), then the read-back. The passes
// live in passes/, the frame's images and buffers in frame_targets.h, the
// lights' packing in lights.h. runtime/README.md describes the frame.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <functional>
#include <glm/gtc/matrix_transform.hpp>

#include "config.h"
#include "half_float.h"
#include "light_space.h"
#include "lights.h"
#include "passes/pass.h"
#include "renderer_impl.h"
#include "shadow_methods.h"
#include "surface.h"

namespace penumbra {

using namespace passes;

namespace {

// Timestamps between the passes: interval i ends at timestamp i + 1.
//
// llvmpipe takes a timestamp when its rasterizer threads reach it in the
// scene being binned, at the next flush, while compute runs on the queue's
// thread at once: written once, a pass's time landed in a neighbouring
// interval (a 1024^2 view fit read as 60 ms in ordinary frames and as 0.05 ms
// in floor frames, where its own work is 3 ms). Each timestamp is written
// twice (vk::writeTimestamp): the second write's flush takes the first at
// once. Floor frames (RenderSettings::measureFloors) are timed on the host,
// beside their floors, each pass submitted alone: every
// interval ends with a submission and a wait, and lasts from the end of the
// previous wait to the end of its own (recording and one round trip included).
// With PENUMBRA_FLOOR_CLOCK=cpu they count the process's CPU time instead of
// the wall clock: on a CPU device (lavapipe) that is the pass's work, and it
// holds steady when other processes share the cores.
double hostClockMs()
{
    static const bool cpu = [] {
        const char* clock = std::getenv("PENUMBRA_FLOOR_CLOCK");
        return clock && std::strcmp(clock, "cpu") == 0;
    }();
    if (!cpu)
        return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
    timespec time{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &time);
    return double(time.tv_sec) * 1e3 + double(time.tv_nsec) * 1e-6;
}

struct PassTimer {
    VkQueryPool pool = VK_NULL_HANDLE;
    std::function<void()> submitAndRestart; // host-timed frames: submit, wait, begin the next command buffer
    std::vector<PassId> ended;              // pass of the interval ending at each timestamp (the first: PassId::Count)
    std::vector<double> hostEnds; // host-timed frames: when each interval ended (hostClockMs)

    // The passes marked since the last call, for errors: "shadow_map, classify, shade".
    std::string passesSinceLastSubmit()
    {
        std::string names;
        for (size_t i = std::max<size_t>(submitted, 1); i < ended.size(); ++i) {
            if (ended[i] == PassId::ViewFitReadback)
                continue; // its interval's work was in the submission before (the mid-frame read-back)
            const std::string name = passName(ended[i]);
            if (names.find(name) == std::string::npos)
                names += (names.empty() ? "" : ", ") + name;
        }
        submitted = ended.size();
        return names.empty() ? "the frame" : names;
    }
    size_t submitted = 0;

    void mark(VkCommandBuffer& cmd, PassId pass)
    {
        if (ended.size() >= kMaxTimestamps)
            fail("render", "too many timestamps");
        ended.push_back(pass);
        if (submitAndRestart) {
            submitAndRestart(); // names the passes up to this one if the device fails
            hostEnds.push_back(hostClockMs());
        }
        vk::writeTimestamp(cmd, pool, vk::kTimestampQueries * uint32_t(ended.size() - 1));
    }
};

} // namespace


void Renderer::Impl::validate(const RenderSettings& settings) const
{
    const VkPhysicalDeviceLimits& limits = device.properties.limits;
    if (!geometry.triangles)
        fail("render", "no model loaded");
    if (settings.width == 0 || settings.height == 0 || settings.width > 16384 || settings.height > 16384)
        fail("render", "image size must be 1..16384 pixels per side");
    if (settings.shadowMapSize < 16 || settings.shadowMapSize > limits.maxImageDimension2D)
        fail("render", "shadow-map size must be 16.." + std::to_string(limits.maxImageDimension2D));
    const VkDeviceSize pixelBytes = VkDeviceSize(settings.width) * settings.height * 16;
    if (pixelBytes > device.maxAllocationSize || pixelBytes / 4 + 16 > limits.maxStorageBufferRange)
        fail("render", std::to_string(settings.width) + "x" + std::to_string(settings.height) +
                           " exceeds this device's buffer limits (one RGBA32F image must fit one allocation and the ray list one storage binding)");
    const ShadowMethodSpec& spec = shadowMethodSpec(settings.shadows);
    const bool areaLights = std::any_of(lights.begin(), lights.end(), [](const Light& l) { return isAreaLight(l); });
    if (settings.shadows == ShadowMethod::AliasFree) {
        // afsm's bitmasks: one bit per light sample per view sample (section 4.2); only area lights have samples.
        if (areaLights && (settings.lightSamples < PENUMBRA_AFSM_MIN_SAMPLES || settings.lightSamples > PENUMBRA_AFSM_MAX_SAMPLES))
            fail("render", "afsm soft shadows take " + std::to_string(PENUMBRA_AFSM_MIN_SAMPLES) + ".." + std::to_string(PENUMBRA_AFSM_MAX_SAMPLES) +
                               " light samples per pixel (--samples), not " + std::to_string(settings.lightSamples));
        const uint64_t largest = passes::afsmLargestBuffer(settings.width, settings.height, settings.lightSamples, areaLights);
        const std::string size = std::to_string(settings.width) + "x" + std::to_string(settings.height);
        if (largest > device.maxAllocationSize)
            fail("render", (areaLights ? "afsm soft shadows at " + size + " with " + std::to_string(settings.lightSamples) + " light samples need "
                                       : "afsm at " + size + " needs ") +
                               std::to_string(largest >> 20) + " MiB in one buffer (" +
                               (largest > passes::afsmLargestBuffer(settings.width, settings.height, 0, false) ? "sample masks" : "the sample list") +
                               "), more than one allocation of this device (" + std::to_string(device.maxAllocationSize >> 20) +
                               " MiB): use " + (areaLights ? "fewer samples or " : "") + "a smaller image");
        // The casters read the slots through one texel view, 16-byte texels: 2 a sample (soft: 3).
        const uint64_t texels = uint64_t(settings.width) * settings.height * (areaLights ? 3 : 2);
        if (texels > limits.maxTexelBufferElements)
            fail("render", "afsm at " + size + " needs a texel view of " + std::to_string(texels) + " elements for its sample list, more than this device's " +
                               std::to_string(limits.maxTexelBufferElements) + ": use a smaller image");
    } else if (settings.lightSamples < 4 || settings.lightSamples > PENUMBRA_MAX_SAMPLES) {
        fail("render", "light samples must be 4.." + std::to_string(PENUMBRA_MAX_SAMPLES) + " for " + spec.name + " (afsm: " +
                           std::to_string(PENUMBRA_AFSM_MIN_SAMPLES) + ".." + std::to_string(PENUMBRA_AFSM_MAX_SAMPLES) + ")");
    }
    if (settings.penumbraMaps != 1 && settings.penumbraMaps != 5)
        fail("render", "penumbra maps must be 1 (the light's centre) or 5 (centre and corners)");
    if (settings.softShadowMaps < 1 || settings.softShadowMaps > 6)
        fail("render", "soft shadow maps (sm) must be 1..6");
    // A penumbra mask binds every level of the map (4/3 x 4 bytes per texel) as one storage buffer.
    const uint64_t maskBytes = (1 + maskTexels(settings.shadowMapSize)) * 4;
    if (spec.uses(Step::PenumbraMask) && maskBytes > limits.maxStorageBufferRange && areaLights) {
        uint32_t largest = settings.shadowMapSize;
        while (largest > 16 && (1 + maskTexels(largest)) * 4 > limits.maxStorageBufferRange)
            largest /= 2;
        fail("render", "shadow-map size " + std::to_string(settings.shadowMapSize) + " is too large for " + spec.name +
                           " soft shadows on this device: the penumbra mask (" + std::to_string(maskBytes >> 20) +
                           " MiB) exceeds its storage-buffer limit (" + std::to_string(limits.maxStorageBufferRange >> 20) + " MiB); use " +
                           std::to_string(largest) + " or less");
    }
    if (areaLights && !spec.softShadows())
        fail("render", std::string(spec.name) + " does not do soft shadows (area lights) yet: use sm, srt or frt for them");
    if (settings.shadows == ShadowMethod::AliasFree && !device.aliasFree)
        fail("render", "afsm needs geometry shaders, fragment-shader stores and depth clamping, which " + device.info.name + " lacks");
    if (settings.shadows == ShadowMethod::RayHierarchy) {
        if (!device.rayHierarchy)
            fail("render", "rh needs geometry shaders and vertex-stage stores, which " + device.info.name + " lacks");
        if (geometry.encoding != GeometryEncoding::Compressed)
            fail("render", "rh needs the compressed model (the uncompressed reference is for raster benchmarks)");
    }
    if (geometry.paged()) {
        if (settings.measureFloors)
            fail("--geometry-budget", "floors are measured in core (no budget)");
        if (settings.cull == CullMode::None)
            fail("--geometry-budget", "--cull none draws the whole model in one list: use frustum or all under a budget");
    }
    if (spec.traces() && geometry.encoding != GeometryEncoding::Compressed)
        fail("render", "ray-traced shadows need the compressed model (the uncompressed reference is for raster benchmarks)");
}

// One frame being recorded: its lights, camera, views and the passes'
// sequence per light.
struct Renderer::Impl::FrameScript {
    Impl& r;
    const RenderSettings& settings;
    const ShadowMethodSpec& spec;
    const Bounds bounds;
    const float rayOffset;
    std::vector<Light> lights;
    ViewProjection view;
    gpu::FrameData data{};
    VkCommandBuffer cmd;
    PassTimer timer;
    std::vector<uint32_t> lightFirstView;                          // first shadow view of each light
    std::vector<std::shared_ptr<const ReceiverMask>> receiverMasks; // layer k of light i at 6 i + k
    std::vector<VkDeviceAddress> thinClusterMask;                   // the same layers; 0: every cluster
    std::vector<uint32_t> thinClusterBits; // their bits, built here and copied whole into the mapped buffer
    uint32_t viewFitMask = 0, receiverGridMask = 0;
    // Whether the frame runs view_fit (fitToView), which also counts the covered pixels (the first shade need not).
    bool viewFitRuns() const { return viewFitMask || receiverGridMask; }
    bool rhFrame = false; // the rh pass's counters were cleared this frame
    std::vector<std::vector<uint32_t>> finalRanges; // paged geometry: the clusters of each range of a view's phase 2
    // afsm, area lights: each light's grid layers and whether they are cube faces.
    std::vector<std::vector<AfsmLayer>> afsmLayers;
    std::vector<bool> afsmCube;
    uint64_t afsmClosedClusters = 0; // afsm: the model's closed clusters
    bool afsmBackFaces = false;      // afsm: they cast only light-back-facing triangles this frame
    bool afsmOffsetClear = true;     // afsm: the rays' offset is at most the default (closedClearance's bound)
    // The frame shows material colours: RenderSettings::colors, on a model with
    // more than white. Only then does the camera write its albedo target.
    const bool colours;

    // method: the sequences the frame runs (srt's frames that trace every pixel run frt's: SelectiveChoice).
    FrameScript(Impl& renderer, const RenderSettings& s, ShadowMethod method)
        : r(renderer), settings(s), spec(shadowMethodSpec(method)), bounds(r.geometry.bounds),
          rayOffset(s.rayOffset > 0.0f ? s.rayOffset : shadowRayOffset(bounds, r.geometry.maxPositionError)),
          lights(r.lights.empty() ? std::vector<Light>{defaultLight()} : r.lights), cmd(r.commandBuffer),
          colours(s.colors && r.geometry.coloured)
    {
        const Camera camera = r.camera ? *r.camera : defaultCamera(bounds);
        view = cameraViewProjection(camera, bounds, float(s.width) / float(s.height));
        data.cameraPosition = glm::vec4(view.eye, 1.0f);
        data.shading = glm::vec4(s.ambient, s.albedo, 0.0f, 0.0f);
        data.background = glm::vec4(s.background[0], s.background[1], s.background[2], 1.0f);
        data.pip = glm::vec4(float(PENUMBRA_PIP_DELTA_FRACTION), 0.0f, 0.0f, 0.0f);
        uint32_t maxLayers = 1;
        for (size_t i = 0; i < lights.size(); ++i) {
            // The maps of lights among the geometry start at the nearest triangle's depth (light_space.h: lightProjection).
            data.lights[i] = packLight(lights[i], bounds, s, nullptr, r.model ? &*r.model : nullptr);
            maxLayers = std::max(maxLayers, layers(uint32_t(i)));
        }
        if (r.targets.ensure(r.device, s.width, s.height, s.shadowMapSize, maxLayers))
            r.bindTargets();
        if (s.shadows == ShadowMethod::AliasFree) {
            r.ensureAfsmTargets();
            // Closed meshes cast only their light-back-facing triangles unless the camera may see inside one,
            // or the rays start farther off their receivers than the default offset the preprocessor kept
            // flagged solids clear of (closedClearance): then a ray might start inside a flagged solid.
            const bool compressed = r.geometry.encoding == GeometryEncoding::Compressed && r.model && r.shadowCulling.model;
            afsmOffsetClear = rayOffset <= shadowRayOffset(bounds, r.geometry.maxPositionError);
            afsmClosedClusters = r.afsm.prepareModel(r.device, compressed ? &*r.model : nullptr);
            afsmBackFaces = compressed && afsmOffsetClear &&
                            r.afsm.closedBackFaces(*r.model, *r.shadowCulling.model, view.eye, view.viewProj);
            afsmLayers.resize(lights.size());
            afsmCube.assign(lights.size(), false);
            for (size_t i = 0; i < lights.size(); ++i)
                if (isAreaLight(lights[i])) {
                    bool cube = false;
                    afsmLayers[i] = afsmAreaLayers(lights[i], bounds, cube);
                    afsmCube[i] = cube;
                }
        }
        if (s.shadows == ShadowMethod::RayHierarchy) {
            r.ensureRhTargets();
            rhFrame = true;
        }
        if (s.readbackLightLayers)
            r.targets.ensureLightLayers(r.device);
        if (s.measureFloors)
            r.ensureFloors();
        std::memcpy(r.targets.frameUniforms.mapped, &data, sizeof(data));
        lightFirstView.resize(lights.size());
        if (r.geometry.paged()) {
            r.pages.beginFrame();
            r.pages.ensureParking(r.device, uint64_t(s.width) * s.height);
        }
        receiverMasks.resize(6 * lights.size());
        thinClusterMask.assign(6 * lights.size(), 0);
        // Maps fitted to what the camera sees: directional lights, area lights whose maps are drawn, and afsm's
        // area-light grids (afsmAreaLayers). Views that cull the casters beside the points the camera sees: every
        // light but area lights.
        const bool gridsAllowed = s.cullBesideReceivers && s.cull != CullMode::None && r.geometry.encoding == GeometryEncoding::Compressed;
        for (uint32_t i = 0; spec.lightViews && i < lights.size(); ++i) {
            const bool area = isAreaLight(lights[i]);
            const bool afsmGrid = area && s.shadows == ShadowMethod::AliasFree;
            if (s.fitShadowMapsToView && (lights[i].type == LightType::Directional || (area && spec.drawsAreaMaps()) || afsmGrid))
                viewFitMask |= 1u << i;
            if (gridsAllowed && !area)
                receiverGridMask |= 1u << i;
        }
        timer.pool = r.queryPool;
        if (r.geometry.paged()) {
            // The lists a view draws, cut into ranges whose pages fit the pool (Culling::cutRanges).
            auto cutRanges = [this](const std::vector<uint32_t>& drawn) {
                std::vector<uint32_t> cuts, range;
                finalRanges.clear();
                GeometryPages::RangeCut cut(r.pages);
                for (uint32_t i = 0; i < drawn.size(); ++i) {
                    if (drawn[i] == Culling::kNoQuery)
                        continue;
                    if (!cut.add(drawn[i])) {
                        cuts.push_back(i);
                        finalRanges.push_back(std::move(range));
                        range.clear();
                        cut.next();
                        cut.add(drawn[i]);
                    }
                    range.push_back(drawn[i]);
                }
                finalRanges.push_back(std::move(range));
                return cuts;
            };
            auto ensureRange = [this](Culling& culling) {
                return [this, &culling](uint32_t view, size_t range) {
                    ensureResident(finalRanges.at(range), "the " + culling.viewName(view) + " view", true);
                };
            };
            auto queriesAnswered = [this](Culling& culling) {
                return [this, &culling](uint32_t view) {
                    r.submitAndWait(cmd, timer.passesSinceLastSubmit());
                    beginCommands();
                    return culling.finalDrawn(r.device, view);
                };
            };
            for (Culling* culling : {&r.culling, &r.shadowCulling}) {
                culling->cutRanges = cutRanges;
                culling->ensureRange = ensureRange(*culling);
                culling->queriesAnswered = queriesAnswered(*culling);
            }
        }
        if (s.measureFloors)
            timer.submitAndRestart = [this] {
                r.submitAndWait(cmd, timer.passesSinceLastSubmit());
                beginCommands();
            };
    }

    ~FrameScript()
    {
        for (Culling* culling : {&r.culling, &r.shadowCulling}) {
            culling->cutRanges = nullptr;
            culling->ensureRange = nullptr;
            culling->queriesAnswered = nullptr;
        }
    }

    uint32_t layers(uint32_t light) const { return uint32_t(data.lights[light].spotCosLayers.z); }
    uint32_t width() const { return r.targets.width; }
    uint32_t height() const { return r.targets.height; }

    void beginCommands()
    {
        VK_CHECK(vkResetCommandBuffer(cmd, 0));
        VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
        begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
        VK_CHECK(vkBeginCommandBuffer(cmd, &begin));
    }

    // The shadow views of every light's maps: its layers, or an area light's maps (if drawn).
    void planShadowViews()
    {
        std::vector<CullView> views;
        const bool occlusion = spec.shadowViewOcclusion && settings.depthBiasConstant >= 0.0f && settings.depthBiasSlope >= 0.0f;
        for (uint32_t i = 0; i < lights.size(); ++i) {
            lightFirstView[i] = uint32_t(views.size());
            const bool area = isAreaLight(lights[i]);
            if (area && settings.shadows == ShadowMethod::AliasFree) {
                // afsm's layers of an area light: frusta that hold the light and the layer's samples.
                for (const AfsmLayer& layer : afsmLayers[i])
                    views.push_back({"light" + std::to_string(i) + (afsmCube[i] ? ".face" + std::to_string(layer.index) : ""),
                                     1 + 6 * i + layer.index, layer.cull, false, false, nullptr});
                continue;
            }
            const uint32_t maps = area ? (spec.drawsAreaMaps() ? uint32_t(data.lights[i].spotCosLayers.w) : 0u) : spec.lightViews ? layers(i) : 0u;
            for (uint32_t k = 0; k < maps; ++k)
                views.push_back({"light" + std::to_string(i) + (maps > 1 ? (area ? ".map" : ".face") + std::to_string(k) : ""),
                                 1 + 6 * i + k, data.lights[i].viewProj[k], false, occlusion, area ? nullptr : receiverMasks[6 * i + k]});
        }
        r.shadowCulling.beginFrame(r.device, settings.cull, settings.adaptiveOcclusion, std::move(views));
        if (r.geometry.paged())
            r.shadowCulling.refreshCommands(r.geometry.commands); // planned from the load-time commands
    }

    // Paged geometry: makes the clusters resident (geometry_pages.h). A change
    // needs the device idle: with inFrame, the frame's commands so far are
    // submitted first and a new command buffer begun after.
    void ensureResident(const std::vector<uint32_t>& clusters, const std::string& what, bool inFrame)
    {
        GeometryPages& pages = r.pages;
        // Draw commands follow residency (culling.h). The tracer's rounds (not inFrame) change residency
        // without drawing: they leave the refresh (a pass over every planned draw) to the next in-frame call.
        if (!pages.allResident(clusters)) {
            if (inFrame)
                r.submitAndWait(cmd, timer.passesSinceLastSubmit());
            pages.ensure(r.device, r.geometry, *r.model, clusters, what);
            drawsStale = true;
            if (inFrame)
                beginCommands();
        } else {
            pages.ensure(r.device, r.geometry, *r.model, clusters, what); // the pages' last use only
        }
        if (inFrame && drawsStale)
            refreshDraws();
    }

    bool drawsStale = false; // residency changed since the culling's draw commands were refreshed
    void refreshDraws()
    {
        r.culling.refreshCommands(r.geometry.commands);
        r.shadowCulling.refreshCommands(r.geometry.commands);
        drawsStale = false;
    }

    // Paged geometry: a thin-triangle step in ranges. Each view's clusters are
    // those of its receiver mask's bits (every cluster for area lights) that
    // can reach it (clusterMayReachView); their union is cut into ranges
    // whose pages fit the pool, and each range is made resident and its part
    // of every view's clusters decoded (a cluster mask per range and view).
    // The thin map takes the minimum of what every range writes, so the map
    // is the same in any order.
    void recordThinInRanges(uint32_t light, bool area, uint32_t slot, uint32_t views, const std::function<ThinView(uint32_t)>& thinView)
    {
        const CullModel& model = *r.shadowCulling.model;
        const uint32_t clusterCount = uint32_t(model.clusterMin.size());
        const gpu::LightData& l = data.lights[light];
        const size_t words = (clusterCount + 31) / 32;
        std::vector<std::vector<uint32_t>> sets(views);
        std::vector<uint8_t> used(clusterCount, 0);
        for (uint32_t k = 0; k < views; ++k) {
            const uint32_t* mask = nullptr;
            if (!area && thinClusterMask[6 * light + k])
                mask = thinClusterBits.data() + (6 * light + k) * words;
            const glm::mat4& viewProj = l.viewProj[area ? slot : k];
            for (uint32_t c = 0; c < clusterCount; ++c)
                if ((!mask || (mask[c >> 5] >> (c & 31)) & 1u) &&
                    clusterMayReachView(viewProj, model.clusterMin[c], model.clusterMax[c], r.targets.shadowSize, 4.0f)) {
                    sets[k].push_back(c);
                    used[c] = 1;
                }
        }
        std::vector<uint32_t> clusters;
        for (uint32_t c = 0; c < clusterCount; ++c)
            if (used[c])
                clusters.push_back(c);
        const std::vector<std::vector<uint32_t>> ranges = r.pages.cutIntoRanges(clusters);
        std::vector<uint32_t> rangeOf(clusterCount, 0);
        for (uint32_t j = 0; j < ranges.size(); ++j)
            for (uint32_t c : ranges[j])
                rangeOf[c] = j;
        const size_t regionBytes = words * sizeof(uint32_t);
        if (r.pages.thinMasks.size < ranges.size() * views * regionBytes) { // the old masks may be in use
            r.submitAndWait(cmd, timer.passesSinceLastSubmit());
            beginCommands();
        } else if (r.pages.thinMasks.buffer) { // rewritten below: the previous step's must have run
            r.submitAndWait(cmd, timer.passesSinceLastSubmit());
            beginCommands();
        }
        r.pages.ensureThinMasks(r.device, std::max<uint64_t>(ranges.size() * views * regionBytes, 4));
        std::vector<uint32_t> bits(ranges.size() * views * words, 0u);
        for (uint32_t k = 0; k < views; ++k)
            for (uint32_t c : sets[k])
                bits[(rangeOf[c] * views + k) * words + (c >> 5)] |= 1u << (c & 31);
        vk::writeMapped(r.pages.thinMasks, bits.data(), bits.size() * sizeof(uint32_t));
        const VkDeviceAddress base = vk::bufferAddress(r.device, r.pages.thinMasks);
        for (uint32_t j = 0; j < ranges.size(); ++j) {
            ensureResident(ranges[j], "light " + std::to_string(light) + "'s thin-triangle views", true);
            for (uint32_t k = 0; k < views; ++k) {
                ThinView thin = thinView(k);
                thin.clusterMask = base + (j * views + k) * regionBytes;
                r.thinTriangles.record(cmd, r.device, r.geometry, r.trace.modelTableAddress(), r.targets.shadowSize,
                                       r.targets.thinMap.layers, thin);
            }
        }
    }

    // Paged geometry: afsm's compute path bins a layer's casters (its view's
    // clusters) in ranges whose pages fit the pool, each made resident in turn
    // (its raster path draws the view in ranges through the culling's hooks).
    // Empty in core.
    passes::AfsmPass::PagedCasters afsmPagedCasters(uint32_t light, uint32_t view)
    {
        passes::AfsmPass::PagedCasters paged;
        if (!r.geometry.paged())
            return paged;
        paged.ranges = r.pages.cutIntoRanges(r.shadowCulling.viewClusters(view));
        paged.makeResident = [this, light](const std::vector<uint32_t>& range) {
            ensureResident(range, "light " + std::to_string(light) + "'s afsm casters", true);
        };
        return paged;
    }

    // afsm, after a layer's samples: its most samples in one cell, read back
    // (the frame's commands so far submitted and waited for) when a cell of
    // the grid could hold more than one fragment's slice (AfsmPass::mayCrowd;
    // the casters then draw the crowded cells once per further slice); 0
    // otherwise.
    uint32_t afsmCellMost(bool soft)
    {
        if (!r.afsm.mayCrowd(soft))
            return 0;
        r.afsm.recordCellMostReadback(cmd);
        r.submitAndWait(cmd, timer.passesSinceLastSubmit());
        beginCommands();
        return r.afsm.cellMost();
    }

    // Paged geometry: rh's casters are drawn in batches within ranges whose
    // pages fit the pool, each range made resident before its first batch
    // (the device is idle then: every batch ends with a wait). Empty in core.
    passes::RhPaging rhPaging(uint32_t light)
    {
        passes::RhPaging paging;
        if (!r.geometry.paged())
            return paging;
        paging.cut = [this](const std::vector<uint32_t>& clusters) { return r.pages.cutIntoRanges(clusters); };
        paging.makeResident = [this, light](const std::vector<uint32_t>& clusters) {
            ensureResident(clusters, "light " + std::to_string(light) + "'s rh casters", true);
        };
        return paging;
    }

    // Paged geometry: after a trace pass, the rays it parked are traced again
    // until none is left. The clusters the last dispatch visited are made
    // resident when they fit together (then its parked rays all finish: a ray
    // traced again visits no cluster it did not visit before); otherwise the
    // first half of its parked rays (in Z order over the pixels) is traced
    // alone, and so on down to one entry: a single ray is then traced once per
    // range of its clusters that fits; a pixel's light samples must fit together.
    // After a batch that fit, the next one taken from the rest is twice as large.
    void traceParked(uint32_t light, uint32_t samples)
    {
        GeometryPages& pages = r.pages;
        r.submitAndWait(cmd, timer.passesSinceLastSubmit());
        // Parked entries arrive in atomic order; sorted along a Z curve over the pixels, a batch's rays are
        // neighbours whose working sets overlap, so halving leaves fewer, larger batches that fit the pool.
        const uint32_t width = r.targets.width;
        auto zOrder = [width](uint32_t entry) {
            const uint32_t pixel = entry & ~uint32_t(PENUMBRA_RAY_ONE_SAMPLE);
            uint64_t key = 0;
            for (uint32_t bit = 0; bit < 16; ++bit)
                key |= uint64_t(((pixel % width) >> bit) & 1u) << (2 * bit) | uint64_t(((pixel / width) >> bit) & 1u) << (2 * bit + 1);
            return key;
        };
        auto parked = [&] {
            std::vector<std::pair<uint64_t, uint32_t>> keyed;
            keyed.reserve(pages.parkedCount());
            for (uint32_t i = 0; i < pages.parkedCount(); ++i)
                keyed.push_back({zOrder(pages.parkedEntries()[i]), pages.parkedEntries()[i]});
            std::sort(keyed.begin(), keyed.end());
            std::vector<uint32_t> entries(keyed.size());
            for (size_t i = 0; i < keyed.size(); ++i)
                entries[i] = keyed[i].second;
            return entries;
        };
        std::vector<uint32_t> front = parked(), rest;
        std::vector<uint32_t> visited = pages.visitedClusters();
        pages.frame.parkedRays += front.size();
        size_t batch = front.size();
        const std::string what = "the rays toward light " + std::to_string(light);
        auto dispatch = [&](const std::vector<uint32_t>& toTrace) { dispatchParked(light, samples, toTrace); };
        for (uint32_t round = 0; !front.empty() || !rest.empty(); ++round) {
            if (round > 4 * 1024 * 1024)
                fail("--geometry-budget", "parked rays of light " + std::to_string(light) + " did not finish");
            std::vector<uint32_t> toTrace;
            if (front.empty()) {
                const size_t take = std::min(batch, rest.size());
                toTrace.assign(rest.begin(), rest.begin() + take);
                rest.erase(rest.begin(), rest.begin() + take);
            } else if (pages.fits(visited)) {
                ensureResident(visited, what, false);
                toTrace.swap(front);
                batch = std::max<size_t>(2 * batch, 1); // the next batch from `rest` may be larger again
            } else if (front.size() == 1) {
                // One entry whose clusters exceed the pool. A single ray (hard shadows, or a pixel outside
                // the penumbra mask) is any-hit: traced once per range of its clusters that fits, it is
                // shadowed if one range hits it and lit otherwise (each trace writes its visibility, and a
                // ray traced again enters the same clusters). A pixel's light samples must fit together.
                if (samples != 0 && (front[0] & PENUMBRA_RAY_ONE_SAMPLE) == 0)
                    ensureResident(visited, "one pixel's light samples toward light " + std::to_string(light), false); // fails
                const std::vector<std::vector<uint32_t>> ranges = pages.cutIntoRanges(visited);
                const uint32_t entry = front[0];
                for (const std::vector<uint32_t>& range : ranges) {
                    ensureResident(range, "one ray toward light " + std::to_string(light), false);
                    dispatch({entry});
                    if (pages.parkedCount() == 0)
                        break; // it hit
                }
                front.clear();
                continue;
            } else {
                const size_t half = front.size() / 2;
                rest.insert(rest.begin(), front.begin() + half, front.end());
                toTrace.assign(front.begin(), front.begin() + half);
                batch = half;
            }
            front.clear();
            dispatch(toTrace);
            front = parked();
            visited = pages.visitedClusters();
            pages.frame.parkedRays += front.size();
        }
        beginCommands();
    }

    // Paged geometry: traces the listed ray-list entries again (one dispatch, submitted and waited for);
    // the parking buffer then holds what they parked and visited.
    void dispatchParked(uint32_t light, uint32_t samples, const std::vector<uint32_t>& toTrace)
    {
        GeometryPages& pages = r.pages;
        {
            // The list into the frame's ray list (its header holds the indirect dispatch), then the trace.
            auto* list = static_cast<uint32_t*>(pages.retraceList.mapped);
            passes::TracePass::writeListHeader(r.device, uint32_t(toTrace.size()), list);
            std::copy(toTrace.begin(), toTrace.end(), list + PENUMBRA_RAY_LIST_HEADER_UINTS);
            pages.clearParking();
            beginCommands();
            vk::memoryBarrier(cmd, kCompute | kIndirect, kStorageRW | kIndirectRead, kCopy, kTransferWrite);
            const VkBufferCopy region{0, 0, (PENUMBRA_RAY_LIST_HEADER_UINTS + toTrace.size()) * sizeof(uint32_t)};
            vkCmdCopyBuffer(cmd, pages.retraceList.buffer, r.targets.rayList.buffer, 1, &region);
            vk::memoryBarrier(cmd, kCopy, kTransferWrite, kCompute | kIndirect, kStorageRead | kIndirectRead);
            r.trace.record(cmd, light, uint32_t(data.lights[light].positionType.w), rayOffset, samples, pages.parkingAddress(r.device),
                           pages.clusterWords());
            vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute | kHost, kStorageRW | VK_ACCESS_2_HOST_READ_BIT);
            r.submitAndWait(cmd, "trace (parked rays)");
            ++pages.frame.parkingRounds;
        }
    }

    // RenderSettings::measureFloors: a raster pass's floor, every triangle of
    // the uncompressed model drawn depth-only from viewProj into a depth target of the pass's size.
    void drawFloor(const vk::Image& target, const glm::mat4& viewProj)
    {
        vk::transition(cmd, target, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL, kDepthTests,
                       VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT, kDepthTests,
                       VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);
        r.shadowMap.record(cmd, r.culling, ~0u, r.floorGeometry, target, 0, {viewProj}, {});
    }

    // Camera: the G-buffer, and the targets of the per-pixel passes made ready.
    void recordCamera()
    {
        FrameTargets& t = r.targets;
        if (settings.measureFloors) {
            drawFloor(t.floorDepth, view.viewProj);
            timer.mark(cmd, PassId::CameraFloor);
        }
        vkCmdFillBuffer(cmd, t.stats.buffer, 0, VK_WHOLE_SIZE, 0);
        vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute, kStorageRW);
        r.gbuffer.record(cmd, r.culling, 0, r.geometry, {&t.surface, &t.albedo, &t.depth},
                         {view.viewProj, glm::vec4(view.eye, 1.0f), colours ? vk::bufferAddress(r.device, r.geometry.albedo) : 0,
                          afsmBackFaces ? r.afsm.closedBitsAddress(r.device) : 0});
        timer.mark(cmd, PassId::Camera);
        for (vk::Image* image : {&t.color, &t.visibility})
            vk::transition(cmd, *image, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL, kNone, 0, kCompute, kStorageRW);
    }

    // The view fit: bounds and receiver grids read back (the one mid-frame
    // submission), maps narrowed, receiver masks built, shadow views planned.
    void fitToView()
    {
        std::vector<uint32_t> gridLayers(lights.size());
        for (uint32_t i = 0; i < lights.size(); ++i)
            gridLayers[i] = layers(i);
        if (settings.measureFloors) {
            r.viewFit.recordFloor(cmd, r.device, r.targets.viewBounds, width(), height());
            timer.mark(cmd, PassId::ViewFitFloor);
        }
        uint32_t pointMask = 0, directionalMask = 0;
        for (uint32_t i = 0; i < lights.size(); ++i) {
            pointMask |= lights[i].type == LightType::Point ? 1u << i : 0u;
            directionalMask |= lights[i].type == LightType::Directional ? 1u << i : 0u;
        }
        const uint32_t used = viewFitMask | receiverGridMask;
        r.viewFit.record(cmd, r.device, r.targets.viewBounds, r.targets.receiverGrids, viewFitMask, receiverGridMask, pointMask & used,
                         directionalMask & used, gridLayers, width(), height(),
                         vk::bufferAddress(r.device, r.targets.stats) + PENUMBRA_STAT_COVERED * sizeof(uint64_t));
        timer.mark(cmd, PassId::ViewFit);
        r.submitAndWait(cmd, timer.passesSinceLastSubmit());

        for (uint32_t i = 0; i < lights.size(); ++i) {
            const glm::mat4 gridViewProj = data.lights[i].viewProj[0]; // a directional light's model-fitted map
            if (viewFitMask & (1u << i)) {
                ViewClip clips[6];
                readViewClips(r.targets.viewBounds, i, clips);
                if (settings.shadows == ShadowMethod::AliasFree && isAreaLight(lights[i])) {
                    // afsm's grid of the area light around the samples (its map 0 stays model-fitted: the bounds' space).
                    bool cube = false;
                    afsmLayers[i] = afsmAreaLayers(lights[i], bounds, cube, &clips[0], r.targets.afsmGrid);
                    afsmCube[i] = cube;
                } else {
                    data.lights[i] = packLight(lights[i], bounds, settings, clips, r.model ? &*r.model : nullptr);
                }
            }
            if (receiverGridMask & (1u << i))
                for (uint32_t layer = 0; layer < layers(i); ++layer)
                    receiverMasks[6 * i + layer] =
                        readReceiverMask(r.targets.viewBounds, i, layer, layer == 0 ? gridViewProj : data.lights[i].viewProj[layer],
                                         data.lights[i].viewProj[layer], r.targets.shadowSize);
        }
        if (spec.uses(Step::ThinTriangles) && receiverGridMask) {
            // The clusters whose thin triangles may reach a receiver's texel, per light layer.
            const size_t words = (r.shadowCulling.model->clusterMin.size() + 31) / 32;
            const VkDeviceSize bytes = 6 * lights.size() * words * sizeof(uint32_t);
            r.targets.ensureThinClusterMasks(r.device, bytes);
            thinClusterBits.assign(6 * lights.size() * words, 0u);
            const VkDeviceAddress base = vk::bufferAddress(r.device, r.targets.thinClusterMasks);
            for (size_t l = 0; l < receiverMasks.size(); ++l)
                if (receiverMasks[l]) {
                    ReceiverMask thinReach = *receiverMasks[l];
                    thinReach.margin *= passes::kThinMaskMarginScale;
                    r.shadowCulling.markClustersNearReceivers(thinReach, thinClusterBits.data() + l * words);
                    thinClusterMask[l] = base + l * words * sizeof(uint32_t);
                }
            vk::writeMapped(r.targets.thinClusterMasks, thinClusterBits.data(), bytes);
        }
        std::memcpy(r.targets.frameUniforms.mapped, &data, sizeof(data));
        planShadowViews();
        beginCommands();
        r.shadowCulling.resetQueries(cmd);
        timer.mark(cmd, PassId::ViewFitReadback); // the round trip through the host
    }

    // One step of a light's sequence; slot: the area light's map (0: the centre), first: its first map drawn.
    void runStep(const MethodStep& step, uint32_t light, bool area, uint32_t slot, bool first)
    {
        const gpu::LightData& l = data.lights[light];
        FrameTargets& t = r.targets;
        const uint32_t maps = uint32_t(l.spotCosLayers.w);
        switch (step.step) {
        case Step::ClearMarks:
            vkCmdFillBuffer(cmd, t.marks.buffer, 0, VK_WHOLE_SIZE, 0);
            vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute, kStorageRW);
            return;
        case Step::ShadowMap:
            if (settings.measureFloors) {
                for (uint32_t layer = 0; layer < (area ? 1 : layers(light)); ++layer)
                    drawFloor(t.floorMapDepth, l.viewProj[area ? slot : layer]);
                timer.mark(cmd, PassId::ShadowMapFloor);
            }
            r.shadowMap.begin(cmd, t.shadowMap);
            for (uint32_t layer = 0; layer < (area ? 1 : layers(light)); ++layer)
                r.shadowMap.record(cmd, r.shadowCulling, lightFirstView[light] + (area ? slot : layer), r.geometry, t.shadowMap, layer,
                                   {l.viewProj[area ? slot : layer]}, {settings.depthBiasConstant, settings.depthBiasSlope});
            r.shadowMap.end(cmd, t.shadowMap);
            timer.mark(cmd, PassId::ShadowMap);
            return;
        case Step::ThinTriangles: {
            r.thinTriangles.clear(cmd, t.thinMap, t.shadowSize, area ? 0 : layers(light), area);
            auto thinView = [&](uint32_t layer) {
                if (area) {
                    const float halfTan = 0.5f * l.mapRange[slot].y;
                    return ThinView{l.viewProj[slot], 0, glm::vec3(l.mapEye[slot]), true, 1.0f / std::sqrt(1.0f + 2.0f * halfTan * halfTan),
                                    l.mapRange[slot].y, 0, true};
                }
                const float depthPerDistance = uint32_t(l.positionType.w) == PENUMBRA_LIGHT_SPOT ? l.spotCosLayers.y : 0.57735f;
                return ThinView{l.viewProj[layer], layer, glm::vec3(l.positionType), l.shadowParams.z != 0.0f, depthPerDistance,
                                l.shadowParams.w, thinClusterMask[6 * light + layer], false};
            };
            const uint32_t views = area ? 1 : layers(light);
            if (r.geometry.paged())
                recordThinInRanges(light, area, slot, views, thinView);
            else
                for (uint32_t layer = 0; layer < views; ++layer)
                    r.thinTriangles.record(cmd, r.device, r.geometry, r.trace.modelTableAddress(), t.shadowSize, t.thinMap.layers,
                                           thinView(layer));
            vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRead);
            timer.mark(cmd, PassId::ThinTriangles);
            return;
        }
        case Step::PenumbraMask: {
            const uint32_t top = maskTopLevel(t.shadowSize);
            r.penumbraMask.clear(cmd);
            r.classify.recordSoft(cmd, {light, slot, PENUMBRA_SOFT_RECEIVERS, 0, 1.0f, t.shadowSize, top, 0}, uint32_t(l.positionType.w), width(),
                                  height());
            const float range = l.mapRange[slot].x - l.mapEye[slot].w;
            r.penumbraMask.record(cmd, {glm::inverse(l.viewProj[slot]), light, slot, 0, t.shadowSize, top, spec.uses(Step::ThinTriangles) ? 1u : 0u,
                                        float(PENUMBRA_PIP_DELTA_FRACTION) * range, 0},
                                   uint32_t(l.positionType.w));
            timer.mark(cmd, PassId::PenumbraMask);
            return;
        }
        case Step::Classify:
            for (bool floor : {true, false}) {
                if (floor && !settings.measureFloors)
                    continue;
                if (area) {
                    const uint32_t mode = slot == 0 ? step.mode : step.cornerMode;
                    const bool average = mode == PENUMBRA_SOFT_AVERAGE;
                    r.classify.recordSoft(cmd, {light, slot, mode, average && first ? 1u : 0u, average ? 1.0f / float(maps) : 1.0f,
                                                t.shadowSize, maskTopLevel(t.shadowSize), 0},
                                          uint32_t(l.positionType.w), width(), height(), floor);
                } else {
                    r.classify.record(cmd, {light, step.mode}, uint32_t(l.positionType.w), width(), height(), floor);
                }
                timer.mark(cmd, floor ? PassId::ClassifyFloor : PassId::Classify);
            }
            return;
        case Step::Compact:
            if (settings.measureFloors) {
                r.compact.recordFloor(cmd, width(), height());
                timer.mark(cmd, PassId::CompactFloor);
            }
            r.compact.record(cmd, width(), height());
            timer.mark(cmd, PassId::Compact);
            return;
        case Step::Trace:
            if (r.geometry.paged()) {
                r.pages.clearParking();
                r.trace.record(cmd, light, uint32_t(l.positionType.w), rayOffset, area ? settings.lightSamples : 0, r.pages.parkingAddress(r.device),
                               r.pages.clusterWords());
                vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute | kHost, kStorageRW | VK_ACCESS_2_HOST_READ_BIT);
                timer.mark(cmd, PassId::Trace);
                traceParked(light, area ? settings.lightSamples : 0);
                return;
            }
            r.trace.record(cmd, light, uint32_t(l.positionType.w), rayOffset, area ? settings.lightSamples : 0);
            vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCompute, kStorageRW);
            timer.mark(cmd, PassId::Trace);
            return;
        case Step::AliasFree:
            if (area) {
                // Soft shadows (section 4): the table for the light's shape, then its grid's layers.
                r.afsm.prepareSoft(r.device, cmd, settings.lightSamples, lights[light].type == LightType::Rectangle);
                r.afsm.clear(cmd);
                const std::vector<AfsmLayer>& grid = afsmLayers[light];
                for (uint32_t k = 0; k < grid.size(); ++k) {
                    r.afsm.recordSamples(cmd, light, grid[k].index, grid[k].grid, afsmCube[light], rayOffset, true);
                    timer.mark(cmd, PassId::AfsmSamples);
                    const uint32_t most = afsmCellMost(true);
                    const passes::AfsmPass::PagedCasters paged = afsmPagedCasters(light, lightFirstView[light] + k);
                    r.afsm.recordCasters(cmd, r.device, r.shadowCulling, r.geometry, r.trace.modelTableAddress(),
                                         {lightFirstView[light] + k, 6 * light + grid[k].index, grid[k].grid, light, rayOffset, true,
                                          afsmBackFaces, most},
                                         [this] { timer.mark(cmd, PassId::AfsmBin); }, &paged);
                    timer.mark(cmd, PassId::AfsmCasters);
                }
                return;
            }
            r.afsm.clear(cmd);
            for (uint32_t layer = 0; layer < layers(light); ++layer) {
                const bool parallel = lights[light].type == LightType::Directional; // sheared slots (afsm.glsli: AfsmParallel)
                r.afsm.recordSamples(cmd, light, layer, l.viewProj[layer], layers(light) == 6, rayOffset, false, parallel);
                timer.mark(cmd, PassId::AfsmSamples);
                const uint32_t most = afsmCellMost(false);
                const passes::AfsmPass::PagedCasters paged = afsmPagedCasters(light, lightFirstView[light] + layer);
                const auto afterBin = [this] { timer.mark(cmd, PassId::AfsmBin); };
                const auto afterRows = [this] {
                    timer.mark(cmd, PassId::AfsmRows);
                    r.submitAndWait(cmd, timer.passesSinceLastSubmit());
                    beginCommands();
                };
                passes::AfsmPass::CasterLayer casters{lightFirstView[light] + layer, 6 * light + layer, l.viewProj[layer], light, rayOffset, false,
                                                      afsmBackFaces, most, parallel};
                // A directional light's casters in two passes (AfsmPass::twoPassSplit): those nearest the light,
                // which shadow most where a roof covers the view; then, if they shadowed enough of it, the cells'
                // depths again over the samples still lit, and the rest against those.
                const float split = r.afsm.twoPassSplit();
                if (parallel && split > 0.0f && r.afsm.rowPassUsed(r.shadowCulling, r.geometry, r.trace.modelTableAddress()) &&
                    r.afsm.nearCoverPays(r.shadowCulling, lightFirstView[light] + layer, l.viewProj[layer])) {
                    passes::AfsmPass::CasterLayer nearest = casters;
                    nearest.nearTo = split;
                    nearest.countShadowed = true;
                    r.afsm.recordCasters(cmd, r.device, r.shadowCulling, r.geometry, r.trace.modelTableAddress(), nearest, afterBin, &paged,
                                         afterRows);
                    timer.mark(cmd, PassId::AfsmCasters);
                    r.shadowCulling.resetViewTimestamps(cmd, casters.view); // the second pass marks the view again
                    casters.nearFrom = split;
                    casters.trimRows = r.afsm.refreshPays(r.afsm.shadowedPixels());
                    if (casters.trimRows) {
                        r.afsm.recordRefresh(cmd, light, layer, l.viewProj[layer], rayOffset);
                        timer.mark(cmd, PassId::AfsmSamples);
                    }
                }
                r.afsm.recordCasters(cmd, r.device, r.shadowCulling, r.geometry, r.trace.modelTableAddress(), casters, afterBin, &paged, afterRows);
                timer.mark(cmd, PassId::AfsmCasters);
            }
            return;
        case Step::RayHierarchy: {
            r.afsm.clear(cmd);
            if (rhFrame) {
                r.rh.beginFrame(cmd);
                rhFrame = false;
            }
            // One hierarchy over all the light's rays; the casters of all its views (a point light's six faces).
            std::vector<std::vector<uint32_t>> clusters;
            for (uint32_t layer = 0; layer < layers(light); ++layer) {
                clusters.push_back(r.shadowCulling.viewClusters(lightFirstView[light] + layer));
                r.shadowCulling.markView(cmd, lightFirstView[light] + layer, false);
            }
            passes::RhOptions options;
            options.test = settings.coneTest == ConeTest::Spheres ? PENUMBRA_RH_TEST_SPHERES : PENUMBRA_RH_TEST_PRECISE;
            options.sort = settings.rhSort;
            options.twoPass = settings.rhTwoPass;
            options.earlyAccept = settings.rhEarlyAccept;
            options.cullBehindReceivers = settings.rhCullBehindReceivers;
            // Section 3.6: closed clusters cast only light-back-facing triangles, where that is exact (rh.h).
            const bool directional = lights[light].type == LightType::Directional;
            options.closedCulling = settings.rhClosedMeshes && r.model &&
                                    passes::closedCullingExact(*r.model, view.eye,
                                                               directional ? -glm::normalize(lights[light].direction) : lights[light].position,
                                                               directional);
            r.rh.recordLight(cmd, light, lights[light], rayOffset, options, r.geometry, *r.shadowCulling.model, clusters,
                             [this](uint32_t cluster) { return (r.model->clusters[cluster].flags & model::kClusterClosed) != 0; },
                             [this] { timer.mark(cmd, PassId::RhBuild); },
                             [this] {
                                 r.submitAndWait(cmd, "rh_traverse");
                                 beginCommands();
                             },
                             rhPaging(light));
            for (uint32_t layer = 0; layer < layers(light); ++layer)
                r.shadowCulling.markView(cmd, lightFirstView[light] + layer, true);
            timer.mark(cmd, PassId::RhTraverse);
            return;
        }
        case Step::AfsmResolve:
            r.afsm.recordResolve(cmd, light, rayOffset, area);
            timer.mark(cmd, PassId::AfsmSamples);
            return;
        case Step::Shade: {
            const bool firstLight = light + 1 == lights.size();
            const ShadePush push{light, firstLight ? 1u : 0u, settings.debugPip && spec.traces() ? 1u : 0u,
                                 firstLight && !viewFitRuns() ? 1u : 0u, colours ? 1u : 0u};
            // kShadeLookup: the visibility from the shadow map, stored only where it is read back (no classify
            // pass wrote the marks, which the light layers read: zero).
            const bool lookup = step.mode == kShadeLookup && !area;
            const bool storeVisibility = settings.readbackGBuffer || settings.readbackLightLayers;
            if (lookup && settings.readbackLightLayers) {
                vkCmdFillBuffer(cmd, t.marks.buffer, 0, VK_WHOLE_SIZE, 0);
                vk::memoryBarrier(cmd, kClear, kTransferWrite, kCompute | kCopy, kStorageRW | kTransferRead);
            }
            if (settings.measureFloors) {
                r.shade.record(cmd, push, uint32_t(l.positionType.w), width(), height(), true, lookup);
                timer.mark(cmd, PassId::ShadeFloor);
            }
            r.shade.record(cmd, push, uint32_t(l.positionType.w), width(), height(), false, lookup, storeVisibility);
            timer.mark(cmd, PassId::Shade);
            if (settings.readbackLightLayers)
                copyLightLayers(light);
            return;
        }
        }
    }

    // RenderSettings::readbackLightLayers: the light's visibility and marks
    // into its slice of the read-back buffers, before the next light rewrites them.
    void copyLightLayers(uint32_t light)
    {
        FrameTargets& t = r.targets;
        const VkDeviceSize slice = VkDeviceSize(width()) * height() * 4;
        vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCopy, kTransferRead);
        vk::transition(cmd, t.visibility, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, kCompute, kStorageWrite, kCopy,
                       kTransferRead);
        VkBufferImageCopy region{};
        region.bufferOffset = light * slice;
        region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
        region.imageExtent = {width(), height(), 1};
        vkCmdCopyImageToBuffer(cmd, t.visibility.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, t.readbackLightVisibility.buffer, 1, &region);
        vk::transition(cmd, t.visibility, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL, kCopy, kTransferRead,
                       kCompute | kCopy, kStorageRW | kTransferRead);
        VkBufferCopy marks{0, light * slice, slice};
        vkCmdCopyBuffer(cmd, t.marks.buffer, t.readbackLightMarks.buffer, 1, &marks);
        vk::memoryBarrier(cmd, kCopy, kTransferRead, kCompute | kClear, kStorageRW | kTransferWrite);
    }

    // The method's sequence for one light.
    void recordLight(uint32_t light)
    {
        if (!isAreaLight(lights[light])) {
            for (const MethodStep& step : spec.hard)
                runStep(step, light, false, 0, true);
            return;
        }
        const uint32_t maps = uint32_t(data.lights[light].spotCosLayers.w);
        for (const MethodStep& step : spec.softBegin)
            runStep(step, light, true, 0, true);
        for (uint32_t m = 0; m < maps; ++m) // corner maps first; the centre map (slot 0) last, its depths decide umbra and lit
            for (const MethodStep& step : spec.softMap)
                runStep(step, light, true, maps - 1 - m, m == 0);
        for (const MethodStep& step : spec.softEnd)
            runStep(step, light, true, 0, true);
    }

    void recordReadback()
    {
        FrameTargets& t = r.targets;
        auto copyImage = [&](vk::Image& image, vk::Buffer& buffer) {
            vk::transition(cmd, image, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, kCompute | kColorOut,
                           kStorageWrite | VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT, kCopy, kTransferRead);
            VkBufferImageCopy region{};
            region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
            region.imageExtent = {width(), height(), 1};
            vkCmdCopyImageToBuffer(cmd, image.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, buffer.buffer, 1, &region);
        };
        copyImage(t.color, t.readbackColor);
        vk::memoryBarrier(cmd, kCompute, kStorageWrite, kCopy, kTransferRead);
        VkBufferCopy statsRegion{0, 0, PENUMBRA_STAT_COUNT * sizeof(uint64_t)};
        vkCmdCopyBuffer(cmd, t.stats.buffer, t.readbackStats.buffer, 1, &statsRegion);
        if (settings.readbackGBuffer) {
            copyImage(t.surface, t.readbackSurface);
            if (colours)
                copyImage(t.albedo, t.readbackAlbedo);
            copyImage(t.visibility, t.readbackVisibility);
        }
        vk::memoryBarrier(cmd, kCopy | kCompute, kTransferWrite | kStorageWrite, kHost, VK_ACCESS_2_HOST_READ_BIT);
        timer.mark(cmd, PassId::Readback);
    }

    Frame finish(std::chrono::steady_clock::time_point cpuStart);
};

Frame Renderer::Impl::FrameScript::finish(std::chrono::steady_clock::time_point cpuStart)
{
    const FrameTargets& t = r.targets;
    Frame frame;
    frame.color.width = width();
    frame.color.height = height();
    const size_t pixels = size_t(width()) * height();
    auto floats = [](const vk::Buffer& buffer) { return static_cast<const float*>(buffer.mapped); };
    frame.color.rgba.resize(pixels * 4);
    halfToFloat(static_cast<const uint16_t*>(t.readbackColor.mapped), frame.color.rgba.data(), pixels * 4); // kColorFormat
    if (settings.readbackGBuffer) {
        const auto* surface = static_cast<const uint32_t*>(t.readbackSurface.mapped);
        const auto* albedo = static_cast<const uint32_t*>(t.readbackAlbedo.mapped);
        frame.positions.resize(pixels * 4);
        frame.normals.resize(pixels * 4);
        for (size_t i = 0; i < pixels; ++i)
            decodeSurface(surface + 4 * i, colours ? albedo[i] : kWhiteAlbedo, &frame.positions[4 * i], &frame.normals[4 * i]);
        frame.visibility.assign(floats(t.readbackVisibility), floats(t.readbackVisibility) + pixels);
    }

    if (settings.readbackLightLayers) {
        const float* visibility = floats(t.readbackLightVisibility);
        const uint32_t* marks = static_cast<const uint32_t*>(t.readbackLightMarks.mapped);
        frame.lightVisibility.assign(visibility, visibility + pixels * lights.size());
        frame.pip.assign(pixels, 0.0f);
        for (size_t l = 0; l < lights.size(); ++l)
            for (size_t i = 0; i < pixels; ++i)
                if (marks[l * pixels + i] != 0)
                    frame.pip[i] = 1.0f;
    }

    // Timings and counters.
    // Each timestamp's first query (vk::writeTimestamp).
    std::vector<uint64_t> queries(vk::kTimestampQueries * timer.ended.size()), ticks(timer.ended.size());
    vk::readQueryResults(r.device, r.queryPool, 0, uint32_t(queries.size()), queries.size() * sizeof(uint64_t), queries.data(), sizeof(uint64_t),
                         VK_QUERY_RESULT_64_BIT, "the frame's timestamps");
    for (size_t i = 0; i < ticks.size(); ++i)
        ticks[i] = queries[vk::kTimestampQueries * i];
    const double period = r.device.properties.limits.timestampPeriod * 1e-6; // ms per tick
    double passMs[size_t(PassId::Count)] = {};
    bool ran[size_t(PassId::Count)] = {};
    for (size_t i = 1; i < ticks.size(); ++i) {
        passMs[size_t(timer.ended[i])] +=
            timer.hostEnds.empty() ? double(ticks[i] - ticks[i - 1]) * period
                                   : timer.hostEnds[i] - timer.hostEnds[i - 1];
        ran[size_t(timer.ended[i])] = true;
    }
    const uint64_t* counters = static_cast<const uint64_t*>(t.readbackStats.mapped);
    FrameStats& out = frame.stats;
    out.triangles = r.geometry.triangles;
    out.width = width();
    out.height = height();
    out.lights = uint32_t(lights.size());
    out.shadows = settings.shadows;
    out.coveredPixels = counters[PENUMBRA_STAT_COVERED]; // counted by view_fit, or by the first light's shade pass
    out.pipPixels = counters[PENUMBRA_STAT_PIP];
    out.pipFraction = out.coveredPixels ? double(out.pipPixels) / (double(out.coveredPixels) * out.lights) : 0.0;
    out.rays = counters[PENUMBRA_STAT_RAYS];
    out.nodesVisited = counters[PENUMBRA_STAT_NODES];
    out.leavesVisited = counters[PENUMBRA_STAT_LEAVES];
    out.triangleTests = counters[PENUMBRA_STAT_TRIANGLES];
    out.penumbraPixels = counters[PENUMBRA_STAT_PENUMBRA];
    const auto areaLights = uint32_t(std::count_if(lights.begin(), lights.end(), [](const Light& l) { return isAreaLight(l); }));
    out.penumbraFraction = out.coveredPixels && areaLights ? double(out.penumbraPixels) / (double(out.coveredPixels) * areaLights) : 0.0;
    out.lightSamples = areaLights && (spec.traces() || settings.shadows == ShadowMethod::AliasFree) ? settings.lightSamples
                       : areaLights                                                                ? settings.softShadowMaps
                                                                                                   : 0;
    out.rayOffset = spec.traces() || settings.shadows == ShadowMethod::AliasFree || settings.shadows == ShadowMethod::RayHierarchy ? rayOffset
                                                                                                                                : 0.0f;
    if (settings.shadows == ShadowMethod::AliasFree) {
        out.afsmClosedClusters = afsmClosedClusters;
        out.afsmCellMost = uint32_t(counters[PENUMBRA_STAT_AFSM_CELL_MOST]);
        out.afsmSliceDraws = r.afsm.takeSliceDraws();
        r.afsm.takeWideStats(out.afsmWideCasters, out.afsmWideRasterLayers, out.afsmTwoPassLayers, out.afsmRefreshedLayers);
        out.afsmComputePath = r.afsm.computePathUsed();
        out.afsmClosedCasting = !afsmClosedClusters ? "none closed"
                                : afsmBackFaces     ? "back faces"
                                : !afsmOffsetClear  ? "both sides (ray offset above the default)"
                                                    : "both sides (camera inside a closed mesh)";
    }
    if (settings.shadows == ShadowMethod::RayHierarchy) {
        const passes::RhFrameStats rh = r.rh.frameStats();
        out.rays = rh.rays;
        out.nodesVisited = rh.pairsTested;
        out.triangleTests = rh.rayTests;
        out.rhCasters = rh.casters;
        out.rhBatches = rh.batches;
        out.rhRounds = rh.rounds;
        out.rhPeakPairBytes = rh.peakPairBytes;
        out.rhLights = rh.lights;
        out.rhSortedLights = rh.sortedLights;
        out.rhAcceptedNodes = rh.accepted;
        out.rhIncoherence = rh.incoherence;
        out.rhClosedCulled = rh.closedCulled;
    }
    if (r.geometry.paged()) {
        const GeometryPageStats& pages = r.pages.frame;
        out.geometryBudgetBytes = r.pages.slotBytes();
        out.geometryBytes = r.pages.geometryBytes();
        out.residentPeakBytes = pages.residentPeakBytes;
        out.modelDeviceBytes = r.geometry.deviceBytes;
        out.pagesUploaded = pages.pagesUploaded;
        out.bytesStreamed = pages.bytesStreamed;
        out.parkingRounds = pages.parkingRounds;
        out.parkedRays = pages.parkedRays;
    }
    out.device = r.device.info;
    for (uint32_t pass = 0; pass < uint32_t(PassId::Count); ++pass)
        if (ran[pass])
            out.passes.push_back({passName(PassId(pass)), passMs[pass]});
    out.cull = settings.cull;
    out.views = r.culling.endFrame(r.device);
    for (ViewCullStats& shadowView : r.shadowCulling.endFrame(r.device))
        out.views.push_back(std::move(shadowView));
    out.gpuMs = double(ticks.back() - ticks.front()) * period;
    out.cpuMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - cpuStart).count();
    return frame;
}

Frame Renderer::Impl::render(const RenderSettings& settings)
{
    vk::checkUsable(device);
    validate(settings);
    const auto cpuStart = std::chrono::steady_clock::now();
    // srt: this frame's way, selective or every pixel (selective_choice.h). Frames that time the
    // floors, show the traced pixels or stream the model always run srt's own sequence.
    const bool adaptive = settings.shadows == ShadowMethod::Selective && settings.srtTraceAllWhenCheaper && !settings.measureFloors &&
                          !settings.debugPip && !settings.readbackLightLayers && !geometry.paged();
    const bool traceAll = adaptive && srtChoice.traceAll(selectiveKey(settings));
    FrameScript frame(*this, settings, traceAll ? ShadowMethod::FullRayTrace : settings.shadows);
    const bool readBack = frame.viewFitRuns();
    culling.beginFrame(device, settings.cull, settings.adaptiveOcclusion, {{"camera", 0, frame.view.viewProj, true, true, nullptr, frame.colours}});
    if (!readBack)
        frame.planShadowViews();
    if (geometry.paged()) {
        culling.refreshCommands(geometry.commands); // planned from the load-time commands; the views make their pages resident
    }

    frame.beginCommands();
    vkCmdResetQueryPool(commandBuffer, queryPool, 0, vk::kTimestampQueries * kMaxTimestamps);
    culling.resetQueries(commandBuffer);
    if (!readBack)
        shadowCulling.resetQueries(commandBuffer);
    frame.timer.mark(commandBuffer, PassId::Count);
    frame.recordCamera();
    if (readBack)
        frame.fitToView();
    // Lights in reverse order, so that the visibility image ends with light 0's (readback).
    for (uint32_t step = 0; step < frame.lights.size(); ++step)
        frame.recordLight(uint32_t(frame.lights.size()) - 1 - step);
    frame.recordReadback();
    submitAndWait(commandBuffer, frame.timer.passesSinceLastSubmit());
    Frame out = frame.finish(cpuStart);
    if (adaptive) {
        srtChoice.record(out.stats.gpuMs);
        out.stats.srtTracedAll = traceAll;
        out.stats.srtProbe = srtChoice.lastWasProbe();
        out.stats.srtChosen = srtChoice.chosen();
    }
    return out;
}

// What srt's measured costs depend on besides the camera: the model, the lights and the settings that
// change the work (FNV-1a over their values).
uint64_t Renderer::Impl::selectiveKey(const RenderSettings& s) const
{
    uint64_t hash = 1469598103934665603ull;
    auto mix = [&hash](const void* data, size_t bytes) {
        for (size_t i = 0; i < bytes; ++i)
            hash = (hash ^ static_cast<const uint8_t*>(data)[i]) * 1099511628211ull;
    };
    auto mixValue = [&mix](auto value) { mix(&value, sizeof(value)); };
    mixValue(modelGeneration);
    for (uint32_t value : {s.width, s.height, s.shadowMapSize, s.lightSamples, s.penumbraMaps, uint32_t(s.cull)})
        mixValue(value);
    for (bool value : {s.fitShadowMapsToView, s.cullBesideReceivers, s.adaptiveOcclusion})
        mixValue(value);
    for (float value : {s.rayOffset, s.depthBiasConstant, s.depthBiasSlope})
        mixValue(value);
    for (const Light& light : lights) {
        mixValue(uint32_t(light.type));
        for (const glm::vec3& v : {light.position, light.direction, light.up})
            for (int k = 0; k < 3; ++k)
                mixValue(v[k]);
        for (float value : {light.range, light.innerConeDegrees, light.outerConeDegrees, light.width, light.height, light.radius})
            mixValue(value);
    }
    return hash;
}

} // namespace penumbra
