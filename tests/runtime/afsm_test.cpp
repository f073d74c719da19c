// Alias-free shadow maps (Sintorn et al. 2008, section 3): hard shadows
// exact by construction, so against the Embree oracle on the suite's scenes,
// a point light among the geometry and thin wires, at most 0.01% of the
// light-facing pixels may differ (rounding at triangle edges).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <string>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>
#include <gtest/gtest.h>

#include "penumbra/generate.h"
#include "penumbra/preprocess.h"
#include "penumbra/oracle.h"
#include "penumbra/penumbra.h"
#include "passes/afsm.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

struct Result {
    test::Comparison afsm, srt;
    test::Comparison afsmDecoded; // against the oracle on the triangles the GPU draws (decodeMesh)
};

// afsm and srt against the oracle on afsm's G-buffer; only the pixels whose
// point `compared` accepts (all when empty).
// model: the mesh preprocessed (default: with default options).
Result compareWithOracle(const Mesh& mesh, const Camera& camera, const Light& light, uint32_t size,
                         const std::function<bool(glm::vec3)>& compared = {}, const CompressedModel* model = nullptr,
                         Frame* afsmFrame = nullptr)
{
    // The model the renderer draws, and whose decoded triangles the second oracle takes (loadModel(mesh) builds the same).
    const CompressedModel built = model ? CompressedModel{} : buildCompressedModel(mesh, PreprocessOptions{});
    const CompressedModel& drawn = model ? *model : built;
    Renderer renderer;
    renderer.loadModel(drawn);
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
    const Mesh decodedMesh = decodeMesh(drawn);
    std::vector<float> decoded = EmbreeOracle(decodedMesh).hardShadowVisibility(afsm.positions, afsm.normals, light, options);
    for (size_t i = 0; i < oracle.size(); ++i)
        if (oracle[i] < 0.0f)
            decoded[i] = -1.0f;
    Result result{test::compareVisibility(oracle, afsm.visibility), test::compareVisibility(oracle, srt.visibility),
                  test::compareVisibility(decoded, afsm.visibility)};
    std::printf("afsm: %zu of %zu light-facing pixels differ from the oracle (srt: %zu; afsm on the decoded mesh: %zu)\n", result.afsm.differing,
                result.afsm.compared, result.srt.differing, result.afsmDecoded.differing);
    bool casters = false;
    for (const PassTiming& pass : afsm.stats.passes)
        casters |= pass.name == "afsm_casters";
    EXPECT_TRUE(casters) << "afsm ran without its casters pass";
    if (afsmFrame)
        *afsmFrame = std::move(afsm);
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
        EXPECT_LE(r.afsm.fraction(), test::sourceMeshBound(name))
            << name << ": afsm differs from the oracle on " << r.afsm.differing << " of " << r.afsm.compared << " (srt: " << r.srt.differing << ")";
        EXPECT_LE(r.afsmDecoded.fraction(), test::kDecodedMeshBound)
            << name << ": afsm differs from the decoded-mesh oracle on " << r.afsmDecoded.differing << " of " << r.afsmDecoded.compared;
        EXPECT_LE(r.afsm.differing, r.srt.differing) << name;
    }
}

// The hard casters the compute path leaves are tested a grid row at a time
// (afsm_wide.comp); the clusters it cannot finish (its list full, or a caster
// past its loop budget) are left to the raster path, which then draws only
// theirs. Every route gives the same image, bit for bit: the row pass on its
// own, the raster path on its own (PENUMBRA_AFSM_WIDE=0), and the two
// together (a list of 64 casters; a budget of 12 iterations a caster). So do
// the two passes of a directional light's casters (the nearest first, then
// the rest with the cells' depths counted again over the samples still lit,
// rows trimmed to them): off, and forced on with a split at mid-depth and a
// refresh whatever the first pass shadowed (with the list full, too).
TEST(AliasFreeShadowMaps, RowPassAndRasterPathGiveTheSameImage)
{
    for (const char* name : {"interior", "city"}) {
        GenerateOptions options;
        options.triangles = 60'000;
        const Scene scene = generateScene(name, options);
        const CompressedModel model = buildCompressedModel(scene.mesh, PreprocessOptions{});
        auto render = [&](std::vector<std::pair<const char*, const char*>> variables) {
            for (const auto& [variable, value] : variables)
                setenv(variable, value, 1); // read when the renderer is made
            Renderer renderer;
            for (const auto& [variable, value] : variables)
                unsetenv(variable);
            renderer.loadModel(model);
            renderer.setCamera(scene.cameras[0]);
            renderer.setLights({scene.lights[0]});
            RenderSettings settings;
            settings.width = settings.height = 256;
            settings.shadows = ShadowMethod::AliasFree;
            Frame frame = renderer.render(settings);
            EXPECT_EQ(renderer.validationMessageCount(), 0u);
            return frame;
        };
        const Frame rows = render({{"PENUMBRA_AFSM_TWO_PASS", "0"}});
        const Frame raster = render({{"PENUMBRA_AFSM_WIDE", "0"}});
        const Frame full = render({{"PENUMBRA_AFSM_WIDE_CAPACITY", "64"}, {"PENUMBRA_AFSM_TWO_PASS", "0"}});
        const Frame budget = render({{"PENUMBRA_AFSM_WIDE_ITERATIONS", "12"}, {"PENUMBRA_AFSM_TWO_PASS", "0"}});
        const std::pair<const char*, const char*> split{"PENUMBRA_AFSM_NEAR_DEPTH", "0.5"}, always{"PENUMBRA_AFSM_REFRESH_SHARE", "0"};
        const Frame twoPass = render({split, always});
        const Frame twoPassFull = render({split, always, {"PENUMBRA_AFSM_WIDE_CAPACITY", "64"}});
        const Frame byDefault = render({});
        std::printf("[ afsm     ] %s: %u casters row by row, %u with the raster path off\n", name, rows.stats.afsmWideCasters,
                    raster.stats.afsmWideCasters);
        EXPECT_GT(rows.stats.afsmWideCasters, 0u) << name;
        EXPECT_EQ(rows.stats.afsmWideRasterLayers, 0u) << name;
        EXPECT_EQ(raster.stats.afsmWideCasters, 0u) << name;
        EXPECT_EQ(full.stats.afsmWideRasterLayers, 1u) << name;
        EXPECT_EQ(budget.stats.afsmWideRasterLayers, 1u) << name;
        EXPECT_EQ(rows.stats.afsmTwoPassLayers, 0u) << name;
        EXPECT_EQ(twoPass.stats.afsmTwoPassLayers, 1u) << name;
        EXPECT_EQ(twoPass.stats.afsmRefreshedLayers, 1u) << name;
        EXPECT_GE(twoPassFull.stats.afsmWideRasterLayers, 1u) << name;
        std::printf("[ afsm     ] %s: by default %u layer(s) in two passes, %u refreshed\n", name, byDefault.stats.afsmTwoPassLayers,
                    byDefault.stats.afsmRefreshedLayers);
        const std::pair<const Frame*, const char*> others[] = {{&raster, "raster path alone"}, {&full, "list full"}, {&budget, "loop budget"},
                                                               {&twoPass, "two passes"},       {&twoPassFull, "two passes, list full"},
                                                               {&byDefault, "default"}};
        for (const auto& [other, what] : others) {
            ASSERT_EQ(other->visibility.size(), rows.visibility.size());
            size_t differing = 0;
            for (size_t i = 0; i < rows.visibility.size(); ++i)
                differing += rows.visibility[i] != other->visibility[i];
            EXPECT_EQ(differing, 0u) << name << ": " << what;
        }
    }
}

// Scenes built with PreprocessOptions::separateClosed, so that their closed
// parts get clusters of their own; a part is flagged kClusterClosed (and casts
// only its light-back-facing triangles, section 3.3) unless another surface
// comes within the shadow rays' offset of it (crowdedComponents): a ray
// starting on that surface could start inside the part and see none of its
// back faces. Against the oracle on the source mesh, every triangle casting.
// Every closed part of the suite scenes touches another surface (buildings
// and furniture stand on floors, beams and pipes meet, the statue crosses its
// ground), so none is flagged there; before the rule, 12 (city) and 10
// (plant) pixels differed: samples on a wall inside the footprint of a fin
// flush with it (depth resolution) and on the ground under a slab, their
// origins inside the part. Without the camera pass's outside-only rule
// (gbuffer.frag.outside) the far sides of thin parts would show. The
// thin-wire scene's wires float free: they stay flagged and cast back faces;
// the three that cross the central box and the box on the ground are not.
TEST(AliasFreeShadowMaps, ClosedPartsCastBackFacesAndMatchTheOracle)
{
    struct Case {
        std::string name;
        Mesh mesh;
        Camera camera;
        Light light;
        uint32_t size;
        bool flagged;
    };
    std::vector<Case> cases;
    for (const char* name : {"city", "interior", "plant", "scan"}) {
        GenerateOptions options;
        options.triangles = 60'000;
        Scene scene = generateScene(name, options);
        cases.push_back({name, std::move(scene.mesh), scene.cameras[0], scene.lights[0], 256, false});
    }
    Camera wireCamera;
    wireCamera.position = {0, 12, 16};
    wireCamera.target = {0, 0, 0};
    Light sun;
    sun.direction = glm::normalize(glm::vec3(0.3f, -1.0f, 0.2f));
    cases.push_back({"thin wires", test::wiresOverGround(), wireCamera, sun, 512, true});
    Camera cubeCamera;
    cubeCamera.position = {5.0f, 6.0f, 7.0f};
    cubeCamera.target = {0.0f, 1.0f, 0.0f};
    cases.push_back({"cube over a floor", test::cubeOverFloor(0.5f), cubeCamera, sun, 256, true});
    for (const Case& c : cases) {
        PreprocessOptions build;
        build.separateClosed = true;
        const CompressedModel model = buildCompressedModel(c.mesh, build);
        uint64_t flagged = 0;
        for (const model::ClusterRecord& cluster : model.clusters)
            flagged += (cluster.flags & model::kClusterClosed) ? 1 : 0;
        Frame frame;
        Result r = compareWithOracle(c.mesh, c.camera, c.light, c.size, {}, &model, &frame);
        std::printf("%s, closed parts separated: %llu of %zu clusters closed, casting %s\n", c.name.c_str(), (unsigned long long)flagged,
                    model.clusters.size(), frame.stats.afsmClosedCasting.c_str());
        EXPECT_EQ(frame.stats.afsmClosedClusters, flagged) << c.name;
        if (c.flagged) {
            EXPECT_GT(flagged, 0u) << c.name;
            EXPECT_EQ(frame.stats.afsmClosedCasting, "back faces") << c.name;
        }
        EXPECT_GT(r.afsm.compared, 5000u) << c.name;
        EXPECT_LE(r.afsm.fraction(), test::sourceMeshBound(c.name))
            << c.name << ": afsm differs from the oracle on " << r.afsm.differing << " of " << r.afsm.compared;
        EXPECT_LE(r.afsmDecoded.fraction(), test::kDecodedMeshBound)
            << c.name << ": afsm differs from the decoded-mesh oracle on " << r.afsmDecoded.differing << " of " << r.afsmDecoded.compared;
    }
}

// The compute path (afsm_bin.comp) decodes up to 4 leaves per invocation and
// bins each triangle with a bounded amount of work; lavapipe silently ends an
// invocation's loops after 65535 iterations, so a model built with large
// leaves would lose casters there. The frame keeps the compute path only when
// the bound (passes::afsmBinIterations) fits: on with the default leaves, off
// with 64-triangle leaves, whose frame (every caster rasterized) still matches
// the oracle.
TEST(AliasFreeShadowMaps, LargeLeavesTurnTheComputePathOff)
{
    EXPECT_LE(passes::afsmBinIterations(PreprocessOptions{}.maxLeafTriangles, 4 * PreprocessOptions{}.maxLeafTriangles),
              uint64_t(PENUMBRA_AFSM_FRAGMENT_ITERATIONS));
    EXPECT_GT(passes::afsmBinIterations(64, 128), 65535u);
    GenerateOptions options;
    options.triangles = 60'000;
    Scene scene = generateScene("scan", options);
    for (uint32_t leaf : {PreprocessOptions{}.maxLeafTriangles, 64u}) {
        PreprocessOptions build;
        build.maxLeafTriangles = leaf;
        const CompressedModel model = buildCompressedModel(scene.mesh, build);
        Frame frame;
        Result r = compareWithOracle(scene.mesh, scene.cameras[0], scene.lights[0], 256, {}, &model, &frame);
        EXPECT_EQ(frame.stats.afsmComputePath, leaf != 64u) << leaf << "-triangle leaves";
        EXPECT_GT(r.afsm.compared, 5000u);
        EXPECT_LE(r.afsm.fraction(), 1e-4) << leaf << "-triangle leaves: afsm differs from the oracle on " << r.afsm.differing << " of "
                                           << r.afsm.compared;
    }
}

// A ray offset above the default voids the preprocessor's clearance (a ray could
// start inside a flagged solid): the frame casts both sides of closed clusters.
TEST(AliasFreeShadowMaps, LargerRayOffsetCastsBothSides)
{
    const Mesh mesh = test::cubeOverFloor(0.5f);
    PreprocessOptions build;
    build.separateClosed = true;
    Renderer renderer;
    renderer.loadModel(buildCompressedModel(mesh, build));
    Camera camera;
    camera.position = {5.0f, 6.0f, 7.0f};
    camera.target = {0.0f, 1.0f, 0.0f};
    renderer.setCamera(camera);
    RenderSettings settings;
    settings.width = settings.height = 64;
    settings.shadows = ShadowMethod::AliasFree;
    const Frame standard = renderer.render(settings);
    EXPECT_EQ(standard.stats.afsmClosedCasting, "back faces");
    settings.rayOffset = 2.0f * standard.stats.rayOffset;
    const Frame larger = renderer.render(settings);
    EXPECT_EQ(larger.stats.afsmClosedCasting, "both sides (ray offset above the default)");
    settings.rayOffset = standard.stats.rayOffset;
    EXPECT_EQ(renderer.render(settings).stats.afsmClosedCasting, "back faces");
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
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

// ---------------------------------------------------------------------------
// Soft shadows (section 4): rectangle, disk and sphere lights as srt and frt
// have them, against frt and the oracle with the same number of samples, and
// against the oracle tracing the table's own samples.

struct SoftCase {
    const char* name;
    Mesh mesh;
    Camera camera;
    Light light;
};

Light rectangleLight(glm::vec3 position, float width, float height)
{
    Light light;
    light.type = LightType::Rectangle;
    light.position = position;
    light.direction = {0.1f, -1.0f, 0.05f};
    light.up = {0, 0, 1};
    light.width = width;
    light.height = height;
    light.intensity = 40.0f;
    return light;
}

// The soft-shadow test's scenes (soft_shadow_test.cpp): a cube over a floor
// under each light shape, and a city under a rectangle light.
std::vector<SoftCase> softCases()
{
    std::vector<SoftCase> cases;
    Camera camera;
    camera.position = {5.0f, 6.0f, 7.0f};
    camera.target = {0.0f, 1.0f, 0.0f};
    cases.push_back({"cube, rectangle light", test::cubeOverFloor(0.5f), camera, rectangleLight({0.5f, 7.0f, 0.3f}, 2.0f, 1.0f)});
    Light disk = rectangleLight({-1.0f, 6.0f, 0.5f}, 1.0f, 1.0f);
    disk.type = LightType::Disk;
    disk.radius = 0.8f;
    cases.push_back({"cube, disk light", test::cubeOverFloor(0.3f), camera, disk});
    Light sphere;
    sphere.type = LightType::Sphere;
    sphere.position = {1.5f, 6.5f, -1.0f};
    sphere.radius = 0.6f;
    sphere.intensity = 40.0f;
    cases.push_back({"cube, sphere light", test::cubeOverFloor(0.7f), camera, sphere});
    GenerateOptions options;
    options.triangles = 10'000;
    Scene city = generateScene("city", options);
    Bounds b = computeBounds(city.mesh);
    Light cityLight = rectangleLight(b.center() + glm::vec3(0.2f, 0.9f, 0.1f) * glm::length(b.extent()), 8.0f, 4.0f);
    cases.push_back({"city, rectangle light", std::move(city.mesh), defaultCamera(b), cityLight});
    return cases;
}

Frame renderSoft(Renderer& renderer, ShadowMethod method, uint32_t size, uint32_t samples)
{
    RenderSettings settings;
    settings.width = settings.height = size;
    settings.shadows = method;
    settings.lightSamples = samples;
    settings.readbackGBuffer = true;
    Frame frame = renderer.render(settings);
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
    return frame;
}

// Visibility differences over the pixels the reference covers (values < 0
// other than the background count as 0); samples: per pixel, the difference
// in light samples.
struct SoftComparison {
    size_t compared = 0, over = 0;
    double sumAbs = 0;
    std::vector<double> samplesOff;
    double meanAbs() const { return compared ? sumAbs / double(compared) : 1.0; }
    double overFraction() const { return compared ? double(over) / double(compared) : 1.0; }
    // The q-quantile of samplesOff.
    double quantile(double q)
    {
        if (samplesOff.empty())
            return 0.0;
        std::sort(samplesOff.begin(), samplesOff.end());
        return samplesOff[std::min(samplesOff.size() - 1, size_t(q * double(samplesOff.size())))];
    }
};

SoftComparison compareSoft(const std::vector<float>& reference, const std::vector<float>& other, float threshold, uint32_t samples)
{
    SoftComparison c;
    for (size_t i = 0; i < reference.size(); ++i) {
        if (reference[i] == -1.0f)
            continue;
        const double d = std::abs(double(std::max(reference[i], 0.0f)) - double(std::max(other[i], 0.0f)));
        ++c.compared;
        c.sumAbs += d;
        c.over += d > threshold;
        c.samplesOff.push_back(std::round(d * samples));
    }
    return c;
}

// The acceptance: against frt with 256 samples on the same light, at
// most 1% of the pixels off by more than 1/16 and mean |dv| <= 0.005 (the two
// sample sets differ: frt's are stratified per pixel, afsm's are the table's,
// turned per pixel), and to the same bounds against the Embree oracle. frt
// itself must match the oracle tracing its own stratified samples: on
// lavapipe a shader invocation ends its loops after 65535 iterations in all
// (llvmpipe's LP_MAX_TGSI_LOOP_ITERATIONS), which cut frt's 256 rays per pixel
// short on the city (frt 0.12 mean |dv| from the oracle, darker where rays
// were cut) until the tracer took an area light's samples in dispatches of
// PENUMBRA_TRACE_SAMPLES_PER_DISPATCH (now 0.00002).
TEST(AliasFreeShadowMaps, SoftShadowsAgreeWithFullRayTracing)
{
    const uint32_t samples = 256;
    for (SoftCase& c : softCases()) {
        SCOPED_TRACE(c.name);
        Renderer renderer;
        renderer.loadModel(c.mesh);
        renderer.setCamera(c.camera);
        renderer.setLights({c.light});
        Frame afsm = renderSoft(renderer, ShadowMethod::AliasFree, 256, samples);
        Frame frt = renderSoft(renderer, ShadowMethod::FullRayTrace, 256, samples);
        EXPECT_GT(frt.stats.penumbraPixels, 100u);
        EXPECT_EQ(afsm.stats.lightSamples, samples);
        OracleOptions options;
        options.originOffset = afsm.stats.rayOffset;
        const std::vector<float> oracle = EmbreeOracle(c.mesh).softShadowVisibility(afsm.positions, afsm.normals, 256, c.light, 0, samples, options);
        SoftComparison toOracle = compareSoft(oracle, afsm.visibility, 1.0f / 16.0f, samples);
        SoftComparison toFrt = compareSoft(frt.visibility, afsm.visibility, 1.0f / 16.0f, samples);
        SoftComparison frtToOracle = compareSoft(oracle, frt.visibility, 1.0f / 16.0f, samples);
        std::printf("%s: afsm vs frt (%u samples) mean |dv| %.5f, %.4f%% off by > 1/16; vs the oracle %.5f, %.4f%%; frt vs the oracle %.5f\n",
                    c.name, samples, toFrt.meanAbs(), toFrt.overFraction() * 100.0, toOracle.meanAbs(), toOracle.overFraction() * 100.0,
                    frtToOracle.meanAbs());
        EXPECT_GT(toOracle.compared, 10'000u);
        EXPECT_LE(toOracle.overFraction(), 0.01);
        EXPECT_LE(toOracle.meanAbs(), 0.005);
        EXPECT_LE(frtToOracle.meanAbs(), 0.001) << "frt's 256 rays a pixel, against the oracle on the same samples";
        EXPECT_LE(toFrt.overFraction(), 0.01);
        EXPECT_LE(toFrt.meanAbs(), 0.005);
    }
}

// The model as the renderer draws it: its compressed form decoded (16-bit
// quantized vertices), so that the oracle sees the same triangles.
Mesh asRendered(const Mesh& mesh)
{
    return decodeMesh(buildCompressedModel(mesh, PreprocessOptions{}));
}

// Against the oracle tracing exactly the table's samples (OracleOptions::
// afsmSamples) on the triangles afsm draws (the quantized model: on the source
// triangles the city's 10 k-triangle clusters, quantized coarsely, move a
// wall enough to change 3 pixels by 9% of their light) only the table's
// discretization is left: a plane's line is
// off by at most delta = AfsmTableSize::lineError (half a step in distance,
// half a step in angle at the light's rim), so only the samples within delta
// of a line can flip. A line crossing the light has about band = n 2 delta
// chord / area of them (chord <= 2 rho; area 4 for the rectangle's square,
// pi for the disk). Bounds asserted: mean |dv| <= 0.0005, and every pixel
// within 2 band + 4 samples (a few lines per pixel, and a point set's uneven
// spread over a thin band: 4.6-4.9 samples of 128, 17-25 of 1024); measured:
// mean |dv| <= 0.00013, at most 2 samples of 128 and 9 of 1024 off.
TEST(AliasFreeShadowMaps, SoftShadowsDifferFromTheOracleOnlyByTheTable)
{
    for (SoftCase& c : softCases()) {
        SCOPED_TRACE(c.name);
        Renderer renderer;
        renderer.loadModel(c.mesh);
        renderer.setCamera(c.camera);
        renderer.setLights({c.light});
        EmbreeOracle oracle(asRendered(c.mesh));
        const bool rectangle = c.light.type == LightType::Rectangle;
        for (uint32_t samples : {128u, 1024u}) {
            Frame afsm = renderSoft(renderer, ShadowMethod::AliasFree, 256, samples);
            OracleOptions options;
            options.originOffset = afsm.stats.rayOffset;
            options.afsmSamples = true;
            std::vector<float> reference = oracle.softShadowVisibility(afsm.positions, afsm.normals, 256, c.light, 0, samples, options);
            SoftComparison diff = compareSoft(reference, afsm.visibility, 1.0f / 16.0f, samples);
            const double delta = passes::afsmTableSize(samples).lineError(rectangle);
            const double band = samples * 2.0 * delta * (rectangle ? 2.0 * std::sqrt(2.0) / 4.0 : 2.0 / 3.14159265);
            const double bound = 2.0 * band + 4.0;
            size_t beyond = 0;
            for (double off : diff.samplesOff)
                beyond += off > bound;
            std::printf("%s, %u samples: afsm vs the oracle on the table's samples: mean |dv| %.6f, %zu of %zu pixels more than %.1f samples "
                        "off (largest %.0f)\n",
                        c.name, samples, diff.meanAbs(), beyond, diff.compared, bound, diff.quantile(1.0));
            EXPECT_GT(diff.compared, 10'000u);
            EXPECT_LE(diff.meanAbs(), 0.0005);
            EXPECT_EQ(beyond, 0u);
        }
    }
}

// An area light low beside the cube: its map from the centre would be wider
// than PENUMBRA_AREA_MAX_HALF_FOV, so afsm's grid is the six faces of a cube
// around it (afsmAreaLayers), each with its own lists and casters.
TEST(AliasFreeShadowMaps, SoftShadowsOfALightAmongTheGeometry)
{
    const Mesh mesh = test::cubeOverFloor(0.4f);
    const Bounds bounds = computeBounds(mesh);
    Light sphere;
    sphere.type = LightType::Sphere;
    sphere.position = {2.5f, 3.5f, 2.5f};
    sphere.radius = 0.3f;
    sphere.intensity = 20.0f;
    bool cube = false;
    EXPECT_EQ(passes::afsmAreaLayers(sphere, bounds, cube).size(), 6u);
    EXPECT_TRUE(cube);
    Camera camera;
    camera.position = {5.0f, 6.0f, 7.0f};
    camera.target = {0.0f, 1.0f, 0.0f};
    Renderer renderer;
    renderer.loadModel(mesh);
    renderer.setCamera(camera);
    renderer.setLights({sphere});
    const uint32_t samples = 128;
    Frame afsm = renderSoft(renderer, ShadowMethod::AliasFree, 256, samples);
    OracleOptions options;
    options.originOffset = afsm.stats.rayOffset;
    options.afsmSamples = true;
    std::vector<float> reference = EmbreeOracle(asRendered(mesh)).softShadowVisibility(afsm.positions, afsm.normals, 256, sphere, 0, samples, options);
    SoftComparison diff = compareSoft(reference, afsm.visibility, 1.0f / 16.0f, samples);
    std::printf("sphere light beside the cube: afsm vs the oracle on the table's samples: mean |dv| %.6f, %.4f%% off by > 1/16, "
                "penumbra %.1f%%\n",
                diff.meanAbs(), diff.overFraction() * 100.0, afsm.stats.penumbraFraction * 100.0);
    EXPECT_GT(diff.compared, 10'000u);
    EXPECT_GT(afsm.stats.penumbraPixels, 100u);
    EXPECT_LE(diff.meanAbs(), 0.001);
    EXPECT_LE(diff.overFraction(), 0.001);
}

// ---------------------------------------------------------------------------
// Closed meshes (section 3.3, "Avoiding bias"): clusters flagged
// kClusterClosed cast only their light-back-facing triangles. Equal to the
// oracle (every triangle) wherever the camera sees from outside every closed
// mesh; a camera inside one (or a near plane that cuts one open) sees points
// whose shadow rays leave it through a front face only, and then the frame
// casts both sides (FrameStats::afsmClosedCasting).

struct ClosedCase {
    Mesh mesh;
    Camera camera;
    Light light;
};

// afsm against the oracle (on the quantized model as drawn), with the closed
// clusters separated (PreprocessOptions::separateClosed); `casting` is what the
// frame reports.
test::Comparison closedAgainstOracle(const ClosedCase& c, std::string& casting, uint64_t& closedClusters)
{
    PreprocessOptions options;
    options.separateClosed = true;
    const CompressedModel model = buildCompressedModel(c.mesh, options);
    Renderer renderer;
    renderer.loadModel(model);
    renderer.setCamera(c.camera);
    renderer.setLights({c.light});
    RenderSettings settings;
    settings.width = settings.height = 256;
    settings.shadows = ShadowMethod::AliasFree;
    settings.readbackGBuffer = true;
    Frame afsm = renderer.render(settings);
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
    casting = afsm.stats.afsmClosedCasting;
    closedClusters = afsm.stats.afsmClosedClusters;
    OracleOptions oracleOptions;
    oracleOptions.originOffset = afsm.stats.rayOffset;
    const std::vector<float> oracle = EmbreeOracle(decodeMesh(model)).hardShadowVisibility(afsm.positions, afsm.normals, c.light, oracleOptions);
    return test::compareVisibility(oracle, afsm.visibility);
}

// Closed boxes (12 outward-facing triangles each; one wound inside out) on an
// open ground, under a sun: outside every box the back faces alone give the
// oracle's shadows.
TEST(AliasFreeShadowMaps, ClosedMeshesCastTheirBackFaces)
{
    ClosedCase c;
    test::addQuad(c.mesh, {-10, 0, -10}, {-10, 0, 10}, {10, 0, 10}, {10, 0, -10}); // open: both sides cast
    for (int i = 0; i < 9; ++i) {
        const float x = -6.0f + 4.0f * float(i % 3), z = -6.0f + 4.0f * float(i / 3);
        test::addBox(c.mesh, {x, 0.5f + 0.3f * float(i), z}, {x + 1.5f, 2.0f + 0.4f * float(i), z + 1.2f});
    }
    // The last box wound inside out: not flagged (negative volume), so it casts both sides.
    const size_t firstIndex = c.mesh.indices.size() - 36;
    for (size_t t = firstIndex; t < c.mesh.indices.size(); t += 3)
        std::swap(c.mesh.indices[t + 1], c.mesh.indices[t + 2]);
    c.camera.position = {14, 12, 16};
    c.camera.target = {0, 1, 0};
    c.light.direction = glm::normalize(glm::vec3(0.4f, -1.0f, 0.3f));
    std::string casting;
    uint64_t closed = 0;
    const test::Comparison r = closedAgainstOracle(c, casting, closed);
    std::printf("closed boxes under a sun: %zu of %zu light-facing pixels differ from the oracle; %llu closed clusters, %s\n", r.differing,
                r.compared, (unsigned long long)closed, casting.c_str());
    EXPECT_GT(closed, 0u);
    EXPECT_EQ(casting, "back faces");
    EXPECT_GT(r.compared, 20'000u);
    EXPECT_LE(r.fraction(), 1e-4);
}

// A camera inside a closed room lit from outside through its walls: every
// shadow ray of what it sees leaves through a front face, so the frame casts
// both sides and the room is dark, as the oracle says; and a camera outside
// whose near plane cuts the room open sees the same inside.
TEST(AliasFreeShadowMaps, ReceiversInsideAClosedMeshAreShadowed)
{
    ClosedCase c;
    test::addBox(c.mesh, {-5, 0, -5}, {5, 4, 5});                 // the room, closed
    test::addBox(c.mesh, {-1, 0.5f, -1}, {1, 2.0f, 1});           // a closed block over its floor (touching it, neither is flagged)
    test::addQuad(c.mesh, {-20, -0.1f, -20}, {-20, -0.1f, 20}, {20, -0.1f, 20}, {20, -0.1f, -20}); // open ground outside
    c.light.type = LightType::Point;
    c.light.position = {2, 12, 3};
    c.light.intensity = 400;
    for (int variant = 0; variant < 2; ++variant) {
        if (variant == 0) {
            c.camera.position = {3.5f, 3.0f, 4.0f}; // inside the room
            c.camera.target = {-2, 0.5f, -2};
        } else {
            c.camera.position = {0.0f, 2.0f, 7.0f}; // outside, 2 units from the wall, near plane 2.5: the wall is cut away
            c.camera.target = {0, 1, 0};
            c.camera.nearPlane = 2.5f;
        }
        std::string casting;
        uint64_t closed = 0;
        const test::Comparison r = closedAgainstOracle(c, casting, closed);
        std::printf("%s: %zu of %zu light-facing pixels differ from the oracle; %llu closed clusters, %s\n",
                    variant == 0 ? "camera inside a closed room" : "near plane cutting a closed room", r.differing, r.compared,
                    (unsigned long long)closed, casting.c_str());
        EXPECT_GT(closed, 0u);
        EXPECT_EQ(casting, "both sides (camera inside a closed mesh)");
        EXPECT_GT(r.compared, 5'000u);
        EXPECT_LE(r.fraction(), 1e-4);
    }
}

TEST(AliasFreeShadowMaps, RejectsBadSettings)
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
    auto expectError = [&](const std::string& expected) {
        try {
            renderer.render(settings);
            ADD_FAILURE() << "afsm accepted " << settings.lightSamples << " light samples at " << settings.width << "x" << settings.height;
        } catch (const Error& e) {
            EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
            std::printf("%s\n", e.what());
            EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
        }
    };
    for (uint32_t samples : {16u, 127u, 1025u}) {
        settings.lightSamples = samples;
        expectError("afsm soft shadows take 128..1024 light samples per pixel (--samples), not " + std::to_string(samples));
    }
    // Masks of 1024 bits for 5000^2 view samples (3.2 GB) exceed one allocation of lavapipe (2 GiB);
    // devices with larger allocations take them.
    if (renderer.device().type == "cpu") {
        settings.lightSamples = 1024;
        settings.width = settings.height = 5000;
        expectError("afsm soft shadows at 5000x5000 with 1024 light samples need 3051 MiB in one buffer");
    }
    // A hard light takes any sample count (afsm has no samples for it).
    settings.width = settings.height = 64;
    settings.lightSamples = 16;
    Light sun;
    sun.direction = {0.3f, -1.0f, 0.2f};
    renderer.setLights({sun});
    EXPECT_NO_THROW(renderer.render(settings));
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
}

} // namespace
} // namespace penumbra
