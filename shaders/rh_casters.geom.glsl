#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
// Cone ray hierarchies, the casters of one batch (rh.glsli): the clusters of
// the light layer's culled view are drawn with the rasterizer off; each
// triangle, decoded by the vertex shader exactly as the tracer decodes it
// (afsm_casters.vert.glsl), is appended to the batch's triangle list in world
// space. Triangles without area are left out (the watertight test never hits
// them). The host sizes each batch by its clusters' triangle counts, so the
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
    uint capacity; // triangles the list holds
    uint pad0, pad1, pad2;
} push;

void main()
{
    vec3 v0 = worldPosition[0], v1 = worldPosition[1], v2 = worldPosition[2];
    if (cross(v1 - v0, v2 - v0) == vec3(0.0))
        return;
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
