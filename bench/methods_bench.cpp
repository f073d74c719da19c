// Hard-shadow methods side by side (the paper's Figure 8): per model, sm, srt
// and frt on the GPU (warm-up, then median and best of N frames, per-pass
// times, PIP fraction, rays, BVH nodes) and the Embree oracle tracing every
// pixel on the same cores; pixel mismatch of each method against the oracle.
//   bench_methods MODEL... [--size N] [--frames N] [--device NAME]
// MODEL is any importable file, or gen:NAME:TRIANGLES for a procedural scene.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "penumbra/generate.h"
#include "penumbra/oracle.h"
#include "penumbra/penumbra.h"

namespace {

using namespace penumbra;

Scene loadScene(const std::string& spec)
{
    if (spec.rfind("gen:", 0) == 0) {
        size_t colon = spec.find(':', 4);
        GenerateOptions options;
        options.triangles = colon == std::string::npos ? 1'000'000 : std::stoull(spec.substr(colon + 1));
        return generateScene(spec.substr(4, colon - 4), options);
    }
    return importScene(spec);
}

struct Measured {
    double medianMs = 0, bestMs = 0;
    Frame frame;
};

Measured measure(Renderer& renderer, RenderSettings settings, int frames)
{
    renderer.render(settings); // warm-up
    std::vector<double> times;
    Measured m;
    for (int i = 0; i < frames; ++i) {
        m.frame = renderer.render(settings);
        times.push_back(m.frame.stats.gpuMs);
    }
    std::sort(times.begin(), times.end());
    m.medianMs = times[times.size() / 2];
    m.bestMs = times.front();
    return m;
}

double mismatch(const std::vector<float>& oracle, const std::vector<float>& visibility)
{
    size_t compared = 0, differing = 0;
    for (size_t i = 0; i < oracle.size(); ++i)
        if (oracle[i] >= 0.0f) {
            ++compared;
            differing += oracle[i] != visibility[i];
        }
    return compared ? double(differing) / double(compared) : 0.0;
}

} // namespace

int main(int argc, char** argv)
{
    std::vector<std::string> models;
    uint32_t size = 1024;
    int frames = 3;
    std::string device;
    for (int i = 1; i < argc; ++i) {
        if (std::strcmp(argv[i], "--size") == 0 && i + 1 < argc) size = uint32_t(std::atoi(argv[++i]));
        else if (std::strcmp(argv[i], "--frames") == 0 && i + 1 < argc) frames = std::max(1, std::atoi(argv[++i]));
        else if (std::strcmp(argv[i], "--device") == 0 && i + 1 < argc) device = argv[++i];
        else models.push_back(argv[i]);
    }
    if (models.empty()) {
        std::fprintf(stderr, "usage: bench_methods MODEL|gen:NAME:TRIANGLES... [--size N] [--frames N] [--device NAME]\n");
        return 2;
    }
    try {
        RendererOptions options;
        options.device = device;
        Renderer renderer(options);
        const DeviceInfo& info = renderer.device();
        std::printf("device: %s (%s), %ux%u, %d frames after warm-up, times are GPU ms per frame (median / best)\n", info.name.c_str(),
                    info.driver.c_str(), size, size, frames);
        std::printf("%-22s %10s %16s %16s %16s %12s %8s %10s %12s %9s %9s %9s\n", "model", "triangles", "sm ms", "srt ms", "frt ms",
                    "oracle ms", "PIP %", "srt rays", "frt/srt", "sm err%", "srt err%", "frt err%");
        for (const std::string& spec : models) {
            Scene scene = loadScene(spec);
            renderer.loadModel(scene.mesh);
            if (!scene.cameras.empty())
                renderer.setCamera(scene.cameras[0]);
            Light light = scene.lights.empty() ? defaultLight() : scene.lights[0];
            renderer.setLights({light});
            RenderSettings settings;
            settings.width = settings.height = size;
            settings.readbackGBuffer = true;
            Measured results[3];
            const ShadowMethod methods[3] = {ShadowMethod::ShadowMap, ShadowMethod::Selective, ShadowMethod::FullRayTrace};
            for (int m = 0; m < 3; ++m) {
                settings.shadows = methods[m];
                results[m] = measure(renderer, settings, frames);
            }
            const Frame& frt = results[2].frame;
            EmbreeOracle oracle(scene.mesh);
            OracleOptions oracleOptions;
            oracleOptions.originOffset = frt.stats.rayOffset;
            std::vector<double> oracleTimes;
            std::vector<float> reference;
            for (int i = 0; i < frames; ++i) {
                auto start = std::chrono::steady_clock::now();
                reference = oracle.hardShadowVisibility(frt.positions, frt.normals, light, oracleOptions);
                oracleTimes.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
            }
            std::sort(oracleTimes.begin(), oracleTimes.end());
            char sm[32], srt[32], frtText[32];
            std::snprintf(sm, sizeof(sm), "%.0f / %.0f", results[0].medianMs, results[0].bestMs);
            std::snprintf(srt, sizeof(srt), "%.0f / %.0f", results[1].medianMs, results[1].bestMs);
            std::snprintf(frtText, sizeof(frtText), "%.0f / %.0f", results[2].medianMs, results[2].bestMs);
            std::printf("%-22s %10llu %16s %16s %16s %12.0f %8.2f %10llu %11.2fx %9.3f %9.3f %9.3f\n", spec.c_str(),
                        (unsigned long long)results[0].frame.stats.triangles, sm, srt, frtText, oracleTimes[oracleTimes.size() / 2],
                        results[1].frame.stats.pipFraction * 100.0, (unsigned long long)results[1].frame.stats.rays,
                        results[2].medianMs / results[1].medianMs, mismatch(reference, results[0].frame.visibility) * 100.0,
                        mismatch(reference, results[1].frame.visibility) * 100.0, mismatch(reference, frt.visibility) * 100.0);
            for (int m = 0; m < 3; ++m) {
                std::printf("    %s passes:", shadowMethodName(methods[m]));
                for (const PassTiming& pass : results[m].frame.stats.passes)
                    std::printf(" %s %.1f", pass.name.c_str(), pass.gpuMs);
                std::printf(" | rays %llu nodes %llu\n", (unsigned long long)results[m].frame.stats.rays,
                            (unsigned long long)results[m].frame.stats.nodesVisited);
            }
            std::printf("{\"bench\":\"methods\",\"model\":\"%s\",\"device\":\"%s\",\"driver\":\"%s\",\"size\":%u,\"sm_ms\":%.2f,\"srt_ms\":%.2f,"
                        "\"frt_ms\":%.2f,\"oracle_ms\":%.2f,\"pip_fraction\":%.5f,\"srt_rays\":%llu,\"frt_rays\":%llu,"
                        "\"sm_mismatch\":%.6f,\"srt_mismatch\":%.6f,\"frt_mismatch\":%.6f}\n",
                        spec.c_str(), info.name.c_str(), info.driver.c_str(), size, results[0].medianMs, results[1].medianMs,
                        results[2].medianMs, oracleTimes[oracleTimes.size() / 2], results[1].frame.stats.pipFraction,
                        (unsigned long long)results[1].frame.stats.rays, (unsigned long long)results[2].frame.stats.rays,
                        mismatch(reference, results[0].frame.visibility), mismatch(reference, results[1].frame.visibility),
                        mismatch(reference, frt.visibility));
            std::fflush(stdout);
        }
    } catch (const Error& e) {
        std::fprintf(stderr, "bench_methods: error: %s\n", e.what());
        return 1;
    }
    return 0;
}
