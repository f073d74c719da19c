// The benchmark suite times a case only once the occlusion culling has learnt
// the light's views (bench/suite_internal.h: CullLog). Sequences of triangles
// drawn per view, as the culling produces them: the learning (falling), the
// steady cycle (PENUMBRA_CULL_RETEST_FRAMES), and a view that never settles.
#include <gtest/gtest.h>

#include "config.h"
#include "suite_internal.h"

namespace penumbra::bench {
namespace {

FrameStats frame(std::initializer_list<std::pair<const char*, uint64_t>> views)
{
    FrameStats stats;
    for (const auto& [name, drawn] : views) {
        ViewCullStats view;
        view.name = name;
        view.trianglesDrawn = drawn;
        stats.views.push_back(view);
    }
    return stats;
}

// The frame (1-based) at which the log first calls the sequence steady; 0: never.
size_t firstSteady(CullLog& log, const std::vector<uint64_t>& light, uint64_t camera = 1000)
{
    for (size_t i = 0; i < light.size(); ++i)
        if (log.steady(frame({{"camera", camera}, {"light0", light[i]}})))
            return i + 1;
    return 0;
}

TEST(BenchCullLog, WaitsWhileAViewLearnsThenThroughItsCycle)
{
    static_assert(PENUMBRA_CULL_RETEST_FRAMES == 4, "the sequences below assume a 4-frame retest cycle");
    // The 1 M interior's sun view at 1024^2 (thousands of triangles drawn), as the culling drew it:
    // two frames of everything, the learning, then an uneven cycle of 4-6 frames.
    CullLog log;
    const std::vector<uint64_t> interior = {888, 888, 768, 654, 520, 437, 435, 423, 410, 395, 438, 438, 425, 409, 392, 436, 436};
    // The most drawn in 5 frames: 888 888 768 654 520 437 438 438 ... from frame 5: steady at frame
    // 12, the eleventh after the warm-up frame, as `penumbra bench` reported for that scene.
    EXPECT_EQ(firstSteady(log, interior), 12u);
}

TEST(BenchCullLog, ASteadyViewNeedsAWindowOfHistory)
{
    CullLog log;
    const std::vector<uint64_t> flat(10, 500);
    // Five frames make the first window, two more show it has stopped falling.
    EXPECT_EQ(firstSteady(log, flat), 7u);
    // Later methods of the same light find the history there: their first frame is steady.
    EXPECT_TRUE(log.steady(frame({{"camera", 1000}, {"light0", 500}})));
    // One that draws no light view (frt) is judged by the camera's history alone.
    EXPECT_TRUE(log.steady(frame({{"camera", 1000}})));
}

TEST(BenchCullLog, AViewStillFallingIsNotSteady)
{
    CullLog log;
    std::vector<uint64_t> falling;
    for (uint64_t drawn = 1000; drawn > 500; drawn -= 20)
        falling.push_back(drawn);
    EXPECT_EQ(firstSteady(log, falling), 0u);
    // Every view must be steady: a settled light does not make a learning camera steady.
    CullLog two;
    for (uint64_t i = 0; i < 12; ++i)
        EXPECT_FALSE(two.steady(frame({{"camera", 2000 - 50 * i}, {"light0", 700}})));
}

} // namespace
} // namespace penumbra::bench
