// Cone ray hierarchies (rh) against the other hard-shadow methods, A/B style:
// per scene a point light among the geometry (as the suite's 'point' section:
// a quarter of the height above the centre), every configuration rendered
// once to warm up, then N rounds in which each configuration renders one
// frame in turn (interleaved, so a noisy machine slows them alike). Prints
// per configuration the median GPU and wall-clock ms, the median of each
// pass, and rh's counters (rays, cone tests, ray tests, casters, rounds,
// peak pair memory); with --oracle, each configuration's pixels that differ
// from the Embree oracle.
//   bench_rh [gen:NAME:TRIANGLES | MODEL]... [--size N] [--frames N] [--light point|spot|sun]
//            [--oracle] [--config NAME]...
// A configuration is a method (sm, srt, frt, rh) with rh options after a
// colon, comma-separated: sorted, unsorted, auto, spheres, precise, ea, noea,
// 2p, no2p, closed, open; e.g. --config frt --config rh:auto,ea --config rh:unsorted.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "penumbra/generate.h"
#include "penumbra/oracle.h"
#include "penumbra/penumbra.h"
#include "tool_util.h"

namespace {

using namespace penumbra;

Scene loadScene(const std::string& spec)
{
    if (spec.rfind("gen:", 0) == 0) {
        size_t colon = spec.find(':', 4);
        GenerateOptions options;
        options.triangles = colon == std::string::npos ? 250'000 : std::stoull(spec.substr(colon + 1));
        return generateScene(spec.substr(4, colon - 4), options);
    }
    return importScene(spec);
}

struct Config {
    std::string name;
    RenderSettings settings;
};

Config parseConfig(const std::string& text, uint32_t size)
{
    Config c;
    c.name = text;
    c.settings.width = c.settings.height = size;
    const size_t colon = text.find(':');
    c.settings.shadows = parseShadowMethod(text.substr(0, colon));
    if (colon == std::string::npos)
        return c;
    std::stringstream options(text.substr(colon + 1));
    std::string option;
    while (std::getline(options, option, ',')) {
        if (option == "sorted") c.settings.rhSort = RhSort::On;
        else if (option == "unsorted") c.settings.rhSort = RhSort::Off;
        else if (option == "auto") c.settings.rhSort = RhSort::Auto;
        else if (option == "spheres" || option == "precise") c.settings.coneTest = parseConeTest(option);
        else if (option == "ea") c.settings.rhEarlyAccept = true;
        else if (option == "noea") c.settings.rhEarlyAccept = false;
        else if (option == "closed") c.settings.rhClosedMeshes = true;
        else if (option == "nogrid") c.settings.rhCullBehindReceivers = false;
        else if (option == "open") c.settings.rhClosedMeshes = false;
        else if (option == "2p") c.settings.rhTwoPass = true;
        else if (option == "no2p") c.settings.rhTwoPass = false;
        else throw Error("bench_rh: unknown rh option '" + option + "' in " + text);
    }
    return c;
}

using penumbra::bench_tool::median;

struct Runs {
    std::vector<double> gpu, cpu;
    std::map<std::string, std::vector<double>> passes;
    FrameStats last;
    Frame warm;
};

} // namespace

int main(int argc, char** argv)
{
    std::vector<std::string> scenes, configNames;
    uint32_t size = 320;
    int frames = 3;
    bool oracle = false;
    std::string lightKind = "point";
    for (int i = 1; i < argc; ++i) {
        if (std::strcmp(argv[i], "--size") == 0 && i + 1 < argc) size = uint32_t(std::atoi(argv[++i]));
        else if (std::strcmp(argv[i], "--frames") == 0 && i + 1 < argc) frames = std::max(1, std::atoi(argv[++i]));
        else if (std::strcmp(argv[i], "--config") == 0 && i + 1 < argc) configNames.push_back(argv[++i]);
        else if (std::strcmp(argv[i], "--light") == 0 && i + 1 < argc) lightKind = argv[++i];
        else if (std::strcmp(argv[i], "--oracle") == 0) oracle = true;
        else scenes.push_back(argv[i]);
    }
    if (scenes.empty())
        scenes = {"gen:city:250000", "gen:interior:250000", "gen:plant:250000", "gen:scan:250000"};
    if (configNames.empty())
        configNames = {"sm", "srt", "frt", "rh"};
    try {
        std::vector<Config> configs;
        for (const std::string& name : configNames)
            configs.push_back(parseConfig(name, size));
        Renderer renderer;
        std::printf("device: %s, %ux%u, %d interleaved frames after a warm-up; ms are medians\n", renderer.device().name.c_str(), size, size,
                    frames);
        for (const std::string& spec : scenes) {
            Scene scene = loadScene(spec);
            renderer.loadModel(scene.mesh);
            const Bounds bounds = computeBounds(scene.mesh);
            if (!scene.cameras.empty())
                renderer.setCamera(scene.cameras[0]);
            Light light;
            if (lightKind == "sun") {
                light = scene.lights.empty() ? defaultLight() : scene.lights[0];
                if (light.type != LightType::Directional) {
                    light = defaultLight();
                }
            } else {
                light.type = lightKind == "spot" ? LightType::Spot : LightType::Point;
                light.position = bounds.center() + glm::vec3(0.0f, 0.25f * (bounds.max.y - bounds.min.y), 0.0f);
                light.intensity = 4.0f * glm::dot(bounds.extent(), bounds.extent());
                light.direction = glm::normalize(glm::vec3(0.2f, -1.0f, 0.1f));
                light.outerConeDegrees = 50.0f;
                light.innerConeDegrees = 40.0f;
            }
            renderer.setLights({light});
            std::vector<Runs> runs(configs.size());
            for (size_t c = 0; c < configs.size(); ++c) {
                RenderSettings s = configs[c].settings;
                s.readbackGBuffer = oracle;
                runs[c].warm = renderer.render(s);
            }
            for (int f = 0; f < frames; ++f)
                for (size_t c = 0; c < configs.size(); ++c) {
                    Frame frame = renderer.render(configs[c].settings);
                    Runs& r = runs[c];
                    r.gpu.push_back(frame.stats.gpuMs);
                    r.cpu.push_back(frame.stats.cpuMs);
                    std::map<std::string, double> sums;
                    for (const PassTiming& p : frame.stats.passes)
                        sums[p.name] += p.gpuMs;
                    for (const auto& [name, ms] : sums)
                        r.passes[name].push_back(ms);
                    r.last = frame.stats;
                }
            std::vector<float> reference;
            if (oracle) {
                EmbreeOracle embree(scene.mesh);
                OracleOptions options;
                options.originOffset = runs[0].warm.stats.rayOffset;
                reference = embree.hardShadowVisibility(runs[0].warm.positions, runs[0].warm.normals, light, options);
            }
            std::printf("%s (%llu triangles), %s light\n", spec.c_str(), (unsigned long long)runs[0].last.triangles, lightKind.c_str());
            for (size_t c = 0; c < configs.size(); ++c) {
                const Runs& r = runs[c];
                std::printf("  %-22s gpu %8.1f  wall %8.1f ms", configs[c].name.c_str(), median(r.gpu), median(r.cpu));
                if (oracle) {
                    size_t compared = 0, differing = 0;
                    for (size_t i = 0; i < reference.size(); ++i)
                        if (reference[i] >= 0.0f) {
                            ++compared;
                            differing += reference[i] != r.warm.visibility[i];
                        }
                    std::printf("  differ %zu of %zu", differing, compared);
                    if (std::getenv("BENCH_RH_DIFF"))
                        for (size_t i = 0; i < reference.size(); ++i)
                            if (reference[i] >= 0.0f && reference[i] != r.warm.visibility[i]) {
                                const float* p = &r.warm.positions[4 * i];
                                const float* n = &r.warm.normals[4 * i];
                                std::printf("\n    pixel %zu: oracle %.0f, got %.0f at (%.5f %.5f %.5f) normal (%.3f %.3f %.3f)", i, reference[i],
                                            r.warm.visibility[i], p[0], p[1], p[2], n[0], n[1], n[2]);
                            }
                }
                std::printf("\n     ");
                for (const auto& [name, ms] : r.passes)
                    std::printf(" %s %.1f", name.c_str(), median(ms));
                std::printf("\n");
                if (configs[c].settings.shadows == ShadowMethod::RayHierarchy)
                    std::printf("      rays %llu, cone tests %llu, ray tests %llu, casters %llu, batches %u, rounds %u, peak pairs %llu KiB, "
                                "sorted %u of %u, incoherence %.2f, accepted nodes %llu, closed culling %u\n",
                                (unsigned long long)r.last.rays, (unsigned long long)r.last.nodesVisited,
                                (unsigned long long)r.last.triangleTests, (unsigned long long)r.last.rhCasters, r.last.rhBatches,
                                r.last.rhRounds, (unsigned long long)(r.last.rhPeakPairBytes >> 10), r.last.rhSortedLights,
                                r.last.rhLights, r.last.rhIncoherence, (unsigned long long)r.last.rhAcceptedNodes, r.last.rhClosedCulled);
            }
            std::fflush(stdout);
        }
    } catch (const Error& e) {
        std::fprintf(stderr, "bench_rh: error: %s\n", e.what());
        return 1;
    }
    return 0;
}
