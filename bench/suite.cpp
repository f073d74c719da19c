// The benchmark suite (Lauterbach et al. 2009, section 6): a list of cases,
// scene x method x hard/soft, each warmed up once (that frame also reads the
// G-buffer back for the oracle comparison and the images) and then timed over
// N frames; the scalability run over simplification levels of one scan model
// (Figure 7, left) and the light-size sweep (Figure 7, right). Output:
// report.cpp.
#include "penumbra/bench.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>

#include <glm/geometric.hpp>
#include <sys/resource.h>

#include "penumbra/generate.h"
#include "penumbra/oracle.h"
#include "penumbra/preprocess.h"
#include "penumbra/progress_bar.h"
#include "config.h"
#include "suite_internal.h"

namespace penumbra {

using namespace bench;

namespace {

// The methods measured side by side (frt also gives the oracle its G-buffer); soft cases skip those without area lights.
constexpr ShadowMethod kGpuMethods[] = {ShadowMethod::ShadowMap, ShadowMethod::Selective, ShadowMethod::FullRayTrace,
                                       ShadowMethod::AliasFree, ShadowMethod::RayHierarchy};
constexpr const char* kOracleName = "oracle";

double msSince(std::chrono::steady_clock::time_point start)
{
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

uint64_t peakRssBytes()
{
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return uint64_t(usage.ru_maxrss) * 1024; // Linux: kilobytes
}

double median(std::vector<double> values)
{
    if (values.empty())
        return kNoValue;
    std::sort(values.begin(), values.end());
    size_t n = values.size();
    return n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

double best(const std::vector<double>& values)
{
    return values.empty() ? kNoValue : *std::min_element(values.begin(), values.end());
}

// Mean |visibility - oracle| over the pixels the oracle traced (covered and
// light-facing); for hard shadows, the share of pixels that differ.
double visibilityError(const std::vector<float>& oracle, const std::vector<float>& visibility)
{
    if (oracle.size() != visibility.size())
        fail("bench", "oracle and renderer visibility differ in size");
    double sum = 0;
    size_t compared = 0;
    for (size_t i = 0; i < oracle.size(); ++i)
        if (oracle[i] >= 0.0f) {
            ++compared;
            sum += std::fabs(double(std::clamp(visibility[i], 0.0f, 1.0f)) - double(oracle[i]));
        }
    return compared ? sum / double(compared) : 0.0;
}

// The hard-shadow light: an area light shrinks to a point at its centre
// (area lights cast soft shadows).
Light hardLightFor(const Light& light)
{
    Light hard = light;
    if (light.type == LightType::Rectangle || light.type == LightType::Disk || light.type == LightType::Sphere)
        hard.type = LightType::Point;
    return hard;
}

// The "point" section's light: a point light among the geometry, a quarter
// of the height above the centre (the plant's pipes, the city's street, the
// interior's nave), lit as brightly as the generators' lights.
Light pointLightAmong(const Bounds& bounds)
{
    Light point;
    point.type = LightType::Point;
    point.position = bounds.center() + glm::vec3(0.0f, 0.25f * (bounds.max.y - bounds.min.y), 0.0f);
    point.intensity = 4.0f * glm::dot(bounds.extent(), bounds.extent());
    return point;
}

// Whether a method runs in a section with this light: rh takes point and spot
// lights, and directional ones in the methods section (not in the scalability
// sweep, to keep its time), never area lights; afsm is left out of the point
// section (a point light among the geometry costs it minutes per frame on
// lavapipe: its casters near the light cover the whole grid of a cube face).
bool methodTakes(ShadowMethod method, const std::string& section, const Light& light)
{
    if (method == ShadowMethod::RayHierarchy)
        return light.type == LightType::Point || light.type == LightType::Spot ||
               (light.type == LightType::Directional && section == "methods");
    if (method == ShadowMethod::AliasFree)
        return section != "point";
    return true;
}

// A scene generated, preprocessed and uploaded.
struct LoadedScene {
    std::string name;
    Scene scene;
    Bounds bounds;
    Camera camera;
    Light light;            // hard shadows: the generator's suggested light
    uint64_t triangles = 0; // stored
    double bytesPerTriangle = 0;
    uint64_t deviceBytes = 0;
    std::unique_ptr<EmbreeOracle> oracle; // built on first use, for every case of the scene
    double oracleBuildMs = 0;
};

void loadInto(Renderer& renderer, LoadedScene& loaded)
{
    PreprocessStats stats;
    CompressedModel model = buildCompressedModel(loaded.scene.mesh, PreprocessOptions{}, &stats);
    renderer.loadModel(model);
    loaded.triangles = stats.triangles;
    loaded.bytesPerTriangle = stats.bytesPerTriangle;
    loaded.deviceBytes = renderer.modelDeviceBytes();
    loaded.bounds = computeBounds(loaded.scene.mesh);
    loaded.camera = loaded.scene.cameras.empty() ? defaultCamera(loaded.bounds) : loaded.scene.cameras[0];
    loaded.light = hardLightFor(loaded.scene.lights.empty() ? defaultLight() : loaded.scene.lights[0]);
    renderer.setCamera(loaded.camera);
}

LoadedScene generateAndLoad(Renderer& renderer, const std::string& name, uint64_t triangles)
{
    LoadedScene loaded;
    loaded.name = name;
    GenerateOptions options;
    options.triangles = triangles;
    loaded.scene = generateScene(name, options);
    loadInto(renderer, loaded);
    return loaded;
}

// The soft-shadow light: a sphere of radiusFraction x the scene diagonal. A
// directional light becomes a sphere two diagonals away against its
// direction, its intensity scaled so that the scene centre is lit as before.
Light areaLightFor(const Light& light, const Bounds& bounds, double radiusFraction)
{
    float diagonal = glm::length(bounds.extent());
    Light area = light;
    area.type = LightType::Sphere;
    area.radius = float(radiusFraction) * diagonal;
    if (light.type == LightType::Directional) {
        float distance = 2.0f * diagonal;
        area.position = bounds.center() - glm::normalize(light.direction) * distance;
        area.intensity = light.intensity * distance * distance;
        area.range = 0.0f;
    }
    return area;
}

struct Measurement {
    Frame gbuffer;                 // the warm-up frame, with positions, normals and visibility
    std::vector<FrameStats> timed; // the timed frames, without G-buffer readback
    std::vector<FrameStats> floors; // frames with RenderSettings::measureFloors (sm and srt of the methods section)
    uint32_t settleFrames = 0;     // untimed frames after the warm-up until the culling was steady and srt had chosen (warmUp)
};

// The measurement whose G-buffer the oracle traces from (every method's camera pass is the
// same): frt's, else the first that reports its ray offset (a method that traces), else the first.
size_t referenceIndex(const std::vector<ShadowMethod>& methods, const std::vector<Measurement>& measured)
{
    for (size_t i = 0; i < methods.size(); ++i)
        if (methods[i] == ShadowMethod::FullRayTrace)
            return i;
    for (size_t i = 0; i < measured.size(); ++i)
        if (measured[i].gbuffer.stats.rayOffset > 0.0f)
            return i;
    return 0;
}

Frame renderShadows(Renderer& renderer, const RenderSettings& settings, ShadowKind kind, const SoftShadowParams& params)
{
    return kind == ShadowKind::Hard ? renderHardShadows(renderer, settings)
                                    : renderSoftShadows(renderer, settings, params);
}

// The warm-up of one case: a frame that reads the G-buffer back, then untimed frames
// (log: the scene's culling log for this light; nullptr: none beyond the GPU's clocks).
Measurement warmUp(Renderer& renderer, RenderSettings settings, ShadowKind kind, const SoftShadowParams& params, CullLog* log)
{
    Measurement m;
    const auto start = std::chrono::steady_clock::now();
    settings.readbackGBuffer = true;
    m.gbuffer = renderShadows(renderer, settings, kind, params);
    settings.readbackGBuffer = false;
    // A GPU idle while the CPU built the scene runs its first frames at low
    // clocks (an H200's first method per scene: camera 6.6-7.3 ms against
    // 2.4-2.6 for the next ones). Untimed frames until half a second has
    // passed bring the clocks up; a CPU device (lavapipe) needs none.
    if (renderer.device().type != "cpu")
        for (uint32_t i = 0; i < 200 && std::chrono::steady_clock::now() - start < std::chrono::milliseconds(500); ++i)
            renderShadows(renderer, settings, kind, params);
    // Untimed frames until the culling is steady (CullLog), at most kSettleFrames: otherwise a
    // scene's first method timed the culling's learning and the next ones its steady state.
    constexpr uint32_t kSettleFrames = 16;
    bool steady = !log || log->steady(m.gbuffer.stats);
    FrameStats last = m.gbuffer.stats;
    for (uint32_t i = 0; !steady && i < kSettleFrames; ++i) {
        last = renderShadows(renderer, settings, kind, params).stats;
        steady = log->steady(last);
        ++m.settleFrames;
    }
    // srt chooses frame by frame between its own sequence and a ray for every pixel (selective_choice.h):
    // untimed frames until it has measured both ways (at the latest its 19th frame), so that the timed
    // frames show its choice rather than its probe.
    for (uint32_t i = 0; settings.shadows == ShadowMethod::Selective && settings.srtTraceAllWhenCheaper && !last.srtChosen && i < kSettleFrames + 3; ++i) {
        last = renderShadows(renderer, settings, kind, params).stats;
        ++m.settleFrames;
    }
    return m;
}

// A case timed alone: warmUp, `frames` timed frames, then as many floor frames when `floors`.
Measurement measure(Renderer& renderer, RenderSettings settings, ShadowKind kind, const SoftShadowParams& params,
                    uint32_t frames, bool floors = false)
{
    Measurement m = warmUp(renderer, settings, kind, params, nullptr);
    for (uint32_t i = 0; i < frames; ++i)
        m.timed.push_back(renderShadows(renderer, settings, kind, params).stats);
    settings.measureFloors = floors;
    for (uint32_t i = 0; floors && i < frames; ++i)
        m.floors.push_back(renderShadows(renderer, settings, kind, params).stats);
    return m;
}

// Medians over the floor frames of each stage that has a floor.
std::vector<FloorSummary> floorSummaries(const std::vector<FrameStats>& frames)
{
    std::vector<FloorSummary> out;
    for (const char* stage : {"camera", "view_fit", "shadow_map", "classify", "compact", "shade"}) {
        std::vector<double> ms, floorMs;
        for (const FrameStats& stats : frames) {
            double pass = -1, floor = -1;
            for (const PassTiming& t : stats.passes) {
                if (t.name == stage) pass = t.gpuMs;
                if (t.name == std::string(stage) + "_floor") floor = t.gpuMs;
            }
            if (pass >= 0 && floor >= 0) {
                ms.push_back(pass);
                floorMs.push_back(floor);
            }
        }
        if (!ms.empty())
            out.push_back({stage, median(ms), median(floorMs)});
    }
    return out;
}

class SuiteRunner {
  public:
    explicit SuiteRunner(const SuiteOptions& options) : options(options), progressBar(options.progress)
    {
        RendererOptions rendererOptions;
        rendererOptions.device = options.device;
        renderer = std::make_unique<Renderer>(rendererOptions);
        results.options = options;
        results.device = renderer->device();
        char date[32];
        std::time_t now = std::time(nullptr);
        std::strftime(date, sizeof(date), "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&now));
        results.date = date;
        soft.lightSamples = options.lightSamples;
        soft.afsmSamples = options.afsmSamples;
        soft.penumbraMaps = options.penumbraMaps;
        soft.softShadowMaps = options.softShadowMaps;
        // Steps for the progress bar: 4 per scene and kind, 4 per level, 4 per light radius, 1 per afsm sample count.
        totalSteps = options.scenes.size() * (2 * 4 + 9) + options.levels.size() * 5 + options.lightRadii.size() * 4 +
                     options.afsmSampleCounts.size();
    }

    SuiteResults run()
    {
        std::error_code error;
        std::filesystem::create_directories(std::filesystem::path(options.outDir) / "images", error);
        if (error)
            fail(options.outDir, "cannot create the results folder: " + error.message());
        for (const BenchScene& scene : options.scenes)
            runMethods(scene);
        if (wants("scalability"))
            runScalability();
        if (wants("light_size"))
            runLightSweep();
        if (wants("afsm_samples") && wantsMethod(ShadowMethod::AliasFree))
            runAfsmSampleSweep();
        progressBar.finish();
        return std::move(results);
    }

  private:
    // SuiteOptions::sections and ::methods: empty lists take everything.
    bool wants(const std::string& section) const
    {
        return options.sections.empty() || std::find(options.sections.begin(), options.sections.end(), section) != options.sections.end();
    }
    bool wantsMethod(ShadowMethod method) const
    {
        return options.methods.empty() ||
               std::find(options.methods.begin(), options.methods.end(), shadowMethodName(method)) != options.methods.end();
    }

    void step(const std::string& label)
    {
        progressBar.update(label, double(doneSteps) / double(std::max<size_t>(totalSteps, 1)));
    }
    void stepDone(const std::string& label)
    {
        ++doneSteps;
        step(label);
    }

    RenderSettings baseSettings(ShadowMethod method) const
    {
        RenderSettings settings;
        settings.width = settings.height = options.size;
        settings.shadows = method;
        settings.srtTraceAllWhenCheaper = options.srtAdaptive;
        return settings;
    }

    Record baseRecord(const std::string& section, const LoadedScene& loaded, const std::string& method,
                      ShadowKind kind) const
    {
        Record r;
        r.section = section;
        r.scene = loaded.name;
        r.triangles = loaded.triangles;
        r.method = method;
        r.kind = kind;
        r.width = r.height = options.size;
        r.frames = options.frames;
        r.bytesPerTriangle = loaded.bytesPerTriangle;
        r.deviceBytes = loaded.deviceBytes;
        r.device = results.device.name;
        r.driver = results.device.driver;
        return r;
    }

    void printRecord(const Record& r)
    {
        progressBar.finish();
        if (!r.available) {
            std::printf("%-11s %-9s %10llu %-6s %-4s %s\n", r.section.c_str(), r.scene.c_str(),
                        (unsigned long long)r.triangles, r.method.c_str(), shadowKindName(r.kind), r.note.c_str());
        } else {
            std::printf("%-11s %-9s %10llu %-6s %-4s %9.1f ms (best %.1f) | PIP %5.2f%% | rays %9llu | err %.4f%%",
                        r.section.c_str(), r.scene.c_str(), (unsigned long long)r.triangles, r.method.c_str(),
                        shadowKindName(r.kind), r.medianMs, r.bestMs,
                        r.method == kOracleName ? 100.0 : r.pipFraction * 100.0, (unsigned long long)r.rays,
                        std::isnan(r.error) ? 0.0 : r.error * 100.0);
            if (r.kind == ShadowKind::Soft)
                std::printf(" | radius %.4g | penumbra %.2f%%", r.lightRadius, r.penumbraFraction * 100.0);
            if (r.settleFrames)
                std::printf(" | steady after %u more frames", r.settleFrames);
            if (!r.note.empty())
                std::printf(" | %s", r.note.c_str());
            std::printf("\n");
        }
        std::fflush(stdout);
    }

    void add(Record r)
    {
        r.peakRssBytes = peakRssBytes();
        printRecord(r);
        results.records.push_back(std::move(r));
    }

    // Records of one GPU method from its measurement.
    Record gpuRecord(const std::string& section, const LoadedScene& loaded, ShadowMethod method, ShadowKind kind,
                     const Measurement& m) const
    {
        Record r = baseRecord(section, loaded, shadowMethodName(method), kind);
        std::vector<double> gpu, cpu;
        std::map<std::string, std::vector<double>> perPass;
        std::vector<std::string> passOrder;
        for (const FrameStats& stats : m.timed) {
            gpu.push_back(stats.gpuMs);
            cpu.push_back(stats.cpuMs);
            for (const PassTiming& pass : stats.passes) {
                if (!perPass.count(pass.name))
                    passOrder.push_back(pass.name);
                perPass[pass.name].push_back(pass.gpuMs);
            }
        }
        r.medianMs = median(gpu);
        r.bestMs = best(gpu);
        r.cpuMedianMs = median(cpu);
        for (const std::string& name : passOrder)
            r.passes.push_back({name, median(perPass[name]), best(perPass[name])});
        const FrameStats& last = m.timed.empty() ? m.gbuffer.stats : m.timed.back();
        r.pipFraction = last.pipFraction;
        r.rays = last.rays;
        r.nodesVisited = last.nodesVisited;
        r.penumbraFraction = kind == ShadowKind::Soft ? penumbraFraction(m.gbuffer, kind) : kNoValue;
        r.floors = floorSummaries(m.floors);
        r.settleFrames = m.settleFrames;
        const auto tracedAll = std::count_if(m.timed.begin(), m.timed.end(), [](const FrameStats& s) { return s.srtTracedAll; });
        if (tracedAll)
            r.note = "every light-facing pixel traced in " + std::to_string(tracedAll) + " of " + std::to_string(m.timed.size()) +
                     " timed frames (measured cheaper than the map and selective rays: --srt-adaptive); error of srt's own first frame";
        return r;
    }

    // Every method of kGpuMethods (soft: those with area lights) and the oracle on one loaded scene with the light already
    // set; errors against the oracle; images when imagePrefix is not empty.
    // Returns the records (also added to the results).
    void measureAllMethods(const std::string& section, LoadedScene& loaded, ShadowKind kind, const Light& light,
                           double radius, double level, double simplifyError, const std::string& imagePrefix)
    {
        std::string label = section + " " + loaded.name;
        std::vector<ShadowMethod> methods;
        for (ShadowMethod method : kGpuMethods)
            if ((kind == ShadowKind::Hard || shadowMethodDoesAreaLights(method)) && methodTakes(method, section, light) &&
                wantsMethod(method))
                methods.push_back(method);
        // Each method warmed up in turn (the first one waits for the culling to learn this light),
        // then the timed frames in rounds, one frame of each method a round, so that a burst of
        // load on a shared machine lands on every method rather than on one (timed one after
        // another, two runs of the full suite gave the 1 M interior's srt / sm at 1024^2 as 1.24
        // and 1.53; bursts that last a whole scene still move both). Then the floor frames,
        // method by method.
        std::vector<Measurement> measured(methods.size());
        CullLog cullLog;
        for (size_t i = 0; i < methods.size(); ++i) {
            step(label + " " + shadowMethodName(methods[i]));
            measured[i] = warmUp(*renderer, baseSettings(methods[i]), kind, soft, &cullLog);
        }
        step(label + " timed");
        for (uint32_t frame = 0; frame < options.frames; ++frame)
            for (size_t i = 0; i < methods.size(); ++i)
                measured[i].timed.push_back(renderShadows(*renderer, baseSettings(methods[i]), kind, soft).stats);
        for (size_t i = 0; i < methods.size(); ++i) {
            const bool floors = options.floors && section == "methods" &&
                                (methods[i] == ShadowMethod::ShadowMap || methods[i] == ShadowMethod::Selective);
            if (floors) {
                RenderSettings settings = baseSettings(methods[i]);
                settings.measureFloors = true;
                for (uint32_t frame = 0; frame < options.frames; ++frame)
                    measured[i].floors.push_back(renderShadows(*renderer, settings, kind, soft).stats);
            }
            stepDone(label + " " + shadowMethodName(methods[i]));
        }

        // The oracle on the frt frame's G-buffer (every method shares the camera pass).
        step(label + " oracle");
        if (methods.empty())
            return;
        const size_t referenceMethod = referenceIndex(methods, measured);
        const Frame& reference = measured[referenceMethod].gbuffer;
        float rayOffset = reference.stats.rayOffset > 0.0f ? reference.stats.rayOffset : 1e-4f;
        if (!loaded.oracle) {
            auto buildStart = std::chrono::steady_clock::now();
            loaded.oracle = std::make_unique<EmbreeOracle>(loaded.scene.mesh);
            loaded.oracleBuildMs = msSince(buildStart);
        }
        const EmbreeOracle& oracle = *loaded.oracle;
        double buildMs = loaded.oracleBuildMs;
        std::vector<double> times;
        std::vector<float> oracleVisibility;
        uint64_t oracleRays = 0;
        for (uint32_t i = 0; i < std::max(options.frames, 1u); ++i) {
            auto start = std::chrono::steady_clock::now();
            oracleVisibility = kind == ShadowKind::Hard
                                   ? oracleHardVisibility(oracle, reference, light, rayOffset)
                                   : oracleSoftVisibility(oracle, reference, light, rayOffset, soft);
            times.push_back(msSince(start));
            oracleRays = oracle.raysTraced();
        }

        for (size_t i = 0; i < methods.size(); ++i) {
            Record r = gpuRecord(section, loaded, methods[i], kind, measured[i]);
            r.error = visibilityError(oracleVisibility, measured[i].gbuffer.visibility);
            if (kind == ShadowKind::Soft && methods[i] == ShadowMethod::AliasFree) {
                // afsm keeps its own samples (the table's, SuiteOptions::afsmSamples): against the oracle tracing
                // them only the table's discretization is left.
                r.error = visibilityError(oracleSoftVisibility(oracle, measured[i].gbuffer, light, rayOffset, soft, true),
                                          measured[i].gbuffer.visibility);
                r.note = std::to_string(soft.afsmSamples) + " light samples; error against the oracle on the table's samples";
            }
            r.lightRadius = radius;
            r.level = level;
            r.simplifyError = simplifyError;
            if (kind == ShadowKind::Soft)
                r.lightSamples = methods[i] == ShadowMethod::AliasFree ? soft.afsmSamples
                                 : methods[i] == ShadowMethod::ShadowMap ? soft.softShadowMaps
                                                                         : soft.lightSamples;
            add(r);
        }
        Record o = baseRecord(section, loaded, kOracleName, kind);
        o.medianMs = median(times);
        o.bestMs = best(times);
        o.cpuMedianMs = o.medianMs;
        o.passes = {{"bvh_build", buildMs, buildMs}, {"trace", o.medianMs, o.bestMs}};
        o.rays = oracleRays;
        o.error = 0.0;
        o.lightRadius = radius;
        o.level = level;
        o.simplifyError = simplifyError;
        o.deviceBytes = 0;
        o.note = "Embree on the CPU, every light-facing pixel";
        if (kind == ShadowKind::Soft) {
            size_t covered = 0, penumbra = 0;
            for (float v : oracleVisibility)
                if (v != kVisibilityBackground) {
                    ++covered;
                    penumbra += v > 0.0f && v < 1.0f;
                }
            o.penumbraFraction = covered ? double(penumbra) / double(covered) : 0.0;
        }
        add(o);
        stepDone(label + " oracle");

        if (!imagePrefix.empty())
            writeImages(imagePrefix, measured, reference, oracleVisibility, light);
    }

    void runMethods(const BenchScene& benchScene)
    {
        step("methods " + benchScene.name);
        LoadedScene loaded = generateAndLoad(*renderer, benchScene.name, benchScene.triangles);
        std::string prefix = "images/" + loaded.name;
        renderer->setLights({loaded.light});
        if (wants("methods"))
            measureAllMethods("methods", loaded, ShadowKind::Hard, loaded.light, 0.0, 1.0, kNoValue, prefix + "-hard");
        Light area = areaLightFor(loaded.light, loaded.bounds, options.softLightRadius);
        renderer->setLights({area});
        if (wants("soft"))
            measureAllMethods("methods", loaded, ShadowKind::Soft, area, options.softLightRadius, 1.0, kNoValue,
                              prefix + "-soft");
        // Omni-directional hard shadows: a point light among the geometry, with rh.
        const Light point = pointLightAmong(loaded.bounds);
        renderer->setLights({point});
        if (wants("point"))
            measureAllMethods("point", loaded, ShadowKind::Hard, point, 0.0, 1.0, kNoValue, prefix + "-point");
        if (wants("rh_variants") && wantsMethod(ShadowMethod::RayHierarchy))
            measureRhVariants(loaded);
    }

    // The paper's Table 2 on our scenes: rh with each cone test, rays sorted
    // or not (early accept on, one pass: the defaults), then early accept off
    // and two-pass on for the precise test on sorted rays: time, cone tests
    // (nodes visited) and the traversal's peak pair memory, under the point
    // section's light (already set).
    void measureRhVariants(const LoadedScene& loaded)
    {
        struct Variant {
            ConeTest test;
            bool sorted, earlyAccept, twoPass;
        };
        const Variant variants[] = {{ConeTest::Precise, true, true, false},  {ConeTest::Spheres, true, true, false},
                                    {ConeTest::Precise, false, true, false}, {ConeTest::Spheres, false, true, false},
                                    {ConeTest::Precise, true, false, false}, {ConeTest::Precise, true, true, true}};
        for (const Variant& v : variants) {
            const std::string name = std::string("rh ") + coneTestName(v.test) + (v.sorted ? " sorted" : " unsorted") +
                                     (v.earlyAccept ? "" : ", no early accept") + (v.twoPass ? ", two-pass" : "");
            step("rh variants " + loaded.name + " " + name);
            RenderSettings settings = baseSettings(ShadowMethod::RayHierarchy);
            settings.coneTest = v.test;
            settings.rhSort = v.sorted ? RhSort::On : RhSort::Off;
            settings.rhEarlyAccept = v.earlyAccept;
            settings.rhTwoPass = v.twoPass;
            // A warm-up frame before the first variant only (the pass's buffers
            // and pipelines are made by then), then the suite's frames, but no
            // more once the timed ones add up to kVariantBudgetMs: the slow
            // variants (spheres, unsorted) take 10-40 s a frame on lavapipe at
            // 320^2, and their medians come from fewer frames (the note says how many).
            constexpr double kVariantBudgetMs = 15'000.0;
            if (&v == &variants[0])
                renderer->render(settings);
            std::vector<double> gpu;
            FrameStats last;
            double spent = 0.0;
            for (uint32_t i = 0; i < std::max(options.frames, 1u) && (i == 0 || spent < kVariantBudgetMs); ++i) {
                last = renderer->render(settings).stats;
                gpu.push_back(last.gpuMs);
                spent += last.gpuMs;
            }
            Record r = baseRecord("rh_variants", loaded, name, ShadowKind::Hard);
            r.medianMs = median(gpu);
            r.bestMs = best(gpu);
            r.rays = last.rays;
            r.nodesVisited = last.nodesVisited;
            r.rhPeakPairBytes = last.rhPeakPairBytes;
            r.note = std::to_string(last.triangleTests) + " ray tests, " + std::to_string(last.rhCasters) + " casters, " +
                     std::to_string(last.rhAcceptedNodes) + " nodes accepted, " + std::to_string(last.rhBatches) + " batches, " + std::to_string(gpu.size()) + " timed frames";
            add(r);
        }
    }

    // Figure 7 (left): one scan model, simplified level by level (each level
    // from the previous one, largest first), every method per level.
    void runScalability()
    {
        if (options.levels.empty())
            return;
        step("scalability: generate");
        GenerateOptions generateOptions;
        generateOptions.triangles = options.scanTriangles;
        Scene full = generateScene("scan", generateOptions);
        std::vector<double> levels = options.levels;
        std::sort(levels.rbegin(), levels.rend());
        Mesh previous = std::move(full.mesh);
        double previousRatio = 1.0;
        for (double level : levels) {
            char label[64];
            std::snprintf(label, sizeof(label), "scalability 1/%g", 1.0 / level);
            step(label);
            LoadedScene loaded;
            loaded.name = "scan";
            loaded.scene.cameras = full.cameras;
            loaded.scene.lights = full.lights;
            double simplifyError = 0.0;
            if (level < previousRatio) {
                SimplifiedMesh simplified = simplifyMesh(previous, float(level / previousRatio));
                simplifyError = simplified.error;
                previous = std::move(simplified.mesh);
                previousRatio = level;
            }
            loaded.scene.mesh = previous;
            loadInto(*renderer, loaded);
            renderer->setLights({loaded.light});
            measureAllMethods("scalability", loaded, ShadowKind::Hard, loaded.light, 0.0, level, simplifyError, "");
            // The paper's Figure 11: afsm soft shadows (its fewest samples, 128 in the paper) against the triangle count.
            if (!wantsMethod(ShadowMethod::AliasFree))
                continue;
            const Light area = areaLightFor(loaded.light, loaded.bounds, options.softLightRadius);
            renderer->setLights({area});
            measureAfsmSoft("afsm_triangles", loaded, area, options.softLightRadius, level, options.afsmSampleCounts.front());
        }
    }

    // Figure 7 (right): soft shadows of one scene against the light radius.
    // Radius 0 rows are the hard-shadow records of the same scene.
    void runLightSweep()
    {
        if (options.lightRadii.empty())
            return;
        auto it = std::find_if(options.scenes.begin(), options.scenes.end(),
                               [&](const BenchScene& s) { return s.name == options.sweepScene; });
        uint64_t triangles = it != options.scenes.end() ? it->triangles : 200'000;
        for (const Record& r : std::vector<Record>(results.records))
            if (r.section == "methods" && r.scene == options.sweepScene && r.kind == ShadowKind::Hard) {
                Record copy = r;
                copy.section = "light_size";
                copy.note = "radius 0: the hard-shadow record of the method comparison";
                results.records.push_back(copy);
            }
        step("light size: generate");
        LoadedScene loaded = generateAndLoad(*renderer, options.sweepScene, triangles);
        for (double radius : options.lightRadii) {
            Light area = areaLightFor(loaded.light, loaded.bounds, radius);
            renderer->setLights({area});
            measureAllMethods("light_size", loaded, ShadowKind::Soft, area, radius, 1.0, kNoValue, "");
        }
    }

    // afsm soft shadows with `samples` light samples, the scene's area light
    // already set; error against the oracle on the table's samples (table
    // error only). The paper's Figures 11 and 13.
    void measureAfsmSoft(const std::string& section, LoadedScene& loaded, const Light& area, double radius, double level, uint32_t samples)
    {
        const std::string label = section + " " + loaded.name + " afsm " + std::to_string(samples);
        step(label);
        SoftShadowParams params = soft;
        params.afsmSamples = samples;
        Measurement m = measure(*renderer, baseSettings(ShadowMethod::AliasFree), ShadowKind::Soft, params, options.frames);
        if (!loaded.oracle) {
            auto buildStart = std::chrono::steady_clock::now();
            loaded.oracle = std::make_unique<EmbreeOracle>(loaded.scene.mesh);
            loaded.oracleBuildMs = msSince(buildStart);
        }
        const float rayOffset = m.gbuffer.stats.rayOffset > 0.0f ? m.gbuffer.stats.rayOffset : 1e-4f;
        Record r = gpuRecord(section, loaded, ShadowMethod::AliasFree, ShadowKind::Soft, m);
        r.error = visibilityError(oracleSoftVisibility(*loaded.oracle, m.gbuffer, area, rayOffset, params, true), m.gbuffer.visibility);
        r.lightRadius = radius;
        r.level = level;
        r.lightSamples = samples;
        r.note = std::to_string(samples) + " light samples; error against the oracle on the table's samples";
        add(r);
        stepDone(label);
    }

    // The paper's Figure 13: afsm soft shadows against the number of light
    // samples, on the sweep scene with the method comparison's light radius.
    void runAfsmSampleSweep()
    {
        if (options.afsmSampleCounts.empty())
            return;
        auto it = std::find_if(options.scenes.begin(), options.scenes.end(),
                               [&](const BenchScene& s) { return s.name == options.sweepScene; });
        LoadedScene loaded = generateAndLoad(*renderer, options.sweepScene, it != options.scenes.end() ? it->triangles : 200'000);
        const Light area = areaLightFor(loaded.light, loaded.bounds, options.softLightRadius);
        renderer->setLights({area});
        for (uint32_t samples : options.afsmSampleCounts)
            measureAfsmSoft("afsm_samples", loaded, area, options.softLightRadius, 1.0, samples);
    }

    // Shadow image of one visibility buffer: N.L shading times visibility,
    // so that panels differ only where visibility differs.
    Image shadowImage(const Frame& frame, const std::vector<float>& visibility, const Light& light) const
    {
        Image image;
        image.width = frame.color.width;
        image.height = frame.color.height;
        image.rgba.assign(size_t(image.width) * image.height * 4, 1.0f);
        bool directional = light.type == LightType::Directional;
        glm::vec3 towardSun = directional ? -glm::normalize(light.direction) : glm::vec3(0.0f);
        for (size_t i = 0; i < size_t(image.width) * image.height; ++i) {
            const float* p = &frame.positions[i * 4];
            float value = 0.04f;
            if (p[3] != 0.0f) {
                glm::vec3 n(frame.normals[i * 4], frame.normals[i * 4 + 1], frame.normals[i * 4 + 2]);
                glm::vec3 toLight =
                    directional ? towardSun : glm::normalize(light.position - glm::vec3(p[0], p[1], p[2]));
                float lit = std::max(glm::dot(n, toLight), 0.0f) * std::clamp(visibility[i], 0.0f, 1.0f);
                value = 0.12f + 0.8f * lit;
            }
            image.rgba[i * 4] = image.rgba[i * 4 + 1] = image.rgba[i * 4 + 2] = value;
        }
        return image;
    }

    // Red: the method lights what the oracle shadows; blue: the reverse;
    // intensity is the difference. Agreeing pixels are dim grey.
    static Image differenceImage(const Frame& frame, const std::vector<float>& oracle)
    {
        Image image;
        image.width = frame.color.width;
        image.height = frame.color.height;
        image.rgba.assign(size_t(image.width) * image.height * 4, 1.0f);
        for (size_t i = 0; i < size_t(image.width) * image.height; ++i) {
            float* out = &image.rgba[i * 4];
            out[0] = out[1] = out[2] = frame.positions[i * 4 + 3] != 0.0f ? 0.01f : 0.0f;
            if (oracle[i] < 0.0f)
                continue;
            float d = std::clamp(frame.visibility[i], 0.0f, 1.0f) - oracle[i];
            if (d > 0.0f) {
                out[0] = d;
                out[1] = out[2] = 0.0f;
            } else if (d < 0.0f) {
                out[2] = -d;
                out[0] = out[1] = 0.0f;
            }
        }
        return image;
    }

    void writeImages(const std::string& prefix, const std::vector<Measurement>& measured, const Frame& reference,
                     const std::vector<float>& oracle, const Light& light)
    {
        std::vector<Image> shadows, differences, colors;
        for (const Measurement& m : measured) {
            shadows.push_back(shadowImage(m.gbuffer, m.gbuffer.visibility, light));
            differences.push_back(differenceImage(m.gbuffer, oracle));
            colors.push_back(m.gbuffer.color);
        }
        shadows.push_back(shadowImage(reference, oracle, light));
        struct Output {
            const char* suffix;
            const std::vector<Image>& panels;
        } outputs[] = {{"-shadows.png", shadows}, {"-diff.png", differences}, {"-color.png", colors}};
        for (const Output& output : outputs) {
            std::string relative = prefix + output.suffix;
            writeSideBySide(output.panels, (std::filesystem::path(options.outDir) / relative).string());
            results.images.push_back(relative);
        }
    }

    const SuiteOptions& options;
    ProgressBar progressBar;
    std::unique_ptr<Renderer> renderer;
    SuiteResults results;
    SoftShadowParams soft;
    size_t totalSteps = 0;
    size_t doneSteps = 0;
};

void checkOptions(const SuiteOptions& options)
{
    if (options.outDir.empty())
        fail("bench", "no results folder");
    if (options.size < 16 || options.size > 8192)
        fail("bench --size " + std::to_string(options.size), "must be 16..8192");
    if (options.frames < 1 || options.frames > 1000)
        fail("bench --frames " + std::to_string(options.frames), "must be 1..1000");
    for (const BenchScene& scene : options.scenes) {
        const std::vector<std::string> names = generatorNames();
        if (std::find(names.begin(), names.end(), scene.name) == names.end())
            fail("bench", "unknown scene '" + scene.name + "'");
    }
    for (double level : options.levels)
        if (!(level > 0.0 && level <= 1.0))
            fail("bench", "simplification levels must be in (0, 1]");
    for (double radius : options.lightRadii)
        if (!(radius > 0.0 && radius < 1.0))
            fail("bench", "light radii must be in (0, 1) of the scene diagonal");
    if (options.lightSamples < 4 || options.lightSamples > 256)
        fail("bench", "light samples must be 4..256");
    // afsm's range (shaders/config.h: PENUMBRA_AFSM_MIN_SAMPLES, _MAX_SAMPLES).
    if (options.afsmSamples < 128 || options.afsmSamples > 1024)
        fail("bench", "afsm light samples must be 128..1024");
    for (uint32_t samples : options.afsmSampleCounts)
        if (samples < 128 || samples > 1024)
            fail("bench", "afsm sample counts must be 128..1024");
    if (options.softShadowMaps < 1 || options.softShadowMaps > 6)
        fail("bench", "soft shadow maps must be 1..6");
    if (options.penumbraMaps != 1 && options.penumbraMaps != 5)
        fail("bench", "penumbra maps must be 1 or 5");
}

} // namespace

namespace bench {

bool CullLog::steady(const FrameStats& stats)
{
    constexpr size_t window = PENUMBRA_CULL_RETEST_FRAMES + 1;
    bool all = true;
    for (const ViewCullStats& view : stats.views) {
        std::vector<uint64_t>& log = drawn[view.name];
        log.push_back(view.trianglesDrawn);
        const size_t n = log.size();
        auto most = [&](size_t last) { return double(*std::max_element(log.begin() + (last + 1 - window), log.begin() + (last + 1))); };
        auto same = [&](size_t last) {
            const double x = most(last), y = most(last - 1);
            return std::abs(x - y) <= 0.01 * std::max(x, y);
        };
        all = all && n >= window + 2 && same(n - 1) && same(n - 2);
    }
    return all;
}

size_t stageGroupOf(const std::string& passName)
{
    static const std::map<std::string, size_t> groups = {{"camera", 0},        {"view_fit", 0},   {"view_fit_readback", 5},   {"shadow_map", 0},     {"thin_triangles", 1},
                                                         {"penumbra_mask", 1}, {"classify", 1},   {"compact", 2},
                                                         {"trace", 3},         {"shade", 4},      {"readback", 5},
                                                         {"afsm_casters", 0},  {"afsm_bin", 0},     {"afsm_rows", 0},     {"afsm_samples", 1},
                                                         {"rh_build", 1},      {"rh_traverse", 3}};
    auto it = groups.find(passName);
    return it == groups.end() ? kStageGroupCount - 1 : it->second;
}

} // namespace bench

std::vector<std::string> suiteNames()
{
    return {"smoke", "quick", "full"};
}

SuiteOptions suiteOptions(const std::string& suite)
{
    SuiteOptions o;
    o.suite = suite;
    if (suite == "smoke") {
        // CI: every code path, tiny inputs.
        o.size = 128;
        o.frames = 1;
        o.scenes = {{"city", 20'000}, {"scan", 20'000}};
        o.scanTriangles = 64'000;
        o.levels = {1.0 / 16, 1.0 / 4, 1.0};
        o.lightRadii = {0.005, 0.02};
        o.afsmSamples = 128;
        o.afsmSampleCounts = {128, 1024};
    } else if (suite == "quick") {
        // 320^2, the 250 k suite scenes: 28 min on the shared 2-core machine with afsm and rh (rh_variants, soft
        // full ray tracing and afsm's sweeps dominate); ctest runs the smoke suite instead.
        o.size = 320;
        o.frames = 3;
        o.scenes = {{"city", 250'000}, {"interior", 250'000}, {"plant", 250'000}, {"scan", 250'000}};
        o.scanTriangles = 1'000'000;
        o.levels = {1.0 / 256, 1.0 / 64, 1.0 / 16, 1.0 / 4, 1.0};
        o.lightRadii = {0.0025, 0.01, 0.04};
        o.afsmSamples = 128;
    } else if (suite == "full") {
        // The paper's shapes: 1024^2, 1-2 M triangle scenes, a 16 M-triangle scan in 9 levels.
        o.size = 1024;
        o.frames = 3;
        o.scenes = {{"city", 1'000'000}, {"interior", 1'000'000}, {"plant", 2'000'000}, {"scan", 2'000'000}};
        o.scanTriangles = 16'000'000;
        o.levels = {1.0 / 256, 1.0 / 128, 1.0 / 64, 1.0 / 32, 1.0 / 16, 1.0 / 8, 1.0 / 4, 1.0 / 2, 1.0};
        o.lightRadii = {0.00125, 0.0025, 0.005, 0.01, 0.02, 0.04, 0.08};
    } else {
        fail("bench " + suite, "unknown suite (smoke, quick or full)");
    }
    return o;
}

std::string defaultResultsDir(const std::string& suite)
{
    char date[32];
    std::time_t now = std::time(nullptr);
    std::strftime(date, sizeof(date), "%Y%m%d-%H%M%S", std::gmtime(&now));
    return "results/" + suite + "-" + date;
}

size_t runSuite(const SuiteOptions& options)
{
    checkOptions(options);
    SuiteRunner runner(options);
    SuiteResults results = runner.run();
    std::string plotNote = writeReport(results);
    std::printf("%s\n", plotNote.c_str());
    return results.records.size();
}

} // namespace penumbra
