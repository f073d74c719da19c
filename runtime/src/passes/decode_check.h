// Decode check (shaders/decode_check.vert.glsl): the model's vertices as the
// GPU's vertex stage dequantizes them (Renderer::decodeVerticesOnGpu).
#pragma once

#include <vector>

#include "model_geometry.h"

namespace penumbra::passes {

// x, y, z per vertex of the compressed model, in model order.
std::vector<float> decodeVerticesOnGpu(vk::Device& device, const GpuGeometry& geometry);

} // namespace penumbra::passes
