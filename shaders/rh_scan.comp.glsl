#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
// Cone ray hierarchies: exclusive prefix sum, in place, of the per-tile or
// per-key ray counts of rh_rays.comp, turning them into first slots. The
// block totals live in the same buffer after the counts (at push.sums).
// Three dispatches (push.phase):
//  0: each workgroup scans a block of RH_SCAN_BLOCK counts and writes its total;
//  1: one workgroup scans the block totals (at most RH_SCAN_BLOCK of them);
//  2: each block adds its total's prefix.
// Each invocation holds 32 consecutive counts, read and written as 8 uvec4
// (llvmpipe loads a storage buffer lane by lane: fewer, wider loads).

#include "config.h"

layout(local_size_x = 64) in;

#define RH_SCAN_VECTORS 8u                       // uvec4 per invocation
#define RH_SCAN_BLOCK (64u * 4u * RH_SCAN_VECTORS) // 2048 counts per workgroup

layout(set = 0, binding = 0, std430) buffer Counts { uvec4 counts[]; }; // count, then slot; the block totals at push.sums

layout(push_constant) uniform RhScanPush {
    uint count; // counts (a multiple of 4); block totals: (count + RH_SCAN_BLOCK - 1) / RH_SCAN_BLOCK
    uint sums;  // the first block total's index (a multiple of RH_SCAN_BLOCK)
    uint phase;
    uint pad;
} push;

shared uint subgroupTotals[64];

void main()
{
    uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    uint blocks = (push.count + RH_SCAN_BLOCK - 1u) / RH_SCAN_BLOCK;
    uint first = (push.phase == 1u ? push.sums : group * RH_SCAN_BLOCK) / 4u + gl_LocalInvocationIndex * RH_SCAN_VECTORS;
    uint end = (push.phase == 1u ? push.sums + blocks + 3u : push.count + 3u) / 4u; // past the last vector holding values
    if (push.phase == 2u) {
        uint add = counts[(push.sums + group) / 4u][(push.sums + group) & 3u];
        for (uint k = 0u; k < RH_SCAN_VECTORS; ++k)
            if (first + k < end)
                counts[first + k] += uvec4(add);
        return;
    }
    uvec4 values[RH_SCAN_VECTORS];
    uint sum = 0u;
    for (uint k = 0u; k < RH_SCAN_VECTORS; ++k) {
        values[k] = first + k < end ? counts[first + k] : uvec4(0u);
        sum += values[k].x + values[k].y + values[k].z + values[k].w;
    }
    // Exclusive prefix of the invocations' sums: in the subgroup, then over the subgroups (in order).
    uint running = subgroupExclusiveAdd(sum);
    uint subgroupTotal = subgroupAdd(sum);
    if (subgroupElect())
        subgroupTotals[gl_SubgroupID] = subgroupTotal;
    barrier();
    uint total = 0u;
    for (uint s = 0u; s < gl_NumSubgroups; ++s) {
        uint t = subgroupTotals[s];
        running += s < gl_SubgroupID ? t : 0u;
        total += t;
    }
    for (uint k = 0u; k < RH_SCAN_VECTORS; ++k) {
        uvec4 v = values[k];
        uvec4 prefix = uvec4(running, running + v.x, running + v.x + v.y, running + v.x + v.y + v.z);
        if (first + k < end)
            counts[first + k] = prefix;
        running = prefix.w + v.w;
    }
    if (push.phase == 0u && gl_LocalInvocationIndex == 0u)
        counts[(push.sums + group) / 4u][(push.sums + group) & 3u] = total;
}
