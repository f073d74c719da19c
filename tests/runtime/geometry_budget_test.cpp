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
#include <cstdlib>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include "penumbra/generate.h"
#include "penumbra/penumbra.h"
#include "penumbra/preprocess.h"
#include "penumbra/oracle.h"
#include "passes/afsm.h"

namespace penumbra {
namespace {

constexpr uint32_t kSize = 256;
constexpr uint64_t kPageBytes = 6144; // small pages, so that 1/16 of a 150k-triangle model holds several views

RendererOptions budgetOptions(uint64_t budget)
{
    RendererOptions options;
    options.geometryBudgetBytes = budget;
    options.geometryPageBytes = kPageBytes;
    return options;
}

// samples: soft shadows' light samples (4: the fewest, the tests stay fast; afsm takes 128 or more).
Frame renderFrame(Renderer& renderer, ShadowMethod method, CullMode cull = CullMode::All, uint32_t samples = 4)
{
    RenderSettings settings;
    settings.cull = cull;
    settings.width = settings.height = kSize;
    settings.shadows = method;
    settings.shadowMapSize = 512;
    settings.lightSamples = samples;
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
                       const std::vector<ShadowMethod>& methods, const char* name, bool expectParking, uint32_t samples = 4)
{
    Renderer unlimited;
    unlimited.loadModel(city.model);
    std::vector<std::unique_ptr<Renderer>> budgeted;
    for (uint64_t divisor : {4u, 16u}) {
        budgeted.push_back(std::make_unique<Renderer>(budgetOptions(city.geometryBytes / divisor)));
        budgeted.back()->loadModel(city.model);
    }
    uint64_t streamed = 0, rounds = 0, pages = 0;
    for (size_t f = 0; f < frames.size(); ++f)
        for (ShadowMethod method : methods) {
            unlimited.setCamera(frames[f].first);
            unlimited.setLights(frames[f].second);
            const Frame expected = renderFrame(unlimited, method, CullMode::All, samples);
            for (size_t b = 0; b < budgeted.size(); ++b) {
                Renderer& renderer = *budgeted[b];
                renderer.setCamera(frames[f].first);
                renderer.setLights(frames[f].second);
                const Frame frame = renderFrame(renderer, method, CullMode::All, samples);
                const std::string what = std::string(name) + " frame " + std::to_string(f) + " " + shadowMethodName(method) +
                                         " budget 1/" + (b == 0 ? "4" : "16");
                expectSameImage(expected, frame, what);
                const FrameStats& s = frame.stats;
                EXPECT_EQ(s.geometryBytes, city.geometryBytes) << what;
                EXPECT_LE(s.residentPeakBytes, s.geometryBudgetBytes) << what;
                EXPECT_LE(s.geometryBudgetBytes, city.geometryBytes / (b == 0 ? 4 : 16)) << what;
                streamed += s.bytesStreamed;
                rounds += s.parkingRounds;
                pages += s.pagesUploaded;
                EXPECT_EQ(s.bytesStreamed == 0, s.pagesUploaded == 0) << what;
            }
        }
    std::printf("[ budget   ] %s: %llu pages (%llu bytes) streamed, %llu parking rounds over %zu frames\n", name, (unsigned long long)pages,
                (unsigned long long)streamed, (unsigned long long)rounds, frames.size());
    // Pages move; rays park where the light has no views of its own (frt's area lights draw no map).
    EXPECT_GT(streamed, 0u) << name;
    if (expectParking) {
        EXPECT_GT(rounds, 0u) << name;
    }
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

// A point light above the camera path's patch, moving along it (six cube faces, each its own view).
std::vector<Light> pointPath(const std::vector<Camera>& cameras, const Bounds& bounds)
{
    const float diagonal = glm::length(bounds.max - bounds.min);
    std::vector<Light> path;
    for (size_t step = 0; step < cameras.size(); ++step) {
        Light point;
        point.type = LightType::Point;
        point.position = cameras[step].target + glm::vec3(0.02f + 0.01f * float(step), 0.06f, 0.015f) * diagonal;
        point.intensity = 0.02f * diagonal * diagonal;
        path.push_back(point);
    }
    return path;
}

// afsm and rh have no shadow map to draw in ranges: afsm bins its casters in
// compute per range of its views' clusters (and rasterizes the others in the
// views' ranges), rh gathers its casters in batches within ranges. Both OR
// what each caster shadows, so the ranges leave the image as it is.
TEST(GeometryBudget, AliasFreeAndRayHierarchySameImagesAlongCameraAndLightPaths)
{
    const Budgeted city = preparedCity();
    const Bounds bounds = modelBounds(city.model);
    const std::vector<Camera> cameras = cameraPath(bounds);
    const std::vector<Light> suns = sunPath(), points = pointPath(cameras, bounds);
    std::vector<std::pair<Camera, std::vector<Light>>> sunFrames, pointFrames;
    for (size_t i = 0; i < 2; ++i) { // two steps of each path keep the test short (afsm and rh draw six layers per point light)
        sunFrames.push_back({cameras[i], {suns[i]}});
        if (i < 1)
            pointFrames.push_back({cameras[i], {points[i]}});
    }
    compareAlongPaths(city, sunFrames, {ShadowMethod::AliasFree, ShadowMethod::RayHierarchy}, "afsm, rh sun", false);
    compareAlongPaths(city, pointFrames, {ShadowMethod::AliasFree, ShadowMethod::RayHierarchy}, "afsm, rh point", false);
}

// The default camera and sun see the whole model, 16 times the budget: afsm's
// binned casters and rh's caster batches come in many ranges.
TEST(GeometryBudget, AliasFreeAndRayHierarchyWholeModelInRanges)
{
    const Budgeted city = preparedCity();
    Renderer unlimited, budgeted(budgetOptions(city.geometryBytes / 16));
    unlimited.loadModel(city.model);
    budgeted.loadModel(city.model);
    for (ShadowMethod method : {ShadowMethod::AliasFree, ShadowMethod::RayHierarchy}) {
        const Frame expected = renderFrame(unlimited, method);
        const Frame actual = renderFrame(budgeted, method);
        expectSameImage(expected, actual, std::string("whole-model view, ") + shadowMethodName(method));
        EXPECT_GT(actual.stats.pagesUploaded * kPageBytes, city.geometryBytes) << shadowMethodName(method); // the pool's contents cycle
        EXPECT_LE(actual.stats.residentPeakBytes, actual.stats.geometryBudgetBytes);
    }
}

// afsm's soft shadows (section 4): every caster ORs the light samples it
// hides into the samples' masks, in ranges under a budget.
TEST(GeometryBudget, AliasFreeSoftShadowsSameImages)
{
    const Budgeted city = preparedCity();
    const Bounds bounds = modelBounds(city.model);
    const std::vector<Camera> cameras = cameraPath(bounds);
    compareAlongPaths(city, {{cameras[0], {rectangleAbove(cameras[0], bounds, 0.0f)}}}, {ShadowMethod::AliasFree}, "afsm soft", false, 128);
}

// afsm's soft grid on the close-up (issue 17). Fitted to the whole model
// (fitShadowMapsToView off) the grid puts every sample of the frame into one
// cell, more than one fragment may test (lavapipe ends an invocation's loops
// after 65535 iterations: afsmSliceSamples), so the casters draw that cell
// again per further slice of its list; before the slices, the later samples
// went untested and which ones followed lavapipe's threads. Fitted to the
// view (the default) the samples spread over the grid. Both must give the
// same image (every sample tested against every caster; only the grid
// differs), repeat it bit for bit with lavapipe's threads, and differ from
// the oracle tracing the table's own samples only by the table.
TEST(GeometryBudget, AliasFreeCrowdedSoftGridIsSlicedAndExact)
{
    const Budgeted city = preparedCity();
    const Bounds bounds = modelBounds(city.model);
    const std::vector<Camera> cameras = cameraPath(bounds);
    const Light light = rectangleAbove(cameras[0], bounds, 0.0f);
    const uint32_t samples = 128;
    Renderer renderer;
    renderer.loadModel(city.model);
    renderer.setCamera(cameras[0]);
    renderer.setLights({light});
    auto render = [&](bool fit) {
        RenderSettings settings;
        settings.width = settings.height = kSize;
        settings.shadows = ShadowMethod::AliasFree;
        settings.lightSamples = samples;
        settings.readbackGBuffer = true;
        settings.fitShadowMapsToView = fit;
        Frame frame = renderer.render(settings);
        EXPECT_EQ(renderer.validationMessageCount(), 0u);
        return frame;
    };
    const Frame fitted = render(true);
    const Frame crowded = render(false);
    const Frame again = render(false);
    const uint32_t slice = passes::afsmSliceSamples(samples);
    std::printf("[ afsm     ] most samples in a cell: %u fitted to the view, %u fitted to the model (%u slice draws; a slice holds %u)\n",
                fitted.stats.afsmCellMost, crowded.stats.afsmCellMost, crowded.stats.afsmSliceDraws, slice);
    EXPECT_LE(fitted.stats.afsmCellMost, slice);
    EXPECT_EQ(fitted.stats.afsmSliceDraws, 0u);
    EXPECT_GT(crowded.stats.afsmCellMost, 2 * slice); // the case the slices are for
    EXPECT_EQ(crowded.stats.afsmSliceDraws, (crowded.stats.afsmCellMost - 1) / slice);
    expectSameImage(crowded, again, "crowded grid, twice");
    expectSameImage(fitted, crowded, "grid fitted to the view against the crowded one");

    EmbreeOracle oracle(decodeMesh(city.model));
    OracleOptions options;
    options.originOffset = crowded.stats.rayOffset;
    options.afsmSamples = true;
    const std::vector<float> reference = oracle.softShadowVisibility(crowded.positions, crowded.normals, kSize, light, 0, samples, options);
    size_t compared = 0, beyond = 0;
    double sum = 0.0;
    for (size_t i = 0; i < reference.size(); ++i) {
        if (reference[i] == -1.0f)
            continue;
        const double d = std::abs(double(std::max(reference[i], 0.0f)) - double(std::max(crowded.visibility[i], 0.0f)));
        ++compared;
        sum += d;
        beyond += d * samples > 4.0; // the table's bound for 128 samples (afsm_test: SoftShadowsDifferFromTheOracleOnlyByTheTable)
    }
    EXPECT_GT(compared, 30'000u);
    EXPECT_LE(sum / double(compared), 0.0005);
    EXPECT_EQ(beyond, 0u);
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

// A pool of two pages holds less than what one long shadow ray crosses: such a
// ray is traced once per range of its clusters that fits (any-hit: shadowed if
// one range hits it), and the image is still the same.
TEST(GeometryBudget, OneRayLargerThanThePoolTracedInRanges)
{
    const Budgeted city = preparedCity();
    Renderer unlimited, budgeted(budgetOptions(2 * kPageBytes));
    unlimited.loadModel(city.model);
    budgeted.loadModel(city.model);
    Light sun;
    sun.type = LightType::Directional;
    sun.direction = glm::normalize(glm::vec3(0.8f, -0.35f, 0.3f)); // low: long rays across the city
    sun.intensity = 3.0f;
    for (Renderer* renderer : {&unlimited, &budgeted})
        renderer->setLights({sun});
    const Frame expected = renderFrame(unlimited, ShadowMethod::FullRayTrace);
    const Frame actual = renderFrame(budgeted, ShadowMethod::FullRayTrace);
    expectSameImage(expected, actual, "rays larger than the pool");
    EXPECT_GT(actual.stats.parkingRounds, 0u);
    EXPECT_LE(actual.stats.residentPeakBytes, 2 * kPageBytes);
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

// Only the BVH's top (the nodes above the clusters), the cluster table and one
// word per node stay resident: a cluster's own nodes live in its page, so the
// device holds far less than the model's BVH besides the pool.
TEST(GeometryBudget, ClusterNodesLiveInPages)
{
    const Budgeted city = preparedCity();
    const uint64_t budget = city.geometryBytes / 16;
    Renderer renderer(budgetOptions(budget));
    renderer.loadModel(city.model);
    uint64_t topNodes = 0;
    for (const model::Node& node : city.model.nodes)
        topNodes += node.cluster == model::kNoCluster ? 1 : 0;
    ASSERT_LT(topNodes * 10, city.model.nodes.size());
    const uint64_t pool = budget / kPageBytes * kPageBytes + (topNodes * 80 + 47) / 48 * 48;
    const uint64_t perCluster = sizeof(model::ClusterRecord) + 20 /* draw */ + 4 /* colour */;
    EXPECT_EQ(renderer.modelDeviceBytes(), pool + city.model.nodes.size() * 4 + city.model.clusters.size() * perCluster);
    EXPECT_LT(renderer.modelDeviceBytes(), budget + city.model.nodes.size_bytes() / 3);
    Renderer unlimited;
    unlimited.loadModel(city.model);
    EXPECT_GT(unlimited.modelDeviceBytes(), city.geometryBytes);
}

// Raster views and thin-triangle steps are drawn in ranges and single rays
// traced per range, so what must fit at once is one pixel's light samples: with
// 2 pages, a soft-shadowed pixel's samples toward a light beside the city do not.
TEST(GeometryBudget, BudgetBelowOneViewFailsWithOneLine)
{
    const Budgeted city = preparedCity();
    Renderer renderer(budgetOptions(2 * kPageBytes));
    renderer.loadModel(city.model);
    const Bounds bounds = modelBounds(city.model);
    const Camera camera = cameraPath(bounds)[0];
    Light side = rectangleAbove(camera, bounds, 0.0f);
    side.position = camera.target + glm::vec3(0.45f, 0.08f, 0.3f) * glm::length(bounds.max - bounds.min); // low: long rays
    side.direction = glm::normalize(camera.target - side.position);
    renderer.setCamera(camera);
    renderer.setLights({side});
    try {
        renderFrame(renderer, ShadowMethod::FullRayTrace);
        FAIL() << "expected an error";
    } catch (const std::exception& e) {
        const std::string message = e.what();
        EXPECT_EQ(message.find('\n'), std::string::npos) << message;
        EXPECT_EQ(message.rfind("--geometry-budget: a budget of 12.0 KiB holds 2 pages of 6.0 KiB, smaller than the working set of", 0), 0u)
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
