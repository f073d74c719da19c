// IEEE 754 half-precision (binary16) to float, for the colour image's
// read-back (frame_targets.h: kColorFormat is RGBA16F, so that the shade
// pass writes 8 bytes a pixel instead of 16).
#pragma once

#include <cstddef>
#include <cstdint>

namespace penumbra {

// out[i] = in[i] as a float, exactly (every half is a float), for i < count:
// with F16C where the CPU has it, else a branch-free conversion.
void halfToFloat(const uint16_t* in, float* out, size_t count);

// The branch-free conversion alone (what halfToFloat does without F16C).
void halfToFloatPortable(const uint16_t* in, float* out, size_t count);

} // namespace penumbra
