// Independent CPU reference for shadows: Embree (libembree-dev) on the
// original, uncompressed triangles. Never used by the renderer; tests and
// benchmarks compare every shadow method against it.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "penumbra/mesh.h"

namespace penumbra {

struct OracleOptions {
    // Shadow-ray origins are moved this far along the light-facing normal,
    // in model units (absorbs quantization and interpolation error).
    float originOffset = 1e-4f;
    unsigned threads = 0; // 0: all cores
    // Soft shadows: trace the light samples of afsm's lookup table
    // (penumbra/light_sampling.h, afsmLightPoint: one fixed set of `samples`
    // points per light shape, turned or mirrored per pixel) instead of the
    // per-pixel stratified samples of srt and frt. afsm against this oracle
    // differs only by the table's discretization.
    bool afsmSamples = false;
};

// Visibility per pixel: 1 lit, 0 shadowed, -1 background (position w == 0),
// -2 facing away from the light (no ray traced: unlit by shading anyway).
inline constexpr float kVisibilityBackground = -1.0f;
inline constexpr float kVisibilityBackFacing = -2.0f;

class EmbreeOracle {
public:
    // Builds an Embree BVH over the mesh (copied). Throws Error on failure.
    explicit EmbreeOracle(const Mesh& mesh);
    ~EmbreeOracle();
    EmbreeOracle(const EmbreeOracle&) = delete;
    EmbreeOracle& operator=(const EmbreeOracle&) = delete;

    // One occlusion ray per covered pixel toward the light (its centre for
    // point-like and area lights, along -direction for directional lights),
    // from the G-buffer position (xyzw per pixel) offset along the normal
    // (xyz per pixel) flipped to face the light.
    std::vector<float> hardShadowVisibility(const std::vector<float>& positions, const std::vector<float>& normals, const Light& light,
                                            const OracleOptions& options = {}) const;

    // Soft shadows of an area light: per covered pixel the fraction of
    // `samples` light samples (penumbra/light_sampling.h, seeded by the pixel
    // x = i % width, y = i / width and lightIndex, as the GPU tracer does)
    // that no triangle blocks; samples below the pixel's plane count as
    // blocked. kVisibilityBackFacing where no sample is above the plane or the
    // pixel is behind a one-sided emitter. options.afsmSamples: afsm's samples.
    std::vector<float> softShadowVisibility(const std::vector<float>& positions, const std::vector<float>& normals, uint32_t width,
                                            const Light& light, uint32_t lightIndex, uint32_t samples,
                                            const OracleOptions& options = {}) const;

    uint64_t raysTraced() const { return rays; }

private:
    struct Impl;
    std::unique_ptr<Impl> impl;
    mutable uint64_t rays = 0;
};

} // namespace penumbra
