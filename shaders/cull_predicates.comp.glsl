#version 460
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_GOOGLE_include_directive : require
// Occlusion culling, between the two phases of a view (culling.h). The final
// draw list is ascending by cluster; its commands are either conditional (on
// an occlusion query of phase 2) or repeats of phase-1 clusters (camera only).
// Step 0: firstPassed = the smallest list position whose query counted samples.
// Step 1: instanceCount = 1 for a conditional command whose query passed and
// for a repeat after firstPassed, else 0. Repeats before the first newly
// visible cluster cannot change the image (culling.h), so a view where
// nothing new appeared draws nothing in its second phase.

#include "config.h"

layout(local_size_x = PENUMBRA_CULL_GROUP_SIZE) in;

layout(buffer_reference, std430, buffer_reference_align = 4) buffer Uints
{
    uint values[];
};

layout(push_constant) uniform PredicatePush
{
    uint64_t commands;       // VkDrawIndexedIndirectCommand[count] (5 uints each)
    uint64_t commandQueries; // uint[count]: query index, or 0xFFFFFFFF (a repeat of a phase-1 cluster)
    uint64_t queryResults;   // uint per query of the frame (samples passed)
    uint64_t firstPassed;    // uint of this view, 0xFFFFFFFF before step 0
    uint count;
    uint step;
} push;

void main()
{
    uint i = gl_GlobalInvocationID.x;
    if (i >= push.count)
        return;
    uint query = Uints(push.commandQueries).values[i];
    bool passed = query != 0xFFFFFFFFu && Uints(push.queryResults).values[query] != 0u;
    if (push.step == 0) {
        if (passed)
            atomicMin(Uints(push.firstPassed).values[0], i);
        return;
    }
    bool draw = query == 0xFFFFFFFFu ? i > Uints(push.firstPassed).values[0] : passed;
    Uints(push.commands).values[i * 5u + 1u] = draw ? 1u : 0u;
}
