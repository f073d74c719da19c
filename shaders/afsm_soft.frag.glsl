#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
// Alias-free shadow maps, soft shadows (Sintorn et al. 2008, section 4.2):
// for one caster and one grid cell of its influence region
// (afsm_soft.geom.glsl), the samples listed in the cell against the caster
// (afsm_casters.glsli: afsmTestCellSoft, four table lookups per sample): one
// slice of the cell's list, at most afsmSliceSamples(samples) from
// push.sliceBegin (afsm.glsli: lavapipe's loop limit); a crowded cell's
// later slices come in later draws (afsm_soft.geom.glsl).

#include "config.h"
#include "shadow_common.glsli"
#include "shadow_ray.glsli"
#include "penumbra/light_sampling.h"
#define AFSM_SOFT 1
#include "afsm.glsli"

// The depth test (the cells' farthest samples) before the shader: it stores, so without this the test would run after it.
layout(early_fragment_tests) in;
layout(location = 0) flat in vec3 vertex0;
layout(location = 1) flat in vec3 vertex1;
layout(location = 2) flat in vec3 vertex2;

// C++: runtime/src/passes/afsm.h (AfsmSoftBinding).
layout(set = 0, binding = 0, std140) uniform Frame { FrameData frame; };
layout(set = 0, binding = 1) uniform usamplerBuffer cellFirstTexels;  // R32UI: first slot per cell (afsm_casters.glsli: afsmCellFirst)
layout(set = 0, binding = 2) uniform usamplerBuffer cellCountTexels;  // R32UI: samples per cell (afsmCellCount)
layout(set = 0, binding = 3, std430) buffer Shadowed { uint shadowed[]; };            // per pixel: every light sample hidden
layout(set = 0, binding = 5) uniform usamplerBuffer cellDepthTexels;  // R32UI: per cell, its farthest sample depth (afsmCellDepth)
layout(set = 0, binding = 6, std430) buffer SlotShadowed { uint slotShadowed[]; }; // per slot: shadowed[] of its pixel
layout(set = 0, binding = 7, std430) buffer CellAlive { uint cellAlive[]; };          // per cell: samples not yet shadowed
layout(set = 0, binding = 8, std430) readonly buffer ClosedBits { uint closedBits[]; }; // bit per cluster: kClusterClosed
layout(set = 0, binding = 9) uniform usamplerBuffer slotTexels;                      // RGBA32UI over the slots (afsm_casters.glsli: afsmRaySlotAt)

#include "afsm_casters.glsli"

layout(push_constant) uniform AfsmSoftPush {
    mat4 viewProj;
    uint64_t masks;     // afsmQuads(samples) uvec4 per pixel
    uint64_t table;     // afsm_table.comp.glsl
    uint lightIndex;
    uint gridSize;
    float originOffset;
    uint samples;
    uint tableSize;     // angles | distances << 16
    float computeCells;
    uint closedBackFaces;
    uint sliceBegin;    // the first sample of each cell's list this draw tests (0, or a later slice of the crowded cells)
} push;

void main()
{
    uvec2 cellXY = uvec2(gl_FragCoord.xy);
    uint cell = cellXY.y * push.gridSize + cellXY.x;
    // Empty cells and those whose samples all lie nearer the light failed the depth test (afsm_soft.geom.glsl).
    if (cellAlive[cell] == 0u || afsmCellCount(cell) <= push.sliceBegin)
        return;
    afsmTestCellSoft(cell, push.sliceBegin, push.sliceBegin + afsmSliceSamples(push.samples), frame.lights[push.lightIndex], AfsmSoftTable(push.masks, push.table, push.samples, push.tableSize),
                     vertex0, vertex1, vertex2);
}
