#include "half_float.h"

#include <cstring>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define PENUMBRA_HAVE_F16C_PATH 1
#endif

namespace penumbra {

namespace {

float floatFromBits(uint32_t u)
{
    float f;
    std::memcpy(&f, &u, sizeof(f));
    return f;
}

uint32_t bitsFromFloat(float f)
{
    uint32_t u;
    std::memcpy(&u, &f, sizeof(u));
    return u;
}

} // namespace

// The exponent rebias of a normal half; Inf/NaN get the float's all-ones
// exponent; a subnormal half (exponent 0) is renormalized by one float
// subtraction (F. Giesen's "half_to_float_fast5").
void halfToFloatPortable(const uint16_t* in, float* out, size_t count)
{
    constexpr uint32_t kExponentMask = 0x7c00u << 13;
    for (size_t i = 0; i < count; ++i) {
        const uint32_t h = in[i];
        const uint32_t magnitude = (h & 0x7fffu) << 13;
        const uint32_t exponent = magnitude & kExponentMask;
        uint32_t bits = magnitude + ((127u - 15u) << 23);
        bits += exponent == kExponentMask ? (128u - 16u) << 23 : 0u;
        const float subnormal = floatFromBits(bits + (1u << 23)) - floatFromBits(113u << 23);
        bits = exponent == 0 ? bitsFromFloat(subnormal) : bits;
        out[i] = floatFromBits(bits | (h & 0x8000u) << 16);
    }
}

namespace {

#ifdef PENUMBRA_HAVE_F16C_PATH
__attribute__((target("avx,f16c"))) size_t halfToFloatF16c(const uint16_t* in, float* out, size_t count)
{
    size_t i = 0;
    for (; i + 8 <= count; i += 8)
        _mm256_storeu_ps(out + i, _mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i*>(in + i))));
    return i;
}
#endif

} // namespace

void halfToFloat(const uint16_t* in, float* out, size_t count)
{
    size_t done = 0;
#ifdef PENUMBRA_HAVE_F16C_PATH
    static const bool f16c = __builtin_cpu_supports("avx") && __builtin_cpu_supports("f16c");
    if (f16c)
        done = halfToFloatF16c(in, out, count);
#endif
    halfToFloatPortable(in + done, out + done, count - done);
}

} // namespace penumbra
