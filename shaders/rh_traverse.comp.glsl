#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_ballot : require
// Cone ray hierarchies, one traversal step (rh.glsli; Olsson and Assarsson
// 2011, sections 3.1-3.3): each record (triangle, node) of the chunk
// rh_step picked tests the node's 4 children with the test of the
// pipeline (kTest): cones (point and spot lights) or slabs (directional lights:
// this shader compiled with PENUMBRA_RH_PARALLEL). A child that passes
// becomes a record of the next depth (one atomic per subgroup, no workgroup
// barriers: they are expensive on CPU drivers); a child the triangle covers
// (early accept, kEarlyAccept) is marked covered and its rays are
// shadowed later, whole (rh_build.comp's resolve mode); a record whose node
// was covered meanwhile is dropped. Below a leaf each of its rays not yet
// shadowed gets the tracer's exact watertight ray/triangle test on the
// tracer's ray (rhShadowRay, rhParallelRay), and a hit sets the pixel's
// shadow flag (afsm's resolve turns the flags into the light's visibility).
// The four children of a node are tested by one invocation: one record and
// one triangle load for four tests, and records are written only for the
// children that pass (llvmpipe loads and stores lane by lane).

#include "config.h"
#include "shadow_common.glsli"
#include "shadow_ray.glsli"
#include "rh.glsli"

layout(local_size_x = PENUMBRA_RH_GROUP_SIZE) in;

// C++: runtime/src/passes/rh.h (RhTraverseBinding).
#include "surface.glsli"
layout(set = 0, binding = 0, rgba32ui) uniform readonly uimage2D gSurface; // binding 1, the G-buffer's albedo, is not read
layout(set = 0, binding = 2, std140) uniform Frame { FrameData frame; };
layout(set = 0, binding = 3, std430) readonly buffer Rays { uvec4 rayQuads[]; }; // 4 rays (one leaf) per element
layout(set = 0, binding = 4, std430) buffer Nodes { u64vec4 nodes[]; };
layout(set = 0, binding = 5, std430) readonly buffer TrianglesA { u64vec4 trianglesA[]; }; // v0, v1, v2.xy (rh_casters.geom)
layout(set = 0, binding = 6, std430) readonly buffer TrianglesB { uvec2 trianglesB[]; };   // v2.z, faces (rh_casters.geom)
layout(set = 0, binding = 7, std430) buffer Records { uint64_t records[]; };              // triangle | node << 32
layout(set = 0, binding = 8, std430) buffer Shadowed { uint shadowed[]; };
#define RH_STATE_BINDING 9
RH_STATE_DECLARE();
#define RH_STEP_BINDING 10
RH_STEP_DECLARE();
// 1: the rays, nodes, triangles and records are read through the texel views below (RhPass::texelAccess):
// on lavapipe a texel fetch is a gather, any other load that is not uniform a loop over the lanes.
layout(constant_id = 0) const uint kTexelAccess = 0u;
// The test (PENUMBRA_RH_TEST_*) and early accept (1: covered children are accepted whole, section 3.3) are
// constants of the pipeline: llvmpipe runs both sides of an if (masked), and fewer live values spill less.
layout(constant_id = 1) const uint kTest = PENUMBRA_RH_TEST_PRECISE;
layout(constant_id = 2) const uint kEarlyAccept = 1u;
// 1: the leaves' pipeline (each record's rays get the exact test), 0: the inner levels' (each record's four
// children get the cone or slab test). rh_step.comp sends each step to one of them: llvmpipe runs an if's
// body masked even when no lane enters it, so one shader for both paid for the other's code.
layout(constant_id = 3) const uint kLeaf = 0u;
layout(set = 0, binding = 11) uniform usamplerBuffer rayTexels;       // RGBA32UI: rayQuads
layout(set = 0, binding = 12) uniform usamplerBuffer nodeTexels;      // RGBA32UI: nodes, two a node
layout(set = 0, binding = 13) uniform usamplerBuffer triangleTexelsA; // RGBA32UI: trianglesA, two a triangle
layout(set = 0, binding = 14) uniform usamplerBuffer triangleTexelsB; // RG32UI: trianglesB
layout(set = 0, binding = 15) uniform usamplerBuffer recordTexels;    // RG32UI: records

u64vec4 loadNode(uint index)
{
    if (kTexelAccess == 0u)
        return nodes[index];
    uvec4 a = texelFetch(nodeTexels, int(2u * index)), b = texelFetch(nodeTexels, int(2u * index + 1u));
    return u64vec4(pack64(a.xy), pack64(a.zw), pack64(b.xy), pack64(b.zw));
}

// A node's last 32-bit word (-1.0 once covered: coveredWord), one texel fetch.
uint loadNodeLastWord(uint index)
{
    return kTexelAccess != 0u ? texelFetch(nodeTexels, int(2u * index + 1u)).w : unpack32(nodes[index].w).y;
}

u64vec4 loadTriangleA(uint index)
{
    if (kTexelAccess == 0u)
        return trianglesA[index];
    uvec4 a = texelFetch(triangleTexelsA, int(2u * index)), b = texelFetch(triangleTexelsA, int(2u * index + 1u));
    return u64vec4(pack64(a.xy), pack64(a.zw), pack64(b.xy), pack64(b.zw));
}

uvec2 loadTriangleB(uint index)
{
    return kTexelAccess != 0u ? texelFetch(triangleTexelsB, int(index)).xy : trianglesB[index];
}

// A record as (triangle, node).
uvec2 loadRecord(uint index)
{
    return kTexelAccess != 0u ? texelFetch(recordTexels, int(index)).xy : unpack32(records[index]);
}

uvec4 loadRayQuad(uint index)
{
    return kTexelAccess != 0u ? texelFetch(rayTexels, int(index)) : rayQuads[index];
}

layout(push_constant) uniform RhTraversePush {
    uint lightIndex;
    float originOffset; // the rays' origin offset (the cones grow by it)
    uint faces;         // the light's faces (6: a point light's cube faces)
    uint pad0;
} push;


void main()
{
    uint i = gl_GlobalInvocationID.x;
    uint depth = stepInfo.stepDepth;
    uint level = stepInfo.levels - 1u - depth;
    bool live = i < stepInfo.stepCount;
    uint triangle = 0u, node = 0u;
    if (depth == 0u) {
        // The root's records: every triangle with every node of the root level.
        uint rootNodes = RH_LEVEL_WORD(stepInfo.levelCount, level);
        uint index = stepInfo.stepBegin + i;
        triangle = index / rootNodes;
        node = index - triangle * rootNodes;
    } else {
        uvec2 record = loadRecord(stepInfo.stepBegin + (live ? i : 0u));
        triangle = record.x;
        node = record.y;
    }
    vec3 v0, v1, v2;
    uvec2 b = loadTriangleB(triangle);
    unpackTriangle(loadTriangleA(triangle), uintBitsToFloat(b.x), v0, v1, v2);
    // The cube faces whose rays this caster may shadow (its cluster's culled views, rh_casters.geom).
    bool gate = push.faces > 1u;
    uint casterFaces = b.y;
    // A record whose node was covered since it was written: every ray below is in shadow.
    PENUMBRA_SKIP_UNLESS(kEarlyAccept != 0u && depth > 0u && live)
    {
        live = loadNodeLastWord(RH_LEVEL_WORD(stepInfo.levelOffset, level) + node) != floatBitsToUint(-1.0);
    }
#ifdef PENUMBRA_RH_PARALLEL
    vec3 toLight = -normalize(frame.lights[push.lightIndex].directionRange.xyz);
    ParallelFrame frameL = parallelFrame(toLight);
    vec3 t0 = toParallel(frameL, v0), t1 = toParallel(frameL, v1), t2 = toParallel(frameL, v2);
#else
    vec3 light = frame.lights[push.lightIndex].positionType.xyz;
#endif
    uint tested = 0u, accepted = 0u, passing = 0u, hits = 0u; // passing: bit k for child k
    // Inner node: its four children.
    if (kLeaf == 0u) {
        uint childOffset = RH_LEVEL_WORD(stepInfo.levelOffset, level - 1u);
        uint childCount = RH_LEVEL_WORD(stepInfo.levelCount, level - 1u);
        bool accept = kEarlyAccept != 0u;
        // What the tests need of the triangle, once; then each child in turn (few values live at once:
        // llvmpipe keeps every vector of all 8 lanes in registers or on the stack).
#ifdef PENUMBRA_RH_PARALLEL
        SlabTriangle slab;
        PENUMBRA_SKIP_UNLESS(live && kTest == PENUMBRA_RH_TEST_PRECISE)
        {
            slab = slabTriangle(t0, t1, t2);
        }
#else
        ConeTriangle cone;
        SphereTriangle sphere;
        PENUMBRA_SKIP_UNLESS(live && kTest == PENUMBRA_RH_TEST_PRECISE)
        {
            cone = coneTriangle(v0, v1, v2, light, push.originOffset);
        }
        PENUMBRA_SKIP_UNLESS(live && kTest == PENUMBRA_RH_TEST_SPHERES)
        {
            sphere = sphereTriangle(v0, v1, v2, light, push.originOffset);
        }
#endif
        for (uint k = 0u; k < 4u; ++k) {
            uint child = 4u * node + k;
            Node c = unpackNode(loadNode(childOffset + min(child, childCount - 1u)));
            bool faced = !gate || (casterFaces & nodeFaces(c)) != 0u;
#ifdef PENUMBRA_RH_PARALLEL
            bool valid = live && faced && child < childCount && c.a.x <= c.a.z && !nodeCovered(c);
#else
            bool valid = live && faced && child < childCount && c.a.w >= 0.0 && !nodeCovered(c);
#endif
            tested += valid ? 1u : 0u;
            uint result = RH_MISS;
#ifdef PENUMBRA_RH_PARALLEL
            PENUMBRA_SKIP_UNLESS(valid && kTest == PENUMBRA_RH_TEST_PRECISE)
            {
                result = preciseSlabTest(slab, c, accept);
            }
            PENUMBRA_SKIP_UNLESS(valid && kTest == PENUMBRA_RH_TEST_SPHERES)
            {
                result = sphereMayMeetSlab(c, t0, t1, t2) ? RH_MAY : RH_MISS;
            }
#else
            PENUMBRA_SKIP_UNLESS(valid && kTest == PENUMBRA_RH_TEST_PRECISE)
            {
                result = preciseConeTest(cone, c, push.originOffset, accept);
            }
            PENUMBRA_SKIP_UNLESS(valid && kTest == PENUMBRA_RH_TEST_SPHERES)
            {
                result = sphereMayMeetCone(sphere, c, push.originOffset) ? RH_MAY : RH_MISS;
            }
#endif
            PENUMBRA_SKIP_UNLESS(result == RH_COVERS)
            {
                nodes[childOffset + child].w = coveredWord(c);
                ++accepted;
            }
            passing |= result == RH_MAY ? 1u << k : 0u;
        }
        // The passing children's records, one atomic per subgroup.
        uint count = bitCount(passing);
        uint slot = subgroupExclusiveAdd(count);
        uint total = subgroupAdd(count);
        uint base = 0u;
        if (subgroupElect() && total != 0u)
            base = atomicAdd(state.segEnd[depth + 1u], total);
        base = subgroupBroadcastFirst(base) + slot;
        for (uint m = passing; m != 0u; m &= m - 1u)
            records[base++] = pack64(uvec2(triangle, 4u * node + uint(findLSB(m))));
    }
    // Leaf: the exact test of each of its rays not yet in shadow.
    if (kLeaf != 0u) {
        uvec4 pixels = live ? loadRayQuad(node) : uvec4(RH_NO_RAY);
        uint open = 0u;
        for (uint k = 0u; k < 4u; ++k)
            if (pixels[k] != RH_NO_RAY && shadowed[pixels[k]] == 0u)
                open |= 1u << k;
        tested = bitCount(open);
        hits = 0u;
        int width = imageSize(gSurface).x;
        for (uint m = open; m != 0u; m &= m - 1u) {
            uint pixelIndex = pixels[findLSB(m)];
            ivec2 pixel = ivec2(int(pixelIndex % uint(width)), int(pixelIndex / uint(width)));
            ShadowRay ray;
            const uvec4 surface = imageLoad(gSurface, pixel);
#ifdef PENUMBRA_RH_PARALLEL
            bool lit = rhParallelRay(toLight, surfacePosition(surface), surfaceNormal(surface), push.originOffset, ray);
#else
            bool lit = rhShadowRay(light, surfacePosition(surface), surfaceNormal(surface), push.originOffset, ray);
#endif
            if (lit && hitsTriangle(ray, shearVertex(ray, v0), shearVertex(ray, v1), shearVertex(ray, v2))) {
                shadowed[pixelIndex] = 1u;
                ++hits;
            }
        }
    }
    uint subgroupTested = subgroupAdd(tested);
    uint subgroupAccepted = subgroupAdd(accepted);
    uint subgroupHits = subgroupAdd(hits);
    if (subgroupElect()) {
        if (subgroupTested != 0u) {
            atomicAdd(state.depthTests[min(depth, PENUMBRA_RH_MAX_LEVELS - 1u)], subgroupTested);
            if (kLeaf != 0u)
                atomicAdd(state.rayTests, uint64_t(subgroupTested));
            else
                atomicAdd(state.pairsTested, uint64_t(subgroupTested));
        }
        if (subgroupHits != 0u)
            atomicAdd(state.rayHits, uint64_t(subgroupHits));
        if (subgroupAccepted != 0u) {
            atomicAdd(state.accepted, uint64_t(subgroupAccepted));
            atomicAdd(state.lightAccepted, subgroupAccepted);
        }
    }
}
