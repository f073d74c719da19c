// srt's choice between its own sequence and a ray for every pixel
// (selective_choice.h): the schedule of its probes on given frame times, and
// on the device, that a frame which traces every pixel is frt's frame.
#include <algorithm>

#include <gtest/gtest.h>

#include "penumbra/generate.h"
#include "penumbra/penumbra.h"
#include "selective_choice.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

// Runs one frame: traceAll's answer, then the time the frame took in that way.
bool frame(SelectiveChoice& choice, double selectiveMs, double allMs, uint64_t key = 1)
{
    const bool all = choice.traceAll(key);
    choice.record(all ? allMs : selectiveMs);
    return all;
}

TEST(SelectiveChoice, ProbesOnceSteadyThenTakesTheCheaperWay)
{
    SelectiveChoice choice;
    EXPECT_FALSE(frame(choice, 500, 50)); // the first frame: not timed
    EXPECT_FALSE(frame(choice, 100, 50));
    EXPECT_FALSE(frame(choice, 99, 50));  // no longer 5% faster: steady
    EXPECT_FALSE(choice.chosen());
    EXPECT_TRUE(frame(choice, 100, 500)); // the first probe: not timed (its shaders compile)
    EXPECT_TRUE(choice.lastWasProbe());
    EXPECT_FALSE(choice.chosen());
    EXPECT_TRUE(frame(choice, 100, 50));  // the probe that counts
    EXPECT_TRUE(choice.lastWasProbe());
    EXPECT_TRUE(choice.chosen());
    EXPECT_TRUE(choice.tracingAll());
    for (uint32_t i = 0; i < SelectiveChoice::kMinInterval; ++i) {
        EXPECT_TRUE(frame(choice, 100, 50)) << i;
        EXPECT_FALSE(choice.lastWasProbe());
    }
    EXPECT_FALSE(frame(choice, 40, 50)); // srt's own way probed again: its first frame is not timed
    EXPECT_TRUE(choice.lastWasProbe());
    EXPECT_EQ(choice.probeInterval(), SelectiveChoice::kMinInterval);
    EXPECT_FALSE(frame(choice, 100, 50)); // the frame that counts, and it lost
    EXPECT_TRUE(choice.lastWasProbe());
    EXPECT_TRUE(choice.tracingAll());
    EXPECT_EQ(choice.probeInterval(), 2 * SelectiveChoice::kMinInterval);
}

// After many frames that traced every pixel, srt's own first frame is slow (its light views'
// culling relearns the view): a probe of srt's own way is timed on its second frame.
TEST(SelectiveChoice, ProbesOfSrtsOwnWayAreTimedOnTheirSecondFrame)
{
    SelectiveChoice choice;
    while (!choice.chosen())
        frame(choice, 100, 80);
    ASSERT_TRUE(choice.tracingAll());
    uint32_t probeFrames = 0;
    for (uint32_t i = 0; i <= SelectiveChoice::kMinInterval && !probeFrames; ++i)
        if (!frame(choice, 200, 80)) // srt's own first frame after the interval: slow, not timed
            ++probeFrames;
    ASSERT_EQ(probeFrames, 1u);
    EXPECT_FALSE(frame(choice, 60, 80)); // its second frame: warm, and cheaper by more than the margin
    EXPECT_FALSE(choice.tracingAll());
    EXPECT_FALSE(frame(choice, 60, 80));
    EXPECT_FALSE(choice.lastWasProbe());
}

TEST(SelectiveChoice, KeepsSelectiveRaysWhereTracingEveryPixelCostsMore)
{
    SelectiveChoice choice;
    uint32_t probes = 0, frames = 0;
    for (; frames < 600; ++frames) {
        const bool all = frame(choice, 100, 300);
        probes += all ? 1 : 0;
        EXPECT_EQ(all, choice.lastWasProbe()) << frames;
    }
    EXPECT_FALSE(choice.tracingAll());
    // Probes at frames 4 (not timed), 5, 14, 31, 64, 129, 258 and 515: each lost, the next one twice as far
    // (the first two timed ones 8 frames apart).
    EXPECT_EQ(probes, 8u);
    EXPECT_EQ(choice.probeInterval(), SelectiveChoice::kMaxInterval);
}

TEST(SelectiveChoice, NeedsTheMarginToSwitchAndStartsOverForANewKey)
{
    SelectiveChoice choice;
    for (int i = 0; i < 3; ++i)
        frame(choice, 100, 97);
    EXPECT_TRUE(frame(choice, 100, 97)); // not timed
    EXPECT_TRUE(frame(choice, 100, 97)); // 3% cheaper: not enough
    EXPECT_TRUE(choice.chosen());
    EXPECT_FALSE(choice.tracingAll());
    EXPECT_FALSE(frame(choice, 100, 50, 2)); // new key: its first frames again
    EXPECT_FALSE(choice.chosen());
}

TEST(SelectiveChoice, ProbesAtTheLatestAfterTheSettleFrames)
{
    SelectiveChoice choice;
    double ms = 1000;
    uint32_t frames = 1;
    while (!frame(choice, ms, 10)) {
        ms *= 0.9; // still getting faster by 10% a frame: never steady
        ++frames;
    }
    EXPECT_EQ(frames, SelectiveChoice::kSettleFrames + 1);
}

// srt frames until the choice is made (at most the settle frames and two probes): the last probe, and the
// last frame of srt's own way when `selective` is given.
Frame renderUntilChosen(Renderer& renderer, const RenderSettings& settings, Frame* selective = nullptr)
{
    Frame probe;
    for (uint32_t i = 0; i < SelectiveChoice::kSettleFrames + 2 && !probe.stats.srtChosen; ++i) {
        Frame f = renderer.render(settings);
        EXPECT_EQ(f.stats.srtTracedAll, f.stats.srtProbe) << "before the first choice, only the probes trace every pixel";
        if (f.stats.srtProbe)
            probe = std::move(f);
        else if (selective)
            *selective = std::move(f);
    }
    EXPECT_TRUE(probe.stats.srtChosen) << "no choice after the settle frames and two probes";
    return probe;
}

size_t differingPixels(const std::vector<float>& a, const std::vector<float>& b)
{
    EXPECT_EQ(a.size(), b.size());
    size_t differing = 0;
    for (size_t i = 0; i < std::min(a.size(), b.size()); ++i)
        differing += a[i] != b[i] ? 1 : 0;
    return differing;
}

// On the device: a plant whose shadow map leaves many pixels in doubt. Every
// frame is exact where it traces; the frame that traces every pixel is frt's
// frame to the pixel; with the choice off, or when the traced pixels are shown,
// srt never traces every pixel.
TEST(SelectiveChoice, AFrameThatTracesEveryPixelIsFrtsFrame)
{
    GenerateOptions options;
    options.triangles = 40'000;
    Scene scene = generateScene("plant", options);
    Renderer renderer;
    renderer.loadModel(scene.mesh);
    renderer.setCamera(scene.cameras[0]);
    renderer.setLights({scene.lights[0]});
    RenderSettings settings;
    settings.width = settings.height = 160;
    settings.readbackGBuffer = true;
    settings.shadows = ShadowMethod::FullRayTrace;
    const Frame frt = renderer.render(settings);
    settings.shadows = ShadowMethod::Selective;
    Frame selective;
    const Frame probe = renderUntilChosen(renderer, settings, &selective);
    EXPECT_TRUE(probe.stats.srtTracedAll);
    EXPECT_EQ(probe.stats.rays, frt.stats.rays);
    EXPECT_LT(selective.stats.rays, frt.stats.rays);
    EXPECT_EQ(differingPixels(probe.visibility, frt.visibility), 0u) << "the probe is frt's frame";

    for (bool debugPip : {false, true}) {
        RenderSettings fixed = settings;
        fixed.srtTraceAllWhenCheaper = debugPip;
        fixed.debugPip = debugPip;
        fixed.width = fixed.height = 128; // a new key
        for (uint32_t i = 0; i < SelectiveChoice::kSettleFrames + 2; ++i) {
            const FrameStats stats = renderer.render(fixed).stats;
            EXPECT_FALSE(stats.srtTracedAll || stats.srtProbe) << i;
        }
    }
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
}

// Soft shadows take the same choice: a sphere light's probe frame is frt's soft frame to the pixel (the
// samples are seeded by the pixel).
TEST(SelectiveChoice, SoftShadowProbeIsFrtsSoftFrame)
{
    GenerateOptions options;
    options.triangles = 20'000;
    Scene scene = generateScene("city", options);
    Light sphere;
    sphere.type = LightType::Sphere;
    sphere.position = {0.0f, 80.0f, 0.0f};
    sphere.radius = 4.0f;
    sphere.intensity = 2e4f;
    Renderer renderer;
    renderer.loadModel(scene.mesh);
    renderer.setLights({sphere});
    RenderSettings settings;
    settings.width = settings.height = 96;
    settings.readbackGBuffer = true;
    settings.shadows = ShadowMethod::FullRayTrace;
    const Frame frt = renderer.render(settings);
    settings.shadows = ShadowMethod::Selective;
    const Frame probe = renderUntilChosen(renderer, settings);
    EXPECT_TRUE(probe.stats.srtTracedAll);
    EXPECT_GT(probe.stats.lightSamples, 0u);
    const auto penumbra = std::count_if(frt.visibility.begin(), frt.visibility.end(), [](float v) { return v > 0.0f && v < 1.0f; });
    EXPECT_GT(penumbra, 50) << "the light should cast soft shadows here";
    EXPECT_EQ(differingPixels(probe.visibility, frt.visibility), 0u) << "the soft probe is frt's frame";
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
}

} // namespace
} // namespace penumbra
