// Per-cluster 16-bit position quantization (the "quantized vertices" of the
// ReduceM-like representation, Lauterbach et al. 2009, section 5.1): each
// coordinate is stored as q in 0..65535 with decoded = boxMin + float(q) * step,
// step = extent / 65535 per axis (0 for a flat axis). q is the rounded value,
// then q-1..q+1 are tried with the decoder's exact float arithmetic (no fused
// multiply-add) and the closest is kept, so the error is at most half a step
// plus one rounding. The reported error is measured with decodePosition.
#include <algorithm>
#include <cmath>

#include "preprocess_internal.h"

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC optimize("fp-contract=off")
#endif
#if defined(__clang__)
#pragma clang fp contract(off)
#endif

namespace penumbra::preprocess_detail {

namespace {

float decodeCoordinate(float boxMin, float step, uint32_t q)
{
    volatile float scaled = float(q) * step;
    return boxMin + scaled;
}

uint16_t quantizeCoordinate(float p, float boxMin, float step)
{
    if (step == 0.0f)
        return 0;
    long guess = std::lround(double(p - boxMin) / double(step));
    guess = std::clamp(guess, 0L, 65535L);
    long best = guess;
    float bestError = std::fabs(decodeCoordinate(boxMin, step, uint32_t(guess)) - p);
    for (long q = std::max(0L, guess - 1); q <= std::min(65535L, guess + 1); ++q) {
        float error = std::fabs(decodeCoordinate(boxMin, step, uint32_t(q)) - p);
        if (error < bestError) {
            bestError = error;
            best = q;
        }
    }
    return uint16_t(best);
}

} // namespace

void quantizeCluster(const Mesh& mesh, const uint32_t* vertices, uint32_t count, model::ClusterRecord& record,
                     model::QuantizedVertex* out, glm::vec3* decoded, Box& inputBox, float& maxError)
{
    inputBox = Box();
    for (uint32_t i = 0; i < count; ++i)
        inputBox.grow(mesh.position(vertices[i]));
    for (int a = 0; a < 3; ++a) {
        record.boxMin[a] = inputBox.min[a];
        float extent = inputBox.max[a] - inputBox.min[a];
        record.step[a] = extent > 0.0f ? extent / 65535.0f : 0.0f;
    }
    maxError = 0.0f;
    for (uint32_t i = 0; i < count; ++i) {
        const glm::vec3 p = mesh.position(vertices[i]);
        model::QuantizedVertex& q = out[i];
        q.x = quantizeCoordinate(p.x, record.boxMin[0], record.step[0]);
        q.y = quantizeCoordinate(p.y, record.boxMin[1], record.step[1]);
        q.z = quantizeCoordinate(p.z, record.boxMin[2], record.step[2]);
        decoded[i] = decodePosition(record, q);
        glm::vec3 error = glm::abs(decoded[i] - p);
        maxError = std::max({maxError, error.x, error.y, error.z});
    }
}

} // namespace penumbra::preprocess_detail
