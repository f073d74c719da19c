#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
// Cone ray hierarchies, the casters of one batch (rh.glsli): the clusters of
// the light layer's culled view are drawn with the rasterizer off; each
// triangle, decoded by the vertex shader exactly as the tracer decodes it
// (afsm_casters.vert.glsl), is appended to the batch's triangle list in world
// space. Triangles without area are left out (the watertight test never hits
// them). The two-pass traversal draws the casters twice, the large ones
// first, then the rest. The host sizes each batch by its clusters' triangle counts, so the
// list never overflows (RhState::overflow bit 2 says if it did).

#include "config.h"
#include "shadow_ray.glsli"
#include "rh.glsli"

layout(triangles) in;
layout(points, max_vertices = 1) out;

layout(location = 0) in vec3 worldPosition[];

#define RH_STATE_BINDING 0
RH_STATE_DECLARE();
// C++: runtime/src/passes/rh.h (RhCastersBinding).
layout(set = 0, binding = 1, std430) writeonly buffer Triangles { uvec2 triangles[]; }; // 5 words of 64 bits per triangle (x, y, z per vertex, then padding)

layout(push_constant) uniform RhCastersPush {
    vec4 lightLarge; // xyz: the light; w: the two-pass traversal's "large" (bounding-sphere radius / distance from the light)
    uint capacity;   // triangles the list holds
    uint select;     // PENUMBRA_RH_CASTERS_ALL, _LARGE (first pass), _SMALL (second pass)
    uint pad0, pad1;
} push;

void main()
{
    vec3 v0 = worldPosition[0], v1 = worldPosition[1], v2 = worldPosition[2];
    if (cross(v1 - v0, v2 - v0) == vec3(0.0))
        return;
    if (push.select != PENUMBRA_RH_CASTERS_ALL) {
        // Two-pass traversal (section 3.4): good occluders first. A triangle is
        // large when its bounding sphere spans a wide angle from the light.
        vec3 centre = (v0 + v1 + v2) * (1.0 / 3.0);
        float radius = sqrt(max(max(dot(v0 - centre, v0 - centre), dot(v1 - centre, v1 - centre)), dot(v2 - centre, v2 - centre)));
        bool large = radius >= push.lightLarge.w * length(centre - push.lightLarge.xyz);
        if (large != (push.select == PENUMBRA_RH_CASTERS_LARGE))
            return;
    }
    uint slot = atomicAdd(state.triangleCount, 1u);
    if (slot >= push.capacity) {
        atomicOr(state.overflow, 2u);
        return;
    }
    uint base = 5u * slot;
    triangles[base + 0u] = floatBitsToUint(v0.xy);
    triangles[base + 1u] = floatBitsToUint(vec2(v0.z, v1.x));
    triangles[base + 2u] = floatBitsToUint(v1.yz);
    triangles[base + 3u] = floatBitsToUint(v2.xy);
    triangles[base + 4u] = floatBitsToUint(vec2(v2.z, 0.0));
}
