// Light samples of area lights, one implementation compiled both as C++ (the
// Embree oracle, tests) and as GLSL (the GPU tracer, included by shaders), so
// that every method traces the same samples (Lauterbach et al. 2009, 5.1:
// "stratified sampling ... seeded from the sample location"). Keep to the
// common subset of both languages: no references, no swizzles, no overloads.
#ifndef PENUMBRA_LIGHT_SAMPLING_H
#define PENUMBRA_LIGHT_SAMPLING_H

#define PENUMBRA_AREA_RECTANGLE 3u  // == PENUMBRA_LIGHT_RECTANGLE
#define PENUMBRA_AREA_DISK 4u       // == PENUMBRA_LIGHT_DISK
#define PENUMBRA_AREA_SPHERE 5u     // == PENUMBRA_LIGHT_SPHERE

#ifdef __cplusplus
#include <cstdint>
#include <glm/glm.hpp>
namespace penumbra::sampling {
using glm::vec2;
using glm::vec3;
using uint = uint32_t;
using glm::abs;
using glm::ceil;
using glm::cos;
using glm::length;
using glm::normalize;
using glm::sin;
using glm::sqrt;
#define PENUMBRA_FN inline
#else
#define PENUMBRA_FN
#endif

// PCG-style integer hash (Jarzynski and Olano 2020).
PENUMBRA_FN uint pcgHash(uint v)
{
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// Seed of a pixel's samples: its location and the light's index.
PENUMBRA_FN uint sampleSeed(uint x, uint y, uint lightIndex)
{
    return pcgHash(x + pcgHash(y + pcgHash(lightIndex)));
}

PENUMBRA_FN float unitFloat(uint h)
{
    return float(h >> 8u) * (1.0f / 16777216.0f);
}

// Sample i of n in [0,1)^2, stratified: a grid of ceil(sqrt(n)) columns and
// as many rows as needed, one jittered sample per cell.
PENUMBRA_FN vec2 stratifiedSample(uint seed, uint i, uint n)
{
    uint columns = uint(ceil(sqrt(float(n))));
    uint rows = (n + columns - 1u) / columns;
    uint h1 = pcgHash(seed ^ (i * 2654435769u));
    uint h2 = pcgHash(h1 ^ 1013904223u);
    return vec2((float(i % columns) + unitFloat(h1)) / float(columns), (float(i / columns) + unitFloat(h2)) / float(rows));
}

// Shirley and Chiu's concentric map of [0,1)^2 onto the unit disk.
PENUMBRA_FN vec2 concentricDisk(vec2 u)
{
    float ox = 2.0f * u.x - 1.0f, oy = 2.0f * u.y - 1.0f;
    if (ox == 0.0f && oy == 0.0f)
        return vec2(0.0f, 0.0f);
    float r = oy, theta = 1.5707963f - 0.78539816f * (ox / oy);
    if (abs(ox) > abs(oy)) {
        r = ox;
        theta = 0.78539816f * (oy / ox);
    }
    return vec2(r * cos(theta), r * sin(theta));
}

// Point of an area light for the sample u in [0,1)^2. shape: PENUMBRA_AREA_*;
// centre; U and V: half-extent vectors (rectangle: half width and half height
// along its axes; disk: the radius along two axes of its plane; sphere: U.x is
// the radius). A sphere is sampled on its disk facing the receiver.
PENUMBRA_FN vec3 areaLightPoint(uint shape, vec3 centre, vec3 U, vec3 V, vec3 receiver, vec2 u)
{
    if (shape == PENUMBRA_AREA_RECTANGLE)
        return centre + (2.0f * u.x - 1.0f) * U + (2.0f * u.y - 1.0f) * V;
    vec2 d = concentricDisk(u);
    if (shape == PENUMBRA_AREA_DISK)
        return centre + d.x * U + d.y * V;
    // Orthonormal basis around the direction to the receiver (Duff et al. 2017).
    vec3 w = normalize(receiver - centre);
    float s = w.z >= 0.0f ? 1.0f : -1.0f;
    float a = -1.0f / (s + w.z);
    float b = w.x * w.y * a;
    vec3 b1 = vec3(1.0f + s * w.x * w.x * a, s * b, -s * w.x);
    vec3 b2 = vec3(b, s + w.y * w.y * a, -w.y);
    return centre + U.x * (d.x * b1 + d.y * b2);
}

#ifdef __cplusplus
} // namespace penumbra::sampling
#endif
#undef PENUMBRA_FN
#endif
