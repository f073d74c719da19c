#version 450
#extension GL_GOOGLE_include_directive : require
// Cone ray hierarchies, one step of the bounded breadth-first traversal
// (rh.glsli; Olsson and Assarsson 2011, section 4.2), one invocation: drop
// the deepest segments whose records are all processed, pick a chunk of the
// deepest one left (depth 0: the batch's triangles with the root level's
// nodes, not stored), open the
// segment its output goes to, and write rh_traverse's indirect dispatches
// (the inner levels' pipeline or the leaves', the other one empty). A
// chunk is at most an eighth of the free room of the arena: each record
// makes at most 4, so the output fits and room is left for the depths below.
// When nothing is left the batch is done and the dispatch is empty.

#include "config.h"
#include "shadow_ray.glsli"
#include "rh.glsli"

layout(local_size_x = 1) in;

#define RH_STATE_BINDING 0
RH_STATE_DECLARE();

layout(push_constant) uniform RhStepPush {
    uint pairCapacity;     // records the arena holds
    uint triangleCapacity; // triangles the batch's list holds
    uint pad0, pad1;
} push;

// rh_traverse's two indirect dispatches: `groups` workgroups for the inner levels' pipeline or the leaves'.
void writeDispatches(uint groups, bool leaf)
{
    state.dispatchX = leaf ? 0u : groups;
    state.dispatchY = 1u;
    state.dispatchZ = 1u;
    state.leafDispatchX = leaf ? groups : 0u;
    state.leafDispatchY = 1u;
    state.leafDispatchZ = 1u;
}

void finish()
{
    state.done = 1u;
    state.stepCount = 0u;
    writeDispatches(0u, false);
}

void main()
{
    uint triangles = min(state.triangleCount, push.triangleCapacity);
    if (state.levels == 0u || state.done != 0u) {
        finish();
        return;
    }
    uint depth = state.deepest;
    while (depth > 0u && state.cursor[depth] >= state.segEnd[depth])
        --depth;
    state.deepest = depth;
    // The root's records: every triangle with every node of the root level.
    uint rootRecords = triangles * RH_LEVEL_WORD(state.levelCount, state.levels - 1u);
    uint remaining = depth == 0u ? rootRecords - state.rootCursor : state.segEnd[depth] - state.cursor[depth];
    if (remaining == 0u) {
        finish();
        return;
    }
    uint top = depth > 0u ? state.segEnd[depth] : 0u; // first free record
    state.peakPairs = max(state.peakPairs, top);
    uint level = state.levels - 1u - depth;
    uint chunk = min(remaining, 65535u * PENUMBRA_RH_GROUP_SIZE);
    if (level > 0u) {
        chunk = min(chunk, (push.pairCapacity - top) / 8u);
        if (chunk == 0u) {
            state.overflow |= 1u;
            finish();
            return;
        }
        state.segBegin[depth + 1u] = top;
        state.segEnd[depth + 1u] = top;
        state.cursor[depth + 1u] = top;
        state.deepest = depth + 1u;
    }
    state.stepDepth = depth;
    if (depth == 0u) {
        state.stepBegin = state.rootCursor;
        state.rootCursor += chunk;
    } else {
        state.stepBegin = state.cursor[depth];
        state.cursor[depth] += chunk;
    }
    state.stepCount = chunk;
    state.steps += 1u;
    writeDispatches((chunk + PENUMBRA_RH_GROUP_SIZE - 1u) / PENUMBRA_RH_GROUP_SIZE, level == 0u);
}
