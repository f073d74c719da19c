// Out of core (issue 19): frame time against the geometry budget, and the
// bytes each frame streams along a camera path. Per method, one renderer
// without a budget and one per budget (1/divisor of the model's paged
// geometry) render the same path; every frame is compared bit for bit with
// the unlimited one.
//   bench_budget MODEL [--size N] [--frames N] [--methods srt,frt] [--divisors 4,16]
//                      [--budgets MiB,...] [--reference none] [--view whole] [--page KiB] [--out DIR]
//                      [--device NAME]
// MODEL: a .penumbra file, any importable file, or gen:NAME:TRIANGLES.
// --budgets: absolute budgets instead of divisors; --reference none: no
// unlimited renderer (for models whose geometry does not fit the device at
// once): frames are not compared, and their identical column is empty.
// --view whole: the path starts at the view that frames the whole model
// (defaultCamera), not at the model's first camera or a patch of it.
// Writes DIR/budget.csv (one row per frame), DIR/budget_summary.csv (median
// frame time per method and budget), DIR/budget.gp and, when gnuplot is
// installed, DIR/budget.png (frame time against budget; bytes streamed per
// frame along the path).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "penumbra/generate.h"
#include "penumbra/io.h"
#include "penumbra/model_format.h"
#include "penumbra/penumbra.h"
#include "penumbra/preprocess.h"
#include "tool_util.h"

namespace {

using penumbra::bench_tool::median;
using penumbra::bench_tool::splitCommas;

using namespace penumbra;

bool sameImage(const Frame& a, const Frame& b)
{
    return a.color.rgba.size() == b.color.rgba.size() &&
           std::memcmp(a.color.rgba.data(), b.color.rgba.data(), a.color.rgba.size() * sizeof(float)) == 0;
}

} // namespace

int main(int argc, char** argv)
{
    try {
        if (argc < 2) {
            std::fprintf(stderr, "usage: bench_budget MODEL [--size N] [--frames N] [--methods srt,frt] [--divisors 4,16] "
                                 "[--budgets MiB,...] [--reference none] [--view whole] [--page KiB] [--out DIR] [--device NAME]\n");
            return 2;
        }
        std::string modelSpec = argv[1], out = "bench_budget", device;
        uint32_t size = 512, frames = 5;
        uint64_t pageBytes = RendererOptions{}.geometryPageBytes;
        std::vector<std::string> methods = {"srt", "frt"};
        std::vector<uint64_t> divisors = {4, 16};
        std::vector<uint64_t> budgets; // bytes; --budgets replaces the divisors
        bool reference = true, wholeView = false;
        for (int i = 2; i + 1 < argc; i += 2) {
            const std::string key = argv[i], value = argv[i + 1];
            if (key == "--size") size = uint32_t(std::stoul(value));
            else if (key == "--frames") frames = uint32_t(std::stoul(value));
            else if (key == "--methods") methods = splitCommas(value);
            else if (key == "--divisors") {
                divisors.clear();
                for (const std::string& d : splitCommas(value))
                    divisors.push_back(std::stoull(d));
            } else if (key == "--budgets") {
                for (const std::string& b : splitCommas(value))
                    budgets.push_back(uint64_t(std::stod(b) * 1048576.0));
            } else if (key == "--reference") {
                if (value != "none") {
                    std::fprintf(stderr, "bench_budget: --reference takes only 'none'\n");
                    return 2;
                }
                reference = false;
            } else if (key == "--view") {
                if (value != "whole") {
                    std::fprintf(stderr, "bench_budget: --view takes only 'whole'\n");
                    return 2;
                }
                wholeView = true;
            } else if (key == "--page") pageBytes = uint64_t(std::stod(value) * 1024.0);
            else if (key == "--out") out = value;
            else if (key == "--device") device = value;
            else {
                std::fprintf(stderr, "bench_budget: unknown option %s\n", key.c_str());
                return 2;
            }
        }
        // The model, its camera and light.
        CompressedModel model;
        Scene scene;
        if (modelSpec.rfind("gen:", 0) == 0) {
            const size_t colon = modelSpec.find(':', 4);
            GenerateOptions options;
            options.triangles = colon == std::string::npos ? 1'000'000 : std::stoull(modelSpec.substr(colon + 1));
            scene = generateScene(modelSpec.substr(4, colon - 4), options);
            model = buildCompressedModel(scene.mesh, PreprocessOptions{});
        } else if (modelSpec.size() > 9 && modelSpec.substr(modelSpec.size() - 9) == ".penumbra") {
            model = openModelFile(modelSpec);
            scene.cameras = modelCameras(model);
            scene.lights = modelLights(model);
        } else {
            scene = importScene(modelSpec);
            model = buildCompressedModel(scene.mesh, PreprocessOptions{});
        }
        Bounds bounds;
        bounds.min = {model.header.boundsMin[0], model.header.boundsMin[1], model.header.boundsMin[2]};
        bounds.max = {model.header.boundsMax[0], model.header.boundsMax[1], model.header.boundsMax[2]};
        const glm::vec3 extent = bounds.max - bounds.min;
        const float diagonal = glm::length(extent);
        // The path: the model's first camera (else a slanted view of a patch) moving along its view direction.
        Camera start;
        if (wholeView) {
            start = defaultCamera(bounds);
        } else if (!scene.cameras.empty()) {
            start = scene.cameras[0];
        } else {
            const glm::vec3 patch(bounds.min.x + 0.3f * extent.x, bounds.min.y, bounds.min.z + 0.35f * extent.z);
            start.position = patch + glm::vec3(0.02f * extent.x, 0.15f * extent.y + 0.05f * extent.x, 0.03f * extent.z);
            start.target = patch;
            start.yfovDegrees = 20.0f;
        }
        const glm::vec3 forward = glm::normalize(start.target - start.position);
        Light light;
        if (!scene.lights.empty()) {
            light = scene.lights[0];
        } else {
            light.type = LightType::Directional;
            light.direction = glm::normalize(glm::vec3(0.5f, -1.3f, 0.4f));
            light.intensity = 3.0f;
        }

        std::filesystem::create_directories(out);
        std::ofstream csv(out + "/budget.csv");
        csv << "method,divisor,budget_bytes,geometry_bytes,frame,frame_ms,gpu_ms,bytes_streamed,pages_uploaded,parking_rounds,"
               "parked_rays,resident_peak_bytes,identical\n";
        std::ofstream summary(out + "/budget_summary.csv");
        summary << "method,divisor,budget_mib,median_frame_ms,median_bytes_streamed,identical_frames,frames\n";
        uint64_t geometryBytes = 0;
        if (budgets.empty()) {
            RendererOptions probeOptions;
            probeOptions.device = device;
            probeOptions.geometryBudgetBytes = uint64_t(1) << 40;
            probeOptions.geometryPageBytes = pageBytes;
            Renderer probe(probeOptions);
            probe.loadModel(model);
            RenderSettings settings;
            settings.width = settings.height = 16;
            probe.setCamera(start);
            probe.setLights({light});
            geometryBytes = probe.render(settings).stats.geometryBytes;
        }
        if (budgets.empty())
            std::printf("model %s: %llu triangles, paged geometry %.1f MiB in pages of %.0f KiB\n", modelSpec.c_str(),
                        (unsigned long long)model.header.triangleCount, double(geometryBytes) / 1048576.0, double(pageBytes) / 1024.0);
        else
            std::printf("model %s: %llu triangles, pages of %.0f KiB\n", modelSpec.c_str(), (unsigned long long)model.header.triangleCount,
                        double(pageBytes) / 1024.0);
        // Runs: (divisor, budget bytes); divisor 0 with budget 0 is the unlimited reference.
        std::vector<std::pair<uint64_t, uint64_t>> runs;
        if (reference)
            runs.push_back({0, 0});
        if (budgets.empty())
            for (uint64_t divisor : divisors)
                runs.push_back({divisor, geometryBytes / divisor});
        for (uint64_t budget : budgets)
            runs.push_back({0, budget});
        auto runName = [&](size_t r) {
            char text[64];
            if (runs[r].first)
                std::snprintf(text, sizeof(text), "1/%llu", (unsigned long long)runs[r].first);
            else if (runs[r].second)
                std::snprintf(text, sizeof(text), "%g MiB", double(runs[r].second) / 1048576.0);
            else
                std::snprintf(text, sizeof(text), "none");
            return std::string(text);
        };
        int failures = 0;
        for (const std::string& methodName : methods) {
            const ShadowMethod method = parseShadowMethod(methodName);
            std::vector<std::unique_ptr<Renderer>> renderers;
            for (const auto& run : runs) {
                RendererOptions options;
                options.device = device;
                options.geometryBudgetBytes = run.second;
                options.geometryPageBytes = pageBytes;
                renderers.push_back(std::make_unique<Renderer>(options));
                renderers.back()->loadModel(model);
            }
            std::vector<std::vector<double>> times(runs.size()), streamed(runs.size());
            std::vector<uint32_t> identical(runs.size(), 0);
            for (uint32_t f = 0; f < frames; ++f) {
                Camera camera = start;
                const glm::vec3 step = forward * (0.01f * diagonal * float(f));
                camera.position += step;
                camera.target += step;
                Frame referenceFrame;
                for (size_t r = 0; r < runs.size(); ++r) {
                    Renderer& renderer = *renderers[r];
                    renderer.setCamera(camera);
                    renderer.setLights({light});
                    RenderSettings settings;
                    settings.width = settings.height = size;
                    settings.shadows = method;
                    Frame frame;
                    try {
                        frame = renderer.render(settings);
                    } catch (const std::exception& e) {
                        std::printf("%s %s frame %u: %s\n", methodName.c_str(), runName(r).c_str(), f, e.what());
                        ++failures;
                        continue;
                    }
                    const bool compared = reference && r > 0;
                    if (reference && r == 0)
                        referenceFrame = frame;
                    const bool same = !compared || sameImage(referenceFrame, frame);
                    identical[r] += same;
                    failures += same ? 0 : 1;
                    const FrameStats& s = frame.stats;
                    times[r].push_back(s.cpuMs);
                    streamed[r].push_back(double(s.bytesStreamed));
                    csv << methodName << ',' << runs[r].first << ',' << runs[r].second << ','
                        << (geometryBytes ? geometryBytes : s.geometryBytes) << ',' << f << ',' << s.cpuMs << ',' << s.gpuMs << ','
                        << s.bytesStreamed << ',' << s.pagesUploaded << ',' << s.parkingRounds << ',' << s.parkedRays << ','
                        << s.residentPeakBytes << ',' << (reference ? (same ? "1" : "0") : "") << '\n';
                    std::printf("%s budget %s frame %u: %.1f ms, streamed %.2f MiB in %llu pages, %u parking rounds, %s\n",
                                methodName.c_str(), runName(r).c_str(), f, s.cpuMs, double(s.bytesStreamed) / 1048576.0,
                                (unsigned long long)s.pagesUploaded, s.parkingRounds,
                                !reference ? "not compared" : same ? "identical" : "DIFFERS");
                    std::fflush(stdout);
                }
            }
            for (size_t r = 0; r < runs.size(); ++r)
                summary << methodName << ',' << runs[r].first << ','
                        << double(runs[r].second ? runs[r].second : geometryBytes) / 1048576.0 << ',' << median(times[r]) << ','
                        << median(streamed[r]) << ',' << (reference ? std::to_string(identical[r]) : std::string()) << ',' << frames << '\n';
        }
        csv.close();
        summary.close();
        std::ofstream gp(out + "/budget.gp");
        gp << "set datafile separator ','\nset terminal pngcairo size 1200,480\nset output '" << out << "/budget.png'\n"
           << "set multiplot layout 1,2\nset title 'median frame time against geometry budget'\nset xlabel 'budget (MiB; unlimited: the "
              "whole geometry)'\nset ylabel 'ms'\nset logscale x 2\n"
           << "plot for [m in '";
        for (size_t i = 0; i < methods.size(); ++i)
            gp << (i ? " " : "") << methods[i];
        gp << "'] '" << out << "/budget_summary.csv' using (strcol(1) eq m ? $3 : 1/0):4 with linespoints title m\n"
           << "unset logscale x\nset title 'bytes streamed per frame along the camera path'\nset xlabel 'frame'\nset ylabel 'MiB'\n"
           << "plot for [b in '";
        for (size_t r = 0; r < runs.size(); ++r)
            if (runs[r].second)
                gp << (r ? " " : "") << runs[r].second;
        gp << "'] '" << out << "/budget.csv' using ((strcol(1) eq '" << methods[0] << "' && $3 == real(b)) ? $5 : 1/0):($8/1048576) with points pt 7 title '"
           << methods[0] << " '.sprintf('%.1f MiB', real(b)/1048576)\nunset multiplot\n";
        gp.close();
        if (std::system(("command -v gnuplot >/dev/null && gnuplot '" + out + "/budget.gp'").c_str()) != 0)
            std::printf("gnuplot missing or failed: %s/budget.gp not plotted\n", out.c_str());
        std::printf("%s/budget.csv, %s/budget_summary.csv%s\n", out.c_str(), out.c_str(), failures ? "; SOME FRAMES FAILED OR DIFFER" : "");
        return failures ? 1 : 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "bench_budget: %s\n", e.what());
        return 1;
    }
}
