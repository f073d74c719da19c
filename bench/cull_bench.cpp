// Raster culling with the BVH (Lauterbach et al. 2009, 5.1): camera and
// shadow-map pass times with --cull none, frustum and all, and the fraction
// of triangles each view culls, on the generated plant seen from inside its
// steel structure (under its sun, then a lamp inside: six cube faces) and on
// the city at street level (its sun). A sun's map is fitted to what the
// camera sees (RenderSettings::fitShadowMapsToView, in every mode); its
// "shadow map" time includes that fit (bounds pass and host round trip).
//   bench_cull [--frames N] [--size N] [--plant-triangles N] [--city-triangles N] [--device NAME]
// The modes take turns: 6 warm-up frames each (pipelines, and an occlusion
// history in which every visible cell was retested), then N frames each; median
// times, last frame's counts.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "penumbra/generate.h"
#include "penumbra/penumbra.h"
#include "penumbra/preprocess.h"
#include "tool_util.h"

namespace {

using namespace penumbra;

using penumbra::bench_tool::median;

struct Result {
    std::vector<double> camera, shadow; // shadow: the shadow-map pass and, for a sun, fitting its map to the view
    std::vector<ViewCullStats> views;
    double cameraMs() const { return median(camera); }
    double shadowMs() const { return median(shadow); }
};

double culledFraction(const ViewCullStats& view)
{
    uint64_t total = view.trianglesDrawn + view.trianglesCulled;
    return total ? double(view.trianglesCulled) / double(total) : 0.0;
}

// Culled share of the triangles over every light view (all cube faces).
double lightCulledFraction(const std::vector<ViewCullStats>& views)
{
    uint64_t culled = 0, total = 0;
    for (size_t v = 1; v < views.size(); ++v) {
        culled += views[v].trianglesCulled;
        total += views[v].trianglesDrawn + views[v].trianglesCulled;
    }
    return total ? double(culled) / double(total) : 0.0;
}

void measureLights(Renderer& renderer, const char* name, const char* sceneName, const CompressedModel& model,
                   const std::vector<Light>& lights, const char* lightName, uint32_t size, int frames)
{
    renderer.setLights(lights);
    RenderSettings settings;
    settings.width = settings.height = size;
    // The modes take turns frame by frame, so that load from other processes
    // affects them alike; each mode keeps its own history (per view slot, only
    // CullMode::All reads or writes it).
    const CullMode modes[3] = {CullMode::None, CullMode::Frustum, CullMode::All};
    Result results[3];
    for (int frame = -6; frame < frames; ++frame)
        for (int m = 0; m < 3; ++m) {
            settings.cull = modes[m];
            Frame rendered = renderer.render(settings);
            if (frame < 0)
                continue; // warm-up: pipelines, and the occlusion history a moving camera would have
            double shadowMs = 0.0;
            for (const PassTiming& pass : rendered.stats.passes) {
                if (pass.name == "camera")
                    results[m].camera.push_back(pass.gpuMs);
                if (pass.name == "shadow_map" || pass.name == "view_fit")
                    shadowMs += pass.gpuMs;
            }
            results[m].shadow.push_back(shadowMs);
            results[m].views = rendered.stats.views;
        }

    const DeviceInfo& info = renderer.device();
    std::printf("%s, %s: %s, %llu triangles, %ux%u, shadow map %u^2 per layer, %s (%s), median of %d frames\n", name,
                lightName, sceneName, (unsigned long long)model.triangleCount(), size, size, settings.shadowMapSize,
                info.name.c_str(), info.driver.c_str(), frames);
    std::printf("  %-8s %11s %11s %11s   triangles culled per view\n", "cull", "camera", "shadow map", "raster");
    for (int m = 0; m < 3; ++m) {
        const Result& r = results[m];
        std::printf("  %-8s %8.1f ms %8.1f ms %8.1f ms  ", cullModeName(modes[m]), r.cameraMs(), r.shadowMs(),
                    r.cameraMs() + r.shadowMs());
        for (const ViewCullStats& view : r.views)
            std::printf(" %s %.1f%% (%llu q)", view.name.c_str(), 100.0 * culledFraction(view),
                        (unsigned long long)view.queriesIssued);
        std::printf("\n");
    }
    const Result &none = results[0], &all = results[2];
    const double speedup = (none.cameraMs() + none.shadowMs()) / std::max(all.cameraMs() + all.shadowMs(), 1e-9);
    std::printf("  raster speed-up all vs none: camera %.2fx, shadow map %.2fx, both %.2fx\n",
                none.cameraMs() / std::max(all.cameraMs(), 1e-9), none.shadowMs() / std::max(all.shadowMs(), 1e-9),
                speedup);
    std::printf("{\"bench\":\"cull\",\"case\":\"%s\",\"light\":\"%s\",\"scene\":\"%s\",\"triangles\":%llu,\"device\":"
                "\"%s\",\"driver\":\"%s\","
                "\"size\":%u,\"none_camera_ms\":%.3f,\"none_shadow_ms\":%.3f,\"frustum_camera_ms\":%.3f,\"frustum_"
                "shadow_ms\":%.3f,"
                "\"all_camera_ms\":%.3f,\"all_shadow_ms\":%.3f,\"camera_culled\":%.4f,\"light_culled\":%.4f,"
                "\"speedup\":%.3f}\n",
                name, lightName, sceneName, (unsigned long long)model.triangleCount(), info.name.c_str(),
                info.driver.c_str(), size, none.cameraMs(), none.shadowMs(), results[1].cameraMs(),
                results[1].shadowMs(), all.cameraMs(), all.shadowMs(),
                all.views.empty() ? 0.0 : culledFraction(all.views[0]), lightCulledFraction(all.views), speedup);
    std::fflush(stdout);
}

// Generates and preprocesses the scene, then measures it under its own sun
// and, when given, a point light (six cube faces).
void runCase(const char* name, const char* sceneName, uint64_t triangles, const Camera& camera, const Light* pointLight,
             const std::string& device, uint32_t size, int frames)
{
    auto start = std::chrono::steady_clock::now();
    GenerateOptions options;
    options.triangles = triangles;
    Scene scene = generateScene(sceneName, options);
    CompressedModel model = buildCompressedModel(scene.mesh, {});
    scene.mesh = {};
    std::printf("%s: %.0f s to generate and preprocess\n", name,
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    RendererOptions rendererOptions;
    rendererOptions.device = device;
    Renderer renderer(rendererOptions);
    renderer.loadModel(model);
    renderer.setCamera(camera);
    measureLights(renderer, name, sceneName, model, scene.lights, "sun", size, frames);
    if (pointLight)
        measureLights(renderer, name, sceneName, model, {*pointLight}, "point light", size, frames);
}

} // namespace

int main(int argc, char** argv)
{
    std::string device;
    int frames = 5;
    uint32_t size = 1024;
    uint64_t plantTriangles = 12'500'000, cityTriangles = 4'000'000;
    for (int i = 1; i < argc; ++i) {
        auto value = [&] {
            if (i + 1 >= argc) {
                std::fprintf(stderr, "bench_cull: error: %s needs a value\n", argv[i]);
                std::exit(2);
            }
            return std::string(argv[++i]);
        };
        std::string arg = argv[i];
        if (arg == "--frames")
            frames = std::max(1, std::atoi(value().c_str()));
        else if (arg == "--size")
            size = uint32_t(std::max(16, std::atoi(value().c_str())));
        else if (arg == "--plant-triangles")
            plantTriangles = std::strtoull(value().c_str(), nullptr, 10);
        else if (arg == "--city-triangles")
            cityTriangles = std::strtoull(value().c_str(), nullptr, 10);
        else if (arg == "--device")
            device = value();
        else {
            std::fprintf(stderr, "usage: bench_cull [--frames N] [--size N] [--plant-triangles N] [--city-triangles N] "
                                 "[--device NAME]\n");
            return 2;
        }
    }
    try {
        // Inside the first module's steel structure, under its first level,
        // looking past the vertical tanks across the plant.
        Camera plant;
        plant.position = {-4.0f, 2.0f, -15.0f};
        plant.target = {20.0f, 3.0f, -14.0f};
        plant.yfovDegrees = 60.0f;
        // A lamp under the structure's first level, a few metres from the eye.
        Light lamp;
        lamp.type = LightType::Point;
        lamp.position = {-8.0f, 4.0f, -10.0f};
        lamp.intensity = 40.0f;
        if (plantTriangles)
            runCase("plant interior", "plant", plantTriangles, plant, &lamp, device, size, frames);
        // The generator's own camera: eye height in a street, looking along it.
        if (cityTriangles) {
            GenerateOptions small;
            small.triangles = 10'000;
            Camera street = generateScene("city", small).cameras.at(0);
            runCase("city street", "city", cityTriangles, street, nullptr, device, size, frames);
        }
    } catch (const Error& e) {
        std::fprintf(stderr, "bench_cull: error: %s\n", e.what());
        return 1;
    }
    return 0;
}
