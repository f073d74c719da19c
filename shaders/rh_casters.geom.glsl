#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_int64 : require
// Cone ray hierarchies, the casters of one batch (rh.glsli): the clusters of
// the light's culled views are drawn with the rasterizer off; each triangle,
// decoded by the vertex shader exactly as the tracer decodes it
// (afsm_casters.vert.glsl), is appended to the batch's triangle list in world
// space. Triangles without area are left out (the watertight test never hits
// them). The two-pass traversal draws the casters twice, the large ones
// first, then the rest. The host sizes each batch by its clusters' triangle
// counts, so the list never overflows (RhState::overflow bit 2 says if it did).
// Each triangle carries its cluster's faces: a point light's cube faces whose
// culled view (frustum and receiver masks) kept the cluster; its records skip
// the other faces' rays (rh_traverse.comp). Other lights: every bit set.

#include "config.h"
#include "shadow_ray.glsli"
#include "rh.glsli"

layout(triangles) in;
layout(points, max_vertices = 1) out;

layout(location = 0) in vec3 worldPosition[];
layout(location = 1) flat in uint cluster[];

#define RH_STATE_BINDING 0
RH_STATE_DECLARE();
// C++: runtime/src/passes/rh.h (RhCastersBinding).
layout(set = 0, binding = 1, std430) writeonly buffer TrianglesA { u64vec4 trianglesA[]; }; // v0, v1, v2.xy
layout(set = 0, binding = 2, std430) writeonly buffer TrianglesB { uvec2 trianglesB[]; };   // v2.z, the faces it may shadow
layout(set = 0, binding = 3, std430) readonly buffer ClusterFaces { uint clusterFaces[]; }; // per cluster: faces whose view kept it

layout(push_constant) uniform RhCastersPush {
    vec4 lightLarge; // xyz: the light; w: the two-pass traversal's "large" (bounding-sphere radius / distance from the light)
    uint capacity;   // triangles the list holds
    uint select;     // PENUMBRA_RH_CASTERS_ALL, _LARGE (first pass), _SMALL (second pass)
    uint pointLight; // 1: the faces refined per triangle
    uint spotLight;  // 1: a spot light (the light at lightLarge.xyz); else with pointLight 0, directional: toLight
    vec4 toLight;    // directional lights: the unit vector toward the light
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
    // A point light's faces: the cluster's; a triangle whose corners all fall on one face lies inside
    // that face's pyramid (convex) and shadows no other face's rays.
    uint faces = clusterFaces[cluster[0]];
    // Section 3.6: a closed cluster (bit 8, when culling is exact: rh.h) casts only its
    // light-back-facing triangles (and none edge-on); the receivers' own triangles face the light.
    if ((faces & 256u) != 0u) {
        vec3 normal = cross(v1 - v0, v2 - v0);
        vec3 toLight = push.pointLight != 0u || push.spotLight != 0u ? push.lightLarge.xyz - v0 : push.toLight.xyz;
        if (dot(normal, toLight) >= 0.0)
            return;
    }
    faces &= 63u;
    if (push.pointLight != 0u) {
        vec3 light = push.lightLarge.xyz;
        uint f0 = cubeFace(v0 - light), f1 = cubeFace(v1 - light), f2 = cubeFace(v2 - light);
        faces &= f0 == f1 && f1 == f2 ? 1u << f0 : 63u;
    }
    uint slot = atomicAdd(state.triangleCount, 1u);
    if (slot >= push.capacity) {
        atomicOr(state.overflow, 2u);
        return;
    }
    trianglesA[slot] = u64vec4(pack64(floatBitsToUint(v0.xy)), pack64(floatBitsToUint(vec2(v0.z, v1.x))), pack64(floatBitsToUint(v1.yz)),
                               pack64(floatBitsToUint(v2.xy)));
    trianglesB[slot] = uvec2(floatBitsToUint(v2.z), faces);
}
