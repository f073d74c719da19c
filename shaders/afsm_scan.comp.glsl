#version 450
#extension GL_GOOGLE_include_directive : require
// Exclusive prefix sum of the alias-free shadow map's per-cell sample counts
// (afsm_samples.comp.glsl), in place, turning them into each cell's first
// slot of the flat sample list, and the total after the last cell (so that
// cells [a, b]'s slots are [first(a), first(b + 1)): afsm_casters.glsli,
// afsmRowSlots). Three dispatches (push.phase):
//  0: each workgroup scans AFSM_SCAN_BLOCK counts and writes its total to blockSums;
//  1: one workgroup scans the block totals (at most AFSM_SCAN_BLOCK of them) and writes the total;
//  2: each block adds its total's prefix.

#include "config.h"

layout(local_size_x = PENUMBRA_AFSM_SCAN_GROUP) in;

#define AFSM_SCAN_PER_INVOCATION 16u // block of 4096 counts: one level of block totals covers 4096^2 cells
#define AFSM_SCAN_BLOCK (PENUMBRA_AFSM_SCAN_GROUP * AFSM_SCAN_PER_INVOCATION)

layout(set = 0, binding = 0, std430) buffer Counts { uint counts[]; };
layout(set = 0, binding = 1, std430) buffer BlockSums { uint blockSums[]; };

layout(push_constant) uniform AfsmScanPush {
    uint count;  // cells (counts holds one more value: the total)
    uint phase;
} push;

shared uint partial[PENUMBRA_AFSM_SCAN_GROUP];

// Exclusive scan of `value` over the workgroup; the total in `total`.
uint groupExclusiveScan(uint value, out uint total)
{
    uint i = gl_LocalInvocationIndex;
    partial[i] = value;
    barrier();
    for (uint offset = 1u; offset < PENUMBRA_AFSM_SCAN_GROUP; offset <<= 1u) {
        uint add = i >= offset ? partial[i - offset] : 0u;
        barrier();
        partial[i] += add;
        barrier();
    }
    total = partial[PENUMBRA_AFSM_SCAN_GROUP - 1u];
    return partial[i] - value;
}

void main()
{
    uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (push.phase == 2u) {
        uint add = blockSums[group];
        for (uint k = 0u; k < AFSM_SCAN_PER_INVOCATION; ++k) {
            uint i = group * AFSM_SCAN_BLOCK + gl_LocalInvocationIndex * AFSM_SCAN_PER_INVOCATION + k;
            if (i < push.count)
                counts[i] += add;
        }
        return;
    }
    // Phase 0 scans counts block `group`; phase 1 scans blockSums (one block of at most AFSM_SCAN_BLOCK values).
    uint n = push.phase == 0u ? push.count : (push.count + AFSM_SCAN_BLOCK - 1u) / AFSM_SCAN_BLOCK;
    uint base = push.phase == 0u ? group * AFSM_SCAN_BLOCK : 0u;
    uint values[AFSM_SCAN_PER_INVOCATION];
    uint sum = 0u;
    for (uint k = 0u; k < AFSM_SCAN_PER_INVOCATION; ++k) {
        uint i = base + gl_LocalInvocationIndex * AFSM_SCAN_PER_INVOCATION + k;
        values[k] = i < n ? (push.phase == 0u ? counts[i] : blockSums[i]) : 0u;
        sum += values[k];
    }
    uint total;
    uint running = groupExclusiveScan(sum, total);
    for (uint k = 0u; k < AFSM_SCAN_PER_INVOCATION; ++k) {
        uint i = base + gl_LocalInvocationIndex * AFSM_SCAN_PER_INVOCATION + k;
        if (i < n) {
            if (push.phase == 0u)
                counts[i] = running;
            else
                blockSums[i] = running;
        }
        running += values[k];
    }
    if (push.phase == 0u && gl_LocalInvocationIndex == 0u)
        blockSums[group] = total;
    if (push.phase == 1u && gl_LocalInvocationIndex == 0u)
        counts[push.count] = total; // every block's total: the samples listed
}
