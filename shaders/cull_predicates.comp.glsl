#version 460
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_GOOGLE_include_directive : require
// Occlusion culling, between the two phases of a view (culling.h): sets the
// instanceCount of every command of the view's final draw list to 1 when the
// command is unconditional or its occlusion query counted samples, else 0.

#include "config.h"

layout(local_size_x = PENUMBRA_CULL_GROUP_SIZE) in;

layout(buffer_reference, std430, buffer_reference_align = 4) buffer Uints
{
    uint values[];
};

layout(push_constant) uniform PredicatePush
{
    uint64_t commands;       // VkDrawIndexedIndirectCommand[count] (5 uints each)
    uint64_t commandQueries; // uint[count]: query index, or 0xFFFFFFFF (unconditional)
    uint64_t queryResults;   // uint per query of the frame (samples passed)
    uint count;
    uint pad;
} push;

void main()
{
    uint i = gl_GlobalInvocationID.x;
    if (i >= push.count)
        return;
    uint query = Uints(push.commandQueries).values[i];
    bool visible = query == 0xFFFFFFFFu || Uints(push.queryResults).values[query] != 0u;
    Uints(push.commands).values[i * 5u + 1u] = visible ? 1u : 0u;
}
