// Shadow-map baseline against analytic shadow areas: a unit cube floating over
// a plane, seen by an oblique orthographic camera that does not hide the shadow.
#include <cmath>

#include <gtest/gtest.h>

#include "penumbra/penumbra.h"
#include "test_scenes.h"

namespace penumbra {
namespace {



struct AreaResult {
    double area = 0;
    size_t planePixels = 0;
};

// Camera looks along (0,-1,-2)/sqrt(5), so the cube (seen 2 units per unit of
// height away from its shadow) never hides the shadow; each pixel covers
// (h/size)^2 * sqrt(5) of the plane.
AreaResult measureShadowArea(const std::vector<Light>& lights, float orthoHeight, uint32_t size = 512)
{
    Renderer renderer;
    renderer.loadModel(test::cubeOverFloor(0.5235988f));
    Camera camera;
    camera.projection = Projection::Orthographic;
    camera.orthoHeight = orthoHeight;
    camera.position = {0, 5, 10};
    camera.target = {0, 0, 0};
    renderer.setCamera(camera);
    renderer.setLights(lights);
    RenderSettings settings;
    settings.width = settings.height = size;
    settings.readbackGBuffer = true;
    Frame frame = renderer.render(settings);
    EXPECT_EQ(renderer.validationMessageCount(), 0u);

    AreaResult result;
    size_t shadowed = 0;
    for (size_t i = 0; i < size_t(size) * size; ++i) {
        const float* p = &frame.positions[i * 4];
        bool onPlane = p[3] == 1.0f && std::abs(p[1]) < 1e-4f;
        if (!onPlane)
            continue;
        ++result.planePixels;
        if (frame.visibility[i] == 0.0f)
            ++shadowed;
    }
    double pixel = double(orthoHeight) / size;
    result.area = double(shadowed) * pixel * pixel * std::sqrt(5.0);
    std::printf("shadowed plane pixels %zu of %zu, area %.5f\n", shadowed, result.planePixels, result.area);
    return result;
}

TEST(ShadowMap, CubeOverPlaneDirectionalLightFromAbove)
{
    Light sun;
    sun.type = LightType::Directional;
    sun.direction = {0, -1, 0};
    AreaResult result = measureShadowArea({sun}, 2.0f, 512);
    EXPECT_GT(result.planePixels, 100000u);
    EXPECT_NEAR(result.area, 1.0, 0.01) << "analytic shadow area of a unit cube under a vertical sun is 1";
}

TEST(ShadowMap, CubeOverPlanePointLight)
{
    // Light 6 above the plane: the top face (height 3) projects at scale 6/3, area 4.
    Light point;
    point.type = LightType::Point;
    point.position = {0, 6, 0};
    point.intensity = 40.0f;
    AreaResult result = measureShadowArea({point}, 3.0f);
    EXPECT_NEAR(result.area, 4.0, 0.04);
}

TEST(ShadowMap, CubeOverPlaneSpotLight)
{
    Light spot;
    spot.type = LightType::Spot;
    spot.position = {0, 6, 0};
    spot.direction = {0, -1, 0};
    spot.outerConeDegrees = 40.0f;
    spot.innerConeDegrees = 35.0f;
    spot.intensity = 40.0f;
    AreaResult result = measureShadowArea({spot}, 3.0f);
    EXPECT_NEAR(result.area, 4.0, 0.04);
}

TEST(ShadowMap, SeveralLightsAccumulateAndShadowTheSameScene)
{
    Light sun;
    sun.direction = {0, -1, 0};
    Light fill;
    fill.type = LightType::Point;
    fill.position = {3, 5, 3};
    fill.intensity = 10.0f;
    // Visibility reports light 0: same shadow as with the sun alone.
    AreaResult result = measureShadowArea({sun, fill}, 2.0f);
    EXPECT_NEAR(result.area, 1.0, 0.01);
}

TEST(Renderer, ReportsPassTimingsAndDevice)
{
    Renderer renderer;
    renderer.loadModel(test::cubeOverFloor(0.5235988f));
    RenderSettings settings;
    settings.width = 128;
    settings.height = 96;
    Frame frame = renderer.render(settings);
    EXPECT_EQ(frame.color.width, 128u);
    EXPECT_EQ(frame.color.height, 96u);
    EXPECT_EQ(frame.color.rgba.size(), 128u * 96u * 4u);
    EXPECT_EQ(frame.stats.triangles, 14u);
    EXPECT_FALSE(frame.stats.device.name.empty());
    EXPECT_FALSE(frame.stats.device.driver.empty());
    ASSERT_GE(frame.stats.passes.size(), 3u);
    EXPECT_EQ(frame.stats.passes[0].name, "camera");
    EXPECT_GT(frame.stats.gpuMs, 0.0);
    std::string json = statsJson(frame.stats);
    EXPECT_NE(json.find("\"driver\""), std::string::npos);
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
}

TEST(Renderer, RejectsBadSettingsWithClearErrors)
{
    Renderer renderer;
    EXPECT_THROW(renderer.render({}), Error); // no model
    renderer.loadModel(test::cubeOverFloor(0.5235988f));
    RenderSettings settings;
    settings.width = 0;
    try {
        renderer.render(settings);
        FAIL() << "expected Error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("image size"), std::string::npos) << e.what();
    }
    EXPECT_THROW(renderer.setLights(std::vector<Light>(9)), Error);
    Light notANumber;
    notANumber.type = LightType::Point;
    notANumber.position.x = std::nanf("");
    try {
        renderer.setLights({notANumber});
        ADD_FAILURE() << "a light at NaN was taken";
    } catch (const Error& e) {
        EXPECT_EQ(std::string(e.what()), "light 0: its position, direction, up, colour and numbers must be finite");
    }
    EXPECT_THROW(renderer.loadModel(Mesh{}), Error);
    RendererOptions options;
    options.device = "no-such-device-xyz";
    try {
        Renderer missing(options);
        FAIL() << "expected Error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("no such device"), std::string::npos) << e.what();
    }
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
}

} // namespace
} // namespace penumbra
