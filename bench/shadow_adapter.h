// The one place where the benchmark suite calls the renderer and the oracle
// for a shadow computation, hard or soft.
#pragma once

#include <cstdint>
#include <vector>

#include "penumbra/oracle.h"
#include "penumbra/penumbra.h"

namespace penumbra::bench {

enum class ShadowKind { Hard, Soft };

const char* shadowKindName(ShadowKind kind); // "hard", "soft"

// Soft-shadow parameters, shared by the renderer and the oracle so that both
// integrate the same light samples.
struct SoftShadowParams {
    uint32_t lightSamples = 16;  // srt, frt and the oracle: samples over the area light per pixel
    uint32_t afsmSamples = 256;  // afsm and its oracle (the table's samples): light samples per view sample
    uint32_t penumbraMaps = 1;   // srt: shadow maps whose masks mark the penumbra, 1 (centre) or 5 (centre and corners)
    uint32_t softShadowMaps = 4; // sm: point-light shadow maps averaged over the light
};

// One frame of hard shadows from the point-like or directional lights set on
// the renderer, with settings.shadows choosing sm, srt or frt.
Frame renderHardShadows(Renderer& renderer, const RenderSettings& settings);

// One frame of soft shadows from the area light (rectangle, disk or sphere)
// set on the renderer as light 0, settings.shadows choosing the method. Frame::visibility (with
// readbackGBuffer) is the lit fraction of light 0 in [0, 1], -1 background.
Frame renderSoftShadows(Renderer& renderer, const RenderSettings& settings, const SoftShadowParams& params);

// Share of covered pixels in the penumbra (0 < visibility < 1) of a soft
// frame, as the renderer counts it; 0 for hard frames.
double penumbraFraction(const Frame& frame, ShadowKind kind);

// The oracle's visibility of light on the frame's G-buffer (positions and
// normals), rays offset by the frame's ray offset (or the fallback when the
// frame traced nothing): 1 lit, 0 shadowed, fractions in the penumbra for
// soft, kVisibilityBackground and kVisibilityBackFacing as in oracle.h.
std::vector<float> oracleHardVisibility(const EmbreeOracle& oracle, const Frame& frame, const Light& light,
                                        float rayOffset);
// afsmTable: the oracle traces afsm's table samples (params.afsmSamples of
// them; OracleOptions::afsmSamples): against it afsm differs only by its table.
std::vector<float> oracleSoftVisibility(const EmbreeOracle& oracle, const Frame& frame, const Light& light,
                                        float rayOffset, const SoftShadowParams& params, bool afsmTable = false);

} // namespace penumbra::bench
