// Cone ray hierarchies (Olsson and Assarsson 2011): hard shadows of point,
// spot and directional lights, exact by construction (the leaves run the
// tracer's watertight test on the tracer's rays; early accept only where
// every ray of a cone crosses the covering triangle with room to spare), so
// against the Embree oracle at most 0.01% of the light-facing pixels may
// differ, with every option.
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>
#include <gtest/gtest.h>

#include "penumbra/generate.h"
#include "penumbra/oracle.h"
#include "penumbra/penumbra.h"
#include "penumbra/preprocess.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

struct Options {
    ConeTest test = ConeTest::Precise;
    RhSort sort = RhSort::Auto;
    bool twoPass = false;
    bool earlyAccept = true;
    bool closedMeshes = false;
    bool separateClosed = false; // preprocessed so that closed components get clusters of their own (kClusterClosed)
};

struct Result {
    test::Comparison rh, frt;
    test::Comparison rhDecoded; // against the oracle on the triangles the GPU draws (decodeMesh: quantized positions)
    FrameStats stats;
    std::vector<float> visibility;
};

std::string describe(const Options& o)
{
    return std::string(coneTestName(o.test)) + ", order " + rhSortName(o.sort) + (o.twoPass ? ", two-pass" : "") +
           (o.earlyAccept ? ", early accept" : "") + (o.closedMeshes ? ", closed meshes" : "");
}

// rh (with `options`) and frt against the oracle on rh's G-buffer; only the
// pixels whose point `compared` accepts (all when empty).
Result compareWithOracle(const Mesh& mesh, const Camera& camera, const Light& light, uint32_t size, const Options& options = {},
                         const std::function<bool(glm::vec3)>& compared = {})
{
    Renderer renderer;
    PreprocessOptions preprocess;
    preprocess.separateClosed = options.separateClosed;
    CompressedModel model = buildCompressedModel(mesh, preprocess);
    const Mesh decodedMesh = decodeMesh(model);
    renderer.loadModel(std::move(model));
    renderer.setCamera(camera);
    renderer.setLights({light});
    RenderSettings settings;
    settings.width = settings.height = size;
    settings.readbackGBuffer = true;
    settings.shadows = ShadowMethod::RayHierarchy;
    settings.coneTest = options.test;
    settings.rhSort = options.sort;
    settings.rhTwoPass = options.twoPass;
    settings.rhEarlyAccept = options.earlyAccept;
    settings.rhClosedMeshes = options.closedMeshes;
    Frame rh = renderer.render(settings);
    settings.shadows = ShadowMethod::FullRayTrace;
    Frame frt = renderer.render(settings);
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
    EXPECT_GT(rh.stats.rayOffset, 0.0f);
    OracleOptions oracleOptions;
    oracleOptions.originOffset = rh.stats.rayOffset;
    std::vector<float> oracle = EmbreeOracle(mesh).hardShadowVisibility(rh.positions, rh.normals, light, oracleOptions);
    if (compared)
        for (size_t i = 0; i < oracle.size(); ++i)
            if (!compared(glm::vec3(rh.positions[4 * i], rh.positions[4 * i + 1], rh.positions[4 * i + 2])))
                oracle[i] = -1.0f; // not compared
    std::vector<float> decoded = EmbreeOracle(decodedMesh).hardShadowVisibility(rh.positions, rh.normals, light, oracleOptions);
    for (size_t i = 0; i < oracle.size(); ++i)
        if (oracle[i] < 0.0f)
            decoded[i] = -1.0f;
    Result result{test::compareVisibility(oracle, rh.visibility), test::compareVisibility(oracle, frt.visibility),
                  test::compareVisibility(decoded, rh.visibility), rh.stats, rh.visibility};
    std::printf("rh (%s): %zu of %zu light-facing pixels differ from the oracle (frt: %zu; on the decoded mesh: %zu); %llu rays (%s, incoherence %.1f), %llu casters, "
                "%llu cone tests, %llu ray tests, %llu accepted, %u batches, %u rounds, peak records %llu KiB, closed culling %u\n",
                describe(options).c_str(), result.rh.differing, result.rh.compared, result.frt.differing, result.rhDecoded.differing, (unsigned long long)rh.stats.rays,
                rh.stats.rhSortedLights ? "sorted" : "by pixel", rh.stats.rhIncoherence, (unsigned long long)rh.stats.rhCasters,
                (unsigned long long)rh.stats.nodesVisited, (unsigned long long)rh.stats.triangleTests,
                (unsigned long long)rh.stats.rhAcceptedNodes, rh.stats.rhBatches, rh.stats.rhRounds,
                (unsigned long long)(rh.stats.rhPeakPairBytes >> 10), rh.stats.rhClosedCulled);
    bool traversed = false;
    for (const PassTiming& pass : rh.stats.passes)
        traversed |= pass.name == "rh_traverse";
    EXPECT_TRUE(traversed) << "rh ran without its traversal";
    EXPECT_GT(rh.stats.rays, 0u);
    EXPECT_EQ(rh.stats.rhLights, 1u);
    return result;
}

Scene suiteScene(const char* name)
{
    GenerateOptions options;
    options.triangles = 60'000;
    return generateScene(name, options);
}

Light sunFrom(glm::vec3 direction)
{
    Light sun;
    sun.type = LightType::Directional;
    sun.direction = glm::normalize(direction);
    sun.intensity = 3.0f;
    return sun;
}

TEST(ConeRayHierarchies, PointLightAmongTheGeometryMatchesTheOracle)
{
    for (const char* name : {"interior", "city", "plant"}) {
        Scene scene = suiteScene(name);
        for (ConeTest test : {ConeTest::Precise, ConeTest::Spheres}) {
            Options options;
            options.test = test;
            Result r = compareWithOracle(scene.mesh, scene.cameras[0], test::pointLightAmong(computeBounds(scene.mesh), 0.25f), 256, options);
            EXPECT_GT(r.rh.compared, 5000u) << name;
            // rh's leaves run the tracer's own test, so it never differs more than frt does; the plant's thin
            // pipes seen from among them give frt itself 14 of 36k grazing rays that Embree decides the other way.
            EXPECT_LE(r.rh.differing, r.frt.differing) << name << " (" << coneTestName(test) << ")";
            EXPECT_LE(r.rh.fraction(), std::string(name) == "plant" ? 5e-4 : 1e-4)
                << name << " (" << coneTestName(test) << "): rh differs from the oracle on " << r.rh.differing << " of " << r.rh.compared
                << " (frt: " << r.frt.differing << ")";
            // On the triangles the GPU draws (quantized), the plant too is within 0.01%: what differs above is quantization.
            EXPECT_LE(r.rhDecoded.fraction(), 1e-4)
                << name << " (" << coneTestName(test) << "): rh differs from the decoded-mesh oracle on " << r.rhDecoded.differing
                << " of " << r.rhDecoded.compared;
            EXPECT_GT(r.stats.rhCasters, 0u);
        }
    }
}

TEST(ConeRayHierarchies, EveryOrderAndTraversalShadowsTheSamePixels)
{
    Scene scene = suiteScene("interior");
    const Light light = test::pointLightAmong(computeBounds(scene.mesh), 0.25f);
    Options sortedOptions;
    sortedOptions.sort = RhSort::On;
    Result sorted = compareWithOracle(scene.mesh, scene.cameras[0], light, 256, sortedOptions);
    EXPECT_LE(sorted.rh.fraction(), 1e-4);
    EXPECT_EQ(sorted.stats.rhSortedLights, 1u);
    std::vector<Options> variants(4, sortedOptions);
    variants[0].sort = RhSort::Off;    // the paper's unsorted variant: the hierarchy over the pixels (Morton order)
    variants[1].earlyAccept = false;   // section 3.3 off
    variants[2].twoPass = true;        // section 3.4: large casters, rebuild, the rest
    variants[3].sort = RhSort::Auto;   // chosen per frame
    for (const Options& options : variants) {
        Result r = compareWithOracle(scene.mesh, scene.cameras[0], light, 256, options);
        EXPECT_EQ(r.rh.differing, sorted.rh.differing) << describe(options);
        EXPECT_EQ(r.stats.rays, sorted.stats.rays) << describe(options);
        EXPECT_EQ(r.visibility, sorted.visibility) << describe(options) << ": not the same pixels as sorted, one pass";
        if (options.sort == RhSort::Off) {
            EXPECT_EQ(r.stats.rhSortedLights, 0u);
            // Section 3.5: where the view has depth discontinuities, sorting by direction makes a tighter hierarchy.
            EXPECT_LT(sorted.stats.nodesVisited, r.stats.nodesVisited);
        }
        if (options.twoPass) {
            EXPECT_EQ(r.stats.rhBatches, 2 * sorted.stats.rhBatches);
        }
        if (!options.earlyAccept) {
            EXPECT_EQ(r.stats.rhAcceptedNodes, 0u);
        }
    }
}

TEST(ConeRayHierarchies, EarlyAcceptShadowsCoveredConesWhole)
{
    // A point light over a cube over a floor: the cube's bottom face covers the cones of the floor's rays
    // under it. Accepted whole, they are the same pixels as tested one by one.
    const Mesh mesh = test::cubeOverFloor(0.3f);
    Camera camera;
    camera.position = {2.5f, 6.0f, 4.0f};
    camera.target = {0.0f, 0.0f, 0.0f};
    Light point;
    point.type = LightType::Point;
    point.position = {0.1f, 5.0f, -0.2f};
    point.intensity = 60.0f;
    Options with, without;
    without.earlyAccept = false;
    for (RhSort sort : {RhSort::On, RhSort::Off}) {
        with.sort = without.sort = sort;
        Result accepted = compareWithOracle(mesh, camera, point, 256, with);
        Result tested = compareWithOracle(mesh, camera, point, 256, without);
        EXPECT_LE(accepted.rh.fraction(), 1e-4) << "rh with early accept differs on " << accepted.rh.differing << " of " << accepted.rh.compared;
        EXPECT_EQ(accepted.visibility, tested.visibility) << "early accept changed pixels (order " << rhSortName(sort) << ")";
        EXPECT_GT(accepted.stats.rhAcceptedNodes, 0u);
        EXPECT_EQ(tested.stats.rhAcceptedNodes, 0u);
        EXPECT_LT(accepted.stats.triangleTests, tested.stats.triangleTests) << "accepted cones still had their rays tested";
    }
}

TEST(ConeRayHierarchies, AutoOrderSortsOnlyIncoherentViews)
{
    // The suite's interior from its camera: many depth discontinuities, the rays sorted by direction.
    Scene scene = suiteScene("interior");
    Result interior = compareWithOracle(scene.mesh, scene.cameras[0], test::pointLightAmong(computeBounds(scene.mesh), 0.25f), 256);
    EXPECT_EQ(interior.stats.rhSortedLights, 1u) << "incoherence " << interior.stats.rhIncoherence;
    // A floor seen from above, a point light over it: neighbouring pixels are neighbouring rays, kept in pixel order.
    const Mesh floor = test::cubeOverFloor(0.3f);
    Camera down;
    down.position = {0.0f, 9.0f, 0.01f};
    down.target = {0.0f, 0.0f, 0.0f};
    Light point;
    point.type = LightType::Point;
    point.position = {3.0f, 6.0f, 1.0f};
    point.intensity = 60.0f;
    Result coherent = compareWithOracle(floor, down, point, 256);
    EXPECT_EQ(coherent.stats.rhSortedLights, 0u) << "incoherence " << coherent.stats.rhIncoherence;
    EXPECT_LT(coherent.stats.rhIncoherence, interior.stats.rhIncoherence);
    EXPECT_LE(coherent.rh.fraction(), 1e-4);
}

TEST(ConeRayHierarchies, ClosedMeshesCastOnlyTheirLightBackFacingTriangles)
{
    // Section 3.6. A closed cube over a floor (apart): a ray through the cube enters it through a
    // light-back-facing triangle, so the cube's light-facing ones can go: the same pixels, fewer casters.
    const Mesh cube = test::cubeOverFloor(0.3f);
    Camera camera;
    camera.position = {2.5f, 6.0f, 4.0f};
    camera.target = {0.0f, 0.0f, 0.0f};
    Light point;
    point.type = LightType::Point;
    point.position = {0.1f, 5.0f, -0.2f};
    point.intensity = 60.0f;
    Options culled, all;
    culled.closedMeshes = true;
    culled.separateClosed = all.separateClosed = true;
    for (const Light& light : {point, sunFrom({0.3f, -1.0f, 0.2f})}) {
        Result r = compareWithOracle(cube, camera, light, 256, culled);
        Result reference = compareWithOracle(cube, camera, light, 256, all);
        EXPECT_EQ(r.stats.rhClosedCulled, 1u);
        EXPECT_LT(r.stats.rhCasters, reference.stats.rhCasters);
        EXPECT_EQ(r.visibility, reference.visibility) << "culling the closed cube's light-facing triangles changed pixels";
        EXPECT_LE(r.rh.fraction(), 1e-4);
    }
    // A closed, outward-facing room with the camera inside: under a sun the floor's rays leave the room
    // through light-facing triangles only. The segment from the eye toward the sun crosses one along its
    // winding, so the frame casts them all (rh.h, closedCullingExact): every pixel inside stays in shadow.
    Mesh room;
    test::addBox(room, {-5, 0, -5}, {5, 4, 5});
    test::addBox(room, {-1, 0.5f, -1}, {1, 1.5f, 1}); // over the floor: touching it, neither would be flagged (clearance)
    Camera inside;
    inside.position = {3.5f, 3.0f, 3.5f};
    inside.target = {0.0f, 0.0f, 0.0f};
    Result sun = compareWithOracle(room, inside, sunFrom({0.3f, -1.0f, 0.2f}), 128, culled);
    EXPECT_EQ(sun.stats.rhClosedCulled, 0u);
    EXPECT_EQ(sun.rh.differing, 0u);
    // A point light inside the same room: the eye and the light on one side of every closed surface, culled, exact.
    Light lamp = point;
    lamp.position = {-2.0f, 3.0f, 1.0f};
    Result inner = compareWithOracle(room, inside, lamp, 128, culled);
    EXPECT_EQ(inner.stats.rhClosedCulled, 1u);
    EXPECT_LE(inner.rh.fraction(), 1e-4) << "rh differs from the oracle on " << inner.rh.differing << " of " << inner.rh.compared;
}

TEST(ConeRayHierarchies, SpotLightMatchesTheOracleInsideItsCone)
{
    Scene scene = suiteScene("interior");
    const Bounds bounds = computeBounds(scene.mesh);
    Light spot;
    spot.type = LightType::Spot;
    spot.position = bounds.center() + glm::vec3(0.0f, 0.3f * (bounds.max.y - bounds.min.y), 0.0f);
    spot.direction = glm::normalize(glm::vec3(0.2f, -1.0f, 0.1f));
    spot.outerConeDegrees = 40.0f;
    spot.innerConeDegrees = 30.0f;
    const float cosOuter = std::cos(glm::radians(spot.outerConeDegrees));
    Result r = compareWithOracle(scene.mesh, scene.cameras[0], spot, 256, {},
                                 [&](glm::vec3 p) { return glm::dot(glm::normalize(p - spot.position), spot.direction) >= cosOuter; });
    EXPECT_GT(r.rh.compared, 3000u);
    EXPECT_LE(r.rh.fraction(), 1e-4) << "rh differs from the oracle on " << r.rh.differing << " of " << r.rh.compared;
}

TEST(ConeRayHierarchies, DirectionalLightMatchesTheOracle)
{
    // Parallel rays: a hierarchy of slabs across the light's direction (rh.glsli).
    for (const char* name : {"city", "interior"}) {
        Scene scene = suiteScene(name);
        const Light sun = scene.lights.empty() || scene.lights[0].type != LightType::Directional ? sunFrom({0.4f, -1.0f, 0.3f}) : scene.lights[0];
        for (RhSort sort : {RhSort::On, RhSort::Off}) {
            Options options;
            options.sort = sort;
            Result r = compareWithOracle(scene.mesh, scene.cameras[0], sun, 256, options);
            EXPECT_GT(r.rh.compared, 5000u) << name;
            EXPECT_LE(r.rh.differing, r.frt.differing) << name << " (order " << rhSortName(sort) << ")";
            EXPECT_LE(r.rh.fraction(), 1e-4) << name << ": rh differs from the oracle on " << r.rh.differing << " of " << r.rh.compared;
        }
    }
    // Both slab tests on a small scene.
    Options spheres;
    spheres.test = ConeTest::Spheres;
    Camera camera;
    camera.position = {5.0f, 7.0f, 6.0f};
    camera.target = {0.0f, 1.0f, 0.0f};
    Result r = compareWithOracle(test::cubeOverFloor(0.3f), camera, sunFrom({0.3f, -1.0f, 0.2f}), 128, spheres);
    EXPECT_LE(r.rh.fraction(), 1e-4) << "rh (spheres) differs from the oracle on " << r.rh.differing << " of " << r.rh.compared;
}

TEST(ConeRayHierarchies, ThinWiresAreNotLost)
{
    const Mesh mesh = test::wiresOverGround();
    Camera camera;
    camera.position = {0, 12, 16};
    camera.target = {0, 0, 0};
    Light point;
    point.type = LightType::Point;
    point.position = {1.0f, 9.0f, 0.5f};
    point.intensity = 400.0f;
    for (const Light& light : {point, sunFrom({0.2f, -1.0f, 0.3f})}) {
        Result r = compareWithOracle(mesh, camera, light, 512);
        EXPECT_GT(r.rh.compared, 100000u);
        EXPECT_LE(r.rh.fraction(), 1e-4) << "rh differs from the oracle on " << r.rh.differing << " of " << r.rh.compared;
        EXPECT_LE(r.rhDecoded.fraction(), 1e-4) << "rh differs from the decoded-mesh oracle on " << r.rhDecoded.differing;
    }
}

TEST(ConeRayHierarchies, RejectsWhatItCannotTake)
{
    Renderer renderer;
    renderer.loadModel(test::cubeOverFloor(0.3f));
    RenderSettings settings;
    settings.width = settings.height = 64;
    settings.shadows = ShadowMethod::RayHierarchy;
    Light area;
    area.type = LightType::Rectangle;
    area.position = {0, 8, 0};
    renderer.setLights({area});
    try {
        renderer.render(settings);
        ADD_FAILURE() << "rh accepted an area light";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("rh does not do soft shadows"), std::string::npos) << e.what();
    }
    EXPECT_THROW(parseConeTest("cubes"), Error);
    try {
        parseRhSort("sideways");
        ADD_FAILURE() << "an unknown ray order was accepted";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("--rh-sort sideways"), std::string::npos) << e.what();
    }
    EXPECT_EQ(parseRhSort("auto"), RhSort::Auto);
}

} // namespace
} // namespace penumbra
