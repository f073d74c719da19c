#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
// Alias-free shadow maps, casters (Sintorn et al. 2008, section 3.3): for
// one triangle and one grid cell, the exact test of every sample listed in
// the cell (afsm_samples.comp.glsl): the tracer's watertight ray/triangle
// test of the sample's own shadow ray, whose three edge functions are the
// planes through the ray and each edge (through the light and each edge for
// point and spot lights; the edges' extrusions along the light's direction
// for directional lights) and t the triangle's supporting plane, as in the
// paper, on the ray the sample's slot holds (afsm.glsli: AfsmRaySlot); a hit
// sets the sample's shadow flag (afsm_casters.glsli). No depth is
// compared, so there is no acne and no aliasing, and the result equals the
// tracer's. One fragment tests one slice of the cell's list, at most
// afsmSliceSamples(0) samples from push.sliceBegin (afsm.glsli: lavapipe's
// loop limit); a crowded cell's later slices come in later draws
// (afsm_casters.geom.glsl).

#include "config.h"
#include "shadow_common.glsli"
#include "shadow_ray.glsli"
#include "penumbra/light_sampling.h"
#define AFSM_SLOTS 1
#include "afsm.glsli"

// The depth test (the cells' farthest samples) before the shader: it stores, so without this the test would run after it.
layout(early_fragment_tests) in;
layout(location = 0) flat in vec3 vertex0;
layout(location = 1) flat in vec3 vertex1;
layout(location = 2) flat in vec3 vertex2;
layout(location = 3) flat in vec4 projected01;
layout(location = 4) flat in vec4 projected2;

// C++: runtime/src/passes/afsm.h (AfsmCastersBinding).
layout(set = 0, binding = 1) uniform usamplerBuffer cellFirstTexels;  // R32UI: first slot per cell (afsm_casters.glsli: afsmCellFirst)
layout(set = 0, binding = 2) uniform usamplerBuffer cellCountTexels;  // R32UI: samples per cell (afsmCellCount)
layout(set = 0, binding = 3, std430) buffer Shadowed { uint shadowed[]; };
// Hard shadows of a directional light: the layer's shear, and in parallel.w bit 8 whether the slots are sheared
// (afsm_samples.comp.glsl; afsm.glsli: AfsmParallel).
layout(set = 0, binding = 4, std430) readonly buffer Far { AFSM_FAR_FIELDS; };
#define AFSM_PARALLEL ((parallel.w & 0x100u) != 0u)
layout(set = 0, binding = 5) uniform usamplerBuffer cellDepthTexels;  // R32UI: per cell, its farthest sample depth (afsmCellDepth)
layout(set = 0, binding = 6, std430) buffer SlotShadowed { uint slotShadowed[]; }; // per slot: shadowed[] of its pixel
layout(set = 0, binding = 7, std430) buffer CellAlive { uint cellAlive[]; };          // per cell: samples not yet shadowed
layout(set = 0, binding = 8, std430) readonly buffer ClosedBits { uint closedBits[]; }; // bit per cluster: kClusterClosed
layout(set = 0, binding = 9) uniform usamplerBuffer slotTexels;                      // RGBA32UI over the slots (afsm_casters.glsli: afsmRaySlotAt)

#include "afsm_casters.glsli"

layout(push_constant) uniform AfsmCastersPush {
    mat4 viewProj;
    uint lightIndex;
    uint gridSize;
    float originOffset;
    float computeCells;
    uint closedBackFaces;
    uint sliceBegin;    // the first sample of each cell's list this draw tests (0, or a later slice of the crowded cells)
    uint64_t wideList;  // afsm_casters.geom.glsl's
} push;

void main()
{
    uvec2 cellXY = uvec2(gl_FragCoord.xy);
    uint cell = cellXY.y * push.gridSize + cellXY.x;
    vec2 v[3] = vec2[](projected01.xy, projected01.zw, projected2.xy);
    // Empty cells and those whose samples all lie nearer the light failed the depth test (afsm_casters.geom.glsl).
    // A fragment with nothing to test gets an empty range rather than an early return (lavapipe would
    // run the loop under an execution mask).
    const bool alive = cellAlive[cell] != 0u, more = afsmCellCount(cell) > push.sliceBegin;
    const bool meets = afsmCellMayMeetTriangle(vec2(cellXY) + 0.5, v, projected2.w != 0.0, projected2.z);
    const uint end = alive && more && meets ? push.sliceBegin + afsmSliceSamples(0u) : push.sliceBegin;
    afsmTestCellHard(cell, push.sliceBegin, end, vertex0, vertex1, vertex2);
}
