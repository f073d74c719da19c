// Camera and light projections fitted to the scene bounds (Vulkan clip space:
// depth 0..1, y down).
#pragma once

#include <glm/mat4x4.hpp>

#include "penumbra/mesh.h"

namespace penumbra {

struct ViewProjection {
    glm::mat4 viewProj{1.0f};
    glm::vec3 eye{0.0f};
};

// Camera matrices for an image of the given aspect ratio. Near/far planes of 0
// are derived from the bounds.
ViewProjection cameraViewProjection(const Camera& camera, const Bounds& bounds, float aspect);

// Shadow-map matrices: 1 for directional and spot lights, 6 (+X,-X,+Y,-Y,+Z,-Z)
// for point and area lights (area lights are shadowed from their centre).
// Returns the number of layers written to out.
uint32_t lightViewProjections(const Light& light, const Bounds& bounds, glm::mat4 out[6]);

} // namespace penumbra
