#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_ballot : require
// Cone ray hierarchies, one traversal step (rh.glsli; Olsson and Assarsson
// 2011, sections 3.1-3.2): each (triangle, node) pair of the chunk rh_step
// picked is tested with the cone/triangle test of the push constant. A pair
// that passes above the leaves becomes the pairs of the node's children,
// appended to the next depth's segment (one atomic per subgroup, no
// workgroup barriers: they are expensive on CPU drivers); at a leaf
// each of its rays not yet shadowed gets the tracer's exact watertight
// ray/triangle test (rhShadowRay: the same ray as trace.comp's), and a hit
// sets the pixel's shadow flag (the afsm resolve turns the flags into the
// light's visibility).

#include "config.h"
#include "shadow_common.glsli"
#include "shadow_ray.glsli"
#include "rh.glsli"

layout(local_size_x = PENUMBRA_RH_GROUP_SIZE) in;

// C++: runtime/src/passes/rh.h (RhTraverseBinding).
layout(set = 0, binding = 0, rgba32f) uniform readonly image2D gPosition;
layout(set = 0, binding = 1, rgba32f) uniform readonly image2D gNormal;
layout(set = 0, binding = 2, std140) uniform Frame { FrameData frame; };
layout(set = 0, binding = 3, std430) readonly buffer Rays { uint rayPixels[]; };
layout(set = 0, binding = 4, std430) readonly buffer Nodes { vec4 nodes[]; };
layout(set = 0, binding = 5, std430) readonly buffer Triangles { uvec2 triangles[]; }; // 5 per triangle (rh_casters.geom)
layout(set = 0, binding = 6, std430) buffer Pairs { uvec2 pairs[]; };
layout(set = 0, binding = 7, std430) buffer Shadowed { uint shadowed[]; };
#define RH_STATE_BINDING 8
RH_STATE_DECLARE();

layout(push_constant) uniform RhTraversePush {
    uint lightIndex;
    uint test;          // PENUMBRA_RH_TEST_*
    float originOffset; // the rays' origin offset (the cones grow by it)
    uint pad;
} push;

// The triangle's 9 coordinates in 64-bit words: llvmpipe loads each
// component of a divergent address lane by lane, so wider words cost less.
void loadTriangle(uint triangle, out vec3 v0, out vec3 v1, out vec3 v2)
{
    uint base = 5u * triangle;
    vec2 a = uintBitsToFloat(triangles[base]), b = uintBitsToFloat(triangles[base + 1u]), c = uintBitsToFloat(triangles[base + 2u]);
    vec2 d = uintBitsToFloat(triangles[base + 3u]), e = uintBitsToFloat(triangles[base + 4u]);
    v0 = vec3(a, b.x);
    v1 = vec3(b.y, c);
    v2 = vec3(d, e.x);
}

void main()
{
    uint i = gl_GlobalInvocationID.x;
    uint depth = state.stepDepth;
    uint level = state.levels - 1u - depth;
    bool inStep = i < state.stepCount;
    uint triangle = 0u, node = 0u;
    if (inStep) {
        if (depth == 0u) {
            triangle = state.stepBegin + i;
        } else {
            uvec2 pair = pairs[state.stepBegin + i];
            triangle = pair.x;
            node = pair.y;
        }
    }
    vec3 v0, v1, v2;
    loadTriangle(triangle, v0, v1, v2);
    vec4 node0 = nodes[2u * (state.levelOffset[level] + node)];
    vec4 node1 = nodes[2u * (state.levelOffset[level] + node) + 1u];
    vec3 light = frame.lights[push.lightIndex].positionType.xyz;
    bool pass = inStep && node0.w >= 0.0;
    PENUMBRA_SKIP_UNLESS(pass && node0.w < 3.14159)
    {
        ConeFrame f = coneFrame(node0, node1, light, push.originOffset);
        pass = push.test == PENUMBRA_RH_TEST_SPHERES ? sphereMayMeetCone(f, v0, v1, v2) : preciseMayMeetCone(f, v0, v1, v2);
    }
    // Inner nodes: the children's pairs, one atomic per subgroup.
    uint children = 0u;
    if (pass && level > 0u)
        children = min(4u, state.levelCount[level - 1u] - 4u * node);
    uint slot = subgroupExclusiveAdd(children);
    uint total = subgroupAdd(children);
    uint base = 0u;
    if (subgroupElect() && total != 0u)
        base = atomicAdd(state.segEnd[depth + 1u], total);
    base = subgroupBroadcastFirst(base);
    for (uint k = 0u; k < children; ++k)
        pairs[base + slot + k] = uvec2(triangle, 4u * node + k);
    // Leaves: the exact test of each ray not yet in shadow.
    uint tests = 0u;
    PENUMBRA_SKIP_UNLESS(pass && level == 0u)
    {
        int width = imageSize(gPosition).x;
        for (uint k = 0u; k < 4u; ++k) {
            uint r = 4u * node + k;
            uint pixelIndex = r < state.rayCount ? rayPixels[r] : RH_NO_RAY;
            if (pixelIndex == RH_NO_RAY || shadowed[pixelIndex] != 0u)
                continue;
            ivec2 pixel = ivec2(int(pixelIndex % uint(width)), int(pixelIndex / uint(width)));
            ShadowRay ray;
            if (!rhShadowRay(light, imageLoad(gPosition, pixel).xyz, imageLoad(gNormal, pixel).xyz, push.originOffset, ray))
                continue;
            ++tests;
            if (hitsTriangle(ray, shearVertex(ray, v0), shearVertex(ray, v1), shearVertex(ray, v2)))
                shadowed[pixelIndex] = 1u;
        }
    }
    if (level == 0u) {
        uint subgroupTests = subgroupAdd(tests);
        if (subgroupElect() && subgroupTests != 0u)
            atomicAdd(state.rayTests, uint64_t(subgroupTests));
    }
}
