#version 450
#extension GL_GOOGLE_include_directive : require
// Alias-free shadow maps, casters (Sintorn et al. 2008, section 3.2):
// conservative rasterization of each triangle over the sample grid. lavapipe
// has no conservative-rasterization extension, so the triangle is drawn as
// its bounding rectangle in the grid, grown by one cell on each side: every
// cell whose area the triangle's projection touches has its centre inside,
// so the fragment shader sees every cell whose samples the triangle can
// shadow (afsm_casters.frag.glsl tests them exactly). A triangle reaching
// behind a perspective projection's eye covers the whole grid. With
// push.computeCells > 0 the triangles whose rectangle spans at most that many
// cells were tested by the compute path (afsm_bin.comp.glsl) and are left out.

#include "config.h"
#include "shadow_common.glsli"
#include "shadow_ray.glsli"
#include "penumbra/light_sampling.h"
#include "afsm.glsli"
layout(set = 0, binding = 4, std430) readonly buffer CellCount { uint cellCount[]; }; // samples per cell
#define AFSM_RECTANGLES_ONLY 1
#include "afsm_casters.glsli"

layout(triangles) in;
layout(triangle_strip, max_vertices = 4) out;

layout(location = 0) in vec3 worldPosition[];
layout(location = 0) flat out vec3 vertex0;
layout(location = 1) flat out vec3 vertex1;
layout(location = 2) flat out vec3 vertex2;
// The triangle's projection in grid cells, for the fragment shader's exact
// cell test; projected2.w = 0: no test (a vertex behind the eye).
layout(location = 3) flat out vec4 projected01; // xy vertex 0, zw vertex 1
layout(location = 4) flat out vec4 projected2;  // xy vertex 2, w = 1 when valid

layout(push_constant) uniform AfsmCastersPush {
    mat4 viewProj;     // the layer's projection (the grid's)
    uint lightIndex;
    uint gridSize;     // cells per side
    float originOffset;
    float computeCells; // rectangles of at most this many cells: the compute path's (0: none)
} push;

void main()
{
    vec2 cells[3];
    bool behind;
    AfsmRect r = afsmHardRect(push.viewProj, worldPosition[0], worldPosition[1], worldPosition[2], push.gridSize, cells, behind);
    if (r.empty || afsmComputeTakes(r, push.gridSize, push.computeCells, 1u, true))
        return;
    const vec2 corners[4] = vec2[](vec2(0.0, 0.0), vec2(1.0, 0.0), vec2(0.0, 1.0), vec2(1.0, 1.0));
    for (int i = 0; i < 4; ++i) {
        gl_Position = vec4(mix(r.lo, r.hi, corners[i]), 0.5, 1.0);
        vertex0 = worldPosition[0];
        vertex1 = worldPosition[1];
        vertex2 = worldPosition[2];
        projected01 = behind ? vec4(0.0) : vec4(cells[0], cells[1]);
        projected2 = behind ? vec4(0.0) : vec4(cells[2], 0.0, 1.0);
        EmitVertex();
    }
    EndPrimitive();
}
