// Hard- and soft-shadow calls of the benchmark suite (see shadow_adapter.h).
// Soft shadows are not in this build yet: the soft functions say so. Once
// RenderSettings has lightSamples / penumbraMaps / softShadowMaps, FrameStats
// penumbraFraction and the oracle a soft-visibility function, fill in the
// places marked "soft shadows (#5)" and make softShadowsAvailable() return
// true; nothing else in bench/ changes.
#include "shadow_adapter.h"

namespace penumbra::bench {

const char* shadowKindName(ShadowKind kind)
{
    return kind == ShadowKind::Hard ? "hard" : "soft";
}

bool softShadowsAvailable()
{
    // Soft shadows (#5): return true.
    return false;
}

Frame renderHardShadows(Renderer& renderer, const RenderSettings& settings)
{
    // The suite sets only point-like or directional lights for hard cases (area lights cast soft shadows).
    return renderer.render(settings);
}

Frame renderSoftShadows(Renderer& renderer, const RenderSettings& settings, const SoftShadowParams& params)
{
    // Soft shadows (#5): copy settings, set lightSamples = params.lightSamples, penumbraMaps = params.penumbraMaps
    // and softShadowMaps = params.softShadowMaps (and a soft switch, if there is one), return renderer.render(copy).
    (void)renderer;
    (void)settings;
    (void)params;
    fail("bench", "soft shadows are not available in this build");
}

double penumbraFraction(const Frame& frame, ShadowKind kind)
{
    // Soft shadows (#5): return kind == ShadowKind::Soft ? frame.stats.penumbraFraction : 0.0.
    (void)frame;
    (void)kind;
    return 0.0;
}

std::vector<float> oracleHardVisibility(const EmbreeOracle& oracle, const Frame& frame, const Light& light,
                                        float rayOffset)
{
    OracleOptions options;
    options.originOffset = rayOffset;
    return oracle.hardShadowVisibility(frame.positions, frame.normals, light, options);
}

std::vector<float> oracleSoftVisibility(const EmbreeOracle& oracle, const Frame& frame, const Light& light,
                                        float rayOffset, const SoftShadowParams& params)
{
    // Soft shadows (#5): call the oracle's soft-visibility function on frame.positions and frame.normals with
    // originOffset = rayOffset and the same params.lightSamples as the renderer.
    (void)oracle;
    (void)frame;
    (void)light;
    (void)rayOffset;
    (void)params;
    fail("bench", "soft shadows are not available in this build");
}

} // namespace penumbra::bench
