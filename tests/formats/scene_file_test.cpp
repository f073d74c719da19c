// Scene description JSON and command-line light specs.
#include <fstream>
#include <functional>

#include <gtest/gtest.h>

#include "penumbra/error.h"
#include "penumbra/scene_file.h"

namespace penumbra {
namespace {

std::string writeScene(const std::string& name, const std::string& text)
{
    std::string path = std::string(PENUMBRA_TEST_TMP) + "/" + name;
    std::ofstream(path) << text;
    return path;
}

std::string errorOf(const std::function<void()>& fn)
{
    try {
        fn();
    } catch (const Error& e) {
        return e.what();
    }
    return "(no error)";
}

TEST(SceneFile, ReadsCameraAndEveryLightType)
{
    std::string path = writeScene("full.json", R"({
      "model": "city.glb",
      "camera": {"position": [1, 2, 3], "target": [0, 1, 0], "up": [0, 1, 0], "fov": 60, "near": 0.5, "far": 500},
      "lights": [
        {"type": "directional", "direction": [0, -1, 0.5], "intensity": 3},
        {"type": "point", "position": [0, 10, 0], "color": [1, 0.5, 0.25], "range": 40},
        {"type": "spot", "position": [0, 5, 0], "direction": [0, -1, 0], "inner_cone": 10, "outer_cone": 25},
        {"type": "rectangle", "position": [0, 8, 0], "direction": [0, -1, 0], "width": 2, "height": 1},
        {"type": "disk", "position": [0, 8, 0], "direction": [0, -1, 0], "radius": 0.75},
        {"type": "sphere", "position": [0, 8, 0], "radius": 0.3}
      ]})");
    SceneDescription scene = loadSceneDescription(path);
    EXPECT_EQ(scene.model, std::string(PENUMBRA_TEST_TMP) + "/city.glb");
    ASSERT_TRUE(scene.camera);
    EXPECT_EQ(scene.camera->position, glm::vec3(1, 2, 3));
    EXPECT_FLOAT_EQ(scene.camera->yfovDegrees, 60.0f);
    EXPECT_FLOAT_EQ(scene.camera->farPlane, 500.0f);
    ASSERT_EQ(scene.lights.size(), 6u);
    EXPECT_EQ(scene.lights[0].type, LightType::Directional);
    EXPECT_FLOAT_EQ(scene.lights[0].intensity, 3.0f);
    EXPECT_EQ(scene.lights[1].color, glm::vec3(1, 0.5f, 0.25f));
    EXPECT_FLOAT_EQ(scene.lights[2].outerConeDegrees, 25.0f);
    EXPECT_EQ(scene.lights[3].type, LightType::Rectangle);
    EXPECT_FLOAT_EQ(scene.lights[3].width, 2.0f);
    EXPECT_EQ(scene.lights[4].type, LightType::Disk);
    EXPECT_FLOAT_EQ(scene.lights[4].radius, 0.75f);
    EXPECT_EQ(scene.lights[5].type, LightType::Sphere);
}

TEST(SceneFile, RejectsBadFilesNamingTheFileAndProblem)
{
    struct Case {
        const char* json;
        const char* problem;
    } cases[] = {
        {"{", "invalid JSON"},
        {"[1, 2]", "must be a JSON object"},
        {R"({"camra": {}})", "unknown key 'camra'"},
        {R"({"camera": {"position": [1, 2]}})", "array of 3 numbers"},
        {R"({"camera": {"position": [0, 0, 0], "target": [0, 0, 0]}})", "must differ"},
        {R"({"camera": {"fov": 200}})", "fov"},
        {R"({"lights": {}})", "'lights' must be an array"},
        {R"({"lights": [{"position": [0, 1, 0]}]})", "needs a \"type\""},
        {R"({"lights": [{"type": "laser"}]})", "laser"},
        {R"({"lights": [{"type": "point", "colour": [1, 1, 1]}]})", "unknown light key 'colour'"},
        {R"({"lights": [{"type": "spot", "outer_cone": 120}]})", "spot cones"},
        {R"({"lights": [{"type": "disk", "radius": -1}]})", "radius"},
        {R"({"lights": [{"type": "point", "intensity": "bright"}]})", "'intensity' must be a number"},
        // Found by fuzz_scene_file: a number out of double range threw a JSON
        // exception that was not turned into Error; names with line breaks broke the one-line message.
        {R"({"camera": {"fov": 1e400}})", "invalid JSON"},
        {"3333333333333333333333e333333333333333336", "invalid JSON"},
        {R"({"came\nra": {}})", "unknown key 'came?ra'"},
        {R"({"lights": [{"type": "po\nint"}]})", "light type 'po?int'"},
        {R"({"lights": [{"type": "point", "col\nor": 1}]})", "unknown light key 'col?or'"},
    };
    int index = 0;
    for (const Case& c : cases) {
        std::string path = writeScene("bad" + std::to_string(index++) + ".json", c.json);
        std::string message = errorOf([&] { loadSceneDescription(path); });
        EXPECT_NE(message.find(path), std::string::npos) << c.json << " -> " << message;
        EXPECT_NE(message.find(c.problem), std::string::npos) << c.json << " -> " << message;
        EXPECT_EQ(message.find('\n'), std::string::npos) << c.json << " -> " << message;
    }
    std::string missing = std::string(PENUMBRA_TEST_TMP) + "/missing_scene.json";
    EXPECT_NE(errorOf([&] { loadSceneDescription(missing); }).find("missing_scene.json: cannot open"), std::string::npos);
}

TEST(SceneFile, ParsesCommandLineLightSpecs)
{
    Light spot = parseLightSpec("spot position=0,5,0 direction=0,-1,0 outer_cone=30 inner_cone=20 intensity=50");
    EXPECT_EQ(spot.type, LightType::Spot);
    EXPECT_EQ(spot.position, glm::vec3(0, 5, 0));
    EXPECT_FLOAT_EQ(spot.intensity, 50.0f);
    Light rect = parseLightSpec("rectangle width=2 height=0.5");
    EXPECT_EQ(rect.type, LightType::Rectangle);
    EXPECT_FLOAT_EQ(rect.height, 0.5f);

    EXPECT_NE(errorOf([] { parseLightSpec(""); }).find("empty"), std::string::npos);
    EXPECT_NE(errorOf([] { parseLightSpec("torch"); }).find("torch"), std::string::npos);
    EXPECT_NE(errorOf([] { parseLightSpec("point position=1,2"); }).find("three comma-separated"), std::string::npos);
    EXPECT_NE(errorOf([] { parseLightSpec("point position=1,x,3"); }).find("'x' is not a number"), std::string::npos);
    EXPECT_NE(errorOf([] { parseLightSpec("point brightness=3"); }).find("unknown light key 'brightness'"), std::string::npos);
    EXPECT_NE(errorOf([] { parseLightSpec("point intensity"); }).find("key=value"), std::string::npos);
}

TEST(SceneFile, ParsesOneLightOrCameraFromJsonText)
{
    Light disk = parseLightJson(R"({"type": "disk", "position": [0, 4, 0], "radius": 0.25})", "lights[0]");
    EXPECT_EQ(disk.type, LightType::Disk);
    EXPECT_EQ(disk.position, glm::vec3(0, 4, 0));
    EXPECT_FLOAT_EQ(disk.radius, 0.25f);
    Camera camera = parseCameraJson(R"({"position": [1, 2, 3], "projection": "orthographic", "ortho_height": 5})", "camera");
    EXPECT_EQ(camera.position, glm::vec3(1, 2, 3));
    EXPECT_EQ(camera.projection, Projection::Orthographic);
    EXPECT_FLOAT_EQ(camera.orthoHeight, 5.0f);

    EXPECT_EQ(errorOf([] { parseLightJson(R"({"position": [0, 1, 0]})", "lights[1]"); }), "lights[1]: a light needs a \"type\" string");
    EXPECT_EQ(errorOf([] { parseLightJson(R"({"type": "point", "size": 2})", "lights[0]"); }), "lights[0]: unknown light key 'size'");
    EXPECT_EQ(errorOf([] { parseCameraJson(R"({"fov": "wide"})", "camera"); }), "camera: 'fov' must be a number");
    EXPECT_NE(errorOf([] { parseCameraJson("{", "camera"); }).find("camera: invalid JSON"), std::string::npos);
}

} // namespace
} // namespace penumbra
