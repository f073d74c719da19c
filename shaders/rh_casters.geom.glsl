#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_int64 : require
// Cone ray hierarchies, the casters of one batch (rh.glsli): the clusters of
// the light's culled views are drawn with the rasterizer off; each triangle,
// decoded by the vertex shader exactly as the tracer decodes it
// (world_casters.vert.glsl), is appended to the batch's triangle list in world
// space. Triangles without area are left out (the watertight test never hits
// them). The two-pass traversal draws the casters twice, the large ones
// first, then the rest. The host sizes each batch by its clusters' triangle
// counts, so the list never overflows (RhState::overflow bit 2 says if it did).
// Each triangle carries its cluster's faces: a point light's cube faces whose
// culled view (frustum and receiver masks) kept the cluster; its records skip
// the other faces' rays (rh_traverse.comp). Other lights: every bit set. A
// triangle deeper than every receiver in the cells of the receivers' depth
// grid it covers (rh.glsli) is left out: it can shadow none.

#include "config.h"
#include "shadow_common.glsli"
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
layout(set = 0, binding = 4, std430) readonly buffer DepthGrid { uint depthGrid[]; };      // the receivers' depth grid (rh.glsli)
layout(set = 0, binding = 5, std140) uniform Frame { FrameData frame; };

layout(push_constant) uniform RhCastersPush {
    vec4 lightLarge;    // xyz: the light; w: the two-pass traversal's "large" (bounding-sphere radius / distance from the light)
    vec4 toLightOffset; // directional lights: xyz the unit vector toward the light; w: the rays' origin offset
    uint capacity;      // triangles the list holds
    uint select;        // PENUMBRA_RH_CASTERS_ALL, _LARGE (first pass), _SMALL (second pass)
    uint pointLight;    // 1: a point light (the faces refined per triangle)
    uint spotLight;     // 1: a spot light (at lightLarge.xyz); neither: a directional light
    uint lightIndex;
    uint gridFaces;     // the receivers' depth grid's faces (0: none, no culling behind the receivers)
    uint gridOrder;     // ... and its order (2^order cells a side)
    uint pad0;
} push;

// The deepest receiver over the grid cells that [lo, hi] (face coordinates, [-1, 1]) covers: at most 2 x 2
// cells of the pyramid level where the range spans at most one cell. -inf: none.
float deepestReceiver(uint face, vec2 lo, vec2 hi)
{
    float span = max(hi.x - lo.x, hi.y - lo.y) * 0.5 * float(1u << push.gridOrder);
    uint level = uint(clamp(ceil(log2(max(span, 1.0))), 0.0, float(push.gridOrder)));
    uint side = 1u << (push.gridOrder - level);
    uvec2 first = uvec2(clamp((lo * 0.5 + 0.5) * float(side), vec2(0.0), vec2(float(side) - 1.0)));
    uvec2 last = uvec2(clamp((hi * 0.5 + 0.5) * float(side), vec2(0.0), vec2(float(side) - 1.0)));
    uint base = gridLevelBase(push.gridFaces, push.gridOrder, level) + face * side * side;
    uint deepest = max(max(depthGrid[base + first.y * side + first.x], depthGrid[base + first.y * side + last.x]),
                       max(depthGrid[base + last.y * side + first.x], depthGrid[base + last.y * side + last.x]));
    return deepest == RH_GRID_NONE ? uintBitsToFloat(0xFF800000u) : depthFromOrdered(deepest);
}

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
        vec3 toLight = push.pointLight != 0u || push.spotLight != 0u ? push.lightLarge.xyz - v0 : push.toLightOffset.xyz;
        if (dot(normal, toLight) >= 0.0)
            return;
    }
    faces &= 63u;
    if (push.pointLight != 0u) {
        vec3 light = push.lightLarge.xyz;
        uint f0 = cubeFace(v0 - light), f1 = cubeFace(v1 - light), f2 = cubeFace(v2 - light);
        faces &= f0 == f1 && f1 == f2 ? 1u << f0 : 63u;
    }
    // Behind every receiver (rh.glsli, the receivers' depth grid): a ray can meet the triangle only
    // nearer the light than its origin, and in about its direction (within the offset's angle).
    if (push.gridFaces != 0u) {
        float r = push.toLightOffset.w;
        bool behind = false;
        if (push.pointLight != 0u) {
            vec3 light = push.lightLarge.xyz;
            uint face = cubeFace(v0 - light);
            vec3 w0 = v0 - light, w1 = v1 - light, w2 = v2 - light;
            // No nearer than its plane, nor than its bounding sphere.
            vec3 normal = normalize(cross(w1 - w0, w2 - w0));
            vec3 centre = (w0 + w1 + w2) * (1.0 / 3.0);
            float radius = sqrt(max(max(dot(w0 - centre, w0 - centre), dot(w1 - centre, w1 - centre)), dot(w2 - centre, w2 - centre)));
            float nearest = max(abs(dot(normal, w0)), length(centre) - radius * 1.0001) * 0.9999;
            if (faces == (1u << face) && nearest > 2.5 * r) {
                vec2 c0 = cubeFaceCoordinates(w0, face), c1 = cubeFaceCoordinates(w1, face), c2 = cubeFaceCoordinates(w2, face);
                // A direction within angle g of the triangle's moves its face coordinates by at most 3 tan-rates.
                float spread = r / (nearest - 2.0 * r);
                float dilation = spread < 1.0 ? 3.0 * asin(spread) * 1.001 + 2.0 / float(1u << push.gridOrder) : 100.0;
                vec2 lo = min(min(c0, c1), c2) - dilation, hi = max(max(c0, c1), c2) + dilation;
                if (all(greaterThanEqual(lo, vec2(-1.0))) && all(lessThanEqual(hi, vec2(1.0))))
                    behind = nearest > deepestReceiver(face, lo, hi) * 1.00001 + 1.01 * r;
            }
        } else {
            // Directional: rays go up from their origins, straight across the grid's cells.
            mat4 viewProj = frame.lights[push.lightIndex].viewProj[0];
            vec2 c0 = (viewProj * vec4(v0, 1.0)).xy, c1 = (viewProj * vec4(v1, 1.0)).xy, c2 = (viewProj * vec4(v2, 1.0)).xy;
            float dilation = 2.0 / float(1u << push.gridOrder);
            vec2 lo = min(min(c0, c1), c2) - dilation, hi = max(max(c0, c1), c2) + dilation;
            vec3 heights = vec3(dot(v0, push.toLightOffset.xyz), dot(v1, push.toLightOffset.xyz), dot(v2, push.toLightOffset.xyz));
            float top = max(max(heights.x, heights.y), heights.z);
            float scale = max(max(abs(heights.x), abs(heights.y)), abs(heights.z)) + length(v0);
            behind = -top > deepestReceiver(0u, lo, hi) + 1e-5 * scale;
        }
        if (behind)
            return;
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
