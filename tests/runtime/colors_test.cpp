// Colours from the model (materials' base colour, vertex and face colours)
// through preprocessing into the shade pass, and the cameras and lights a
// preprocessed file keeps from its source glTF (issue 21, parts 4 and 6).
#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "penumbra/io.h"
#include "cli_run.h"
#include "penumbra/penumbra.h"
#include "penumbra/preprocess.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

std::string tmp(const std::string& name)
{
    return test::scratchPath("colors_", name);
}

using test::runCli;

std::string base64(const std::string& bytes)
{
    static const char* table = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    for (size_t i = 0; i < bytes.size(); i += 3) {
        uint32_t v = uint32_t(uint8_t(bytes[i])) << 16;
        if (i + 1 < bytes.size()) v |= uint32_t(uint8_t(bytes[i + 1])) << 8;
        if (i + 2 < bytes.size()) v |= uint32_t(uint8_t(bytes[i + 2]));
        out += table[v >> 18 & 63];
        out += table[v >> 12 & 63];
        out += i + 1 < bytes.size() ? table[v >> 6 & 63] : '=';
        out += i + 2 < bytes.size() ? table[v & 63] : '=';
    }
    return out;
}

// Two quads in the y = 0 plane, facing up: x in [-2, 0] with material 0
// (red, 1 0 0) and x in [0, 2] with material 1 (0.2 0.4 1). One mesh, two
// primitives sharing the positions; a perspective camera above looking down
// (its up -z, so +x is to the right) and a sun straight down.
std::string writeTwoMaterialGltf(const std::string& name)
{
    const float positions[8][3] = {{-2, 0, -1}, {-2, 0, 1}, {0, 0, 1}, {0, 0, -1},
                                   {0, 0, -1},  {0, 0, 1},  {2, 0, 1}, {2, 0, -1}};
    const uint32_t indices[12] = {0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7};
    std::string buffer(reinterpret_cast<const char*>(positions), sizeof(positions));
    buffer.append(reinterpret_cast<const char*>(indices), sizeof(indices));
    const std::string json = R"({
  "asset": {"version": "2.0"},
  "extensionsUsed": ["KHR_lights_punctual"],
  "extensions": {"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 2.0}]}},
  "scene": 0,
  "scenes": [{"nodes": [0, 1, 2]}],
  "nodes": [
    {"mesh": 0},
    {"camera": 0, "translation": [0, 6, 0], "rotation": [-0.70710678, 0, 0, 0.70710678]},
    {"extensions": {"KHR_lights_punctual": {"light": 0}}, "rotation": [-0.70710678, 0, 0, 0.70710678]}
  ],
  "cameras": [{"type": "perspective", "perspective": {"yfov": 0.785398, "znear": 0.1}}],
  "materials": [
    {"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0, 1]}},
    {"name": "blue", "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.4, 1, 1], "metallicFactor": 0}}
  ],
  "meshes": [{"primitives": [
    {"attributes": {"POSITION": 0}, "indices": 1, "material": 0},
    {"attributes": {"POSITION": 0}, "indices": 2, "material": 1}
  ]}],
  "buffers": [{"byteLength": 144, "uri": "data:application/octet-stream;base64,)" +
                             base64(buffer) + R"("}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 96}, {"buffer": 0, "byteOffset": 96, "byteLength": 48}],
  "accessors": [
    {"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3", "min": [-2, 0, -1], "max": [2, 0, 1]},
    {"bufferView": 1, "byteOffset": 0, "componentType": 5125, "count": 6, "type": "SCALAR"},
    {"bufferView": 1, "byteOffset": 24, "componentType": 5125, "count": 6, "type": "SCALAR"}
  ]
})";
    const std::string path = tmp(name);
    std::ofstream(path, std::ios::binary) << json;
    return path;
}

struct Rgb {
    float r, g, b;
};

Rgb pixel(const Image& image, uint32_t x, uint32_t y)
{
    const float* p = &image.rgba[(size_t(y) * image.width + x) * 4];
    return {p[0], p[1], p[2]};
}

Frame renderScene(Renderer& renderer, const Scene& scene, bool colors)
{
    renderer.setCamera(scene.cameras.at(0));
    renderer.setLights(scene.lights);
    RenderSettings settings;
    settings.width = 64;
    settings.height = 48;
    settings.colors = colors;
    return renderer.render(settings);
}

TEST(Colors, TwoMaterialGltfShadesWithItsBaseColours)
{
    const std::string path = writeTwoMaterialGltf("two_materials.gltf");
    Scene scene = importScene(path);
    ASSERT_EQ(scene.mesh.materials.size(), 3u); // red, blue and the default for primitives without one
    EXPECT_EQ(scene.mesh.materials[1].name, "blue");
    ASSERT_EQ(scene.mesh.triangleMaterials, (std::vector<uint32_t>{0, 0, 1, 1}));
    ASSERT_EQ(scene.cameras.size(), 1u);
    ASSERT_EQ(scene.lights.size(), 1u);

    Renderer renderer;
    renderer.loadModel(scene.mesh);
    Frame on = renderScene(renderer, scene, true);
    Frame off = renderScene(renderer, scene, false);
    // Left quarter: red; right quarter: (0.2, 0.4, 1) times the same light; off: grey.
    const Rgb left = pixel(on.color, 16, 24), right = pixel(on.color, 48, 24);
    EXPECT_GT(left.r, 0.5f);
    EXPECT_EQ(left.g, 0.0f);
    EXPECT_EQ(left.b, 0.0f);
    EXPECT_GT(right.b, 0.5f);
    // 8-bit linear colour in the G-buffer; the colour image holds half floats (relative rounding 2^-11 per channel).
    EXPECT_NEAR(right.r / right.b, 51.0f / 255.0f, 1e-3f);
    EXPECT_NEAR(right.g / right.b, 102.0f / 255.0f, 1e-3f);
    EXPECT_FLOAT_EQ(right.b, left.r); // same light, same full channel
    for (uint32_t x : {16u, 48u}) {
        const Rgb grey = pixel(off.color, x, 24);
        EXPECT_EQ(grey.r, grey.g);
        EXPECT_EQ(grey.g, grey.b);
        EXPECT_EQ(grey.r, left.r); // white material: colours on and off agree on the full channel
    }
    // Every covered pixel is one of the two colours.
    size_t red = 0, blue = 0;
    for (uint32_t y = 0; y < on.color.height; ++y)
        for (uint32_t x = 0; x < on.color.width; ++x) {
            const Rgb p = pixel(on.color, x, y);
            red += p.g == 0.0f && p.b == 0.0f && p.r > 0.5f;
            blue += p.b > 0.5f && std::abs(p.r / p.b - 0.2f) < 1e-3f;
        }
    EXPECT_GT(red, 200u); // each quad covers about 19 x 19 pixels
    EXPECT_GT(blue, 200u);
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
}

TEST(Colors, PreprocessedFileKeepsTheMaterialsAndTheImage)
{
    const std::string source = writeTwoMaterialGltf("two_materials_pp.gltf"), model = tmp("two_materials.penumbra");
    std::string output;
    ASSERT_EQ(runCli("preprocess " + source + " -o " + model + " --quiet", &output), 0) << output;
    CompressedModel file = openModelFile(model);
    ASSERT_EQ(file.materials.size(), 3u);
    EXPECT_EQ(file.materials[0].baseColor[0], 1.0f);
    EXPECT_EQ(file.materials[1].baseColor[1], 0.4f);
    ASSERT_EQ(file.clusters.size(), 2u); // one cluster per material
    EXPECT_NE(file.clusters[0].material, file.clusters[1].material);

    Scene scene = importScene(source);
    Renderer renderer;
    renderer.loadModel(scene.mesh);
    Frame fromSource = renderScene(renderer, scene, true);
    renderer.loadModel(file);
    Frame fromFile = renderScene(renderer, scene, true);
    EXPECT_EQ(fromSource.color.rgba, fromFile.color.rgba);
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
}

// Part 6: the glTF's camera and KHR_lights_punctual lights go into the file and
// are used when it is rendered, as they are for the source.
TEST(Colors, PreprocessedFileKeepsTheCamerasAndLights)
{
    const std::string source = tmp("scene_city.glb"), model = tmp("scene_city.penumbra");
    std::string output;
    ASSERT_EQ(runCli("generate city --triangles 20000 -o " + source), 0);
    ASSERT_EQ(runCli("preprocess " + source + " -o " + model + " --quiet", &output), 0) << output;
    Scene scene = importScene(source);
    ASSERT_FALSE(scene.cameras.empty());
    ASSERT_FALSE(scene.lights.empty());
    CompressedModel file = openModelFile(model);
    std::vector<Camera> cameras = modelCameras(file);
    std::vector<Light> lights = modelLights(file);
    ASSERT_EQ(cameras.size(), scene.cameras.size());
    ASSERT_EQ(lights.size(), scene.lights.size());
    for (size_t i = 0; i < cameras.size(); ++i) {
        EXPECT_EQ(cameras[i].position, scene.cameras[i].position);
        EXPECT_EQ(cameras[i].target, scene.cameras[i].target);
        EXPECT_EQ(cameras[i].up, scene.cameras[i].up);
        EXPECT_EQ(cameras[i].yfovDegrees, scene.cameras[i].yfovDegrees);
        EXPECT_EQ(cameras[i].nearPlane, scene.cameras[i].nearPlane);
        EXPECT_EQ(cameras[i].farPlane, scene.cameras[i].farPlane);
    }
    for (size_t i = 0; i < lights.size(); ++i) {
        EXPECT_EQ(lights[i].type, scene.lights[i].type);
        EXPECT_EQ(lights[i].direction, scene.lights[i].direction);
        EXPECT_EQ(lights[i].color, scene.lights[i].color);
        EXPECT_EQ(lights[i].intensity, scene.lights[i].intensity);
    }
    // The CLI renders both the same: same camera, same lights, same pixels.
    const std::string fromSource = tmp("scene_city_source.png"), fromFile = tmp("scene_city_file.png");
    const std::string options = " --size 80x60 --shadows srt --exposure 1 --tonemap none --ground off";
    ASSERT_EQ(runCli("render " + source + " -o " + fromSource + options, &output), 0) << output;
    ASSERT_EQ(runCli("render " + model + " -o " + fromFile + options, &output), 0) << output;
    std::ifstream a(fromSource, std::ios::binary), b(fromFile, std::ios::binary);
    std::string bytesA((std::istreambuf_iterator<char>(a)), {}), bytesB((std::istreambuf_iterator<char>(b)), {});
    EXPECT_FALSE(bytesA.empty());
    EXPECT_EQ(bytesA, bytesB);
    // Without the stored scene the file would be framed by the default camera and the default sun.
    ASSERT_EQ(runCli("info " + model, &output), 0) << output;
    EXPECT_NE(output.find("scene            1 camera(s), 1 light(s)"), std::string::npos) << output;
}

} // namespace
} // namespace penumbra
