#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
// Stream compaction of marked pixels into a dense ray list: each invocation
// takes a 2x2 quad of pixels; per subgroup, an exclusive sum gives each
// invocation the slot of its first marked pixel and the subgroup's total;
// the subgroups' totals, summed in shared memory, give each its place in the
// workgroup's range, which one invocation reserves with a single atomicAdd;
// then every invocation writes its marked pixels' slots. One reservation a
// workgroup (two barriers) rather than one a subgroup: lavapipe's two threads
// take turns at the atomic, so per subgroup the list alternated between two
// far parts of the image every few entries, and the tracer's rounds (8
// consecutive entries a SIMD register) mixed rays from both. Now the list
// runs through a 32x32 block at a time. Phase 1 (one invocation) writes the
// tracer's two indirect dispatch sizes from the final count (2-D above 65535 groups)
// and adds the count to the frame's PIP counter (the pixels given rays).

#include "config.h"

layout(local_size_x = PENUMBRA_COMPACT_GROUP_SIZE) in;

layout(set = 0, binding = 0, std430) readonly buffer Marks { uint marks[]; };
layout(set = 0, binding = 1, std430) buffer RayList { uint rays[]; }; // header, then pixel indices
layout(set = 0, binding = 2, std430) buffer Stats { uint64_t stats[]; };

// Each subgroup's total, then its first entry in the workgroup's range; the range's start.
shared uint sSubgroupEntries[PENUMBRA_COMPACT_GROUP_SIZE];
shared uint sGroupBase;

layout(push_constant) uniform CompactPush {
    uint pixelCount;
    uint phase;   // PENUMBRA_COMPACT_LIST, PENUMBRA_COMPACT_DISPATCH
    uint width;   // of the image (pixelCount = width x height)
    uint height;  // of the image
    uint roundEntries; // the tracer's list entries per workgroup in rounds (TracePass::entriesPerGroup)
} push;

// Each workgroup covers a 32x32 block of pixels: 16 tiles of 8x8 (4 x 4),
// each 16 invocations, each a 2x2 quad (the tile's quads row by row), so the
// rays of a SIMD register of the tracer come from two quads, a 4x2 block of
// neighbouring points: coherent rays (the list keeps this order). No integer
// division: llvmpipe runs it per lane, three of them cost more than the rest
// of the pass. Returns pixel k (0..3, row by row) of the invocation's quad.
uvec2 quadPixel(uint k)
{
    uint invocation = gl_LocalInvocationID.x;
    uint tile = invocation >> 4, quad = invocation & 15u;
    uvec2 tileOrigin = gl_WorkGroupID.xy * 32u + uvec2(tile & 3u, tile >> 2) * 8u;
    return tileOrigin + uvec2(quad & 3u, quad >> 2) * 2u + uvec2(k & 1u, k >> 1);
}

// The index of pixel p, or ~0u outside the image.
uint pixelIndex(uvec2 p)
{
    return p.x < push.width && p.y < push.height ? p.y * push.width + p.x : ~0u;
}

#ifdef PENUMBRA_FLOOR
#include "floor.glsli"
void main()
{
    if (push.phase == PENUMBRA_COMPACT_DISPATCH)
        return;
    // The same quads; each marked pixel writes one list entry (at its own
    // index: the real pass then writes the list from its start, over these).
    for (uint k = 0u; k < 4u; ++k) {
        uint i = pixelIndex(quadPixel(k));
        if (i != ~0u && marks[i] != 0u)
            rays[PENUMBRA_RAY_LIST_HEADER_UINTS + i] = i;
    }
}
#else
void main()
{
    if (push.phase == PENUMBRA_COMPACT_DISPATCH) {
        if (gl_GlobalInvocationID.x != 0u)
            return;
        // 2-D when needed: devices may limit each dimension to 65535 workgroups.
        for (uint i = 0u; i < 2u; ++i) {
            uint perGroup = i == 0u ? PENUMBRA_TRACE_GROUP_SIZE : push.roundEntries;
            uint groups = (rays[0] + perGroup - 1u) / perGroup;
            uint x = min(groups, 65535u);
            rays[1u + 3u * i] = x;
            rays[2u + 3u * i] = x == 0u ? 1u : (groups + x - 1u) / x;
            rays[3u + 3u * i] = 1u;
        }
        atomicAdd(stats[PENUMBRA_STAT_PIP], uint64_t(rays[0]));
        return;
    }
    uint entries[4];
    uint count = 0u;
    for (uint k = 0u; k < 4u; ++k) {
        uint i = pixelIndex(quadPixel(k));
        uint mark = i != ~0u ? marks[i] : 0u;
        entries[k] = i | (mark == PENUMBRA_MARK_ONE_SAMPLE ? PENUMBRA_RAY_ONE_SAMPLE : 0u);
        entries[k] = mark != 0u ? entries[k] : ~0u;
        count += mark != 0u ? 1u : 0u;
    }
    uint total = subgroupAdd(count);
    if (subgroupElect())
        sSubgroupEntries[gl_SubgroupID] = total;
    barrier();
    if (gl_LocalInvocationIndex == 0u) {
        uint sum = 0u;
        for (uint s = 0u; s < gl_NumSubgroups; ++s) {
            const uint entries = sSubgroupEntries[s];
            sSubgroupEntries[s] = sum;
            sum += entries;
        }
        sGroupBase = sum != 0u ? atomicAdd(rays[0], sum) : 0u;
    }
    barrier();
    if (total == 0u)
        return;
    uint slot = PENUMBRA_RAY_LIST_HEADER_UINTS + sGroupBase + sSubgroupEntries[gl_SubgroupID] + subgroupExclusiveAdd(count);
    for (uint k = 0u; k < 4u; ++k)
        if (entries[k] != ~0u)
            rays[slot++] = entries[k];
}
#endif
