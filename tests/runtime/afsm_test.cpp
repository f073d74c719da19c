// Alias-free shadow maps (Sintorn et al. 2008, section 3): hard shadows
// exact by construction, so against the Embree oracle on the suite's scenes,
// a point light among the geometry and thin wires, at most 0.01% of the
// light-facing pixels may differ (rounding at triangle edges).
#include <cmath>
#include <cstdio>
#include <functional>

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>
#include <gtest/gtest.h>

#include "penumbra/generate.h"
#include "penumbra/oracle.h"
#include "penumbra/penumbra.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

struct Result {
    test::Comparison afsm, srt;
};

// afsm and srt against the oracle on afsm's G-buffer; only the pixels whose
// point `compared` accepts (all when empty).
Result compareWithOracle(const Mesh& mesh, const Camera& camera, const Light& light, uint32_t size,
                         const std::function<bool(glm::vec3)>& compared = {})
{
    Renderer renderer;
    renderer.loadModel(mesh);
    renderer.setCamera(camera);
    renderer.setLights({light});
    RenderSettings settings;
    settings.width = settings.height = size;
    settings.readbackGBuffer = true;
    settings.shadows = ShadowMethod::AliasFree;
    Frame afsm = renderer.render(settings);
    settings.shadows = ShadowMethod::Selective;
    Frame srt = renderer.render(settings);
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
    EXPECT_GT(afsm.stats.rayOffset, 0.0f);
    OracleOptions options;
    options.originOffset = afsm.stats.rayOffset;
    std::vector<float> oracle = EmbreeOracle(mesh).hardShadowVisibility(afsm.positions, afsm.normals, light, options);
    if (compared)
        for (size_t i = 0; i < oracle.size(); ++i)
            if (!compared(glm::vec3(afsm.positions[4 * i], afsm.positions[4 * i + 1], afsm.positions[4 * i + 2])))
                oracle[i] = -1.0f; // not compared
    Result result{test::compareVisibility(oracle, afsm.visibility), test::compareVisibility(oracle, srt.visibility)};
    std::printf("afsm: %zu of %zu light-facing pixels differ from the oracle (srt: %zu)\n", result.afsm.differing, result.afsm.compared,
                result.srt.differing);
    bool casters = false;
    for (const PassTiming& pass : afsm.stats.passes)
        casters |= pass.name == "afsm_casters";
    EXPECT_TRUE(casters) << "afsm ran without its casters pass";
    return result;
}

Scene interior()
{
    GenerateOptions options;
    options.triangles = 60'000;
    return generateScene("interior", options);
}

TEST(AliasFreeShadowMaps, SuiteScenesMatchTheOracle)
{
    for (const char* name : {"city", "interior", "plant", "scan"}) {
        GenerateOptions options;
        options.triangles = 60'000;
        Scene scene = generateScene(name, options);
        Result r = compareWithOracle(scene.mesh, scene.cameras[0], scene.lights[0], 256);
        EXPECT_GT(r.afsm.compared, 5000u) << name;
        EXPECT_LE(r.afsm.fraction(), 1e-4) << name << ": afsm differs from the oracle on " << r.afsm.differing << " of " << r.afsm.compared
                                           << " (srt: " << r.srt.differing << ")";
        EXPECT_LE(r.afsm.differing, r.srt.differing) << name;
    }
}

TEST(AliasFreeShadowMaps, PointLightAmongTheGeometryMatchesTheOracle)
{
    Scene scene = interior();
    Result r = compareWithOracle(scene.mesh, scene.cameras[0], test::pointLightAmong(computeBounds(scene.mesh), 0.25f), 256);
    EXPECT_GT(r.afsm.compared, 5000u);
    EXPECT_LE(r.afsm.fraction(), 1e-4) << "afsm differs from the oracle on " << r.afsm.differing << " of " << r.afsm.compared;
}

TEST(AliasFreeShadowMaps, SpotLightMatchesTheOracleInsideItsCone)
{
    Scene scene = interior();
    const Bounds bounds = computeBounds(scene.mesh);
    Light spot;
    spot.type = LightType::Spot;
    spot.position = bounds.center() + glm::vec3(0.0f, 0.3f * (bounds.max.y - bounds.min.y), 0.0f);
    spot.direction = glm::normalize(glm::vec3(0.2f, -1.0f, 0.1f));
    spot.outerConeDegrees = 40.0f;
    spot.innerConeDegrees = 30.0f;
    // Outside the cone no light arrives (and the grid covers only the cone's map): compared inside it.
    const float cosOuter = std::cos(glm::radians(spot.outerConeDegrees));
    Result r = compareWithOracle(scene.mesh, scene.cameras[0], spot, 256,
                                 [&](glm::vec3 p) { return glm::dot(glm::normalize(p - spot.position), spot.direction) >= cosOuter; });
    EXPECT_GT(r.afsm.compared, 3000u);
    EXPECT_LE(r.afsm.fraction(), 1e-4) << "afsm differs from the oracle on " << r.afsm.differing << " of " << r.afsm.compared;
}

TEST(AliasFreeShadowMaps, ThinWiresAreNotLost)
{
    const Mesh mesh = test::wiresOverGround();
    Camera camera;
    camera.position = {0, 12, 16};
    camera.target = {0, 0, 0};
    Light sun;
    sun.direction = glm::normalize(glm::vec3(0.3f, -1.0f, 0.2f));
    Result r = compareWithOracle(mesh, camera, sun, 512);
    EXPECT_LE(r.afsm.fraction(), 1e-4) << "afsm differs from the oracle on " << r.afsm.differing << " of " << r.afsm.compared;
}

TEST(AliasFreeShadowMaps, RejectsAreaLights)
{
    Renderer renderer;
    renderer.loadModel(test::cubeOverFloor(0.3f));
    Light area;
    area.type = LightType::Rectangle;
    area.position = {0, 8, 0};
    renderer.setLights({area});
    RenderSettings settings;
    settings.width = settings.height = 64;
    settings.shadows = ShadowMethod::AliasFree;
    try {
        renderer.render(settings);
        FAIL() << "afsm accepted an area light";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("afsm does not do soft shadows"), std::string::npos) << e.what();
    }
}

} // namespace
} // namespace penumbra
