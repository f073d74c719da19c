// Raster culling (frustum and occlusion queries with the BVH, Lauterbach et
// al. 2009, 5.1) never changes the image: --cull all against --cull none,
// bit for bit, over a camera path (with a jump and a walk through the scene)
// and a moving sun and point light, for every shadow method; and culling
// does cull, so these comparisons cannot pass with it silently off.
#include <cmath>
#include <cstring>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include "penumbra/generate.h"
#include "penumbra/penumbra.h"
#include "penumbra/preprocess.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

constexpr uint32_t kFrames = 20;

struct TestScene {
    const char* name;
    Mesh mesh;
    glm::vec3 center; // camera paths circle this point
    float radius;     // at this distance
    float height;     // and this height above the center
};

std::vector<TestScene> testScenes()
{
    std::vector<TestScene> scenes;
    scenes.push_back({"cubeOverFloor", test::cubeOverFloor(0.3f), {0, 1, 0}, 7.0f, 3.0f});
    for (const char* name : {"city", "interior"}) {
        GenerateOptions options;
        options.triangles = 20'000;
        Scene scene = generateScene(name, options);
        Bounds bounds = computeBounds(scene.mesh);
        glm::vec3 extent = bounds.extent();
        // Low over the city (street level), inside the interior.
        float radius =
            std::string(name) == "city" ? 0.3f * std::max(extent.x, extent.z) : 0.25f * std::max(extent.x, extent.z);
        float height = std::string(name) == "city" ? 0.02f * extent.y : 0.4f * extent.y;
        scenes.push_back(
            {name, std::move(scene.mesh), bounds.center() - glm::vec3(0, 0.5f * extent.y, 0), radius, height});
    }
    return scenes;
}

// Frame f of a camera path: an orbit that dips toward the center, with a jump
// to the far side at frame 10.
Camera pathCamera(const TestScene& scene, uint32_t f)
{
    float angle = 0.35f * float(f) + (f >= 10 ? 3.0f : 0.0f);
    float distance = scene.radius * (0.4f + 0.6f * std::abs(std::cos(0.3f * float(f))));
    Camera camera;
    camera.position = scene.center + glm::vec3(distance * std::cos(angle), scene.height, distance * std::sin(angle));
    camera.target = scene.center + glm::vec3(0, 0.5f * scene.height, 0);
    camera.yfovDegrees = 60.0f;
    return camera;
}

// Frame f of a light path: a sun turning around the sky and a point light
// moving through the scene (six cube faces), or with soft shadows a
// rectangle light moving over it.
std::vector<Light> pathLights(const TestScene& scene, uint32_t f, bool soft)
{
    float angle = 0.3f * float(f) + (f >= 10 ? 2.0f : 0.0f);
    Light sun = defaultLight();
    sun.direction = glm::normalize(glm::vec3(std::cos(angle), -1.2f, std::sin(angle)));
    Light point;
    point.type = LightType::Point;
    point.position = scene.center + glm::vec3(0.5f * scene.radius * std::sin(angle), scene.height + 0.1f * scene.radius,
                                              0.5f * scene.radius * std::cos(angle));
    point.intensity = 20.0f;
    if (soft) {
        point.type = LightType::Rectangle;
        point.position.y += scene.radius;
        point.direction = glm::normalize(glm::vec3(0.2f * std::sin(angle), -1.0f, 0.1f));
        point.width = 0.15f * scene.radius;
        point.height = 0.1f * scene.radius;
    }
    return {sun, point};
}

void expectSameBits(const std::vector<float>& expected, const std::vector<float>& actual, const std::string& what)
{
    EXPECT_EQ(expected.size(), actual.size()) << what;
    if (expected.size() != actual.size())
        return;
    size_t differing = 0;
    for (size_t i = 0; i < expected.size(); ++i)
        differing += std::memcmp(&expected[i], &actual[i], sizeof(float)) != 0;
    EXPECT_EQ(differing, 0u) << what;
}

// Renders the same frames with --cull none and --cull all (each renderer keeps
// its own history) and compares them bit for bit. Returns the clusters that
// occlusion queries and the suns' receiver masks culled over the sequence.
// chunkBytes: RendererOptions::maxModelBufferBytes.
struct SequenceCulling {
    uint64_t occluded = 0;
    uint64_t besideReceivers = 0;
};
SequenceCulling compareSequence(const TestScene& scene, ShadowMethod method, bool moveCamera, uint32_t frameCount = kFrames,
                         uint64_t chunkBytes = 0, bool soft = false)
{
    RendererOptions options;
    options.maxModelBufferBytes = chunkBytes;
    Renderer reference(options), culled(options);
    for (Renderer* renderer : {&reference, &culled})
        renderer->loadModel(scene.mesh);
    RenderSettings settings;
    settings.width = settings.height = 64;
    settings.shadowMapSize = 256;
    settings.shadows = method;
    settings.readbackGBuffer = true;
    settings.adaptiveOcclusion = false; // queries in every view and frame, also where they do not pay
    // srt's own sequence in every frame: whether a frame traces every pixel instead follows the two
    // renderers' own timings (selective_choice.h), and such a frame draws no light view.
    settings.srtTraceAllWhenCheaper = false;
    uint64_t culledClusters = 0, occludedClusters = 0, besideReceivers = 0, penumbraPixels = 0;
    for (uint32_t f = 0; f < frameCount; ++f) {
        const Camera camera = pathCamera(scene, moveCamera ? f : 3);
        const std::vector<Light> lights = pathLights(scene, moveCamera ? 3 : f, soft);
        Frame frames[2];
        for (int i = 0; i < 2; ++i) {
            Renderer& renderer = i == 0 ? reference : culled;
            renderer.setCamera(camera);
            renderer.setLights(lights);
            settings.cull = i == 0 ? CullMode::None : CullMode::All;
            frames[i] = renderer.render(settings);
        }
        const std::string what = std::string(scene.name) + " " + shadowMethodName(method) +
                                 (moveCamera ? " camera" : " light") + " path, frame " + std::to_string(f);
        expectSameBits(frames[0].color.rgba, frames[1].color.rgba, what + ": color");
        expectSameBits(frames[0].positions, frames[1].positions, what + ": positions");
        expectSameBits(frames[0].visibility, frames[1].visibility, what + ": visibility");
        penumbraPixels += frames[1].stats.penumbraPixels;
        // 1 camera + 1 sun + 6 cube faces, or the area light's maps (sm: 4, srt: the centre's).
        const size_t lightViews = !soft ? 6 : method == ShadowMethod::ShadowMap ? settings.softShadowMaps : 1;
        EXPECT_EQ(frames[1].stats.views.size(), 2 + lightViews) << what;
        for (const ViewCullStats& view : frames[1].stats.views) {
            culledClusters += view.clustersCulled;
            occludedClusters += view.clustersOccluded;
            besideReceivers += view.clustersBesideReceivers;
        }
    }
    if (soft) {
        EXPECT_GT(penumbraPixels, 0u) << scene.name << ": the sequence shows soft shadows";
    }
    // Frustum culling was at work (the cube scene has too few clusters).
    if (std::string(scene.name) != "cubeOverFloor") {
        EXPECT_GT(culledClusters, occludedClusters) << scene.name;
    }
    EXPECT_EQ(reference.validationMessageCount(), 0u);
    EXPECT_EQ(culled.validationMessageCount(), 0u);
    return {occludedClusters, besideReceivers};
}

// Hard shadows (and soft shadows, SoftShadowsAreBitIdenticalToNoCulling): sm and srt.
const ShadowMethod kMethods[] = {ShadowMethod::ShadowMap, ShadowMethod::Selective};

// Occlusion queries and the sun's receiver mask culled something in every
// sequence set (the city's streets; the small interior's few cells are mostly
// all in view).
TEST(Culling, CameraPathIsBitIdenticalToNoCulling)
{
    for (ShadowMethod method : kMethods) {
        SequenceCulling total;
        for (const TestScene& scene : testScenes()) {
            SequenceCulling sequence = compareSequence(scene, method, true);
            total.occluded += sequence.occluded;
            total.besideReceivers += sequence.besideReceivers;
        }
        EXPECT_GT(total.occluded, 0u) << shadowMethodName(method);
        EXPECT_GT(total.besideReceivers, 0u) << shadowMethodName(method);
    }
}

TEST(Culling, LightPathIsBitIdenticalToNoCulling)
{
    for (ShadowMethod method : kMethods) {
        SequenceCulling total;
        for (const TestScene& scene : testScenes()) {
            SequenceCulling sequence = compareSequence(scene, method, false);
            total.occluded += sequence.occluded;
            total.besideReceivers += sequence.besideReceivers;
        }
        EXPECT_GT(total.occluded, 0u) << shadowMethodName(method);
        EXPECT_GT(total.besideReceivers, 0u) << shadowMethodName(method);
    }
}

// Soft shadows from a rectangle light (its shadow maps are culled views too),
// over the camera path and the light path, sm (four maps) and srt.
TEST(Culling, SoftShadowsAreBitIdenticalToNoCulling)
{
    for (ShadowMethod method : kMethods)
        for (bool moveCamera : {true, false})
            for (const TestScene& scene : testScenes())
                compareSequence(scene, method, moveCamera, kFrames, 0, true);
}

// A model split into many buffer chunks: the culled draw lists break at every
// chunk boundary (one multi-draw per run of clusters in the same chunk).
TEST(Culling, ChunkedModelIsBitIdenticalToNoCulling)
{
    for (const TestScene& scene : testScenes())
        if (std::string(scene.name) == "city") {
            ASSERT_GT(buildCompressedModel(scene.mesh, {}).vertices.size_bytes(), 4u * 16 * 1024);
            compareSequence(scene, ShadowMethod::ShadowMap, true, 8, 16 * 1024);
        }
}

// From street level most of the city is outside the frustum or behind the
// first buildings: frustum culling drops clusters, occlusion culling drops
// more once the camera has a history, and the counts add up.
TEST(Culling, CullsClustersOutsideTheFrustumAndBehindOccluders)
{
    GenerateOptions options;
    options.triangles = 60'000;
    Scene scene = generateScene("city", options);
    Bounds bounds = computeBounds(scene.mesh);
    Camera camera;
    camera.position = {bounds.min.x + 0.1f * bounds.extent().x, bounds.min.y + 2.0f, bounds.center().z};
    camera.target = {bounds.max.x, bounds.min.y + 2.0f, bounds.center().z};
    Renderer renderer;
    renderer.loadModel(scene.mesh);
    renderer.setCamera(camera);
    RenderSettings settings;
    settings.width = settings.height = 128;
    settings.shadowMapSize = 256;
    settings.adaptiveOcclusion = false; // the frustum holds fewer than PENUMBRA_CULL_MIN_TRIANGLES
    auto cameraView = [&](CullMode mode) {
        settings.cull = mode;
        Frame frame;
        for (int i = 0; i < 6; ++i) // a history, with every visible cell retested once (PENUMBRA_CULL_RETEST_FRAMES)
            frame = renderer.render(settings);
        EXPECT_EQ(frame.stats.cull, mode);
        EXPECT_FALSE(frame.stats.views.empty());
        for (const ViewCullStats& view : frame.stats.views) {
            EXPECT_EQ(view.trianglesDrawn + view.trianglesCulled, frame.stats.triangles) << view.name;
            EXPECT_GT(view.clustersDrawn, 0u) << view.name;
            EXPECT_GT(view.gpuMs, 0.0) << view.name;
        }
        return frame.stats.views.at(0);
    };
    ViewCullStats none = cameraView(CullMode::None);
    ViewCullStats frustum = cameraView(CullMode::Frustum);
    ViewCullStats all = cameraView(CullMode::All);
    EXPECT_EQ(none.name, "camera");
    EXPECT_EQ(none.clustersCulled, 0u);
    EXPECT_EQ(none.queriesIssued, 0u);
    EXPECT_GT(frustum.clustersCulled, frustum.clustersDrawn / 2) << "frustum culling drops most of a street-level view";
    EXPECT_GT(frustum.nodesTested, 0u);
    EXPECT_EQ(frustum.queriesIssued, 0u);
    EXPECT_GT(all.queriesIssued, 0u);
    EXPECT_LT(all.trianglesDrawn, frustum.trianglesDrawn / 2)
        << "occlusion culling drops most of what the frustum keeps";
    EXPECT_GT(all.clustersOccluded, 0u);
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
}

// The sun's map fitted to the view (RenderSettings::fitShadowMapsToView)
// covers only the light-space footprint of what the camera sees, so frustum
// culling drops the casters beside it; fitted to the model, the map holds
// every cluster. A camera that sees nothing keeps the model-fitted map.
TEST(Culling, SunMapFittedToTheViewDropsCastersBesideIt)
{
    GenerateOptions options;
    options.triangles = 60'000;
    Scene scene = generateScene("city", options);
    Bounds bounds = computeBounds(scene.mesh);
    Camera camera;
    camera.position = {bounds.min.x + 0.1f * bounds.extent().x, bounds.min.y + 2.0f, bounds.center().z};
    camera.target = {bounds.max.x, bounds.min.y + 2.0f, bounds.center().z};
    Renderer renderer;
    renderer.loadModel(scene.mesh);
    renderer.setCamera(camera);
    RenderSettings settings;
    settings.width = settings.height = 128;
    settings.shadowMapSize = 256;
    settings.cull = CullMode::Frustum;
    settings.cullBesideReceivers = false; // the fit alone (SunCullsCastersBesideTheVisiblePoints: the mask)
    uint64_t covered[2] = {};
    auto sunView = [&](bool fit) {
        settings.fitShadowMapsToView = fit;
        Frame frame = renderer.render(settings);
        EXPECT_EQ(frame.stats.views.size(), 2u);
        bool timed = false;
        for (const PassTiming& pass : frame.stats.passes)
            timed = timed || pass.name == "view_fit";
        EXPECT_EQ(timed, fit);
        covered[fit ? 1 : 0] = frame.stats.coveredPixels;
        return frame.stats.views.at(1);
    };
    ViewCullStats model = sunView(false), view = sunView(true);
    // The covered pixels: counted by view_fit when it runs, else by the first shade pass; the same count.
    EXPECT_GT(covered[0], 0u);
    EXPECT_EQ(covered[0], covered[1]);
    EXPECT_EQ(model.name, "light0");
    EXPECT_EQ(model.clustersCulled, 0u) << "the model-fitted map holds the whole model";
    EXPECT_GT(view.clustersCulled, view.clustersDrawn) << "a street-level view needs few of the city's casters";

    // Looking away from the model: nothing covered, the map stays model-fitted
    // (and, with the receiver mask, draws nothing: no point reads it).
    camera.target = camera.position + (camera.position - camera.target);
    camera.position += 2.0f * (camera.position - bounds.center());
    renderer.setCamera(camera);
    settings.fitShadowMapsToView = true;
    settings.cullBesideReceivers = false;
    Frame away = renderer.render(settings);
    EXPECT_EQ(away.stats.coveredPixels, 0u);
    EXPECT_EQ(away.stats.views.at(1).clustersCulled, 0u);
    settings.cullBesideReceivers = true;
    away = renderer.render(settings);
    EXPECT_EQ(away.stats.views.at(1).clustersDrawn, 0u);
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
}

// The fitted sun's map is a rectangle around the visible points; of the
// casters inside it, the receiver mask also drops those whose footprint holds
// none of them (a view across the city at a slant covers a wedge of its
// rectangle). A point light's cube faces drop the casters that throw their
// shadows where the camera does not look. Selective ray tracing reads the 3x3
// texels around each point's: with and without the masks it marks the same
// pixels and draws the same image.
TEST(Culling, ShadowViewsCullCastersBesideTheVisiblePoints)
{
    GenerateOptions options;
    options.triangles = 200'000;
    Scene scene = generateScene("city", options);
    Bounds bounds = computeBounds(scene.mesh);
    Camera camera;
    // Over a corner of the city, looking across it to the opposite corner.
    camera.position = {bounds.min.x + 0.1f * bounds.extent().x, bounds.min.y + 20.0f, bounds.min.z + 0.1f * bounds.extent().z};
    camera.target = {bounds.max.x, bounds.min.y + 20.0f, bounds.max.z};
    Light lamp;
    lamp.type = LightType::Point;
    lamp.position = bounds.center() + glm::vec3(0.0f, 0.2f * bounds.extent().y, 0.0f);
    lamp.intensity = 20.0f;
    Renderer renderer;
    renderer.loadModel(scene.mesh);
    renderer.setCamera(camera);
    RenderSettings settings;
    settings.width = settings.height = 128;
    settings.shadowMapSize = 512;
    settings.shadows = ShadowMethod::Selective;
    settings.cull = CullMode::Frustum;
    for (const Light& light : {scene.lights.at(0), lamp}) {
        renderer.setLights({light});
        Frame frames[2];
        for (int withMask = 0; withMask < 2; ++withMask) {
            settings.cullBesideReceivers = withMask == 1;
            frames[withMask] = renderer.render(settings);
        }
        const std::string what = light.type == LightType::Point ? "city, point light" : "city, sun";
        uint64_t culled[2] = {0, 0}, beside[2] = {0, 0};
        for (int withMask = 0; withMask < 2; ++withMask)
            for (size_t v = 1; v < frames[withMask].stats.views.size(); ++v) {
                culled[withMask] += frames[withMask].stats.views[v].clustersCulled;
                beside[withMask] += frames[withMask].stats.views[v].clustersBesideReceivers;
            }
        EXPECT_EQ(beside[0], 0u) << what;
        EXPECT_GT(beside[1], 0u) << what;
        EXPECT_GT(culled[1], culled[0]) << what;
        EXPECT_LE(culled[1], culled[0] + beside[1]) << what << ": some would fail the frustum lower down";
        EXPECT_GT(frames[1].stats.pipPixels, 0u) << what;
        EXPECT_EQ(frames[0].stats.pipPixels, frames[1].stats.pipPixels) << what;
        EXPECT_EQ(frames[0].stats.rays, frames[1].stats.rays) << what;
        expectSameBits(frames[0].color.rgba, frames[1].color.rgba, what + ", srt: color with and without the receiver masks");
    }
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
}

// A view with fewer than PENUMBRA_CULL_MIN_TRIANGLES in its frustum draws them
// without occlusion queries (a query costs more than it can save there), unless
// adaptiveOcclusion is off; the image is the same either way.
TEST(Culling, SmallViewsSkipOcclusionQueries)
{
    GenerateOptions options;
    options.triangles = 2'000;
    Scene scene = generateScene("scan", options);
    Frame frames[2];
    for (int adaptive = 0; adaptive < 2; ++adaptive) {
        Renderer renderer;
        renderer.loadModel(scene.mesh);
        renderer.setCamera(scene.cameras.at(0));
        renderer.setLights(scene.lights);
        RenderSettings settings;
        settings.width = settings.height = 128;
        settings.shadowMapSize = 256;
        settings.cull = CullMode::All;
        settings.adaptiveOcclusion = adaptive != 0;
        uint64_t queries = 0;
        for (int f = 0; f < 3; ++f) {
            frames[adaptive] = renderer.render(settings);
            for (const ViewCullStats& view : frames[adaptive].stats.views)
                queries += view.queriesIssued;
        }
        if (adaptive)
            EXPECT_EQ(queries, 0u) << "a 2,000-triangle model needs no occlusion queries";
        else
            EXPECT_GT(queries, 0u) << "adaptiveOcclusion off queries every view";
        EXPECT_EQ(renderer.validationMessageCount(), 0u);
    }
    EXPECT_EQ(frames[0].color.rgba, frames[1].color.rgba);
}

} // namespace
} // namespace penumbra
