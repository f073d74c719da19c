// The Embree oracle, checked on its own against analytic shadows, then used
// as the reference for the shadow-map baseline.
#include <cmath>

#include <gtest/gtest.h>

#include "penumbra/generate.h"
#include "penumbra/oracle.h"
#include "penumbra/penumbra.h"
#include "test_scenes.h"

namespace penumbra {
namespace {


Frame renderGBuffer(const Mesh& mesh, const Camera& camera, const Light& light, uint32_t size)
{
    return test::renderWithGBuffer(mesh, camera, light, ShadowMethod::ShadowMap, size);
}


TEST(Oracle, MatchesTheAnalyticShadowOfABox)
{
    Mesh mesh = test::cubeOverFloor(0.0f);
    Camera camera;
    camera.projection = Projection::Orthographic;
    camera.orthoHeight = 2.0f;
    camera.position = {0, 5, 10};
    camera.target = {0, 0, 0};
    Light sun;
    sun.direction = {0, -1, 0};
    const uint32_t size = 512;
    Frame frame = renderGBuffer(mesh, camera, sun, size);
    EmbreeOracle oracle(mesh);
    std::vector<float> visibility = oracle.hardShadowVisibility(frame.positions, frame.normals, sun);
    size_t shadowed = 0;
    for (size_t i = 0; i < visibility.size(); ++i)
        shadowed += visibility[i] == 0.0f && std::abs(frame.positions[i * 4 + 1]) < 1e-4f;
    double pixel = 2.0 / size;
    double area = double(shadowed) * pixel * pixel * std::sqrt(5.0); // see shadow_area_test.cpp for the geometry
    EXPECT_NEAR(area, 1.0, 0.01);
    EXPECT_GT(oracle.raysTraced(), 100000u);
}

TEST(Oracle, AgreesWithTheShadowMapAwayFromEdges)
{
    Mesh mesh = test::cubeOverFloor(0.0f);
    Camera camera;
    camera.position = {6, 8, 9};
    camera.target = {0, 1, 0};
    Light sun;
    sun.direction = {-0.3f, -1.0f, -0.2f};
    Frame frame = renderGBuffer(mesh, camera, sun, 256);
    std::vector<float> visibility = EmbreeOracle(mesh).hardShadowVisibility(frame.positions, frame.normals, sun);
    test::Comparison a = test::compareVisibility(visibility, frame.visibility);
    EXPECT_GT(a.compared, 20000u);
    EXPECT_LT(a.fraction(), 0.005) << a.differing << " of " << a.compared;
}

TEST(Oracle, SeesTheThinGeometryTheShadowMapMisses)
{
    GenerateOptions options;
    options.triangles = 150'000;
    Scene city = generateScene("city", options);
    Frame frame = renderGBuffer(city.mesh, city.cameras.at(0), city.lights.at(0), 384);
    std::vector<float> visibility = EmbreeOracle(city.mesh).hardShadowVisibility(frame.positions, frame.normals, city.lights[0]);
    test::Comparison a = test::compareVisibility(visibility, frame.visibility);
    size_t missedShadow = a.missedShadow;
    std::printf("city: shadow map differs from the oracle on %zu of %zu pixels, %zu of them lit where the oracle sees shadow\n",
                a.differing, a.compared, missedShadow);
    EXPECT_LT(a.fraction(), 0.05);   // mostly right ...
    EXPECT_GT(missedShadow, 0u);     // ... but it does miss shadows (thin poles, wires, railings)
}

} // namespace
} // namespace penumbra
