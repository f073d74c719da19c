// The camera pass's surface texel on the host (shaders/surface.glsli): the
// world position's float bits and the octahedral normal in one RGBA32UI
// texel, 0 for the background. Frame reads it back through decodeSurface;
// tests that hand the tracer a G-buffer of their own encode it here.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

namespace penumbra {

constexpr uint32_t kSurfaceCoveredBits = 0x80008000u;
constexpr uint32_t kWhiteAlbedo = 0xFFFFFFu;

inline uint32_t encodeSurfaceNormal(const float normal[3])
{
    const float sum = std::fabs(normal[0]) + std::fabs(normal[1]) + std::fabs(normal[2]);
    float p[2] = {normal[0] / sum, normal[1] / sum};
    if (normal[2] < 0.0f) {
        const float x = p[0], y = p[1];
        p[0] = (1.0f - std::fabs(y)) * (x >= 0.0f ? 1.0f : -1.0f);
        p[1] = (1.0f - std::fabs(x)) * (y >= 0.0f ? 1.0f : -1.0f);
    }
    uint32_t bits = 0;
    for (int k = 0; k < 2; ++k) { // GLSL packSnorm2x16
        const int16_t q = int16_t(std::lround(std::clamp(p[k], -1.0f, 1.0f) * 32767.0f));
        bits |= uint32_t(uint16_t(q)) << (16 * k);
    }
    return bits ^ kSurfaceCoveredBits;
}

inline void decodeSurfaceNormal(uint32_t w, float normal[3])
{
    w ^= kSurfaceCoveredBits;
    float p[2];
    for (int k = 0; k < 2; ++k) // GLSL unpackSnorm2x16
        p[k] = std::clamp(float(int16_t(uint16_t(w >> (16 * k)))) / 32767.0f, -1.0f, 1.0f);
    float n[3] = {p[0], p[1], 1.0f - std::fabs(p[0]) - std::fabs(p[1])};
    const float t = std::max(-n[2], 0.0f);
    n[0] += n[0] >= 0.0f ? -t : t;
    n[1] += n[1] >= 0.0f ? -t : t;
    const float length = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (int k = 0; k < 3; ++k)
        normal[k] = n[k] / length;
}

// A texel for a covered pixel at `position` with unit `normal`.
inline void encodeSurface(const float position[3], const float normal[3], uint32_t texel[4])
{
    std::memcpy(texel, position, 3 * sizeof(float));
    texel[3] = encodeSurfaceNormal(normal);
}

// Frame::positions (xyz, w = 1 covered, 0 background) and Frame::normals
// (xyz, w = the packed albedo as a float) of one texel; albedo: the albedo
// target's value, or kWhiteAlbedo where the frame wrote none.
inline void decodeSurface(const uint32_t texel[4], uint32_t albedo, float position[4], float normal[4])
{
    if (texel[3] == 0) {
        std::fill(position, position + 4, 0.0f);
        std::fill(normal, normal + 4, 0.0f);
        return;
    }
    std::memcpy(position, texel, 3 * sizeof(float));
    position[3] = 1.0f;
    decodeSurfaceNormal(texel[3], normal);
    normal[3] = float(albedo & kWhiteAlbedo);
}

} // namespace penumbra
