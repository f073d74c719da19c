// Lights as the shaders see them: gpu::LightData (config.h) with its shadow
// maps' projections, fitted to the model or to what the camera sees.
#pragma once

#include <vector>

#include <glm/vec3.hpp>

#include "config.h"
#include "penumbra/penumbra.h"

namespace penumbra {

// Bounds of the camera's visible points in the clip space of one model-fitted
// shadow map (view_fit.comp.glsl); not valid: the map stays model-fitted.
struct ViewClip {
    bool valid = false;
    glm::vec3 min{0.0f}, max{0.0f};
};

// Area lights: the points their shadow maps are taken from (the method's AreaMapEyes).
std::vector<glm::vec3> areaMapEyes(const Light& light, glm::vec3 axis, const Bounds& bounds, const RenderSettings& settings);

// viewClip (RenderSettings::fitShadowMapsToView): per map of the light (a
// directional light's one, an area light's spotCosLayers.w), the bounds its
// map is fitted to; null: every map fitted to the model.
// model: the loaded model, whose nearest triangle to a point or spot light,
// or to an area light's map eyes, the maps' near planes go up to
// (light_space.h: lightProjection); null: the model's box alone.
gpu::LightData packLight(const Light& light, const Bounds& bounds, const RenderSettings& settings, const ViewClip* viewClip = nullptr,
                         const CompressedModel* model = nullptr);

} // namespace penumbra
