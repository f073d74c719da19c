// Hard- and soft-shadow calls of the benchmark suite (see shadow_adapter.h).
#include "shadow_adapter.h"

namespace penumbra::bench {

const char* shadowKindName(ShadowKind kind)
{
    return kind == ShadowKind::Hard ? "hard" : "soft";
}

Frame renderHardShadows(Renderer& renderer, const RenderSettings& settings)
{
    // The suite sets only point-like or directional lights for hard cases (area lights cast soft shadows).
    return renderer.render(settings);
}

Frame renderSoftShadows(Renderer& renderer, const RenderSettings& settings, const SoftShadowParams& params)
{
    // Area lights cast soft shadows; the suite sets one for soft cases.
    RenderSettings soft = settings;
    soft.lightSamples = settings.shadows == ShadowMethod::AliasFree ? params.afsmSamples : params.lightSamples;
    soft.penumbraMaps = params.penumbraMaps;
    soft.softShadowMaps = params.softShadowMaps;
    return renderer.render(soft);
}

double penumbraFraction(const Frame& frame, ShadowKind kind)
{
    return kind == ShadowKind::Soft ? frame.stats.penumbraFraction : 0.0;
}

std::vector<float> oracleHardVisibility(const EmbreeOracle& oracle, const Frame& frame, const Light& light,
                                        float rayOffset)
{
    OracleOptions options;
    options.originOffset = rayOffset;
    return oracle.hardShadowVisibility(frame.positions, frame.normals, light, options);
}

std::vector<float> oracleSoftVisibility(const EmbreeOracle& oracle, const Frame& frame, const Light& light,
                                        float rayOffset, const SoftShadowParams& params, bool afsmTable)
{
    OracleOptions options;
    options.originOffset = rayOffset;
    options.afsmSamples = afsmTable;
    // The suite renders one light: index 0 seeds the samples, as on the GPU.
    return oracle.softShadowVisibility(frame.positions, frame.normals, frame.color.width, light, 0,
                                       afsmTable ? params.afsmSamples : params.lightSamples, options);
}

} // namespace penumbra::bench
