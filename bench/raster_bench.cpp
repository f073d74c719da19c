// Raster time of the compressed form (8-bit strips, quantized vertices) against
// an uncompressed indexed float triangle list of the same model: camera and
// shadow-map passes, warm-up then median and best of N frames, device memory.
//   bench_raster MODEL [--frames N] [--size N] [--device NAME]
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "penumbra/penumbra.h"
#include "penumbra/preprocess.h"
#include "tool_util.h"

namespace {

struct Timing {
    double cameraMedian, cameraBest, shadowMedian, shadowBest;
};

using penumbra::bench_tool::median;

Timing measure(penumbra::Renderer& renderer, const penumbra::RenderSettings& settings, int frames)
{
    renderer.render(settings); // warm-up: pipeline compilation, first-touch of memory
    std::vector<double> camera, shadow;
    for (int i = 0; i < frames; ++i) {
        penumbra::Frame frame = renderer.render(settings);
        for (const penumbra::PassTiming& pass : frame.stats.passes) {
            if (pass.name == "camera") camera.push_back(pass.gpuMs);
            if (pass.name == "shadow_map") shadow.push_back(pass.gpuMs);
        }
    }
    return {median(camera), *std::min_element(camera.begin(), camera.end()), median(shadow),
            *std::min_element(shadow.begin(), shadow.end())};
}

} // namespace

int main(int argc, char** argv)
{
    std::string path, device;
    int frames = 7;
    uint32_t size = 1024;
    for (int i = 1; i < argc; ++i) {
        if (std::strcmp(argv[i], "--frames") == 0 && i + 1 < argc) frames = std::max(1, std::atoi(argv[++i]));
        else if (std::strcmp(argv[i], "--size") == 0 && i + 1 < argc) size = uint32_t(std::atoi(argv[++i]));
        else if (std::strcmp(argv[i], "--device") == 0 && i + 1 < argc) device = argv[++i];
        else path = argv[i];
    }
    if (path.empty()) {
        std::fprintf(stderr, "usage: bench_raster MODEL(.ply/.glb/...) [--frames N] [--size N] [--device NAME]\n");
        return 2;
    }
    try {
        penumbra::Scene scene = penumbra::importScene(path);
        penumbra::CompressedModel model = penumbra::buildCompressedModel(scene.mesh, {});
        penumbra::RendererOptions options;
        options.device = device;
        penumbra::Renderer renderer(options);
        penumbra::Camera camera = scene.cameras.empty() ? penumbra::defaultCamera(penumbra::computeBounds(scene.mesh)) : scene.cameras[0];
        renderer.setCamera(camera);
        renderer.setLights(scene.lights);
        penumbra::RenderSettings settings;
        settings.width = settings.height = size;
        settings.cull = penumbra::CullMode::None; // the same draws for both encodings (bench_cull measures culling)

        renderer.loadUncompressedReference(scene.mesh);
        uint64_t referenceBytes = renderer.modelDeviceBytes();
        Timing reference = measure(renderer, settings, frames);
        renderer.loadModel(model);
        uint64_t compressedBytes = renderer.modelDeviceBytes();
        Timing compressed = measure(renderer, settings, frames);

        const penumbra::DeviceInfo& info = renderer.device();
        std::printf("%s: %zu triangles, %ux%u, %s (%s), %d frames after warm-up\n", path.c_str(), scene.mesh.triangleCount(), size, size,
                    info.name.c_str(), info.driver.c_str(), frames);
        std::printf("  %-24s %12s %12s %12s %12s %12s\n", "geometry", "device MiB", "camera med", "camera best", "shadow med", "shadow best");
        auto row = [](const char* name, uint64_t bytes, const Timing& t) {
            std::printf("  %-24s %12.1f %9.2f ms %9.2f ms %9.2f ms %9.2f ms\n", name, bytes / 1048576.0, t.cameraMedian, t.cameraBest,
                        t.shadowMedian, t.shadowBest);
        };
        row("uncompressed float list", referenceBytes, reference);
        row("compressed strips", compressedBytes, compressed);
        double ratio = (compressed.cameraMedian + compressed.shadowMedian) / (reference.cameraMedian + reference.shadowMedian);
        std::printf("  compressed / uncompressed raster time (camera + shadow, median): %.3fx; memory %.2fx\n", ratio,
                    double(compressedBytes) / double(referenceBytes));
        std::printf("{\"bench\":\"raster\",\"model\":\"%s\",\"triangles\":%zu,\"device\":\"%s\",\"driver\":\"%s\",\"size\":%u,"
                    "\"reference_ms\":%.3f,\"compressed_ms\":%.3f,\"ratio\":%.4f,\"reference_bytes\":%llu,\"compressed_bytes\":%llu}\n",
                    path.c_str(), scene.mesh.triangleCount(), info.name.c_str(), info.driver.c_str(), size,
                    reference.cameraMedian + reference.shadowMedian, compressed.cameraMedian + compressed.shadowMedian, ratio,
                    (unsigned long long)referenceBytes, (unsigned long long)compressedBytes);
    } catch (const penumbra::Error& e) {
        std::fprintf(stderr, "bench_raster: error: %s\n", e.what());
        return 1;
    }
    return 0;
}
