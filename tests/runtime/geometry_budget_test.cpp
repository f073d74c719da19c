// Out of core (issue 19, runtime): a geometry budget changes what is on the
// device and when, never the image. Frames along a short camera path and a
// short light path, for sm, srt and frt with hard and soft shadows, rendered
// without a budget and with budgets of 1/4 and 1/16 of the model's paged
// geometry: colour and light 0's visibility must be equal bit for bit. Also
// the stats, and the one-line error when a view's working set exceeds the
// budget.
#include <cmath>
#include <cstdio>
#include <cstring>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include "penumbra/generate.h"
#include "penumbra/penumbra.h"
#include "penumbra/preprocess.h"

namespace penumbra {
namespace {

constexpr uint32_t kSize = 256;
constexpr uint64_t kPageBytes = 4608; // small pages, so that 1/16 of a 150k-triangle model holds several views

RendererOptions budgetOptions(uint64_t budget)
{
    RendererOptions options;
    options.geometryBudgetBytes = budget;
    options.geometryPageBytes = kPageBytes;
    return options;
}

Frame renderFrame(Renderer& renderer, ShadowMethod method, CullMode cull = CullMode::All)
{
    RenderSettings settings;
    settings.cull = cull;
    settings.width = settings.height = kSize;
    settings.shadows = method;
    settings.shadowMapSize = 512;
    settings.lightSamples = 4; // soft shadows: fewest samples, the tests stay fast
    settings.readbackGBuffer = true;
    Frame frame = renderer.render(settings);
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
    return frame;
}

// Colour and visibility, bit for bit.
void expectSameImage(const Frame& expected, const Frame& actual, const std::string& what)
{
    ASSERT_EQ(expected.color.rgba.size(), actual.color.rgba.size()) << what;
    size_t colour = 0, visibility = 0;
    for (size_t i = 0; i < expected.color.rgba.size() / 4; ++i) {
        colour += std::memcmp(&expected.color.rgba[4 * i], &actual.color.rgba[4 * i], 4 * sizeof(float)) != 0;
        visibility += std::memcmp(&expected.visibility[i], &actual.visibility[i], sizeof(float)) != 0;
    }
    EXPECT_EQ(colour, 0u) << what << ": colour differs on " << colour << " pixels";
    EXPECT_EQ(visibility, 0u) << what << ": visibility differs on " << visibility << " pixels";
}

struct Budgeted {
    CompressedModel model;
    uint64_t geometryBytes = 0;
};

Budgeted preparedCity()
{
    GenerateOptions options;
    options.triangles = 150'000;
    Scene scene = generateScene("city", options);
    Budgeted out;
    out.model = buildCompressedModel(scene.mesh, PreprocessOptions{});
    Renderer probe(budgetOptions(uint64_t(1) << 30));
    probe.loadModel(out.model);
    out.geometryBytes = renderFrame(probe, ShadowMethod::ShadowMap).stats.geometryBytes;
    return out;
}

// A camera path over a small part of the model: looking down at a patch at
// a slant, moving across it (the views' working sets are well below the budgets).
std::vector<Camera> cameraPath(const Bounds& bounds)
{
    const glm::vec3 size = bounds.max - bounds.min;
    std::vector<Camera> path;
    for (int step = 0; step < 3; ++step) {
        const glm::vec3 patch(bounds.min.x + (0.3f + 0.04f * step) * size.x, bounds.min.y, bounds.min.z + 0.35f * size.z);
        Camera camera;
        camera.position = patch + glm::vec3(0.02f * size.x, 0.15f * size.y + 0.05f * size.x, 0.03f * size.z);
        camera.target = patch;
        camera.yfovDegrees = 8.0f;
        path.push_back(camera);
    }
    return path;
}

std::vector<Light> sunPath()
{
    std::vector<Light> path;
    for (int step = 0; step < 3; ++step) {
        Light sun;
        sun.type = LightType::Directional;
        const float angle = 0.4f + 0.35f * float(step);
        sun.direction = glm::normalize(glm::vec3(std::cos(angle), -1.3f, std::sin(angle)));
        sun.intensity = 3.0f;
        path.push_back(sun);
    }
    return path;
}

// A small rectangle light high above the camera path's patch, so its map's frustum is a narrow column.
Light rectangleAbove(const Camera& camera, const Bounds& bounds, float shift)
{
    const float diagonal = glm::length(bounds.max - bounds.min);
    Light rectangle;
    rectangle.type = LightType::Rectangle;
    rectangle.position = camera.target + glm::vec3(0.03f + shift, 0.5f, 0.02f) * diagonal;
    rectangle.direction = glm::normalize(camera.target - rectangle.position);
    rectangle.width = 0.02f * diagonal;
    rectangle.height = 0.01f * diagonal;
    rectangle.intensity = 0.5f * diagonal * diagonal;
    return rectangle;
}

Bounds modelBounds(const CompressedModel& model)
{
    Bounds bounds;
    bounds.min = {model.header.boundsMin[0], model.header.boundsMin[1], model.header.boundsMin[2]};
    bounds.max = {model.header.boundsMax[0], model.header.boundsMax[1], model.header.boundsMax[2]};
    return bounds;
}

// Renders every (camera, light set) of the paths with each method on the unlimited renderer and the budgeted ones.
void compareAlongPaths(const Budgeted& city, const std::vector<std::pair<Camera, std::vector<Light>>>& frames,
                       const std::vector<ShadowMethod>& methods, const char* name, bool expectParking)
{
    Renderer unlimited;
    unlimited.loadModel(city.model);
    std::vector<std::unique_ptr<Renderer>> budgeted;
    for (uint64_t divisor : {4u, 16u}) {
        budgeted.push_back(std::make_unique<Renderer>(budgetOptions(city.geometryBytes / divisor)));
        budgeted.back()->loadModel(city.model);
    }
    uint64_t streamed = 0, rounds = 0;
    for (size_t f = 0; f < frames.size(); ++f)
        for (ShadowMethod method : methods) {
            unlimited.setCamera(frames[f].first);
            unlimited.setLights(frames[f].second);
            const Frame expected = renderFrame(unlimited, method);
            for (size_t b = 0; b < budgeted.size(); ++b) {
                Renderer& renderer = *budgeted[b];
                renderer.setCamera(frames[f].first);
                renderer.setLights(frames[f].second);
                const Frame frame = renderFrame(renderer, method);
                const std::string what = std::string(name) + " frame " + std::to_string(f) + " " + shadowMethodName(method) +
                                         " budget 1/" + (b == 0 ? "4" : "16");
                expectSameImage(expected, frame, what);
                const FrameStats& s = frame.stats;
                EXPECT_EQ(s.geometryBytes, city.geometryBytes) << what;
                EXPECT_LE(s.residentPeakBytes, s.geometryBudgetBytes) << what;
                EXPECT_LE(s.geometryBudgetBytes, city.geometryBytes / (b == 0 ? 4 : 16)) << what;
                streamed += s.bytesStreamed;
                rounds += s.parkingRounds;
            }
        }
    std::printf("[ budget   ] %s: %llu bytes streamed, %llu parking rounds over %zu frames\n", name, (unsigned long long)streamed,
                (unsigned long long)rounds, frames.size());
    // Pages move; rays park where the light has no views of its own (frt's area lights draw no map).
    EXPECT_GT(streamed, 0u) << name;
    if (expectParking)
        EXPECT_GT(rounds, 0u) << name;
}

TEST(GeometryBudget, HardShadowsSameImagesAlongCameraAndLightPaths)
{
    const Budgeted city = preparedCity();
    const Bounds bounds = modelBounds(city.model);
    std::vector<std::pair<Camera, std::vector<Light>>> frames;
    const std::vector<Camera> cameras = cameraPath(bounds);
    const std::vector<Light> suns = sunPath();
    for (size_t i = 0; i < cameras.size(); ++i)
        frames.push_back({cameras[i], {suns[i]}});
    compareAlongPaths(city, frames, {ShadowMethod::ShadowMap, ShadowMethod::Selective, ShadowMethod::FullRayTrace}, "hard", false);
}

TEST(GeometryBudget, SoftShadowsSameImages)
{
    const Budgeted city = preparedCity();
    const Bounds bounds = modelBounds(city.model);
    const std::vector<Camera> cameras = cameraPath(bounds);
    compareAlongPaths(city, {{cameras[0], {rectangleAbove(cameras[0], bounds, 0.0f)}}},
                      {ShadowMethod::ShadowMap, ShadowMethod::Selective, ShadowMethod::FullRayTrace}, "soft", false);
}

// frt's area lights draw no map, so no view asks for the casters: a low light's
// rays cross streets of buildings that are not resident, park, and are traced
// again (in several rounds when their pages exceed the budget).
TEST(GeometryBudget, ParkedRaysSameImages)
{
    const Budgeted city = preparedCity();
    const Bounds bounds = modelBounds(city.model);
    const float diagonal = glm::length(bounds.max - bounds.min);
    const std::vector<Camera> cameras = cameraPath(bounds);
    std::vector<std::pair<Camera, std::vector<Light>>> frames;
    for (size_t i = 0; i < 2; ++i) {
        Light low = rectangleAbove(cameras[i], bounds, 0.0f);
        low.position = cameras[i].target + glm::vec3(0.35f, 0.12f + 0.03f * float(i), 0.25f) * diagonal;
        low.direction = glm::normalize(cameras[i].target - low.position);
        frames.push_back({cameras[i], {low}});
    }
    compareAlongPaths(city, frames, {ShadowMethod::FullRayTrace}, "parked", true);
}

// The default camera sees the whole model, far more than 1/16 of it: phase 2
// of its view (the clusters whose occlusion queries passed) is drawn in
// ranges, each made resident in turn, in the same order as without a budget.
TEST(GeometryBudget, ViewsLargerThanTheBudgetDrawnInRanges)
{
    const Budgeted city = preparedCity();
    Renderer unlimited, budgeted(budgetOptions(city.geometryBytes / 16));
    unlimited.loadModel(city.model);
    budgeted.loadModel(city.model);
    uint64_t pages = 0;
    for (int frame = 0; frame < 2; ++frame) { // the first without history, the second with it
        const Frame expected = renderFrame(unlimited, ShadowMethod::ShadowMap);
        const Frame actual = renderFrame(budgeted, ShadowMethod::ShadowMap);
        expectSameImage(expected, actual, "whole-model view, frame " + std::to_string(frame));
        pages += actual.stats.pagesUploaded;
        EXPECT_LE(actual.stats.residentPeakBytes, actual.stats.geometryBudgetBytes);
    }
    EXPECT_GT(pages * kPageBytes, city.geometryBytes / 4); // more than the pool holds
}

// Raster views are drawn in ranges, so what must fit at once is a thin-triangle
// view's clusters or one ray's: with 2 pages, srt's thin-triangle view of the
// whole model does not.
TEST(GeometryBudget, BudgetBelowOneViewFailsWithOneLine)
{
    const Budgeted city = preparedCity();
    Renderer renderer(budgetOptions(2 * kPageBytes));
    renderer.loadModel(city.model);
    try {
        renderFrame(renderer, ShadowMethod::Selective);
        FAIL() << "expected an error";
    } catch (const std::exception& e) {
        const std::string message = e.what();
        EXPECT_EQ(message.find('\n'), std::string::npos) << message;
        EXPECT_EQ(message.rfind("--geometry-budget: a budget of 9.0 KiB holds 2 pages of 4.5 KiB, smaller than the working set of", 0), 0u)
            << message;
    }
    EXPECT_THROW(Renderer(budgetOptions(kPageBytes - 1)).loadModel(city.model), std::exception); // less than a page
    RendererOptions badPage = budgetOptions(city.geometryBytes);
    badPage.geometryPageBytes = 5000; // not a multiple of 48
    EXPECT_THROW(Renderer(badPage).loadModel(city.model), std::exception);
    Renderer none(budgetOptions(city.geometryBytes / 4));
    none.loadModel(city.model);
    EXPECT_THROW(renderFrame(none, ShadowMethod::ShadowMap, CullMode::None), std::exception);
}

} // namespace
} // namespace penumbra
