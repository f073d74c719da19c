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

// Shadow-map projection of a light: 1 layer for directional and spot lights,
// 6 (+X,-X,+Y,-Y,+Z,-Z) for point lights. Area lights: areaMapProjection.
struct LightProjection {
    glm::mat4 viewProj[6];
    uint32_t layers = 1;
    float nearPlane = 0, farPlane = 1; // light-view depth range of every layer
    bool perspective = false;
    float footprint = 1;               // perspective: 2 tan(fov/2); orthographic: map width in model units
    // Orthographic (directional lights): the light's view and the map's
    // x (left, right) and y (bottom, top) range in it.
    glm::mat4 view{1.0f};
    glm::vec4 orthoRect{0.0f};
};
// nearestGeometry: a point or spot light's distance to the model's nearest
// triangle (nearestTriangleDistance; 0: not known). Every depth layer then
// starts at the nearest depth that geometry can have in it, not at the model
// box's (0 for a light among the geometry, clamped to far / 10^4): depth is
// stored as z/w in 32-bit floats, so near / far sets its precision far from
// the light, and 10^-4 left about 2 cm per step at 40 units from a light
// whose range is 92, below the depth bias: acne. A spot light over a floor,
// inside the model's box: sm wrong on 16% of the pixels in its cone before,
// 0.03% after (selective_test.cpp: ASpotLightAmongTheGeometryCastsNoAcne).
LightProjection lightProjection(const Light& light, const Bounds& bounds, float nearestGeometry = 0.0f);

// Directional lights, fitted to the view: narrows the model-fitted map in x
// and y to the light-space bounds of the surface the camera sees, given in the
// model-fitted map's clip space (view_fit.comp.glsl), grown by
// PENUMBRA_VIEW_FIT_MARGIN_TEXELS texels of a mapSize map. The depth range
// stays, so every caster between the light and those receivers is still in
// the map, and the casters beside them fall out of its frustum (culling). The
// texels get finer by the same factor. Returns modelFit unchanged when the
// bounds are empty (nothing covered) or would not make the map smaller.
LightProjection fitDirectionalToView(const LightProjection& modelFit, glm::vec3 clipMin, glm::vec3 clipMax, uint32_t mapSize);

// Shadow map of an area light from one of its points (soft shadows): a single
// perspective map looking along axis, its field of view fitted to the scene
// bounds and capped at PENUMBRA_AREA_MAX_HALF_FOV (capped: some of the scene
// lies outside; pixels there are ray traced).
struct AreaMapProjection {
    glm::mat4 viewProj{1.0f};
    float nearPlane = 0, farPlane = 1;
    float footprint = 2;   // 2 tan(fov / 2)
    bool capped = false;
    glm::mat4 view{1.0f};  // the map's view (eye at the origin, looking down -z)
};
// nearestGeometry: the eye's distance to the model's nearest triangle, as for lightProjection (0: not known).
AreaMapProjection areaMapProjection(glm::vec3 eye, glm::vec3 axis, glm::vec3 up, const Bounds& bounds, float nearestGeometry = 0.0f);

// Area-light map fitted to the view: a narrower map from the same eye, its
// axis through the middle of the camera's visible points (given by their
// bounds in modelFit's clip space, x/w and y/w) and its square field of view
// covering them, widened by spreadTan (the tangent of the widest angle at
// which an occluder beside them can still throw penumbra onto them) and
// PENUMBRA_VIEW_FIT_MARGIN_TEXELS texels of a mapSize map. Its depth range
// holds the bounds (near: the eye's distance to the box, shortened to the
// frustum's corner ray). Returns modelFit unchanged when the eye lies in the
// bounds or the fit would not narrow the map.
AreaMapProjection fitAreaMapToView(const AreaMapProjection& modelFit, glm::vec3 eye, glm::vec3 up, const Bounds& bounds, glm::vec2 clipMin,
                                   glm::vec2 clipMax, float spreadTan, uint32_t mapSize);

} // namespace penumbra
