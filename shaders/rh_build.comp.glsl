#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_int64 : require
// Cone ray hierarchies, the bottom-up build and its helpers (rh.glsli;
// Olsson and Assarsson 2011, section 3.1, after Roger et al. 2007), one mode
// per dispatch:
//  PENUMBRA_RH_BUILD_DECIDE (one invocation): whether the light's rays are
//    sorted (push.sort: on, off, or auto: when the work sorting saves the
//    casters is worth its cost, below), and the indirect dispatches of the
//    sort (none when not sorting);
//  PENUMBRA_RH_BUILD_FACES (one invocation, sorted rays): each face of a
//    point light starts on a multiple of the alignment (a power of 4 near a
//    24th of the rays), so that the nodes below the top levels each hold one
//    face's rays (a cone over two faces is wide and passes most casters);
//    the slots between are left RH_NO_RAY; the list's length;
//  PENUMBRA_RH_BUILD_INIT (one invocation): the levels' sizes and offsets
//    from the ray count;
//  PENUMBRA_RH_BUILD_LEAVES: node i of level 0 bounds rays 4i .. 4i + 3
//    (push.skipShadowed: leaving out the rays already shadowed, for the
//    second pass of the two-pass traversal, whose rebuilt nodes are tighter
//    and whose finished nodes are empty);
//  PENUMBRA_RH_BUILD_LEVEL: node i of level k bounds nodes 4i .. 4i + 3 of
//    level k - 1;
//  PENUMBRA_RH_BUILD_RESOLVE: early accept's rays: each ray under a covered
//    node is in shadow;
//  PENUMBRA_RH_BUILD_GRID: level push.level of the receivers' depth grid,
//    each cell the deepest of its four below.
// A point or spot light's node (rh.glsli) is the cone from the light around
// the directions to the rays' points, with the longest and the shortest
// distance and the cube faces its rays fall on; its half-angle is grown by the rounding margin, and a cone
// wider than pi - 0.001 is stored as pi
// (every triangle passes it). A directional light's node (this shader
// compiled with PENUMBRA_RH_PARALLEL) bounds the rays' origins in the
// light's frame: their rectangle across the light and their heights along it.

#include "config.h"
#include "shadow_common.glsli"
#include "shadow_ray.glsli"
#include "rh.glsli"

layout(local_size_x = PENUMBRA_RH_GROUP_SIZE) in;

// C++: runtime/src/passes/rh.h (RhBuildBinding).
#include "surface.glsli"
layout(set = 0, binding = 0, rgba32ui) uniform readonly uimage2D gSurface; // binding 1, the G-buffer's albedo, is not read
layout(set = 0, binding = 2, std140) uniform Frame { FrameData frame; };
layout(set = 0, binding = 3, std430) buffer Rays { uvec4 rayQuads[]; }; // the ray list, 4 rays (one leaf) per element
layout(set = 0, binding = 4, std430) buffer Nodes { u64vec4 nodes[]; };
#define RH_STATE_BINDING 5
RH_STATE_DECLARE();
layout(set = 0, binding = 6, std430) buffer Shadowed { uint shadowed[]; };
layout(set = 0, binding = 7, std430) buffer DepthGrid { uint depthGrid[]; }; // the receivers' depth grid (rh.glsli)

// The mode is a specialization constant (one pipeline per mode; push.mode holds the same value): llvmpipe runs
// both sides of every if, masked (runtime/README.md), so with every mode in one shader each subgroup ran all
// of them: an empty workgroup cost 8.5 us (6144 of them 52 ms, the depth grid's first level as much).
layout(constant_id = 0) const uint kMode = PENUMBRA_RH_BUILD_LEVEL; // PENUMBRA_RH_BUILD_*

layout(push_constant) uniform RhBuildPush {
    uint lightIndex;
    uint mode;          // PENUMBRA_RH_BUILD_*: kMode's value
    uint level;         // PENUMBRA_RH_BUILD_LEVEL: the level built (>= 1)
    uint skipShadowed;  // PENUMBRA_RH_BUILD_LEAVES: 1 leaves out the rays already shadowed
    float originOffset; // the rays' origin offset (directional lights: the origins are bounded)
    uint sort;          // PENUMBRA_RH_BUILD_DECIDE: PENUMBRA_RH_SORT_*; PENUMBRA_RH_BUILD_GRID: the grid's order
    uint keyGroupsX;    // PENUMBRA_RH_BUILD_DECIDE: the key pass's workgroups (the image's tiles)
    uint keyGroupsY;
    uint scanGroups;    // PENUMBRA_RH_BUILD_DECIDE: the key scan's blocks
    uint faces;         // PENUMBRA_RH_BUILD_FACES: the light's faces (6 or 1)
    uint casters;       // PENUMBRA_RH_BUILD_DECIDE: the triangles of the light's culled views
    uint pad0;
} push;

#ifndef PENUMBRA_RH_PARALLEL
void storeCone(uint index, vec3 axis, float angle, float longest, float shortest, uint faces)
{
    float tested = angle < 0.0 ? 0.0 : grownAngle(angle);
    tested = tested > 3.1406 ? 3.14159265 : tested;
    nodes[index] = packNode(vec4(axis, angle < 0.0 ? -1.0 : withFaces(tested, faces)),
                            vec4(cos(tested), tested >= 3.14159265 ? 0.0 : sin(tested), longest, shortest));
}

// The cone around unit directions (or cones) summed into `sum`, its angle
// found by a second pass over them (see the callers).
vec3 axisOf(vec3 sum, out bool degenerate)
{
    float l = length(sum);
    degenerate = l < 1e-6;
    return degenerate ? vec3(0.0, 0.0, 1.0) : sum / l;
}
#endif

const float kEmpty = 3.0e38; // a slab node with no ray: an empty rectangle

void main()
{
    if (kMode == PENUMBRA_RH_BUILD_DECIDE) {
        if (gl_GlobalInvocationID.x != 0u)
            return;
        bool sorted = push.sort == PENUMBRA_RH_SORT_ON;
        if (push.sort == PENUMBRA_RH_SORT_AUTO) {
            // Section 3.5's trade: sorting costs about PENUMBRA_RH_SORT_COST cone tests' time per ray
            // and saves each caster about PENUMBRA_RH_SORT_SAVING tests per unit of 1 + the tiles' mean
            // incoherence (rh_rays.comp: about 0 on one smooth surface, tens across many depth steps).
            float incoherence = state.coherenceRays == 0ul ? 0.0 : float(state.incoherence) / 256.0 / float(state.coherenceRays);
            float saved = float(push.casters) * float(PENUMBRA_RH_SORT_SAVING) * (1.0 + incoherence);
            sorted = saved > float(PENUMBRA_RH_SORT_COST) * float(state.countedRays);
        }
        state.sorted = sorted ? 1u : 0u;
        state.sortedLights += sorted ? 1u : 0u;
        state.keyDispatchX = sorted ? push.keyGroupsX : 0u;
        state.keyDispatchY = push.keyGroupsY;
        state.keyDispatchZ = 1u;
        state.scanDispatchX = sorted ? push.scanGroups : 0u;
        state.scanDispatchY = 1u;
        state.scanDispatchZ = 1u;
        state.scanPhase1X = sorted ? 1u : 0u;
        state.scanPhase1Y = 1u;
        state.scanPhase1Z = 1u;
        return;
    }
    if (kMode == PENUMBRA_RH_BUILD_FACES) {
        if (gl_GlobalInvocationID.x != 0u || state.sorted == 0u)
            return;
        uint total = 0u;
        for (uint f = 0u; f < 6u; ++f)
            total += state.faceCount[f >> 2u][f & 3u];
        uint alignment = 4u, level = 1u; // alignment = 4^level: a node of level - 1 holds that many rays
        while (alignment * 4u * PENUMBRA_RH_FACE_SPLIT <= total) {
            alignment *= 4u;
            ++level;
        }
        state.tree.y = push.faces > 1u ? level : 0u;
        uint raw = 0u, start = 0u;
        for (uint f = 0u; f < 6u; ++f) {
            uint count = state.faceCount[f >> 2u][f & 3u];
            state.faceShift[f >> 2u][f & 3u] = start - raw;
            raw += count;
            start += count == 0u ? 0u : (f + 1u < push.faces ? (count + alignment - 1u) / alignment * alignment : count);
        }
        state.rayCount = start;
        return;
    }
    if (kMode == PENUMBRA_RH_BUILD_INIT) {
        if (gl_GlobalInvocationID.x != 0u)
            return;
        // The list's last leaf padded (a sorted list has no padding of its own).
        for (uint r = state.rayCount; (r & 3u) != 0u; ++r)
            rayQuads[r >> 2u][r & 3u] = RH_NO_RAY;
        uint count = (state.rayCount + 3u) / 4u;
        uint levels = 0u, offset = 0u;
        while (count > 0u && levels < PENUMBRA_RH_MAX_LEVELS) {
            RH_LEVEL_WORD(state.levelOffset, levels) = offset;
            RH_LEVEL_WORD(state.levelCount, levels) = count;
            offset += count;
            ++levels;
            if (count == 1u)
                break;
            count = (count + 3u) / 4u;
        }
        state.tree.x = levels;
        // The traversal's root: the top, or below the levels whose nodes mix a point light's faces (their
        // cones are wide and pass most casters): its records are every caster with every node of that
        // level, whose children each hold one face's rays.
        state.levels = levels;
        return;
    }
    uint node = gl_GlobalInvocationID.y * (gl_NumWorkGroups.x * PENUMBRA_RH_GROUP_SIZE) + gl_GlobalInvocationID.x;
    if (kMode == PENUMBRA_RH_BUILD_GRID) {
        // Here `node` is a cell of level push.level (faces x side x side).
        uint order = push.sort; // here: the grid's order
        uint side = 1u << (order - push.level);
        if (node >= push.faces * side * side)
            return;
        uint face = node / (side * side), y = (node / side) % side, x = node % side;
        uint below = gridLevelBase(push.faces, order, push.level - 1u) + (face * 2u * side + 2u * y) * 2u * side + 2u * x;
        depthGrid[gridLevelBase(push.faces, order, push.level) + node] =
            max(max(depthGrid[below], depthGrid[below + 1u]), max(depthGrid[below + 2u * side], depthGrid[below + 2u * side + 1u]));
        return;
    }
    uint levels = state.tree.x; // built
    int width = imageSize(gSurface).x;
    if (kMode == PENUMBRA_RH_BUILD_RESOLVE) {
        // Here `node` is a leaf: its rays are in shadow when it or an ancestor below the traversal's root was covered.
        if (state.levels < 2u || node >= RH_LEVEL_WORD(state.levelCount, 0))
            return;
        bool covered = false;
        uint index = node;
        for (uint l = 0u; l + 1u < state.levels; ++l) {
            covered = covered || unpack32(nodes[RH_LEVEL_WORD(state.levelOffset, l) + index].w).y == floatBitsToUint(-1.0);
            index >>= 2u;
        }
        if (!covered)
            return;
        uvec4 pixels = rayQuads[node];
        for (uint k = 0u; k < 4u; ++k)
            if (pixels[k] != RH_NO_RAY)
                shadowed[pixels[k]] = 1u;
        return;
    }
    vec3 light = frame.lights[push.lightIndex].positionType.xyz;
    if (kMode == PENUMBRA_RH_BUILD_LEAVES) {
        if (levels == 0u || node >= RH_LEVEL_WORD(state.levelCount, 0))
            return;
        uvec4 pixels = rayQuads[node];
#ifdef PENUMBRA_RH_PARALLEL
        ParallelFrame f = parallelFrame(-normalize(frame.lights[push.lightIndex].directionRange.xyz));
        vec4 box = vec4(kEmpty, kEmpty, -kEmpty, -kEmpty);
        vec2 heights = vec2(kEmpty, -kEmpty);
        for (uint k = 0u; k < 4u; ++k) {
            uint pixelIndex = pixels[k];
            if (pixelIndex == RH_NO_RAY || (push.skipShadowed != 0u && shadowed[pixelIndex] != 0u))
                continue;
            ivec2 pixel = ivec2(int(pixelIndex % uint(width)), int(pixelIndex / uint(width)));
            // The ray's origin, as rhParallelRay computes it.
            const uvec4 surface = imageLoad(gSurface, pixel);
            vec3 o = toParallel(f, surfacePosition(surface) + surfaceNormal(surface) * push.originOffset);
            box = vec4(min(box.xy, o.xy), max(box.zw, o.xy));
            heights = vec2(min(heights.x, o.z), max(heights.y, o.z));
        }
        nodes[RH_LEVEL_WORD(state.levelOffset, 0) + node] = packNode(box, vec4(heights, 0.0, 0.0));
#else
        vec3 directions[4];
        bool valid[4];
        vec3 sum = vec3(0.0);
        float longest = 0.0, shortest = 3.0e38;
        bool any = false;
        uint faces = 0u;
        for (uint k = 0u; k < 4u; ++k) {
            uint pixelIndex = pixels[k];
            valid[k] = pixelIndex != RH_NO_RAY && (push.skipShadowed == 0u || shadowed[pixelIndex] == 0u);
            directions[k] = vec3(0.0, 0.0, 1.0);
            if (valid[k]) {
                ivec2 pixel = ivec2(int(pixelIndex % uint(width)), int(pixelIndex / uint(width)));
                vec3 d = surfacePosition(imageLoad(gSurface, pixel)) - light;
                faces |= 1u << cubeFace(d);
                float l = length(d);
                longest = max(longest, l);
                shortest = min(shortest, l);
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
        storeCone(RH_LEVEL_WORD(state.levelOffset, 0) + node, axis, any ? angle : -1.0, longest, any ? shortest : 0.0, faces);
#endif
        return;
    }
    // PENUMBRA_RH_BUILD_LEVEL
    uint level = push.level;
    if (level >= levels || node >= RH_LEVEL_WORD(state.levelCount, level))
        return;
    uint childOffset = RH_LEVEL_WORD(state.levelOffset, level - 1u);
    uint childCount = RH_LEVEL_WORD(state.levelCount, level - 1u);
    Node children[4];
    for (uint k = 0u; k < 4u; ++k)
        children[k] = 4u * node + k < childCount ? unpackNode(nodes[childOffset + 4u * node + k]) : unpackNode(u64vec4(0ul));
#ifdef PENUMBRA_RH_PARALLEL
    vec4 box = vec4(kEmpty, kEmpty, -kEmpty, -kEmpty);
    vec2 heights = vec2(kEmpty, -kEmpty);
    for (uint k = 0u; k < 4u; ++k)
        if (4u * node + k < childCount && children[k].a.x <= children[k].a.z) {
            box = vec4(min(box.xy, children[k].a.xy), max(box.zw, children[k].a.zw));
            heights = vec2(min(heights.x, children[k].b.x), max(heights.y, children[k].b.y));
        }
    nodes[RH_LEVEL_WORD(state.levelOffset, level) + node] = packNode(box, vec4(heights, 0.0, 0.0));
#else
    float longest = 0.0, shortest = 3.0e38;
    vec3 sum = vec3(0.0);
    bool any = false;
    uint faces = 0u;
    for (uint k = 0u; k < 4u; ++k) {
        if (4u * node + k >= childCount || children[k].a.w < 0.0)
            continue;
        faces |= nodeFaces(children[k]);
        children[k].a.w = uintBitsToFloat(floatBitsToUint(children[k].a.w) | 63u); // the angle, rounded up past the face bits
        longest = max(longest, children[k].b.z);
        shortest = min(shortest, children[k].b.w);
        sum += children[k].a.xyz;
        any = true;
    }
    bool degenerate;
    vec3 axis = axisOf(sum, degenerate);
    float angle = degenerate ? 3.1416 : 0.0;
    for (uint k = 0u; k < 4u; ++k)
        if (4u * node + k < childCount && children[k].a.w >= 0.0)
            angle = max(angle, angleBetween(axis, children[k].a.xyz) + children[k].a.w);
    storeCone(RH_LEVEL_WORD(state.levelOffset, level) + node, axis, any ? min(angle, 3.1416) : -1.0, longest, any ? shortest : 0.0, faces);
#endif
}
