#version 450
#extension GL_GOOGLE_include_directive : require
// Alias-free shadow maps, casters (Sintorn et al. 2008, section 3.2):
// conservative rasterization of each triangle over the sample grid. lavapipe
// has no conservative-rasterization extension, so the triangle is drawn as
// its bounding rectangle in the grid, grown by one cell on each side: every
// cell whose area the triangle's projection touches has its centre inside,
// so the fragment shader sees every cell whose samples the triangle can
// shadow (afsm_casters.frag.glsl tests them exactly). A triangle reaching
// behind a perspective projection's eye covers the whole grid.

#include "config.h"

layout(triangles) in;
layout(triangle_strip, max_vertices = 4) out;

layout(location = 0) in vec3 worldPosition[];
layout(location = 0) flat out vec3 vertex0;
layout(location = 1) flat out vec3 vertex1;
layout(location = 2) flat out vec3 vertex2;
// The triangle's projection in grid cells, for the fragment shader's exact
// cell test; edges.w = 0: no test (a vertex behind the eye).
layout(location = 3) flat out vec4 projected01; // xy vertex 0, zw vertex 1
layout(location = 4) flat out vec4 projected2;  // xy vertex 2, w = 1 when valid

layout(push_constant) uniform AfsmCastersPush {
    mat4 viewProj;     // the layer's projection (the grid's)
    uint lightIndex;
    uint gridSize;     // cells per side
    float originOffset;
    uint pad;
} push;

void main()
{
    vec2 lo = vec2(-1.0), hi = vec2(1.0);
    bool behind = false;
    vec2 pmin = vec2(3.0e38), pmax = vec2(-3.0e38);
    vec2 cells[3];
    for (int i = 0; i < 3; ++i) {
        vec4 clip = push.viewProj * vec4(worldPosition[i], 1.0);
        if (clip.w <= 1e-20) {
            behind = true;
            break;
        }
        vec2 ndc = clip.xy / clip.w;
        cells[i] = (ndc * 0.5 + 0.5) * float(push.gridSize);
        pmin = min(pmin, ndc);
        pmax = max(pmax, ndc);
    }
    if (!behind) {
        float cell = 2.0 / float(push.gridSize);
        lo = max(pmin - vec2(cell), vec2(-1.0));
        hi = min(pmax + vec2(cell), vec2(1.0));
        if (any(greaterThan(lo, hi)))
            return;
    }
    const vec2 corners[4] = vec2[](vec2(0.0, 0.0), vec2(1.0, 0.0), vec2(0.0, 1.0), vec2(1.0, 1.0));
    for (int i = 0; i < 4; ++i) {
        gl_Position = vec4(mix(lo, hi, corners[i]), 0.5, 1.0);
        vertex0 = worldPosition[0];
        vertex1 = worldPosition[1];
        vertex2 = worldPosition[2];
        projected01 = behind ? vec4(0.0) : vec4(cells[0], cells[1]);
        projected2 = behind ? vec4(0.0) : vec4(cells[2], 0.0, 1.0);
        EmitVertex();
    }
    EndPrimitive();
}
