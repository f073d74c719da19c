// The penumbra Python module over the C++ API (runtime/include/penumbra/penumbra.h):
//   penumbra.render(model, size=(w, h), shadows="srt", camera=None, lights=None, ...) -> float32 (h, w, 4)
//   penumbra.Renderer(model): load once, then set_camera / set_lights / render many frames; .stats
//   penumbra.preprocess(input, output, ...), penumbra.generate(name, output, ...), penumbra.write_image(...)
// Lights are the CLI's strings ('spot position=0,20,0 outer_cone=30') or dicts
// with the scene file's keys; the camera is a dict with the scene file's keys.
// Every failure raises penumbra.Error (a RuntimeError) with the CLI's one-line message.
#include <chrono>
#include <cstdio>
#include <mutex>
#include <optional>

#include <pybind11/eval.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "penumbra/generate.h"
#include "penumbra/penumbra.h"
#include "penumbra/preprocess.h"
#include "penumbra/streamed.h"

namespace py = pybind11;
using namespace pybind11::literals;

namespace {

using namespace penumbra;

bool endsWith(const std::string& text, const std::string& suffix)
{
    return text.size() >= suffix.size() && text.compare(text.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// Hands a float vector to numpy without a copy.
py::array_t<float> toArray(std::vector<float>&& values, const std::vector<py::ssize_t>& shape)
{
    auto* owned = new std::vector<float>(std::move(values));
    py::capsule release(owned, [](void* p) { delete static_cast<std::vector<float>*>(p); });
    return py::array_t<float>(shape, owned->data(), release);
}

// A dict (numpy values allowed) as JSON text for the scene-file parsers.
std::string toJson(const py::handle& value, const std::string& subject)
{
    py::cpp_function plain([](const py::object& o) -> py::object {
        if (py::hasattr(o, "tolist"))
            return o.attr("tolist")();
        throw py::type_error("a " + std::string(py::str(py::type::of(o).attr("__name__"))) + " is not a number or a list");
    });
    try {
        return py::module_::import("json").attr("dumps")(value, "default"_a = plain).cast<std::string>();
    } catch (py::error_already_set& e) {
        fail(subject, py::str(e.value()));
    }
}

Light toLight(const py::handle& value, size_t index)
{
    std::string subject = "lights[" + std::to_string(index) + "]";
    if (py::isinstance<py::str>(value))
        return parseLightSpec(value.cast<std::string>());
    if (py::isinstance<py::dict>(value))
        return parseLightJson(toJson(value, subject), subject);
    fail(subject, "a light is a string like 'point position=0,5,0' or a dict like {'type': 'point', 'position': [0, 5, 0]}");
}

// N or (width, height), integers (numpy's too).
std::pair<uint32_t, uint32_t> toSize(const py::handle& size)
{
    long long w = 0, h = 0;
    try {
        if (py::isinstance<py::sequence>(size) && !py::isinstance<py::str>(size) && py::len(size) == 2) {
            w = size[py::int_(0)].attr("__index__")().cast<long long>();
            h = size[py::int_(1)].attr("__index__")().cast<long long>();
        } else {
            w = h = size.attr("__index__")().cast<long long>();
        }
    } catch (py::error_already_set&) {
        fail("size", "expected N or (width, height), integers");
    }
    if (w < 1 || h < 1 || w > 16384 || h > 16384)
        fail("size", "each side must be 1..16384");
    return {uint32_t(w), uint32_t(h)};
}

py::dict deviceDict(const DeviceInfo& d)
{
    return py::dict("index"_a = d.index, "name"_a = d.name, "type"_a = d.type, "driver"_a = d.driver, "api_version"_a = d.apiVersion);
}

// The CLI's --shadow-fit.
bool fitToView(const std::string& shadowFit)
{
    if (shadowFit != "view" && shadowFit != "model")
        fail("--shadow-fit " + shadowFit, "expected view or model");
    return shadowFit == "view";
}

class PyRenderer {
public:
    PyRenderer(const py::object& model, const std::string& device, bool validation, const py::object& ground)
    {
        RendererOptions options;
        options.device = device;
        options.validation = validation;
        {
            py::gil_scoped_release unlocked;
            renderer.emplace(options);
        }
        if (!model.is_none())
            load(model, ground);
    }

    // Loads a model file (.penumbra, or any format importScene reads, preprocessed
    // in memory) and resets the camera and lights to the model's own.
    // ground: "off", "auto", "below" or a height (the CLI's --ground).
    void load(const py::object& model, const py::object& ground)
    {
        const std::string path = py::str(py::module_::import("os").attr("fspath")(model));
        const Ground groundChoice = py::isinstance<py::str>(ground) ? parseGround(ground.cast<std::string>())
                                                                    : Ground{Ground::Kind::At, ground.cast<float>()};
        Scene scene;
        Bounds bounds;
        {
            py::gil_scoped_release unlocked;
            std::lock_guard lock(mutex);
            CompressedModel compressed;
            if (endsWith(path, ".penumbra")) {
                compressed = openModelFile(path);
                scene.cameras = penumbra::modelCameras(compressed); // the source glTF's, stored by preprocess
                scene.lights = penumbra::modelLights(compressed);
                bounds.min = glm::vec3(compressed.header.boundsMin[0], compressed.header.boundsMin[1], compressed.header.boundsMin[2]);
                bounds.max = glm::vec3(compressed.header.boundsMax[0], compressed.header.boundsMax[1], compressed.header.boundsMax[2]);
            } else {
                scene = importScene(path);
                bounds = computeBounds(scene.mesh);
            }
            applyGround(groundChoice, bounds, scene.mesh, compressed);
            if (!compressed.clusters.empty())
                renderer->loadModel(compressed);
            else
                renderer->loadModel(scene.mesh);
        }
        std::lock_guard lock(mutex);
        modelCamera = scene.cameras.empty() ? defaultCamera(bounds) : scene.cameras[0];
        modelLights = scene.lights;
        renderer->setCamera(modelCamera);
        renderer->setLights(modelLights);
        loaded = true;
    }

    // None: the model's camera (its first glTF camera, else one framing it).
    void setCamera(const py::object& camera)
    {
        Camera chosen = camera.is_none() ? modelCamera : parseCameraJson(toJson(camera, "camera"), "camera");
        std::lock_guard lock(mutex);
        renderer->setCamera(chosen);
    }

    // None or []: the model's lights, else a directional sun.
    void setLights(const py::object& lights)
    {
        std::vector<Light> chosen;
        if (!lights.is_none())
            for (const py::handle& light : lights)
                chosen.push_back(toLight(light, chosen.size()));
        if (chosen.empty())
            chosen = modelLights;
        std::lock_guard lock(mutex);
        renderer->setLights(chosen);
    }

    py::array_t<float> render(const RenderSettings& settings)
    {
        if (!loaded)
            fail("render", "no model loaded");
        Frame frame;
        {
            py::gil_scoped_release unlocked;
            std::lock_guard lock(mutex);
            frame = renderer->render(settings);
        }
        const py::ssize_t w = frame.color.width, h = frame.color.height;
        statsText = statsJson(frame.stats);
        gbuffer = py::none();
        if (settings.readbackGBuffer)
            gbuffer = py::dict("position"_a = toArray(std::move(frame.positions), {h, w, 4}),
                               "normal"_a = toArray(std::move(frame.normals), {h, w, 4}),
                               "visibility"_a = toArray(std::move(frame.visibility), {h, w}));
        return toArray(std::move(frame.color.rgba), {h, w, 4});
    }

    py::object stats() const
    {
        return statsText.empty() ? py::none() : py::module_::import("json").attr("loads")(statsText);
    }

    py::dict device() const { return deviceDict(renderer->device()); }

    uint32_t validationMessages() const { return renderer->validationMessageCount(); }
    py::object gbuffer = py::none();

private:
    std::optional<Renderer> renderer;
    std::mutex mutex; // the GIL is released while Vulkan works
    bool loaded = false;
    Camera modelCamera;
    std::vector<Light> modelLights;
    std::string statsText;
};

py::dict streamedStats(const std::string& output, const StreamedStats& stats)
{
    return py::dict("output"_a = output, "input_triangles"_a = stats.inputTriangles, "triangles"_a = stats.triangles,
                    "clusters"_a = stats.clusters, "nodes"_a = stats.nodes, "chunks"_a = stats.chunks,
                    "largest_chunk"_a = stats.largestChunk, "chunk_capacity"_a = stats.chunkCapacity,
                    "bvh_depth"_a = stats.bvhDepth, "max_position_error"_a = stats.maxPositionError,
                    "bytes"_a = stats.fileBytes, "temporary_bytes"_a = stats.temporaryBytes,
                    "closed_triangles"_a = stats.closedTriangles, "closed_cluster_triangles"_a = stats.closedClusterTriangles,
                    "vertex_cache_hit_rate"_a = stats.vertexCacheHitRate, "seconds"_a = stats.totalSeconds);
}

// Ctrl-C while a long preprocessing call runs with the GIL released: its
// progress callbacks (called on this thread) look at Python's signals at most
// every 50 ms; a pending KeyboardInterrupt (or an exception from any Python
// signal handler) unwinds the C++ call, whose writers remove their temporary
// files, and reaches the caller.
class InterruptCheck {
  public:
    void operator()()
    {
        const auto now = std::chrono::steady_clock::now();
        if (now < next)
            return;
        next = now + std::chrono::milliseconds(50);
        py::gil_scoped_acquire locked;
        if (PyErr_CheckSignals() != 0)
            throw py::error_already_set();
    }

  private:
    std::chrono::steady_clock::time_point next{};
};

py::dict preprocessFile(const std::filesystem::path& inputPath, const std::filesystem::path& outputPath, float simplify, uint32_t clusterVertices,
                        uint32_t clusterTriangles, uint32_t leafTriangles, unsigned threads, bool separateClosed, uint64_t memoryLimit,
                        const std::string& tempDir, const std::string& chunk)
{
    const std::string input = inputPath.string(), output = outputPath.string();
    if (memoryLimit > 0 || !chunk.empty()) {
        // Streamed (preprocess --memory-limit) or one chunk of a distributed build (--chunk I/N).
        if (simplify != 1.0f)
            fail("simplify", "cannot be combined with memory_limit or chunk (simplification needs the whole mesh in memory)");
        if (chunk.empty() && !endsWith(output, ".penumbra"))
            fail(output, "the output must end in .penumbra");
        StreamedOptions options;
        options.build.maxClusterVertices = clusterVertices;
        options.build.maxClusterTriangles = clusterTriangles;
        options.build.maxLeafTriangles = leafTriangles;
        options.build.threads = threads;
        options.build.separateClosed = separateClosed;
        options.memoryLimit = (memoryLimit ? memoryLimit : 1024) << 20;
        options.tempDirectory = tempDir;
        options.progress = [check = InterruptCheck()](const std::string&, double) mutable { check(); };
        StreamedStats stats;
        {
            py::gil_scoped_release unlocked;
            if (chunk.empty()) {
                stats = preprocessStreamed(input, output, options);
            } else {
                unsigned long long index = 0, count = 0;
                char slash = 0, extra = 0;
                if (std::sscanf(chunk.c_str(), "%llu%c%llu%c", &index, &slash, &count, &extra) != 3 || slash != '/' ||
                    count == 0 || index >= count)
                    fail("chunk " + chunk, "expected 'I/N' with 0 <= I < N");
                stats = preprocessChunk(input, output, uint32_t(index), uint32_t(count), options);
            }
        }
        return streamedStats(output, stats);
    }
    if (!endsWith(output, ".penumbra"))
        fail(output, "the output must end in .penumbra");
    if (!(simplify > 0.0f && simplify <= 1.0f))
        fail("simplify", std::string(py::repr(py::float_(simplify))) + " is not a ratio in (0, 1]");
    PreprocessOptions options;
    options.maxClusterVertices = clusterVertices;
    options.maxClusterTriangles = clusterTriangles;
    options.maxLeafTriangles = leafTriangles;
    options.threads = threads;
    options.separateClosed = separateClosed;
    options.progress = [check = InterruptCheck()](const char*, double) mutable { check(); };
    PreprocessStats stats;
    {
        py::gil_scoped_release unlocked;
        Scene scene = importScene(input);
        SimplifiedMesh simplified;
        if (simplify < 1.0f)
            simplified = simplifyMesh(scene.mesh, simplify);
        CompressedModel model = withScene(buildCompressedModel(simplify < 1.0f ? simplified.mesh : scene.mesh, options, &stats),
                                          scene.cameras, scene.lights, input);
        model.header.sourceTriangleCount = scene.mesh.triangleCount();
        model.header.build.simplifyTarget = simplify;
        model.header.simplifyError = simplified.error;
        writeModelFile(model, output);
    }
    return py::dict("output"_a = output, "input_triangles"_a = stats.inputTriangles, "triangles"_a = stats.triangles,
                    "clusters"_a = stats.clusters, "nodes"_a = stats.nodes, "vertices"_a = stats.vertices,
                    "bvh_depth"_a = stats.bvhDepth, "max_position_error"_a = stats.maxPositionError,
                    "bytes_per_triangle"_a = stats.bytesPerTriangle, "materials"_a = stats.materials,
                    "closed_triangles"_a = stats.closedTriangles, "closed_cluster_triangles"_a = stats.closedClusterTriangles,
                    "closed_clusters"_a = stats.closedClusters, "seconds"_a = stats.totalSeconds);
}

} // namespace

PYBIND11_MODULE(penumbra, m)
{
    m.doc() = "Penumbra: accurate hard and soft shadows on massive models, rendered headless with Vulkan";
    py::register_exception<Error>(m, "Error", PyExc_RuntimeError);
    const RenderSettings d;

    py::class_<PyRenderer>(m, "Renderer", "A Vulkan renderer holding one model: load once, render many frames")
        .def(py::init<py::object, std::string, bool, py::object>(), py::arg("model") = py::none(), py::kw_only(), py::arg("device") = "",
             py::arg("validation") = false, py::arg("ground") = "off",
             "model: a model file (.penumbra .obj .ply .stl .gltf .glb .drc) or None; device: index or part of its name; "
             "validation: the Khronos validation layer (also on with PENUMBRA_VALIDATION=1); ground: 'off', 'auto', 'below' "
             "or a height y (the CLI's --ground)")
        .def("load", &PyRenderer::load, py::arg("model"), py::kw_only(), py::arg("ground") = "off",
             "Loads a model file (str or path), with a ground plane as the CLI's --ground ('off', 'auto', 'below' or a "
             "height); the camera and lights become the model's own (the camera frames the model without the ground)")
        .def("set_camera", &PyRenderer::setCamera, py::arg("camera"),
             "dict with keys position target up projection fov ortho_height near far, or None for the model's camera")
        .def("set_lights", &PyRenderer::setLights, py::arg("lights"),
             "list of light strings ('spot position=0,20,0 outer_cone=30') or dicts ({'type': 'spot', ...}); None: the model's")
        .def(
            "render",
            [](PyRenderer& self, const py::object& size, const std::string& shadows, const std::string& cull, const std::string& shadowFit,
               uint32_t shadowMapSize, uint32_t samples, uint32_t penumbraMaps, uint32_t smMaps, float biasConstant, float biasSlope,
               float ambient, float albedo, std::array<float, 3> background, bool debugPip, bool gbuffer, bool colors, bool srtAdaptive) {
                RenderSettings s;
                std::tie(s.width, s.height) = toSize(size);
                s.shadows = parseShadowMethod(shadows);
                s.cull = parseCullMode(cull);
                s.fitShadowMapsToView = fitToView(shadowFit);
                s.shadowMapSize = shadowMapSize;
                s.lightSamples = samples;
                s.penumbraMaps = penumbraMaps;
                s.softShadowMaps = smMaps;
                s.depthBiasConstant = biasConstant;
                s.depthBiasSlope = biasSlope;
                s.ambient = ambient;
                s.albedo = albedo;
                std::copy(background.begin(), background.end(), s.background);
                s.debugPip = debugPip;
                s.readbackGBuffer = gbuffer;
                s.colors = colors;
                s.srtTraceAllWhenCheaper = srtAdaptive;
                return self.render(s);
            },
            "Renders a frame: linear RGBA float32 array (height, width, 4), top row first. Keywords as the CLI's options; "
            "gbuffer=True also fills .gbuffer; colors=False renders every surface grey (the CLI's --colors off); "
            "srt_adaptive=False: srt never traces every pixel in place of its shadow map (the CLI's --srt-adaptive off)",
            py::kw_only(), py::arg("size") = py::make_tuple(d.width, d.height), py::arg("shadows") = "srt",
            py::arg("cull") = cullModeName(d.cull), py::arg("shadow_fit") = "view", py::arg("shadow_map_size") = d.shadowMapSize,
            py::arg("samples") = d.lightSamples, py::arg("penumbra_maps") = d.penumbraMaps, py::arg("sm_maps") = d.softShadowMaps,
            py::arg("bias_constant") = d.depthBiasConstant, py::arg("bias_slope") = d.depthBiasSlope, py::arg("ambient") = d.ambient,
            py::arg("albedo") = d.albedo, py::arg("background") = std::array<float, 3>{d.background[0], d.background[1], d.background[2]},
            py::arg("debug_pip") = false, py::arg("gbuffer") = false, py::arg("colors") = d.colors,
            py::arg("srt_adaptive") = d.srtTraceAllWhenCheaper)
        .def_property_readonly("stats", &PyRenderer::stats, "The last frame's statistics (the CLI's --stats JSON) as a dict")
        .def_readonly("gbuffer", &PyRenderer::gbuffer,
                      "After render(gbuffer=True): dict of position (h, w, 4), normal (h, w, 4) and visibility of light 0 "
                      "(h, w: 1 lit, 0 shadowed, -1 background)")
        .def_property_readonly("device", &PyRenderer::device)
        .def_property_readonly("validation_messages", &PyRenderer::validationMessages);

    // render(): one Renderer, one frame; the settings keywords are Renderer.render's.
    py::exec(R"(
def render(model, size=(1024, 1024), shadows="srt", camera=None, lights=None, ground="off", **settings):
    """Renders a model file to a linear RGBA float32 array (height, width, 4), top row first.

    camera: dict (keys of the scene file: position target up projection fov ortho_height near far) or None
    (the model's). lights: list of the CLI's light strings ('spot position=0,20,0 outer_cone=30') and/or dicts
    ({'type': 'spot', 'position': [0, 20, 0]}), or None (the model's, else a sun). ground: 'off', 'auto', 'below' or a
    height (the CLI's --ground). Other keywords: Renderer.render's.
    """
    renderer = Renderer(model, ground=ground)
    renderer.set_camera(camera)
    renderer.set_lights(lights)
    return renderer.render(size=size, shadows=shadows, **settings)
)",
             m.attr("__dict__"));

    m.def("preprocess", &preprocessFile, py::arg("input"), py::arg("output"), py::kw_only(), py::arg("simplify") = 1.0f,
          py::arg("cluster_vertices") = PreprocessOptions{}.maxClusterVertices,
          py::arg("cluster_triangles") = PreprocessOptions{}.maxClusterTriangles,
          py::arg("leaf_triangles") = PreprocessOptions{}.maxLeafTriangles, py::arg("threads") = 0u,
          py::arg("separate_closed") = PreprocessOptions{}.separateClosed, py::arg("memory_limit") = uint64_t(0),
          py::arg("temp_dir") = std::string(), py::arg("chunk") = std::string(),
          "Compresses a model file into a .penumbra file (as `penumbra preprocess`); returns the build's stats as a dict. "
          "memory_limit (MiB): a streamed build within that memory (--memory-limit); chunk='I/N': write chunk I of N "
          "of a distributed build to output (--chunk), joined by merge(). Ctrl-C (KeyboardInterrupt) stops it within "
          "about 50 ms of the build's progress and leaves no output or temporary file");
    m.def(
        "merge",
        [](const std::vector<std::filesystem::path>& chunks, const std::filesystem::path& outputPath) {
            const std::string output = outputPath.string();
            if (!endsWith(output, ".penumbra"))
                fail(output, "the output must end in .penumbra");
            std::vector<std::string> paths;
            for (const auto& chunk : chunks)
                paths.push_back(chunk.string());
            StreamedStats stats;
            {
                py::gil_scoped_release unlocked;
                stats = mergeChunkFiles(paths, output, {});
            }
            return streamedStats(output, stats);
        },
        py::arg("chunks"), py::arg("output"),
        "Joins the chunk files of preprocess(..., chunk='I/N') into a .penumbra file (as `penumbra merge`)");
    m.def(
        "generate",
        [](const std::string& name, const std::filesystem::path& path, uint64_t triangles, uint64_t seed) {
            const std::string output = path.string();
            formatFromPath(output);
            py::gil_scoped_release unlocked;
            GenerateOptions options;
            options.triangles = triangles;
            options.seed = seed;
            if (!writeSceneStreamed(name, options, output, true)) // the scan as binary PLY: row by row
                exportScene(generateScene(name, options), output);
        },
        py::arg("name"), py::arg("output"), py::kw_only(), py::arg("triangles") = GenerateOptions{}.triangles,
        py::arg("seed") = GenerateOptions{}.seed,
        "Writes a procedural scene (city, interior, plant, scan) with its camera and light (glTF keeps them), as `penumbra generate`");
    m.def(
        "write_image",
        [](const py::array_t<float, py::array::c_style | py::array::forcecast>& rgba, const std::filesystem::path& file,
           const py::object& exposure, const std::string& tonemap, std::array<float, 3> background, const py::dict& layers) {
            const std::string path = file.string();
            if (rgba.ndim() != 3 || rgba.shape(2) != 4)
                fail(path, "expected a float array (height, width, 4)");
            Image image;
            image.height = uint32_t(rgba.shape(0));
            image.width = uint32_t(rgba.shape(1));
            image.rgba.assign(rgba.data(), rgba.data() + rgba.size());
            ImageOptions options;
            options.tonemap = parseToneMap(tonemap);
            if (py::isinstance<py::str>(exposure)) {
                if (exposure.cast<std::string>() != "auto")
                    fail("exposure", "expected a number or 'auto'");
                options.exposure = autoExposure(image, options.tonemap, background.data());
            } else {
                options.exposure = exposure.cast<float>();
            }
            for (auto [name, values] : layers) {
                auto array = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(values);
                if (!array || array.ndim() != 2 || array.shape(0) != rgba.shape(0) || array.shape(1) != rgba.shape(1))
                    fail(path, "layer '" + std::string(py::str(name)) + "': expected a float array (height, width)");
                options.layers.push_back({std::string(py::str(name)), std::vector<float>(array.data(), array.data() + array.size())});
            }
            py::gil_scoped_release unlocked;
            writeImage(image, path, options);
        },
        py::arg("image"), py::arg("path"), py::kw_only(), py::arg("exposure") = 1.0f, py::arg("tonemap") = "none",
        py::arg("background") = std::array<float, 3>{d.background[0], d.background[1], d.background[2]},
        py::arg("layers") = py::dict(),
        "Writes a render() result: .png (8-bit sRGB), .exr (half float linear), ... 8-bit outputs: exposure (a multiplier, "
        "or 'auto': the 95th percentile of the luminance of the pixels not of the background colour maps to 0.8 after the "
        "curve) and tonemap ('none' or 'filmic', the ACES fit of Narkowicz 2015), as the CLI's --exposure and --tonemap "
        "(whose defaults are auto and filmic). layers: .exr only, {name: float array (height, width)} written as "
        "full-float channels, e.g. {'visibility.light0': renderer.gbuffer['visibility']}");
    m.def(
        "devices",
        [] {
            py::list devices;
            for (const DeviceInfo& device : listDevices())
                devices.append(deviceDict(device));
            return devices;
        },
        "The Vulkan devices, as `penumbra devices`");
    m.def("validation_messages", &validationMessagesInProcess, "Validation-layer messages seen by every Renderer so far");
}
