#version 450
#extension GL_GOOGLE_include_directive : require
// Alias-free shadow maps, casters (Sintorn et al. 2008, section 3.2): for
// one triangle and one grid cell, the exact test of every sample listed in
// the cell (afsm_samples.comp.glsl). The test is the tracer's watertight
// ray/triangle test of the sample's own shadow ray: its three edge functions
// are the planes through the ray and each edge (through the light and each
// edge for point and spot lights; the edges' extrusions along the light's
// direction for directional lights) and t the triangle's supporting plane,
// as in the paper; a hit sets the sample's shadow flag. No depth is compared,
// so there is no acne and no aliasing, and the result equals the tracer's.

#include "config.h"
#include "shadow_common.glsli"
#include "shadow_ray.glsli"
#include "afsm.glsli"

layout(location = 0) flat in vec3 vertex0;
layout(location = 1) flat in vec3 vertex1;
layout(location = 2) flat in vec3 vertex2;
layout(location = 3) flat in vec4 projected01;
layout(location = 4) flat in vec4 projected2;

// Whether the cell's square can meet the triangle's projection grown by half a
// cell (the rectangle drawn is only the triangle's bounds, grown by one cell).
// Each edge's half-plane is moved outward by the square's extent along the
// edge's normal (conservative rasterization's edge test) plus that margin:
// a point light's ray starts rayOffset off the line through the light, so an
// occluder very near the light projects slightly beside the sample's cell.
bool cellMayMeetTriangle(vec2 centre)
{
    if (projected2.w == 0.0)
        return true;
    vec2 v[3] = vec2[](projected01.xy, projected01.zw, projected2.xy);
    float area = (v[1].x - v[0].x) * (v[2].y - v[0].y) - (v[1].y - v[0].y) * (v[2].x - v[0].x);
    if (area == 0.0)
        return true; // a sliver seen edge-on: its bounds are all there is
    float orientation = area > 0.0 ? 1.0 : -1.0;
    for (int i = 0; i < 3; ++i) {
        vec2 a = v[i], b = v[(i + 1) % 3];
        vec2 normal = orientation * vec2(b.y - a.y, a.x - b.x); // points outward
        float reach = 0.5 * (abs(normal.x) + abs(normal.y)) + 0.5 * length(normal);
        if (dot(centre - a, normal) > reach)
            return false;
    }
    return true;
}

// C++: runtime/src/passes/afsm.h (AfsmCastersBinding).
layout(set = 0, binding = 0, rgba32f) uniform readonly image2D gPosition;
layout(set = 0, binding = 1, rgba32f) uniform readonly image2D gNormal;
layout(set = 0, binding = 2, std140) uniform Frame { FrameData frame; };
layout(set = 0, binding = 3, std430) readonly buffer CellFirst { uint cellFirst[]; };  // first slot per cell
layout(set = 0, binding = 4, std430) readonly buffer CellCount { uint cellCount[]; };  // samples per cell
layout(set = 0, binding = 5, std430) readonly buffer SampleList { uint samplePixels[]; };
layout(set = 0, binding = 6, std430) buffer Shadowed { uint shadowed[]; };

layout(push_constant) uniform AfsmCastersPush {
    mat4 viewProj;
    uint lightIndex;
    uint gridSize;
    float originOffset;
    uint pad;
} push;

void main()
{
    uvec2 cellXY = uvec2(gl_FragCoord.xy);
    uint cell = cellXY.y * push.gridSize + cellXY.x;
    uint first = cellFirst[cell];
    uint count = cellCount[cell];
    if (count == 0u || !cellMayMeetTriangle(vec2(cellXY) + 0.5))
        return;
    int width = imageSize(gPosition).x;
    for (uint i = 0u; i < count; ++i) {
        uint pixelIndex = samplePixels[first + i];
        if (shadowed[pixelIndex] != 0u)
            continue;
        ivec2 pixel = ivec2(int(pixelIndex) % width, int(pixelIndex) / width);
        ShadowRay ray;
        if (!afsmSampleRay(frame.lights[push.lightIndex], imageLoad(gPosition, pixel).xyz, imageLoad(gNormal, pixel).xyz, push.originOffset, ray))
            continue;
        if (hitsTriangle(ray, shearVertex(ray, vertex0), shearVertex(ray, vertex1), shearVertex(ray, vertex2)))
            shadowed[pixelIndex] = 1u;
    }
}
