// A PNG writer with no dependencies, for builds without OpenImageIO
// (PENUMBRA_WITH_OPENIMAGEIO=OFF): 8-bit RGBA, no filtering, stored (not
// compressed) deflate blocks, so a 1024^2 image takes 4 MiB. The default
// build writes images through OpenImageIO (api.cpp: writeImage).
#pragma once

#include <cstdint>
#include <string>

namespace penumbra {

// Writes width x height pixels of 4 bytes (R, G, B, A; rows top to bottom) to
// path; false if the file cannot be written.
bool writePngRgba8(const std::string& path, uint32_t width, uint32_t height, const uint8_t* rgba);

} // namespace penumbra
