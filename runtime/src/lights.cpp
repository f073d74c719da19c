// Lights as the shaders see them (gpu::LightData), and the points an area
// light's shadow maps are taken from.
#include "lights.h"

#include <cmath>

#include "light_space.h"
#include "penumbra/light_sampling.h"
#include "penumbra/model_format.h"
#include "shadow_methods.h"

namespace penumbra {

// Area lights: the points their shadow maps are taken from. srt: the centre,
// then (penumbraMaps 5) four points on the rim: the rectangle's corners, the
// ends of the disk's axes, or of the sphere's axes across the map direction.
// frt: the centre (its map is not drawn). sm: the centres of K strata of the
// light (penumbra/light_sampling.h), seen from the middle of the scene.
std::vector<glm::vec3> areaMapEyes(const Light& light, glm::vec3 axis, const Bounds& bounds, const RenderSettings& settings)
{
    glm::vec3 u, v;
    areaLightAxes(light, u, v);
    if (light.type == LightType::Sphere) {
        glm::vec3 side = std::abs(axis.x) < 0.9f ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0);
        u = glm::normalize(glm::cross(axis, side)) * light.radius;
        v = glm::normalize(glm::cross(axis, u)) * light.radius;
    }
    std::vector<glm::vec3> eyes;
    const AreaMapEyes kind = shadowMethodSpec(settings.shadows).areaEyes;
    if (kind == AreaMapEyes::Strata) {
        glm::vec3 su, sv;
        areaLightAxes(light, su, sv);
        uint32_t k = settings.softShadowMaps;
        uint32_t columns = uint32_t(std::ceil(std::sqrt(float(k))));
        uint32_t rows = (k + columns - 1) / columns;
        for (uint32_t i = 0; i < k; ++i) {
            glm::vec2 cell((float(i % columns) + 0.5f) / float(columns), (float(i / columns) + 0.5f) / float(rows));
            eyes.push_back(sampling::areaLightPoint(uint32_t(light.type == LightType::Rectangle ? PENUMBRA_LIGHT_RECTANGLE
                                                             : light.type == LightType::Disk ? PENUMBRA_LIGHT_DISK
                                                                                              : PENUMBRA_LIGHT_SPHERE),
                                                    light.position, su, sv, bounds.center(), cell));
        }
        return eyes;
    }
    eyes.push_back(light.position);
    if (kind == AreaMapEyes::CentreAndRim && settings.penumbraMaps == 5) {
        if (light.type == LightType::Rectangle)
            for (glm::vec2 c : {glm::vec2(1, 1), glm::vec2(-1, 1), glm::vec2(-1, -1), glm::vec2(1, -1)})
                eyes.push_back(light.position + c.x * u + c.y * v);
        else
            for (glm::vec3 d : {u, -u, v, -v})
                eyes.push_back(light.position + d);
    }
    return eyes;
}

// viewClip (RenderSettings::fitShadowMapsToView): per map of the light (a
// directional light's one, an area light's spotCosLayers.w), the bounds its
// map is fitted to.
gpu::LightData packLight(const Light& light, const Bounds& bounds, const RenderSettings& settings, const ViewClip* viewClip,
                         const CompressedModel* model)
{
    auto nearestGeometry = [&](glm::vec3 point) { return model ? nearestTriangleDistance(*model, point) : 0.0f; };
    gpu::LightData data{};
    if (isAreaLight(light)) {
        glm::vec3 u, v;
        areaLightAxes(light, u, v);
        bool oneSided = light.type != LightType::Sphere;
        float radius = light.type == LightType::Rectangle ? glm::length(u + v) : light.radius;
        data.areaU = glm::vec4(u, oneSided ? 1.0f : 0.0f);
        data.areaV = glm::vec4(v, radius);
        glm::vec3 axis = oneSided ? glm::normalize(light.direction) : bounds.center() - light.position;
        axis = glm::length(axis) > 0.0f ? glm::normalize(axis) : glm::vec3(0, -1, 0);
        std::vector<glm::vec3> eyes = areaMapEyes(light, axis, bounds, settings);
        for (size_t k = 0; k < eyes.size(); ++k) {
            AreaMapProjection map = areaMapProjection(eyes[k], axis, light.up, bounds, nearestGeometry(eyes[k]));
            if (viewClip && viewClip[k].valid) {
                // srt: an occluder beside the visible points throws penumbra onto them from
                // light points up to Rbig off the eye (penumbra_mask.comp.glsl), so the map
                // widens by that angle seen from the nearest geometry.
                float spreadTan = 0.0f;
                if (shadowMethodSpec(settings.shadows).widenAreaMaps) {
                    const float rBig = glm::length(light.position - eyes[k]) + data.areaV.w;
                    const float nearest = glm::length(glm::clamp(eyes[k], bounds.min, bounds.max) - eyes[k]);
                    const float sine = nearest > 0.0f ? 1.05f * rBig / nearest : 1.0f;
                    spreadTan = sine < 0.9f ? sine / std::sqrt(1.0f - sine * sine) : -1.0f; // -1: too near, stays model-fitted
                }
                map = fitAreaMapToView(map, eyes[k], light.up, bounds, glm::vec2(viewClip[k].min), glm::vec2(viewClip[k].max), spreadTan,
                                       settings.shadowMapSize);
            }
            data.viewProj[k] = map.viewProj;
            data.mapEye[k] = glm::vec4(eyes[k], map.nearPlane);
            data.mapRange[k] = glm::vec4(map.farPlane, map.footprint, map.capped ? 1.0f : 0.0f, 0.0f);
            if (k == 0)
                data.shadowParams = glm::vec4(map.nearPlane, map.farPlane, 1.0f, map.footprint);
        }
        data.spotCosLayers = glm::vec4(1.0f, 1.0f, 1.0f, float(eyes.size()));
    } else {
        LightProjection projection =
            lightProjection(light, bounds, light.type == LightType::Directional ? 0.0f : nearestGeometry(light.position));
        const float modelFootprint = projection.footprint;
        if (viewClip && viewClip[0].valid)
            projection = fitDirectionalToView(projection, viewClip[0].min, viewClip[0].max, settings.shadowMapSize);
        std::copy(std::begin(projection.viewProj), std::end(projection.viewProj), std::begin(data.viewProj));
        data.shadowParams = glm::vec4(projection.nearPlane, projection.farPlane, projection.perspective ? 1.0f : 0.0f, projection.footprint);
        data.spotCosLayers = glm::vec4(std::cos(glm::radians(light.innerConeDegrees)), std::cos(glm::radians(light.outerConeDegrees)),
                                       float(projection.layers), projection.footprint / modelFootprint);
    }
    uint32_t type = 0;
    switch (light.type) {
    case LightType::Point: type = PENUMBRA_LIGHT_POINT; break;
    case LightType::Spot: type = PENUMBRA_LIGHT_SPOT; break;
    case LightType::Directional: type = PENUMBRA_LIGHT_DIRECTIONAL; break;
    case LightType::Rectangle: type = PENUMBRA_LIGHT_RECTANGLE; break;
    case LightType::Disk: type = PENUMBRA_LIGHT_DISK; break;
    case LightType::Sphere: type = PENUMBRA_LIGHT_SPHERE; break;
    }
    data.positionType = glm::vec4(light.position, float(type));
    glm::vec3 direction = glm::length(light.direction) > 0.0f ? glm::normalize(light.direction) : glm::vec3(0, -1, 0);
    data.directionRange = glm::vec4(direction, light.range);
    data.colorIntensity = glm::vec4(light.color, light.intensity);
    return data;
}

} // namespace penumbra
