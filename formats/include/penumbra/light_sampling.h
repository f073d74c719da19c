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
using glm::vec4;
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

// The sphere's sample disk faces the receiver: its two axes (unit vectors),
// an orthonormal basis around w = normalize(receiver - centre) (Duff et al. 2017).
PENUMBRA_FN vec3 sphereDiskAxisU(vec3 w)
{
    float s = w.z >= 0.0f ? 1.0f : -1.0f;
    float a = -1.0f / (s + w.z);
    float b = w.x * w.y * a;
    return vec3(1.0f + s * w.x * w.x * a, s * b, -s * w.x);
}
PENUMBRA_FN vec3 sphereDiskAxisV(vec3 w)
{
    float s = w.z >= 0.0f ? 1.0f : -1.0f;
    float a = -1.0f / (s + w.z);
    float b = w.x * w.y * a;
    return vec3(b, s + w.y * w.y * a, -w.y);
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
    vec3 w = normalize(receiver - centre);
    return centre + U.x * (d.x * sphereDiskAxisU(w) + d.y * sphereDiskAxisV(w));
}

// ---------------------------------------------------------------------------
// Alias-free shadow maps, soft shadows (Sintorn et al. 2008, section 4.2): one
// fixed set of n light samples per light shape, in the light's own 2-D
// coordinates (a rectangle's [-1,1]^2 in units of U and V, the unit disk of a
// disk, or of the sphere's disk facing the receiver), so that a lookup table
// indexed by a plane can hold the bitmask of the samples in front of it. Per
// pixel the set is turned (disk, sphere: a rotation by an angle from the
// pixel's hash) or mirrored (rectangle: its two axes flipped or not), which
// the table absorbs by turning the plane instead ("jittering at almost no
// cost"). The oracle traces exactly these points (afsmLightPoint).

// Radical inverse of k in base 2 (van der Corput), in [0,1).
PENUMBRA_FN float radicalInverse2(uint k)
{
    uint b = k;
    b = ((b & 0x55555555u) << 1u) | ((b >> 1u) & 0x55555555u);
    b = ((b & 0x33333333u) << 2u) | ((b >> 2u) & 0x33333333u);
    b = ((b & 0x0F0F0F0Fu) << 4u) | ((b >> 4u) & 0x0F0F0F0Fu);
    b = ((b & 0x00FF00FFu) << 8u) | ((b >> 8u) & 0x00FF00FFu);
    b = (b << 16u) | (b >> 16u);
    return float(b >> 8u) * (1.0f / 16777216.0f);
}

// Sample k of n in the light's 2-D coordinates, before the pixel's jitter: the
// Hammersley point ((k + 1/2) / n, radical inverse of k), stratified for any n
// (a (0,m,2)-net for n a power of two), on [-1,1]^2 for a rectangle, mapped to
// the unit disk (concentric map) for a disk or a sphere.
PENUMBRA_FN vec2 afsmLocalSample(uint shape, uint k, uint n)
{
    vec2 u = vec2((float(k) + 0.5f) / float(n), radicalInverse2(k));
    if (shape == PENUMBRA_AREA_RECTANGLE)
        return vec2(2.0f * u.x - 1.0f, 2.0f * u.y - 1.0f);
    return concentricDisk(u);
}

// A pixel's jitter as the 2x2 matrix (x: column 0, y: column 1; the sample
// q becomes q.x * col0 + q.y * col1): a rotation by an angle from the seed
// for a disk or a sphere, a mirror of either axis for a rectangle.
PENUMBRA_FN vec4 afsmJitter(uint shape, uint seed)
{
    uint h = pcgHash(seed ^ 0x68bc21ebu);
    if (shape == PENUMBRA_AREA_RECTANGLE) {
        float fx = (h & 1u) != 0u ? -1.0f : 1.0f;
        float fy = (h & 2u) != 0u ? -1.0f : 1.0f;
        return vec4(fx, 0.0f, 0.0f, fy);
    }
    float angle = 6.28318531f * unitFloat(h);
    float c = cos(angle), s = sin(angle);
    return vec4(c, s, -s, c);
}

// The light's two axes for a receiver with the pixel's jitter applied: the
// world point of local sample q is centre + q.x * axisU + q.y * axisV.
PENUMBRA_FN vec3 afsmAxisU(uint shape, vec3 centre, vec3 U, vec3 V, vec3 receiver, vec4 jitter)
{
    if (shape == PENUMBRA_AREA_SPHERE) {
        vec3 w = normalize(receiver - centre);
        return U.x * (jitter.x * sphereDiskAxisU(w) + jitter.y * sphereDiskAxisV(w));
    }
    return jitter.x * U + jitter.y * V;
}
PENUMBRA_FN vec3 afsmAxisV(uint shape, vec3 centre, vec3 U, vec3 V, vec3 receiver, vec4 jitter)
{
    if (shape == PENUMBRA_AREA_SPHERE) {
        vec3 w = normalize(receiver - centre);
        return U.x * (jitter.z * sphereDiskAxisU(w) + jitter.w * sphereDiskAxisV(w));
    }
    return jitter.z * U + jitter.w * V;
}

// World position of light sample k of n for the receiver of the pixel whose
// seed (sampleSeed) is given: what the table of n samples encodes for it.
PENUMBRA_FN vec3 afsmLightPoint(uint shape, vec3 centre, vec3 U, vec3 V, vec3 receiver, uint seed, uint k, uint n)
{
    vec4 jitter = afsmJitter(shape, seed);
    vec2 q = afsmLocalSample(shape, k, n);
    return centre + q.x * afsmAxisU(shape, centre, U, V, receiver, jitter) + q.y * afsmAxisV(shape, centre, U, V, receiver, jitter);
}

#ifdef __cplusplus
} // namespace penumbra::sampling
#endif
#undef PENUMBRA_FN
#endif
