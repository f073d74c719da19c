#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
// Alias-free shadow maps, soft shadows (Sintorn et al. 2008, section 4.2):
// the lookup table from a plane to the bitmask of the light samples in front
// of it (layout and lookup: afsm.glsli, afsmPlaneEntry). Two dispatches:
//  PENUMBRA_AFSM_TABLE_SAMPLES: the n samples' 2-D positions (afsmLocalSample);
//  PENUMBRA_AFSM_TABLE_MASKS: word gl_WorkGroupID.y of every entry: entry
//    (i, j) holds the samples q with cos(theta) q.x + sin(theta) q.y > r for
//    the line at the centre of its cell, theta = (i + 1/2) pi / angles,
//    r = rho (2 (j + 1/2) / distances - 1).
// Built once per light shape (rectangle, or disk for disks and spheres) and n.

#include "config.h"
#include "penumbra/light_sampling.h"

layout(local_size_x = PENUMBRA_AFSM_TABLE_GROUP) in;

layout(set = 0, binding = 0, std430) buffer Samples { vec2 positions[]; }; // the n samples
layout(buffer_reference, std430, buffer_reference_align = 4) buffer WordArray { uint words[]; };

layout(push_constant) uniform AfsmTablePush {
    uint64_t table;    // angles x distances entries of afsmWords(n) words
    uint phase;        // PENUMBRA_AFSM_TABLE_*
    uint shape;        // PENUMBRA_AREA_RECTANGLE or PENUMBRA_AREA_DISK
    uint count;        // n
    uint tableSize;    // angles | distances << 16
} push;

void main()
{
    if (push.phase == PENUMBRA_AFSM_TABLE_SAMPLES) {
        uint k = gl_GlobalInvocationID.x;
        if (k < push.count)
            positions[k] = afsmLocalSample(push.shape, k, push.count);
        return;
    }
    uint angles = push.tableSize & 0xFFFFu, distances = push.tableSize >> 16u;
    uint entry = gl_GlobalInvocationID.x;
    uint w = gl_WorkGroupID.y;
    if (entry >= angles * distances)
        return;
    float theta = (float(entry / distances) + 0.5) * (3.14159265 / float(angles));
    float rho = push.shape == PENUMBRA_AREA_RECTANGLE ? 1.41421356 : 1.0;
    float r = rho * ((2.0 * float(entry % distances) + 1.0) / float(distances) - 1.0);
    vec2 normal = vec2(cos(theta), sin(theta));
    uint bits = 0u;
    uint first = w * 32u;
    uint used = first < push.count ? min(push.count - first, 32u) : 0u;
    for (uint b = 0u; b < used; ++b)
        if (dot(normal, positions[first + b]) > r)
            bits |= 1u << b;
    uint words = ((push.count + 127u) >> 7u) * 4u; // whole quads (afsm.glsli: afsmQuads)
    WordArray(push.table).words[entry * words + w] = bits;
}
