#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
// Stream compaction of marked pixels into a dense ray list: per subgroup, a
// ballot gives each marked pixel its exclusive prefix and the subgroup's
// total, one elected invocation reserves the subgroup's range with a single
// atomicAdd, then every marked pixel writes its slot (no workgroup barriers,
// which are expensive on CPU drivers). Phase 1 (one invocation) writes the
// tracer's indirect dispatch size from the final count (2-D above 65535 groups)
// and adds the count to the frame's PIP counter (the pixels given rays).

#include "config.h"

layout(local_size_x = PENUMBRA_COMPACT_GROUP_SIZE) in;

layout(set = 0, binding = 0, std430) readonly buffer Marks { uint marks[]; };
layout(set = 0, binding = 1, std430) buffer RayList { uint rays[]; }; // header, then pixel indices
layout(set = 0, binding = 2, std430) buffer Stats { uint64_t stats[]; };

layout(push_constant) uniform CompactPush {
    uint pixelCount;
    uint phase;   // PENUMBRA_COMPACT_LIST, PENUMBRA_COMPACT_DISPATCH
    uint width;   // of the image (pixelCount = width x height)
    uint height;  // of the image
} push;

// Each workgroup covers four 8x8 tiles side by side (workgroup (x, y): tiles
// 4x .. 4x + 3 of tile row y), row by row inside a tile, so the rays of a SIMD
// register of the tracer come from one tile: neighbouring points, coherent
// rays (the list keeps this order). No integer division: llvmpipe runs it per
// lane, three of them cost more than the rest of the pass. Returns the pixel
// index, or ~0u outside the image.
uint tilePixel()
{
    uint inside = gl_LocalInvocationID.x & 63u;
    uint x = (gl_WorkGroupID.x * 4u + (gl_LocalInvocationID.x >> 6)) * 8u + (inside & 7u);
    uint y = gl_WorkGroupID.y * 8u + (inside >> 3);
    return x < push.width && y < push.height ? y * push.width + x : ~0u;
}

#ifdef PENUMBRA_FLOOR
#include "floor.glsli"
void main()
{
    if (push.phase == PENUMBRA_COMPACT_DISPATCH)
        return;
    uint i = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * PENUMBRA_COMPACT_GROUP_SIZE + gl_LocalInvocationID.x;
    // Each marked pixel writes one list entry (at its own index: the real
    // pass then writes the list from its start, over these).
    if (i < push.pixelCount && marks[i] != 0u)
        rays[PENUMBRA_RAY_LIST_HEADER_UINTS + i] = i;
}
#else
void main()
{
    if (push.phase == PENUMBRA_COMPACT_DISPATCH) {
        if (gl_GlobalInvocationID.x != 0u)
            return;
        // 2-D when needed: devices may limit each dimension to 65535 workgroups.
        uint groups = (rays[0] + PENUMBRA_TRACE_GROUP_SIZE - 1u) / PENUMBRA_TRACE_GROUP_SIZE;
        uint x = min(groups, 65535u);
        rays[1] = x;
        rays[2] = x == 0u ? 1u : (groups + x - 1u) / x;
        rays[3] = 1u;
        atomicAdd(stats[PENUMBRA_STAT_PIP], uint64_t(rays[0]));
        return;
    }
    uint i = tilePixel();
    bool marked = i != ~0u && marks[i] != 0u;
    uvec4 ballot = subgroupBallot(marked);
    uint total = subgroupBallotBitCount(ballot);
    if (total == 0u)
        return;
    uint base = 0u;
    if (subgroupElect())
        base = atomicAdd(rays[0], total);
    base = subgroupBroadcastFirst(base);
    if (marked)
        rays[PENUMBRA_RAY_LIST_HEADER_UINTS + base + subgroupBallotExclusiveBitCount(ballot)] =
            i | (marks[i] == PENUMBRA_MARK_ONE_SAMPLE ? PENUMBRA_RAY_ONE_SAMPLE : 0u);
}
#endif
