#include "light_space.h"

#include <algorithm>
#include <cmath>

#include <glm/gtc/matrix_transform.hpp>

#include "config.h"
#include "penumbra/error.h"

namespace penumbra {

namespace {

// Flips y so that row 0 of every render target is the top of the view: the
// whole y row, so that off-centre (asymmetric) projections stay in range.
glm::mat4 vulkanClip(glm::mat4 projection)
{
    for (int column = 0; column < 4; ++column)
        projection[column][1] = -projection[column][1];
    return projection;
}

glm::vec3 corner(const Bounds& b, int i)
{
    return {i & 1 ? b.max.x : b.min.x, i & 2 ? b.max.y : b.min.y, i & 4 ? b.max.z : b.min.z};
}

// Any up vector not parallel to forward.
glm::vec3 stableUp(glm::vec3 forward, glm::vec3 preferred)
{
    glm::vec3 f = glm::normalize(forward);
    if (glm::length(preferred) > 0.0f && std::abs(glm::dot(f, glm::normalize(preferred))) < 0.999f)
        return glm::normalize(preferred);
    return std::abs(f.y) < 0.9f ? glm::vec3(0, 1, 0) : glm::vec3(1, 0, 0);
}

// Near and far distances along a view that contain the bounds.
void depthRange(const glm::mat4& view, const Bounds& bounds, float& nearPlane, float& farPlane)
{
    float zMin = 1e30f, zMax = -1e30f;
    for (int i = 0; i < 8; ++i) {
        float z = -(view * glm::vec4(corner(bounds, i), 1.0f)).z;
        zMin = std::min(zMin, z);
        zMax = std::max(zMax, z);
    }
    farPlane = std::max(zMax * 1.01f, 1e-3f);
    nearPlane = std::max(zMin * 0.99f, farPlane * 1e-4f);
}

glm::mat4 perspectiveFitted(glm::vec3 eye, glm::vec3 forward, glm::vec3 up, float fovRadians, float aspect, const Bounds& bounds,
                            float nearPlane = 0.0f, float farPlane = 0.0f)
{
    glm::mat4 view = glm::lookAtRH(eye, eye + forward, stableUp(forward, up));
    float n, f;
    depthRange(view, bounds, n, f);
    if (nearPlane > 0.0f) n = nearPlane;
    if (farPlane > 0.0f) f = farPlane;
    if (!(f > n))
        f = n * 2.0f;
    return vulkanClip(glm::perspectiveRH_ZO(fovRadians, aspect, n, f)) * view;
}

} // namespace

ViewProjection cameraViewProjection(const Camera& camera, const Bounds& bounds, float aspect)
{
    glm::vec3 forward = camera.target - camera.position;
    if (glm::length(forward) == 0.0f)
        fail("camera", "position and target must differ");
    forward = glm::normalize(forward);
    ViewProjection result;
    result.eye = camera.position;
    if (camera.projection == Projection::Perspective) {
        result.viewProj = perspectiveFitted(camera.position, forward, camera.up, glm::radians(camera.yfovDegrees), aspect, bounds,
                                            camera.nearPlane, camera.farPlane);
        return result;
    }
    glm::mat4 view = glm::lookAtRH(camera.position, camera.position + forward, stableUp(forward, camera.up));
    float n, f;
    depthRange(view, bounds, n, f);
    n = camera.nearPlane > 0.0f ? camera.nearPlane : std::min(n, 0.0f) - 1e-3f * (f - n + 1.0f);
    if (camera.farPlane > 0.0f) f = camera.farPlane;
    float h = camera.orthoHeight * 0.5f, w = h * aspect;
    result.viewProj = vulkanClip(glm::orthoRH_ZO(-w, w, -h, h, n, f)) * view;
    return result;
}

LightProjection lightProjection(const Light& light, const Bounds& bounds, float nearestGeometry)
{
    LightProjection result;
    if (light.type == LightType::Directional) {
        glm::vec3 dir = glm::normalize(light.direction);
        float radius = std::max(glm::length(bounds.extent()) * 0.5f, 1e-3f);
        glm::vec3 eye = bounds.center() - dir * radius * 2.0f;
        glm::mat4 view = glm::lookAtRH(eye, bounds.center(), stableUp(dir, light.up));
        glm::vec3 lo(1e30f), hi(-1e30f);
        for (int i = 0; i < 8; ++i) {
            glm::vec3 p = glm::vec3(view * glm::vec4(corner(bounds, i), 1.0f));
            lo = glm::min(lo, p);
            hi = glm::max(hi, p);
        }
        float margin = radius * 1e-3f;
        result.nearPlane = -hi.z - margin;
        result.farPlane = -lo.z + margin;
        glm::mat4 projection = glm::orthoRH_ZO(lo.x - margin, hi.x + margin, lo.y - margin, hi.y + margin, result.nearPlane, result.farPlane);
        result.viewProj[0] = vulkanClip(projection) * view;
        result.footprint = std::max(hi.x - lo.x, hi.y - lo.y) + 2.0f * margin;
        result.view = view;
        result.orthoRect = glm::vec4(lo.x - margin, hi.x + margin, lo.y - margin, hi.y + margin);
        return result;
    }
    result.perspective = true;
    if (light.type == LightType::Spot) {
        glm::vec3 forward = glm::normalize(light.direction);
        glm::mat4 view = glm::lookAtRH(light.position, light.position + forward, stableUp(forward, light.up));
        depthRange(view, bounds, result.nearPlane, result.farPlane);
        float fov = glm::radians(2.0f * light.outerConeDegrees);
        // A point of the frustum at distance r has depth at least r cos of its corners' angle to the axis.
        const float halfTan = std::tan(fov * 0.5f);
        result.nearPlane = std::max(result.nearPlane, 0.99f * nearestGeometry / std::sqrt(1.0f + 2.0f * halfTan * halfTan));
        if (!(result.farPlane > result.nearPlane))
            result.farPlane = result.nearPlane * 2.0f;
        result.viewProj[0] = vulkanClip(glm::perspectiveRH_ZO(fov, 1.0f, result.nearPlane, result.farPlane)) * view;
        result.footprint = 2.0f * std::tan(fov * 0.5f);
        return result;
    }
    static const glm::vec3 axes[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    static const glm::vec3 ups[6] = {{0, -1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}, {0, -1, 0}, {0, -1, 0}};
    // Every face shares one depth range: near small enough for the nearest geometry in any direction.
    glm::vec3 nearest = glm::clamp(light.position, bounds.min, bounds.max);
    float farthest = 0.0f;
    for (int i = 0; i < 8; ++i)
        farthest = std::max(farthest, glm::length(corner(bounds, i) - light.position));
    result.farPlane = std::max(farthest * 1.01f, 1e-3f);
    // A cube face's corners lie at 1 / sqrt(3) of their distance along its axis: 0.5 is below.
    result.nearPlane = std::max(std::max(glm::length(nearest - light.position), nearestGeometry) * 0.5f, result.farPlane * 1e-4f);
    if (!(result.farPlane > result.nearPlane))
        result.farPlane = result.nearPlane * 2.0f;
    result.layers = 6;
    result.footprint = 2.0f; // 90 degrees
    for (int face = 0; face < 6; ++face) {
        glm::mat4 view = glm::lookAtRH(light.position, light.position + axes[face], ups[face]);
        result.viewProj[face] =
            vulkanClip(glm::perspectiveRH_ZO(glm::radians(90.0f), 1.0f, result.nearPlane, result.farPlane)) * view;
    }
    return result;
}

LightProjection fitDirectionalToView(const LightProjection& modelFit, glm::vec3 clipMin, glm::vec3 clipMax, uint32_t mapSize)
{
    if (modelFit.perspective || !(clipMin.x <= clipMax.x && clipMin.y <= clipMax.y))
        return modelFit;
    // Back from clip space: x = left + (c + 1) / 2 (right - left); Vulkan's y
    // is flipped, y = bottom + (1 - c) / 2 (top - bottom).
    const glm::vec4 rect = modelFit.orthoRect;
    const float width = rect.y - rect.x, height = rect.w - rect.z;
    auto toX = [&](float c) { return rect.x + 0.5f * (std::clamp(c, -1.0f, 1.0f) + 1.0f) * width; };
    auto toY = [&](float c) { return rect.z + 0.5f * (1.0f - std::clamp(c, -1.0f, 1.0f)) * height; };
    float left = toX(clipMin.x), right = toX(clipMax.x), bottom = toY(clipMax.y), top = toY(clipMin.y);
    // A floor on the extent (a view of one flat point), then the margin in
    // texels of the narrowed map: m = k (extent + 2 m) / size.
    const float minExtent = 1e-4f * std::max(width, height);
    const float extent = std::max({right - left, top - bottom, minExtent});
    const float texels = float(PENUMBRA_VIEW_FIT_MARGIN_TEXELS);
    const float margin = texels * extent / std::max(float(mapSize) - 2.0f * texels, 1.0f);
    left = std::max(rect.x, left - margin);
    right = std::min(rect.y, std::max(right, left + minExtent) + margin);
    bottom = std::max(rect.z, bottom - margin);
    top = std::min(rect.w, std::max(top, bottom + minExtent) + margin);
    if (right - left >= 0.99f * width && top - bottom >= 0.99f * height)
        return modelFit;
    LightProjection result = modelFit;
    glm::mat4 projection = glm::orthoRH_ZO(left, right, bottom, top, modelFit.nearPlane, modelFit.farPlane);
    result.viewProj[0] = vulkanClip(projection) * modelFit.view;
    result.footprint = std::max(right - left, top - bottom);
    result.orthoRect = glm::vec4(left, right, bottom, top);
    return result;
}

AreaMapProjection areaMapProjection(glm::vec3 eye, glm::vec3 axis, glm::vec3 up, const Bounds& bounds, float nearestGeometry)
{
    AreaMapProjection result;
    glm::vec3 forward = glm::length(axis) > 0.0f ? glm::normalize(axis) : glm::vec3(0, -1, 0);
    glm::mat4 view = glm::lookAtRH(eye, eye + forward, stableUp(forward, up));
    float diagonal = std::max(glm::length(bounds.extent()), 1e-6f);
    float maxTan = 0.0f, nearest = 1e30f, farthest = 0.0f;
    bool behind = false;
    for (int i = 0; i < 8; ++i) {
        glm::vec3 v = glm::vec3(view * glm::vec4(corner(bounds, i), 1.0f));
        float depth = -v.z;
        farthest = std::max(farthest, depth);
        if (depth <= 1e-6f * diagonal) {
            behind = true;
            continue;
        }
        nearest = std::min(nearest, depth);
        maxTan = std::max(maxTan, std::max(std::abs(v.x), std::abs(v.y)) / depth);
    }
    const float capTan = std::tan(glm::radians(float(PENUMBRA_AREA_MAX_HALF_FOV)));
    float halfTan = maxTan * 1.02f + 1e-4f;
    result.capped = behind || halfTan > capTan;
    halfTan = result.capped ? capTan : halfTan;
    result.farPlane = std::max(farthest * 1.01f, 1e-3f);
    result.nearPlane = behind ? result.farPlane * 1e-4f : std::max(nearest * 0.99f, result.farPlane * 1e-4f);
    // A point of the frustum at distance r has depth at least r cos of its corners' angle to the axis.
    result.nearPlane = std::max(result.nearPlane, 0.99f * nearestGeometry / std::sqrt(1.0f + 2.0f * halfTan * halfTan));
    if (!(result.farPlane > result.nearPlane))
        result.farPlane = result.nearPlane * 2.0f;
    result.footprint = 2.0f * halfTan;
    result.viewProj = vulkanClip(glm::perspectiveRH_ZO(2.0f * std::atan(halfTan), 1.0f, result.nearPlane, result.farPlane)) * view;
    result.view = view;
    return result;
}

AreaMapProjection fitAreaMapToView(const AreaMapProjection& modelFit, glm::vec3 eye, glm::vec3 up, const Bounds& bounds, glm::vec2 clipMin,
                                   glm::vec2 clipMax, float spreadTan, uint32_t mapSize)
{
    if (!(clipMin.x <= clipMax.x && clipMin.y <= clipMax.y) || !(spreadTan >= 0.0f))
        return modelFit;
    const glm::vec3 nearestPoint = glm::clamp(eye, bounds.min, bounds.max);
    const float nearest = glm::length(nearestPoint - eye);
    if (!(nearest > 0.0f))
        return modelFit; // the eye lies in the bounds: geometry all around it
    // View-space directions of the clip-space rectangle's corners (Vulkan's y
    // is flipped): x/-z = c.x tan, y/-z = -c.y tan.
    const float halfTan = 0.5f * modelFit.footprint;
    auto direction = [&](float cx, float cy) { return glm::normalize(glm::vec3(cx * halfTan, -cy * halfTan, -1.0f)); };
    const glm::vec3 corners[4] = {direction(clipMin.x, clipMin.y), direction(clipMax.x, clipMin.y), direction(clipMin.x, clipMax.y),
                                  direction(clipMax.x, clipMax.y)};
    const glm::vec3 axisView = direction(0.5f * (clipMin.x + clipMax.x), 0.5f * (clipMin.y + clipMax.y));
    float cone = 0.0f; // half-angle of the cone about the axis that holds the corners
    for (const glm::vec3& corner : corners)
        cone = std::max(cone, std::acos(std::clamp(glm::dot(axisView, corner), -1.0f, 1.0f)));
    // Widened by the penumbra spread, then by the margin in texels of the new
    // map (a texel spans about 2 tan / size radians at its centre).
    const float texels = float(PENUMBRA_VIEW_FIT_MARGIN_TEXELS);
    float angle = cone + std::atan(spreadTan);
    float newHalfTan = std::tan(angle);
    newHalfTan += texels * 2.0f * newHalfTan / std::max(float(mapSize) - 2.0f * texels, 1.0f) * (1.0f + newHalfTan * newHalfTan);
    if (!(newHalfTan < 0.95f * halfTan) || !(angle < 1.5f))
        return modelFit;

    const glm::vec3 axis = glm::normalize(glm::vec3(glm::inverse(modelFit.view) * glm::vec4(axisView, 0.0f)));
    AreaMapProjection result;
    glm::mat4 view = glm::lookAtRH(eye, eye + axis, stableUp(axis, up));
    // Depth range: every point of the bounds inside the frustum is at least
    // `nearest` from the eye, at an angle of at most the corner ray's from the axis.
    float farthest = 0.0f;
    for (int i = 0; i < 8; ++i)
        farthest = std::max(farthest, glm::length(corner(bounds, i) - eye));
    result.farPlane = std::max(farthest * 1.01f, 1e-3f);
    result.nearPlane = std::max(0.99f * nearest / std::sqrt(1.0f + 2.0f * newHalfTan * newHalfTan), result.farPlane * 1e-4f);
    if (!(result.farPlane > result.nearPlane))
        result.farPlane = result.nearPlane * 2.0f;
    result.footprint = 2.0f * newHalfTan;
    result.capped = true; // most of the model lies outside
    result.view = view;
    result.viewProj = vulkanClip(glm::perspectiveRH_ZO(2.0f * std::atan(newHalfTan), 1.0f, result.nearPlane, result.farPlane)) * view;
    return result;
}

} // namespace penumbra
