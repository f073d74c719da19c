// penumbra: command-line front end over the public API.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <new>
#include <optional>
#include <sys/resource.h>
#include <unistd.h>

#include <CLI/CLI.hpp>

#include "penumbra/bench.h"
#include "penumbra/file_io.h"
#include "penumbra/generate.h"
#include "penumbra/progress_bar.h"
#include "penumbra/preprocess.h"
#include "penumbra/penumbra.h"
#include "tool_commands.h"

namespace {

using namespace penumbra;

constexpr const char* kDemoScene = "city";
constexpr uint64_t kDemoTriangles = 1'000'000;

struct RenderArgs {
    std::string model;
    std::string output = "penumbra.png";
    std::string size = "1024";
    std::string scene;
    std::string cameraPosition, cameraTarget, cameraUp;
    float fov = 0.0f;
    float ortho = 0.0f;
    int cameraIndex = 0;
    std::vector<std::string> lights;
    std::string shadows = "sm";
    std::string cull = "all";
    std::string rasterIndices = "auto";
    double geometryBudgetMiB = 0.0;
    double geometryPageKiB = double(RendererOptions{}.geometryPageBytes) / 1024.0;
    std::string shadowFit = "view";
    uint32_t shadowMapSize = 2048;
    uint32_t samples = 0; // 0: the method's default (srt, frt: RenderSettings' 16; afsm: 256)
    uint32_t penumbraMaps = RenderSettings{}.penumbraMaps;
    uint32_t smMaps = RenderSettings{}.softShadowMaps;
    float biasConstant = RenderSettings{}.depthBiasConstant;
    float biasSlope = RenderSettings{}.depthBiasSlope;
    std::string device;
    bool validation = false;
    std::string statsPath;
    uint32_t frames = 1;
    std::string debugImage;
    std::string exposure = "auto";
    std::string tonemap = "filmic";
    std::string ground = "auto";
    std::string colors = "on";
    std::string compare;
    bool exrLayers = false;
    bool floors = false;
    std::string coneTest = "precise";
    std::string rhSort = "auto";
    std::string rhTwoPass = "off";
    std::string rhEarlyAccept = "on";
    std::string rhClosedMeshes = "off";
    std::string srtAdaptive = "on";
};

struct BenchArgs {
    std::string suite;
    std::string out;
    std::string device;
    uint32_t size = 0;           // 0: the suite's
    uint32_t frames = 0;         // 0: the suite's
    uint64_t scanTriangles = 0;  // 0: the suite's
    uint32_t lightSamples = 0;   // 0: the suite's
    uint32_t afsmSamples = 0;    // 0: the suite's
    uint32_t penumbraMaps = 0;   // 0: the suite's
    uint32_t softShadowMaps = 0; // 0: the suite's
    bool quiet = false;
    bool noPlots = false;
    std::string srtAdaptive = "on";
    std::vector<std::string> methods, sections;
};

void parseSize(const std::string& text, RenderSettings& settings)
{
    unsigned w = 0, h = 0;
    char x = 0, extra = 0;
    int n = std::sscanf(text.c_str(), "%u%c%u%c", &w, &x, &h, &extra);
    if (n == 1)
        h = w;
    else if (n != 3 || x != 'x')
        fail("--size " + text, "expected N or WxH");
    if (w == 0 || h == 0 || w > 16384 || h > 16384)
        fail("--size " + text, "each side must be 1..16384");
    settings.width = w;
    settings.height = h;
}

// Written to a temporary name beside it, then renamed: a failed write leaves no file.
void writeTextFile(const std::string& path, const std::string& text)
{
    std::string temporary = path + ".tmp-" + std::to_string(::getpid());
    const TrackedTemporary tracked(temporary); // removed if the process is interrupted
    {
        std::ofstream out(temporary, std::ios::binary);
        out << text << "\n";
        if (!out.flush()) {
            std::remove(temporary.c_str());
            fail(path, "cannot write");
        }
    }
    if (std::rename(temporary.c_str(), path.c_str()) != 0) {
        std::remove(temporary.c_str());
        fail(path, "cannot rename the finished file into place");
    }
}

// --exposure: "auto" (nullopt) or a positive number.
std::optional<float> parseExposure(const std::string& text)
{
    if (text == "auto")
        return std::nullopt;
    char* stop = nullptr;
    float value = std::strtof(text.c_str(), &stop);
    if (text.empty() || *stop != '\0' || !(value > 0.0f) || !std::isfinite(value))
        fail("--exposure " + text, "expected auto or a positive number");
    return value;
}

// Side by side, left to right, all the same size.
Image concatenate(const std::vector<const Image*>& panels)
{
    Image strip;
    strip.width = panels[0]->width * uint32_t(panels.size());
    strip.height = panels[0]->height;
    strip.rgba.resize(size_t(strip.width) * strip.height * 4);
    for (size_t k = 0; k < panels.size(); ++k)
        for (uint32_t y = 0; y < strip.height; ++y)
            std::copy_n(&panels[k]->rgba[size_t(y) * panels[k]->width * 4], size_t(panels[k]->width) * 4,
                        &strip.rgba[(size_t(y) * strip.width + k * panels[k]->width) * 4]);
    return strip;
}

int runRender(const RenderArgs& args)
{
    // Everything the command line says is checked before any slow work.
    RenderSettings settings;
    parseSize(args.size, settings);
    settings.shadows = parseShadowMethod(args.shadows);
    settings.measureFloors = args.floors;
    settings.coneTest = parseConeTest(args.coneTest);
    settings.rhSort = parseRhSort(args.rhSort);
    settings.rhTwoPass = args.rhTwoPass == "on";
    settings.rhEarlyAccept = args.rhEarlyAccept == "on";
    settings.rhClosedMeshes = args.rhClosedMeshes == "on";
    settings.srtTraceAllWhenCheaper = args.srtAdaptive == "on";
    settings.cull = parseCullMode(args.cull);
    const RasterIndices rasterIndices = parseRasterIndices(args.rasterIndices);
    settings.fitShadowMapsToView = args.shadowFit == "view";
    settings.shadowMapSize = args.shadowMapSize;
    // Light samples: srt and frt trace 4..256 per pixel; afsm keeps 128..1024 bits per view sample (one clear error each).
    const bool afsm = settings.shadows == ShadowMethod::AliasFree;
    settings.lightSamples = args.samples ? args.samples : afsm ? 256 : RenderSettings{}.lightSamples;
    if (afsm && (settings.lightSamples < 128 || settings.lightSamples > 1024))
        fail("--samples " + std::to_string(settings.lightSamples), "afsm takes 128..1024 light samples per pixel");
    if (!afsm && settings.lightSamples > 256)
        fail("--samples " + std::to_string(settings.lightSamples), args.shadows + " takes 4..256 light samples per pixel (afsm: 128..1024)");
    settings.penumbraMaps = args.penumbraMaps;
    settings.softShadowMaps = args.smMaps;
    settings.depthBiasConstant = args.biasConstant;
    settings.depthBiasSlope = args.biasSlope;
    settings.debugPip = args.debugImage == "pip";
    settings.colors = args.colors == "on";
    // Outputs first: a bad path fails before the model is loaded or the device created.
    checkImagePath(args.output);
    checkWritable(args.output);
    if (!args.compare.empty()) {
        checkImagePath(args.compare);
        checkWritable(args.compare);
    }
    if (!args.statsPath.empty())
        checkWritable(args.statsPath);
    ImageOptions imageOptions;
    imageOptions.tonemap = parseToneMap(args.tonemap);
    std::optional<float> exposure = parseExposure(args.exposure);
    Ground ground = parseGround(args.ground);
    if (args.exrLayers) {
        std::string extension = args.output.substr(args.output.find_last_of('.'));
        for (char& c : extension)
            c = char(std::tolower(static_cast<unsigned char>(c)));
        if (extension != ".exr")
            fail(args.output, "--exr-layers needs an .exr output");
        settings.readbackGBuffer = true;
        settings.readbackLightLayers = true;
    }
    std::vector<Light> commandLineLights;
    for (const std::string& spec : args.lights)
        commandLineLights.push_back(parseLightSpec(spec));
    std::optional<glm::vec3> position, target, up;
    if (!args.cameraPosition.empty()) position = parseVec3(args.cameraPosition, "--camera-position");
    if (!args.cameraTarget.empty()) target = parseVec3(args.cameraTarget, "--camera-target");
    if (!args.cameraUp.empty()) up = parseVec3(args.cameraUp, "--camera-up");
    SceneDescription description;
    if (!args.scene.empty())
        description = loadSceneDescription(args.scene);
    std::string modelPath = !args.model.empty() ? args.model : description.model;

    RendererOptions options;
    options.device = args.device;
    options.validation = args.validation;
    options.rasterIndices = rasterIndices;
    if (!(args.geometryBudgetMiB >= 0.0) || args.geometryBudgetMiB > 1e9)
        fail("--geometry-budget", "must be a number of MiB >= 0 (0: no budget)");
    options.geometryBudgetBytes = uint64_t(args.geometryBudgetMiB * 1048576.0);
    if (!(args.geometryPageKiB > 0.0) || args.geometryPageKiB > 1048576.0)
        fail("--geometry-page", "must be a number of KiB, 3 .. 1048576");
    options.geometryPageBytes = uint64_t(args.geometryPageKiB * 1024.0);
    std::optional<Renderer> renderer(std::in_place, options);

    auto loadStart = std::chrono::steady_clock::now();
    Scene scene;
    CompressedModel compressed;
    if (modelPath.empty()) {
        GenerateOptions generateOptions;
        generateOptions.triangles = kDemoTriangles;
        scene = generateScene(kDemoScene, generateOptions);
        std::fprintf(stderr, "penumbra: no model given, rendering the built-in demo scene (%s, %zu triangles)\n", kDemoScene,
                     scene.mesh.triangleCount());
    } else if (modelPath.size() > 9 && modelPath.substr(modelPath.size() - 9) == ".penumbra") {
        compressed = openModelFile(modelPath);
        // The cameras and lights the preprocessor stored from the source scene.
        scene.cameras = modelCameras(compressed);
        scene.lights = modelLights(compressed);
    } else {
        scene = importScene(modelPath);
    }
    // The model's own bounds (without a ground) frame the default camera.
    Bounds bounds = computeBounds(scene.mesh);
    if (!compressed.clusters.empty()) {
        bounds.min = glm::vec3(compressed.header.boundsMin[0], compressed.header.boundsMin[1], compressed.header.boundsMin[2]);
        bounds.max = glm::vec3(compressed.header.boundsMax[0], compressed.header.boundsMax[1], compressed.header.boundsMax[2]);
    }
    applyGround(ground, bounds, scene.mesh, compressed);
    if (!compressed.clusters.empty())
        renderer->loadModel(compressed);
    else
        renderer->loadModel(scene.mesh);
    double loadMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - loadStart).count();

    // Camera: command line over scene file over the model's own over the default.
    Camera camera = defaultCamera(bounds);
    if (!scene.cameras.empty()) {
        if (args.cameraIndex < 0 || size_t(args.cameraIndex) >= scene.cameras.size())
            fail("--camera-index " + std::to_string(args.cameraIndex),
                 "the model has " + std::to_string(scene.cameras.size()) + " camera(s)");
        camera = scene.cameras[size_t(args.cameraIndex)];
    }
    if (description.camera)
        camera = *description.camera;
    if (position) camera.position = *position;
    if (target) camera.target = *target;
    if (up) camera.up = *up;
    if (args.fov > 0.0f) {
        camera.projection = Projection::Perspective;
        camera.yfovDegrees = args.fov;
    }
    if (args.ortho > 0.0f) {
        camera.projection = Projection::Orthographic;
        camera.orthoHeight = args.ortho;
    }
    if (camera.position == camera.target)
        fail("camera", "position and target must differ");

    // Lights: command line over scene file over the model's own over the default sun.
    std::vector<Light> lights = scene.lights;
    if (!description.lights.empty())
        lights = description.lights;
    if (!commandLineLights.empty())
        lights = commandLineLights;

    renderer->setCamera(camera);
    renderer->setLights(lights);
    Frame frame;
    for (uint32_t i = 0; i < std::max(args.frames, 1u); ++i)
        frame = renderer->render(settings);
    // --compare: sm | srt | srt with the traced pixels red, one renderer, one exposure (the srt panel's).
    Image strip;
    Frame srt;
    if (!args.compare.empty()) {
        RenderSettings panel = settings;
        panel.readbackGBuffer = false;
        panel.readbackLightLayers = false;
        panel.debugPip = false;
        panel.shadows = ShadowMethod::ShadowMap;
        Image sm = renderer->render(panel).color;
        panel.shadows = ShadowMethod::Selective;
        panel.srtTraceAllWhenCheaper = false; // the panels show srt's own map and rays
        // The main frame is the srt panel when it is one.
        srt = settings.shadows == ShadowMethod::Selective && !settings.debugPip && !frame.stats.srtTracedAll ? frame : renderer->render(panel);
        panel.debugPip = true;
        Image pip = renderer->render(panel).color;
        strip = concatenate({&sm, &srt.color, &pip});
    }
    // The device is gone before anything is written: a validation message, including an object
    // the layer finds leaked when the device is destroyed, fails the run with no output file.
    renderer.reset();
    if (const uint32_t messages = validationMessagesInProcess())
        fail("validation", std::to_string(messages) + " Vulkan validation message(s) (printed above); no output written");

    imageOptions.exposure = exposure ? *exposure : autoExposure(frame.color, imageOptions.tonemap, settings.background);
    if (args.exrLayers)
        imageOptions.layers = frameLayers(frame, camera);
    writeImage(frame.color, args.output, imageOptions);
    std::printf("%s | load %.0f ms | -> %s\n", summaryLine(frame.stats).c_str(), loadMs, args.output.c_str());
    if (!args.compare.empty()) {
        ImageOptions compareOptions;
        compareOptions.tonemap = imageOptions.tonemap;
        compareOptions.exposure = exposure ? *exposure : autoExposure(srt.color, imageOptions.tonemap, settings.background);
        writeImage(strip, args.compare, compareOptions);
        std::printf("compare: sm | srt | pip (%.2f%% of covered pixels traced) -> %s\n", srt.stats.pipFraction * 100.0,
                    args.compare.c_str());
    }
    if (!args.statsPath.empty())
        writeTextFile(args.statsPath, statsJson(frame.stats));
    return 0;
}

int runBench(const BenchArgs& args)
{
    SuiteOptions options = suiteOptions(args.suite);
    options.outDir = args.out.empty() ? defaultResultsDir(args.suite) : args.out;
    options.device = args.device;
    if (args.size) options.size = args.size;
    if (args.frames) options.frames = args.frames;
    if (args.scanTriangles) options.scanTriangles = args.scanTriangles;
    if (args.lightSamples) options.lightSamples = args.lightSamples;
    if (args.afsmSamples) options.afsmSamples = args.afsmSamples;
    if (args.penumbraMaps) options.penumbraMaps = args.penumbraMaps;
    if (args.softShadowMaps) options.softShadowMaps = args.softShadowMaps;
    options.progress = !args.quiet;
    options.plots = !args.noPlots;
    options.srtAdaptive = args.srtAdaptive == "on";
    options.methods = args.methods;
    options.sections = args.sections;
    runSuite(options);
    return 0;
}

int runDevices()
{
    for (const DeviceInfo& device : listDevices())
        std::printf("%u: %s (%s, Vulkan %s, %s)\n", device.index, device.name.c_str(), device.type.c_str(), device.apiVersion.c_str(),
                    device.driver.c_str());
    return 0;
}

} // namespace

int main(int argc, char** argv)
{
    penumbra::removeTemporariesOnSignals("penumbra");
    CLI::App app{"penumbra: accurate hard and soft shadows on massive models, rendered headless with Vulkan"};
    app.require_subcommand(1);
    app.set_version_flag("--version", "penumbra 0.1.0");

    RenderArgs render;
    CLI::App* renderCommand = app.add_subcommand("render", "Render a model (or the built-in demo scene) with shadows to an image");
    renderCommand->add_option("model", render.model, "Model file: .penumbra .obj .ply .stl .gltf .glb .drc (default: built-in demo scene)");
    renderCommand->add_option("-o,--output", render.output, "Output image: .png (8-bit sRGB, exposed and tone mapped) or .exr (linear half float)")->capture_default_str();
    renderCommand->add_option("--size", render.size, "Image size: N or WxH")->capture_default_str();
    renderCommand->add_option("--scene", render.scene, "JSON scene file with camera, lights and optionally the model");
    renderCommand->add_option("--camera-position", render.cameraPosition, "Camera position x,y,z");
    renderCommand->add_option("--camera-target", render.cameraTarget, "Point the camera looks at x,y,z");
    renderCommand->add_option("--camera-up", render.cameraUp, "Camera up vector x,y,z");
    renderCommand->add_option("--camera-index", render.cameraIndex, "Which of the model's glTF cameras to use")->capture_default_str();
    renderCommand->add_option("--fov", render.fov, "Perspective camera: vertical field of view in degrees");
    renderCommand->add_option("--ortho", render.ortho, "Orthographic camera: visible height in model units");
    renderCommand->add_option("--light", render.lights,
                              "Light, repeatable: 'TYPE key=value ...', TYPE one of point spot directional rectangle disk sphere; "
                              "keys position direction up color intensity range inner_cone outer_cone width height radius; "
                              "e.g. --light 'directional direction=-1,-2,-1 intensity=3'");
    renderCommand->add_option("--shadows", render.shadows, "Shadow method: " + shadowMethodsHelp())->capture_default_str();
    renderCommand->add_option("--cull", render.cull,
                              "Raster culling with the BVH: none, frustum, all (frustum + occlusion queries); same image in every mode")
        ->capture_default_str();
    renderCommand->add_option("--raster-indices", render.rasterIndices,
                              "What the raster passes draw of the compressed model: auto (triangles on a CPU device, strips on a "
                              "GPU), strips (the file's strips with primitive restart) or triangles (8-bit lists decoded at load); "
                              "same image")
        ->capture_default_str();
    renderCommand->add_option("--geometry-budget", render.geometryBudgetMiB,
                              "Out of core: at most this many MiB of cluster geometry on the device, in pages streamed as the "
                              "views and rays need them (0: the whole model in core); same image")
        ->capture_default_str();
    renderCommand->add_option("--geometry-page", render.geometryPageKiB,
                              "Page size of --geometry-budget in KiB (a multiple of 48 bytes)")
        ->capture_default_str();
    renderCommand->add_option("--shadow-fit", render.shadowFit,
                              "Directional and area lights' shadow maps cover: view (what the camera sees: finer texels, and the "
                              "casters beside it are culled) or model (the whole model)")
        ->capture_default_str()
        ->check(CLI::IsMember({"view", "model"}));
    renderCommand->add_option("--debug-image", render.debugImage, "pip: tint the pixels given rays red (area lights: the penumbra mask)")->check(CLI::IsMember({"pip"}));
    renderCommand->add_option("--exposure", render.exposure,
                              "8-bit outputs: linear colour multiplier before the tone curve, or auto (the 95th percentile "
                              "of the model's pixels' luminance maps to 0.8 after the curve)")
        ->capture_default_str();
    renderCommand->add_option("--tonemap", render.tonemap, "8-bit outputs: filmic (ACES fit, Narkowicz 2015) or none (clamp)")
        ->capture_default_str()
        ->check(CLI::IsMember({"filmic", "none"}));
    renderCommand->add_option("--ground", render.ground,
                              "Ground plane (real geometry, casts and receives): auto (under a single object: height >= 1/4 of "
                              "its width, not already standing on a wider floor; not for .penumbra files), below (always, under "
                              "the model), off, or y=VALUE")
        ->capture_default_str();
    renderCommand->add_option("--colors", render.colors,
                              "Material colours of the model (glTF base colour, PLY/OBJ vertex or face colours): on, or off "
                              "(every surface grey, as before colours were read)")
        ->capture_default_str()
        ->check(CLI::IsMember({"on", "off"}));
    renderCommand->add_option("--compare", render.compare,
                              "Also write a side-by-side strip sm | srt | srt with the traced pixels red, to this image");
    renderCommand->add_flag("--exr-layers", render.exrLayers,
                            ".exr output: also write float channels visibility.lightN (every light), pip (pixels given rays) and Z (view depth)");
    renderCommand->add_option("--shadow-map-size", render.shadowMapSize, "Shadow-map texels per side")->capture_default_str()->check(CLI::Range(16, 16384));
    renderCommand->add_option("--samples", render.samples, "Area lights: light samples per pixel (soft shadows); srt, frt: 4..256 (default 16), afsm: 128..1024 (default 256)")->check(CLI::Range(4, 1024));
    renderCommand->add_option("--cone-test", render.coneTest, "rh: the cone/triangle test: precise (Olsson and Assarsson 2011, section 3.2) or spheres (bounding spheres, for comparison)")->capture_default_str();
    renderCommand->add_option("--rh-sort", render.rhSort, "rh: order the rays by direction before building the cone hierarchy (section 3.5): on, off (by pixel), or auto (per light layer and frame: sort where the pixels' rays are incoherent)")->capture_default_str()->check(CLI::IsMember({"on", "off", "auto"}));
    renderCommand->add_option("--rh-closed-meshes", render.rhClosedMeshes, "rh: clusters the preprocessor marked closed cast only their light-back-facing triangles (section 3.6; not while the camera is inside a closed mesh the light is outside of); a receiver within one ray offset of a closed surface may lose its shadow (README): on or off")->capture_default_str()->check(CLI::IsMember({"on", "off"}));
    renderCommand->add_option("--rh-early-accept", render.rhEarlyAccept, "rh: a cone that a triangle covers shadows all its rays without descending (section 3.3): on or off")->capture_default_str()->check(CLI::IsMember({"on", "off"}));
    renderCommand->add_option("--rh-two-pass", render.rhTwoPass, "rh: the large casters first, then the hierarchy rebuilt without the rays they shadowed, then the others (section 3.4): on or off")->capture_default_str()->check(CLI::IsMember({"on", "off"}));
    renderCommand->add_option("--srt-adaptive", render.srtAdaptive, "srt, over several frames (--frames): a frame traces every light-facing pixel, without shadow map or classification, where that measured cheaper (probed once the first frames are steady, then now and then); off: always the shadow map and selective rays")->capture_default_str()->check(CLI::IsMember({"on", "off"}));
    renderCommand->add_option("--penumbra-maps", render.penumbraMaps, "Area lights, srt: shadow maps whose edges mark the penumbra: 1 (centre) or 5 (centre and corners)")->capture_default_str()->check(CLI::IsMember({1, 5}));
    renderCommand->add_option("--sm-maps", render.smMaps, "Area lights, sm: point-light shadow maps averaged over the light")->capture_default_str()->check(CLI::Range(1, 6));
    renderCommand->add_option("--bias-constant", render.biasConstant, "Shadow-map depth bias, constant factor")->capture_default_str();
    renderCommand->add_option("--bias-slope", render.biasSlope, "Shadow-map depth bias, slope factor")->capture_default_str();
    renderCommand->add_option("--device", render.device, "Vulkan device: index or part of its name (see 'penumbra devices')");
    renderCommand->add_flag("--validation", render.validation, "Enable the Khronos validation layer; any message fails the run");
    renderCommand->add_flag("--floors", render.floors, "Also time each pass's floor (its null twin, or the raster passes' uncompressed depth-only draw) as <pass>_floor");
    renderCommand->add_option("--stats", render.statsPath, "Write per-pass statistics as JSON to this file");
    renderCommand->add_option("--frames", render.frames, "Render this many frames (timings are of the last)")->capture_default_str()->check(CLI::Range(1, 10000));

    ToolCommands tools;
    addToolCommands(app, tools);

    BenchArgs bench;
    CLI::App* benchCommand = app.add_subcommand("bench", "Benchmark suite: methods, per-stage times, scalability, light size; "
                                                         "writes CSV, JSON, plots, images and summary.md");
    benchCommand->add_option("suite", bench.suite, "smoke (CI, < 1 min), quick (< 5 min on 2 cores), full")->required()->check(CLI::IsMember(suiteNames()));
    benchCommand->add_option("-o,--out", bench.out, "Results folder (default: results/<suite>-<date>)");
    benchCommand->add_option("--device", bench.device, "Vulkan device: index or part of its name (see 'penumbra devices')");
    benchCommand->add_option("--size", bench.size, "Image width and height (default: the suite's)")->check(CLI::Range(16, 8192));
    benchCommand->add_option("--frames", bench.frames, "Timed frames per case after one warm-up (default: the suite's)")->check(CLI::Range(1, 1000));
    benchCommand->add_option("--scan-triangles", bench.scanTriangles, "Scalability: triangles of the full scan model (default: the suite's)")->check(CLI::Range(uint64_t(1000), uint64_t(1'000'000'000)));
    benchCommand->add_option("--light-samples", bench.lightSamples, "Soft shadows: light samples per pixel (default 16)")->check(CLI::Range(4, 256));
    benchCommand->add_option("--afsm-samples", bench.afsmSamples, "Soft shadows, afsm: light samples (bits per view sample; default 256)")->check(CLI::Range(128, 1024));
    benchCommand->add_option("--penumbra-maps", bench.penumbraMaps, "Soft shadows: penumbra maps, 1 or 5 (default 1)")->check(CLI::IsMember({1, 5}));
    benchCommand->add_option("--soft-shadow-maps", bench.softShadowMaps, "Soft shadows, sm: shadow maps averaged over the light (default 4)")->check(CLI::Range(1, 6));
    benchCommand->add_option("--srt-adaptive", bench.srtAdaptive, "srt frames trace every light-facing pixel where that measured cheaper (render's --srt-adaptive): on or off")->capture_default_str()->check(CLI::IsMember({"on", "off"}));
    benchCommand->add_flag("--quiet", bench.quiet, "No progress bar");
    benchCommand->add_flag("--no-plots", bench.noPlots, "Write plot data and gnuplot scripts without running gnuplot");
    benchCommand->add_option("--methods", bench.methods, "Only these GPU methods (the oracle always runs), e.g. --methods sm,srt,frt")
        ->delimiter(',')
        ->check(CLI::IsMember({"sm", "srt", "frt", "afsm", "rh"}));
    benchCommand->add_option("--sections", bench.sections,
                             "Only these sections: methods (hard), soft, point, rh_variants, scalability (with afsm_triangles), light_size, afsm_samples")
        ->delimiter(',')
        ->check(CLI::IsMember({"methods", "soft", "point", "rh_variants", "scalability", "light_size", "afsm_samples"}));

    app.add_subcommand("devices", "List the Vulkan devices");

    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        if (e.get_exit_code() == 0) // --help, --version
            return app.exit(e);
        // Every other parse error (unknown option, value out of range, missing argument) is one error line.
        std::string message = e.what();
        for (char& c : message)
            if (c == '\n' || c == '\r')
                c = ' ';
        std::fprintf(stderr, "penumbra: error: %s\n", message.c_str());
        return 1;
    }
    try {
        if (renderCommand->parsed())
            return runRender(render);
        if (int rc = 0; runToolCommands(tools, rc))
            return rc;
        if (benchCommand->parsed())
            return runBench(bench);
        return runDevices();
    } catch (const Error& e) {
        std::fprintf(stderr, "penumbra: error: %s\n", e.what());
    } catch (const std::bad_alloc&) {
        std::fprintf(stderr, "penumbra: error: out of memory\n");
    } catch (const std::exception& e) {
        std::fprintf(stderr, "penumbra: error: %s\n", e.what());
    }
    return 1;
}
