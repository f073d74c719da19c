// penumbra: command-line front end over the public API.
#include <chrono>
#include <cstdio>
#include <fstream>
#include <new>
#include <optional>

#include <CLI/CLI.hpp>

#include "penumbra/generate.h"
#include "penumbra/penumbra.h"

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
    uint32_t shadowMapSize = 2048;
    float biasConstant = RenderSettings{}.depthBiasConstant;
    float biasSlope = RenderSettings{}.depthBiasSlope;
    std::string device;
    bool validation = false;
    std::string statsPath;
    uint32_t frames = 1;
};

struct GenerateArgs {
    std::string name;
    uint64_t triangles = 1'000'000;
    uint64_t seed = 1;
    std::string output;
    bool draco = false;
    bool ascii = false;
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

void writeTextFile(const std::string& path, const std::string& text)
{
    std::string temporary = path + ".tmp";
    {
        std::ofstream out(temporary, std::ios::binary);
        out << text << "\n";
        if (!out.flush())
            fail(path, "cannot write");
    }
    if (std::rename(temporary.c_str(), path.c_str()) != 0)
        fail(path, "cannot rename the finished file into place");
}

int runRender(const RenderArgs& args)
{
    // Everything the command line says is checked before any slow work.
    RenderSettings settings;
    parseSize(args.size, settings);
    settings.shadows = parseShadowMethod(args.shadows);
    settings.shadowMapSize = args.shadowMapSize;
    settings.depthBiasConstant = args.biasConstant;
    settings.depthBiasSlope = args.biasSlope;
    checkImagePath(args.output);
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
    Renderer renderer(options);

    auto loadStart = std::chrono::steady_clock::now();
    Scene scene;
    if (modelPath.empty()) {
        GenerateOptions generateOptions;
        generateOptions.triangles = kDemoTriangles;
        scene = generateScene(kDemoScene, generateOptions);
        std::fprintf(stderr, "penumbra: no model given, rendering the built-in demo scene (%s, %zu triangles)\n", kDemoScene,
                     scene.mesh.triangleCount());
    } else {
        scene = importScene(modelPath);
    }
    double loadMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - loadStart).count();

    // Camera: command line over scene file over the model's own over the default.
    Camera camera = defaultCamera(computeBounds(scene.mesh));
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

    renderer.loadModel(scene.mesh);
    renderer.setCamera(camera);
    renderer.setLights(lights);
    Frame frame;
    for (uint32_t i = 0; i < std::max(args.frames, 1u); ++i)
        frame = renderer.render(settings);
    writeImage(frame.color, args.output);
    std::printf("%s | load %.0f ms | shadows %s | -> %s\n", summaryLine(frame.stats).c_str(), loadMs, shadowMethodName(settings.shadows),
                args.output.c_str());
    if (!args.statsPath.empty())
        writeTextFile(args.statsPath, statsJson(frame.stats));
    if (renderer.validationMessageCount() > 0) {
        std::fprintf(stderr, "penumbra: error: %u validation message(s)\n", renderer.validationMessageCount());
        return 1;
    }
    return 0;
}

int runGenerate(const GenerateArgs& args)
{
    GenerateOptions options;
    options.triangles = args.triangles;
    options.seed = args.seed;
    auto start = std::chrono::steady_clock::now();
    formatFromPath(args.output); // reject an unknown extension before the work
    Scene scene = generateScene(args.name, options);
    double generateMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    ExportOptions exportOptions;
    exportOptions.binary = !args.ascii;
    exportOptions.draco = args.draco;
    start = std::chrono::steady_clock::now();
    exportScene(scene, args.output, exportOptions);
    double writeMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    std::printf("%s: %zu triangles, %zu vertices, generated in %.0f ms, written in %.0f ms\n", args.output.c_str(),
                scene.mesh.triangleCount(), scene.mesh.vertexCount(), generateMs, writeMs);
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
    CLI::App app{"penumbra: accurate hard and soft shadows on massive models, rendered headless with Vulkan"};
    app.require_subcommand(1);
    app.set_version_flag("--version", "penumbra 0.1.0");

    RenderArgs render;
    CLI::App* renderCommand = app.add_subcommand("render", "Render a model (or the built-in demo scene) with shadows to an image");
    renderCommand->add_option("model", render.model, "Model file: .obj .ply .stl .gltf .glb .drc (default: built-in demo scene)");
    renderCommand->add_option("-o,--output", render.output, "Output image: .png (8-bit sRGB) or .exr (linear half float)")->capture_default_str();
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
    renderCommand->add_option("--shadows", render.shadows, "Shadow method: sm (shadow map)")->capture_default_str();
    renderCommand->add_option("--shadow-map-size", render.shadowMapSize, "Shadow-map texels per side")->capture_default_str()->check(CLI::Range(16, 16384));
    renderCommand->add_option("--bias-constant", render.biasConstant, "Shadow-map depth bias, constant factor")->capture_default_str();
    renderCommand->add_option("--bias-slope", render.biasSlope, "Shadow-map depth bias, slope factor")->capture_default_str();
    renderCommand->add_option("--device", render.device, "Vulkan device: index or part of its name (see 'penumbra devices')");
    renderCommand->add_flag("--validation", render.validation, "Enable the Khronos validation layer; any message fails the run");
    renderCommand->add_option("--stats", render.statsPath, "Write per-pass statistics as JSON to this file");
    renderCommand->add_option("--frames", render.frames, "Render this many frames (timings are of the last)")->capture_default_str()->check(CLI::Range(1, 10000));

    GenerateArgs generate;
    CLI::App* generateCommand = app.add_subcommand("generate", "Write a procedural benchmark scene: city, interior, plant or scan");
    generateCommand->add_option("name", generate.name, "Scene: city, interior, plant, scan")->required();
    generateCommand->add_option("--triangles", generate.triangles, "Triangle budget")->capture_default_str();
    generateCommand->add_option("--seed", generate.seed, "Random seed (same seed, same file)")->capture_default_str();
    generateCommand->add_option("-o,--output", generate.output, "Output model: .ply .glb .gltf .obj .stl .drc")->required();
    generateCommand->add_flag("--draco", generate.draco, "glTF/GLB: compress with KHR_draco_mesh_compression");
    generateCommand->add_flag("--ascii", generate.ascii, "PLY/STL: write ASCII instead of binary");

    app.add_subcommand("devices", "List the Vulkan devices");

    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e);
    }
    try {
        if (renderCommand->parsed())
            return runRender(render);
        if (generateCommand->parsed())
            return runGenerate(generate);
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
