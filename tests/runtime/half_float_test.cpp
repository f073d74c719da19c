// The colour image's read-back conversion (half_float.h): every half, against
// the IEEE 754 definition, on the F16C path and the portable one alike.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

#include "half_float.h"

namespace penumbra {
namespace {

// binary16: sign, 5 exponent bits (bias 15), 10 fraction bits.
double halfValue(uint16_t h)
{
    const int sign = h >> 15, exponent = (h >> 10) & 31, fraction = h & 1023;
    double magnitude;
    if (exponent == 0)
        magnitude = std::ldexp(double(fraction), -24); // subnormal
    else if (exponent == 31)
        magnitude = fraction == 0 ? INFINITY : NAN;
    else
        magnitude = std::ldexp(1024.0 + fraction, exponent - 25);
    return sign ? -magnitude : magnitude;
}

TEST(HalfFloat, EveryHalfConvertsExactly)
{
    std::vector<uint16_t> halves(65536);
    for (uint32_t i = 0; i < halves.size(); ++i)
        halves[i] = uint16_t(i);
    // Odd lengths and offsets: the 8-wide path's remainder goes through the portable one.
    for (size_t offset : {size_t(0), size_t(3), size_t(4)}) {
        std::vector<float> floats(halves.size() - offset, -7.0f);
        if (offset == 4)
            halfToFloatPortable(halves.data() + offset, floats.data(), floats.size());
        else
            halfToFloat(halves.data() + offset, floats.data(), floats.size());
        for (size_t i = 0; i < floats.size(); ++i) {
            const uint16_t h = halves[i + offset];
            const double expected = halfValue(h);
            if (std::isnan(expected)) {
                EXPECT_TRUE(std::isnan(floats[i])) << h;
                continue;
            }
            ASSERT_EQ(double(floats[i]), expected) << "half 0x" << std::hex << h;
            EXPECT_EQ(std::signbit(floats[i]), (h & 0x8000) != 0) << h; // -0 stays -0
        }
    }
}

} // namespace
} // namespace penumbra
