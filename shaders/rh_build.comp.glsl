#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
// Cone ray hierarchies, the bottom-up build (rh.glsli; Olsson and Assarsson
// 2011, section 3.1, after Roger et al. 2007), one mode per dispatch:
//  PENUMBRA_RH_BUILD_INIT (one invocation): the levels' sizes and offsets
//    from the ray count;
//  PENUMBRA_RH_BUILD_LEAVES: node i of level 0 bounds rays 4i .. 4i + 3: the
//    cone from the light around the directions to their points p, and the
//    longest distance from the light (push.skipShadowed: leaving out the rays
//    already shadowed, for the second pass of the two-pass traversal, whose
//    rebuilt cones are tighter and whose finished nodes are empty);
//  PENUMBRA_RH_BUILD_LEVEL: node i of level k bounds the cones of nodes
//    4i .. 4i + 3 of level k - 1.
// A node stores vec4(axis, half-angle) and vec4(longest, cos, sin, 0) of
// the half-angle grown by the rounding margin and at least
// PENUMBRA_RH_MIN_ANGLE (the tests use those); an angle < 0 marks a node with
// no ray below it. A cone wider than pi - 0.001 is stored as pi (every
// triangle passes it).

#include "config.h"
#include "shadow_common.glsli"
#include "shadow_ray.glsli"

layout(local_size_x = PENUMBRA_RH_GROUP_SIZE) in;

// C++: runtime/src/passes/rh.h (RhBuildBinding).
layout(set = 0, binding = 0, rgba32f) uniform readonly image2D gPosition;
layout(set = 0, binding = 1, std140) uniform Frame { FrameData frame; };
layout(set = 0, binding = 2, std430) readonly buffer Rays { uint rayPixels[]; };
layout(set = 0, binding = 3, std430) buffer Nodes { vec4 nodes[]; };
layout(set = 0, binding = 5, std430) readonly buffer Shadowed { uint shadowed[]; };
#include "rh.glsli"
#define RH_STATE_BINDING 4
RH_STATE_DECLARE();

layout(push_constant) uniform RhBuildPush {
    uint lightIndex;
    uint mode;  // PENUMBRA_RH_BUILD_*
    uint level; // PENUMBRA_RH_BUILD_LEVEL: the level built (>= 1)
    uint skipShadowed; // PENUMBRA_RH_BUILD_LEAVES: 1 leaves out the rays already shadowed
} push;

void storeNode(uint index, vec3 axis, float angle, float longest)
{
    float tested = angle < 0.0 ? 0.0 : max(grownAngle(angle), float(PENUMBRA_RH_MIN_ANGLE));
    tested = tested > 3.1406 ? 3.14159265 : tested;
    nodes[2u * index] = vec4(axis, angle < 0.0 ? -1.0 : tested);
    nodes[2u * index + 1u] = vec4(longest, cos(tested), tested >= 3.14159265 ? 0.0 : sin(tested), 0.0);
}

// The cone around unit directions (or cones) summed into `sum`, its angle
// found by a second pass over them (see the callers).
vec3 axisOf(vec3 sum, out bool degenerate)
{
    float l = length(sum);
    degenerate = l < 1e-6;
    return degenerate ? vec3(0.0, 0.0, 1.0) : sum / l;
}

void main()
{
    if (push.mode == PENUMBRA_RH_BUILD_INIT) {
        if (gl_GlobalInvocationID.x != 0u)
            return;
        uint count = (state.rayCount + 3u) / 4u;
        uint levels = 0u, offset = 0u;
        while (count > 0u && levels < PENUMBRA_RH_MAX_LEVELS) {
            state.levelOffset[levels] = offset;
            state.levelCount[levels] = count;
            offset += count;
            ++levels;
            if (count == 1u)
                break;
            count = (count + 3u) / 4u;
        }
        state.levels = levels;
        return;
    }
    uint node = gl_GlobalInvocationID.x;
    vec3 light = frame.lights[push.lightIndex].positionType.xyz;
    if (push.mode == PENUMBRA_RH_BUILD_LEAVES) {
        if (state.levels == 0u || node >= state.levelCount[0])
            return;
        int width = imageSize(gPosition).x;
        vec3 directions[4];
        bool valid[4];
        vec3 sum = vec3(0.0);
        float longest = 0.0;
        bool any = false;
        for (uint k = 0u; k < 4u; ++k) {
            uint r = 4u * node + k;
            uint pixelIndex = r < state.rayCount ? rayPixels[r] : RH_NO_RAY;
            valid[k] = pixelIndex != RH_NO_RAY && (push.skipShadowed == 0u || shadowed[pixelIndex] == 0u);
            directions[k] = vec3(0.0, 0.0, 1.0);
            if (valid[k]) {
                ivec2 pixel = ivec2(int(pixelIndex % uint(width)), int(pixelIndex / uint(width)));
                vec3 d = imageLoad(gPosition, pixel).xyz - light;
                float l = length(d);
                longest = max(longest, l);
                directions[k] = l > 0.0 ? d / l : vec3(0.0, 0.0, 1.0);
                sum += directions[k];
                any = true;
            }
        }
        bool degenerate;
        vec3 axis = axisOf(sum, degenerate);
        float angle = degenerate ? 3.1416 : 0.0;
        for (uint k = 0u; k < 4u; ++k)
            if (valid[k])
                angle = max(angle, angleBetween(axis, directions[k]));
        storeNode(state.levelOffset[0] + node, axis, any ? angle : -1.0, longest);
        return;
    }
    // PENUMBRA_RH_BUILD_LEVEL
    uint level = push.level;
    if (level >= state.levels || node >= state.levelCount[level])
        return;
    uint childOffset = state.levelOffset[level - 1u];
    uint childCount = state.levelCount[level - 1u];
    vec4 cones[4];
    float longest = 0.0;
    vec3 sum = vec3(0.0);
    bool any = false;
    for (uint k = 0u; k < 4u; ++k) {
        uint child = 4u * node + k;
        cones[k] = vec4(0.0, 0.0, 1.0, -1.0);
        if (child < childCount) {
            cones[k] = nodes[2u * (childOffset + child)];
            if (cones[k].w >= 0.0) {
                longest = max(longest, nodes[2u * (childOffset + child) + 1u].x);
                sum += cones[k].xyz;
                any = true;
            }
        }
    }
    bool degenerate;
    vec3 axis = axisOf(sum, degenerate);
    float angle = degenerate ? 3.1416 : 0.0;
    for (uint k = 0u; k < 4u; ++k)
        if (cones[k].w >= 0.0)
            angle = max(angle, angleBetween(axis, cones[k].xyz) + cones[k].w);
    storeNode(state.levelOffset[level] + node, axis, any ? min(angle, 3.1416) : -1.0, longest);
}
