// Hard-shadow methods against each other and against the Embree oracle
// (Lauterbach et al. 2009, 3.1): frt agrees with the oracle, srt with frt, and
// a scene of thin wires shows what plain shadow mapping misses.
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include <glm/trigonometric.hpp>

#include "penumbra/generate.h"
#include "penumbra/oracle.h"
#include "penumbra/penumbra.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

Frame renderMethod(const Mesh& mesh, const Camera& camera, const Light& light, ShadowMethod method, uint32_t size)
{
    return test::renderWithGBuffer(mesh, camera, light, method, size);
}

using test::Comparison;

Comparison compare(const std::vector<float>& reference, const std::vector<float>& other)
{
    return test::compareVisibility(reference, other);
}



TEST(HardShadows, FullRayTracingAgreesWithTheOracle)
{
    struct Case {
        const char* scene;
        uint64_t triangles;
    } cases[] = {{"city", 60'000}, {"interior", 60'000}, {"plant", 60'000}};
    for (const Case& c : cases) {
        GenerateOptions options;
        options.triangles = c.triangles;
        Scene scene = generateScene(c.scene, options);
        const CompressedModel model = buildCompressedModel(scene.mesh, PreprocessOptions{});
        Frame frt = test::renderWithGBuffer(model, scene.cameras[0], scene.lights[0], ShadowMethod::FullRayTrace, 256);
        OracleOptions oracleOptions;
        oracleOptions.originOffset = frt.stats.rayOffset;
        std::vector<float> oracle = EmbreeOracle(scene.mesh).hardShadowVisibility(frt.positions, frt.normals, scene.lights[0], oracleOptions);
        std::vector<float> decoded = EmbreeOracle(decodeMesh(model)).hardShadowVisibility(frt.positions, frt.normals, scene.lights[0], oracleOptions);
        Comparison cmp = compare(oracle, frt.visibility), exact = compare(decoded, frt.visibility);
        std::printf("%s: frt differs from the oracle on %zu of %zu pixels, on the decoded mesh on %zu\n", c.scene, cmp.differing, cmp.compared,
                    exact.differing);
        EXPECT_GT(cmp.compared, 10000u) << c.scene;
        EXPECT_LE(cmp.fraction(), test::sourceMeshBound(c.scene)) << c.scene << ": frt differs from the oracle on " << cmp.differing << " of " << cmp.compared;
        EXPECT_LE(exact.fraction(), test::kDecodedMeshBound)
            << c.scene << ": frt differs from the decoded-mesh oracle on " << exact.differing << " of " << exact.compared;
        EXPECT_GT(frt.stats.rays, 0u);
        EXPECT_GT(frt.stats.nodesVisited, frt.stats.rays);
    }
}

TEST(HardShadows, SelectiveMatchesFullRayTracingAndShadowMapMissesWires)
{
    Mesh mesh = test::wiresOverGround();
    Camera camera;
    camera.position = {0, 12, 16};
    camera.target = {0, 0, 0};
    camera.yfovDegrees = 55;
    Light sun;
    sun.direction = {0.15f, -1.0f, 0.1f};
    Frame sm = renderMethod(mesh, camera, sun, ShadowMethod::ShadowMap, 384);
    Frame srt = renderMethod(mesh, camera, sun, ShadowMethod::Selective, 384);
    Frame frt = renderMethod(mesh, camera, sun, ShadowMethod::FullRayTrace, 384);

    OracleOptions oracleOptions;
    oracleOptions.originOffset = frt.stats.rayOffset;
    std::vector<float> oracle = EmbreeOracle(mesh).hardShadowVisibility(frt.positions, frt.normals, sun, oracleOptions);
    Comparison frtVsOracle = compare(oracle, frt.visibility);
    Comparison smVsOracle = compare(oracle, sm.visibility);
    Comparison srtVsFrt = compare(test::lightFacingOnly(frt.visibility, frt.positions, frt.normals, sun), srt.visibility);
    std::printf("wires: sm misses %zu shadowed pixels; srt differs from frt on %zu of %zu; PIP %.2f%%\n", smVsOracle.missedShadow,
                srtVsFrt.differing, srtVsFrt.compared, srt.stats.pipFraction * 100.0);
    EXPECT_LE(frtVsOracle.fraction(), 1e-4) << frtVsOracle.differing;
    EXPECT_GT(smVsOracle.missedShadow, 200u) << "the shadow map should visibly miss the wires";
    EXPECT_LE(srtVsFrt.fraction(), 5e-4) << srtVsFrt.differing << " of " << srtVsFrt.compared;
    EXPECT_LT(srt.stats.pipFraction, 0.5);
    EXPECT_LT(srt.stats.rays, frt.stats.rays);
}

TEST(HardShadows, SelectiveMatchesFullRayTracingOnProceduralScenes)
{
    for (const char* name : {"city", "interior"}) {
        GenerateOptions options;
        options.triangles = 60'000;
        Scene scene = generateScene(name, options);
        Frame srt = renderMethod(scene.mesh, scene.cameras[0], scene.lights[0], ShadowMethod::Selective, 256);
        Frame frt = renderMethod(scene.mesh, scene.cameras[0], scene.lights[0], ShadowMethod::FullRayTrace, 256);
        Comparison cmp = compare(test::lightFacingOnly(frt.visibility, frt.positions, frt.normals, scene.lights[0]), srt.visibility);
        std::printf("%s: srt differs from frt on %zu of %zu pixels, PIP %.2f%%\n", name, cmp.differing, cmp.compared,
                    srt.stats.pipFraction * 100.0);
        EXPECT_LE(cmp.fraction(), 5e-4) << name;
    }
}

// A point light's cube map is not fitted to the view: over the city a light a
// quarter of the height above the centre has a depth range of about 400
// model units, so the range threshold alone (0.8 units) let the kerbs',
// ledges' and windows' steps go unmarked (srt differed from frt on 0.14% of
// the 250 k city's light-facing pixels at 640^2, and marked 0.17%). Steps
// above a texel's footprint in a neighbourhood that is no plane are marked too
// (shadow_common.glsli: depthDiscontinuityNear). At 120 k triangles and 384^2
// srt differed from frt on 90 pixels of the city (8.9e-4) and 47 of the
// interior (4.6e-4) before, 3 and 30 with the rule (most of the interior's
// rest lie where the 3x3 texels are flat: no step for either test to see).
TEST(HardShadows, SelectiveMatchesFullRayTracingForAPointLightAmongTheGeometry)
{
    const struct {
        const char* name;
        double bound;
    } cases[] = {{"city", 2e-4}, {"interior", 4e-4}};
    for (const auto& [name, bound] : cases) {
        GenerateOptions options;
        options.triangles = 120'000;
        Scene scene = generateScene(name, options);
        const Light point = test::pointLightAmong(computeBounds(scene.mesh), 0.25f);
        Frame srt = renderMethod(scene.mesh, scene.cameras[0], point, ShadowMethod::Selective, 384);
        Frame frt = renderMethod(scene.mesh, scene.cameras[0], point, ShadowMethod::FullRayTrace, 384);
        Comparison cmp = compare(test::lightFacingOnly(frt.visibility, frt.positions, frt.normals, point), srt.visibility);
        std::printf("%s, point light: srt differs from frt on %zu of %zu pixels, PIP %.2f%%\n", name, cmp.differing, cmp.compared,
                    srt.stats.pipFraction * 100.0);
        EXPECT_GT(cmp.compared, 50'000u) << name;
        EXPECT_LE(cmp.fraction(), bound) << name << ": " << cmp.differing << " of " << cmp.compared;
    }
}

// A light among the geometry had its maps' near plane at far / 10^4 (the
// model's box holds the light), so their 32-bit z/w depths kept about 2 cm
// of precision 30 units away, less than the depth bias of one step: a floor
// facing a spot light shadowed itself in speckles (acne) on 4% of its pixels,
// in sm and srt alike (srt marks no pixel of a smooth surface). The near plane
// now goes up to the nearest triangle (light_space.h: lightProjection), and
// srt also marks a pixel the map shadows from a depth its own surface reaches
// within the texel (classify.comp.glsl).
TEST(HardShadows, ASpotLightAmongTheGeometryCastsNoAcne)
{
    Mesh mesh;
    test::addBox(mesh, {-40, -0.1f, -40}, {40, 0, 40});
    test::addBox(mesh, {-3, 0, -3}, {3, 6, 3});
    test::addBox(mesh, {34, 0, 34}, {35, 40, 35}); // a pole: the model's box then holds the light
    Camera camera;
    camera.position = {0, 45, 40};
    camera.target = {0, 0, 0};
    Light spot;
    spot.type = LightType::Spot;
    spot.position = {0, 30, 0};
    spot.direction = {0.1f, -1.0f, 0.15f};
    spot.outerConeDegrees = 50.0f;
    spot.innerConeDegrees = 40.0f;
    spot.intensity = 1000.0f;
    Frame frt = renderMethod(mesh, camera, spot, ShadowMethod::FullRayTrace, 384);
    std::vector<float> reference = test::lightFacingOnly(frt.visibility, frt.positions, frt.normals, spot);
    // Outside the cone the map reads nothing (lit) while frt traces every light-facing pixel: left out.
    const float outerCos = std::cos(glm::radians(spot.outerConeDegrees - 0.5f));
    for (size_t i = 0; i < reference.size(); ++i) {
        const glm::vec3 p(frt.positions[4 * i], frt.positions[4 * i + 1], frt.positions[4 * i + 2]);
        if (reference[i] >= 0.0f && glm::dot(glm::normalize(p - spot.position), glm::normalize(spot.direction)) < outerCos)
            reference[i] = -2.0f;
    }
    for (ShadowMethod method : {ShadowMethod::ShadowMap, ShadowMethod::Selective}) {
        Frame frame = renderMethod(mesh, camera, spot, method, 384);
        Comparison cmp = compare(reference, frame.visibility);
        std::printf("spot among the geometry: %s differs from frt on %zu of %zu pixels\n", shadowMethodName(method), cmp.differing,
                    cmp.compared);
        EXPECT_GT(cmp.compared, 20'000u);
        EXPECT_LE(cmp.fraction(), 5e-4) << shadowMethodName(method) << ": " << cmp.differing << " of " << cmp.compared;
    }
}

// The 2 M scan's well-shaped triangles are a texel or two across in the sun's map fitted to the view:
// some are longer than PENUMBRA_THIN_TEXELS and under it high, but neither they nor the edge-on ones
// are long and narrow (PENUMBRA_THIN_ASPECT), so they are no slivers: the thin pass marked 27.8% of
// the pixels for rays before that rule (as at 1024^2), the discontinuity test alone about 7%. The
// image must still match frt's, and the wires of the test above must still be found.
TEST(HardShadows, WellShapedTrianglesOfADenseSurfaceAreNoSlivers)
{
    GenerateOptions options;
    options.triangles = 2'000'000;
    Scene scene = generateScene("scan", options);
    const CompressedModel model = buildCompressedModel(scene.mesh, PreprocessOptions{});
    Frame srt = test::renderWithGBuffer(model, scene.cameras[0], scene.lights[0], ShadowMethod::Selective, 256);
    Frame frt = test::renderWithGBuffer(model, scene.cameras[0], scene.lights[0], ShadowMethod::FullRayTrace, 256);
    Comparison cmp = compare(test::lightFacingOnly(frt.visibility, frt.positions, frt.normals, scene.lights[0]), srt.visibility);
    std::printf("scan 2M: srt differs from frt on %zu of %zu pixels, PIP %.2f%%\n", cmp.differing, cmp.compared,
                srt.stats.pipFraction * 100.0);
    EXPECT_GT(cmp.compared, 10000u);
    EXPECT_LE(cmp.fraction(), 5e-4) << cmp.differing << " of " << cmp.compared;
    EXPECT_LT(srt.stats.pipFraction, 0.2);
}

// The thin-triangle pass keeps the rectangles of its first listed runs for the fill, up to a capacity
// (PENUMBRA_THIN_RECTS_MAX, within RendererOptions::maxModelBufferBytes); the later runs are decoded
// again from the model, walking the strip bytes from a run's first sliver to its last (restarts,
// degenerate and wider triangles between them). With model buffers of 32 KiB (1,024 rectangles,
// against about 5,300 runs of this city's sun view when the test was written; runs across a leaf's
// strips list about a quarter fewer on the suite's 250 k city) the fill takes both paths, and the
// frame must equal the one whose every run kept its rectangle.
TEST(HardShadows, ThinRunsBeyondTheKeptRectanglesAreDecodedAgain)
{
    GenerateOptions generate;
    generate.triangles = 60'000;
    Scene scene = generateScene("city", generate);
    RenderSettings settings;
    settings.width = settings.height = 256;
    settings.shadows = ShadowMethod::Selective;
    Frame frames[2];
    for (int small = 0; small < 2; ++small) {
        RendererOptions options;
        options.maxModelBufferBytes = small ? 32 * 1024 : 0;
        Renderer renderer(options);
        renderer.loadModel(scene.mesh);
        renderer.setCamera(scene.cameras.at(0));
        renderer.setLights({scene.lights.at(0)});
        frames[small] = renderer.render(settings);
    }
    EXPECT_GT(frames[0].stats.rays, 500u);
    EXPECT_EQ(frames[0].stats.rays, frames[1].stats.rays);
    ASSERT_EQ(frames[0].visibility.size(), frames[1].visibility.size());
    size_t differing = 0;
    for (size_t i = 0; i < frames[0].visibility.size(); ++i)
        differing += frames[0].visibility[i] != frames[1].visibility[i] ? 1 : 0;
    EXPECT_EQ(differing, 0u);
}

TEST(HardShadows, DebugImageMarksTracedPixelsRed)
{
    Mesh mesh = test::wiresOverGround();
    Renderer renderer;
    renderer.loadModel(mesh);
    RenderSettings settings;
    settings.width = settings.height = 128;
    settings.shadows = ShadowMethod::Selective;
    settings.debugPip = true;
    Frame frame = renderer.render(settings);
    // Surfaces are grey under white light (red == green), so a tinted pixel is one whose red exceeds its green.
    size_t red = 0;
    for (size_t i = 0; i < frame.color.rgba.size(); i += 4)
        red += frame.color.rgba[i] > frame.color.rgba[i + 1] + 0.2f;
    EXPECT_GT(red, 0u);
    EXPECT_EQ(red, frame.stats.pipPixels);
    EXPECT_EQ(frame.stats.rays, frame.stats.pipPixels);
}

} // namespace
} // namespace penumbra

namespace penumbra {
namespace {

TEST(HardShadows, SeveralLightsTraceEachLightIndependently)
{
    GenerateOptions options;
    options.triangles = 40'000;
    Scene scene = generateScene("city", options);
    Light point;
    point.type = LightType::Point;
    point.position = glm::vec3(10.0f, 300.0f, 10.0f); // above the rooftops
    point.intensity = 50000.0f;
    for (ShadowMethod method : {ShadowMethod::Selective, ShadowMethod::FullRayTrace}) {
        Renderer renderer;
        renderer.loadModel(scene.mesh);
        renderer.setCamera(scene.cameras[0]);
        RenderSettings settings;
        settings.width = settings.height = 192;
        settings.shadows = method;
        settings.readbackGBuffer = true;
        renderer.setLights({scene.lights[0]});
        Frame alone = renderer.render(settings);
        renderer.setLights({scene.lights[0], point, point});
        Frame together = renderer.render(settings);
        // The visibility readback is light 0's: the other lights' passes must not disturb it.
        EXPECT_EQ(alone.visibility, together.visibility) << shadowMethodName(method);
        EXPECT_GT(together.stats.rays, alone.stats.rays);
        EXPECT_EQ(renderer.validationMessageCount(), 0u);
    }
}

} // namespace
} // namespace penumbra
