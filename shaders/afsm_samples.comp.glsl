#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
// Alias-free shadow maps, the view samples' passes (Sintorn et al. 2008,
// section 3; afsm.glsli). Per camera pixel, one of:
//  PENUMBRA_AFSM_COUNT: the sample's grid cell in layer `layer` gets one more
//    sample (atomicAdd on cellCount);
//  PENUMBRA_AFSM_LIST: after the prefix sum (afsm_scan.comp.glsl) turned the
//    counts into offsets, the sample writes its pixel index into its cell's
//    range of the flat list (cellFill counts the cell's slots taken);
//  PENUMBRA_AFSM_RESOLVE: after every layer's casters (afsm_casters), the
//    light's visibility: 0 where a caster blocked the sample's ray or the
//    surface faces away, 1 elsewhere; -1 for background. Clears the marks
//    (nothing is traced) and counts covered pixels.

#include "config.h"
#include "shadow_common.glsli"
#include "shadow_ray.glsli"
#include "afsm.glsli"

layout(local_size_x = PENUMBRA_SHADE_GROUP_SIZE, local_size_y = PENUMBRA_SHADE_GROUP_SIZE) in;

#define PIXEL_MARKS_ACCESS writeonly
#include "pixel_bindings.glsli"
// C++: runtime/src/passes/afsm.h (AfsmBinding).
layout(set = 0, binding = 6, std430) buffer CellCount { uint cellCount[]; };   // per cell: samples, then (scan) first slot
layout(set = 0, binding = 7, std430) buffer CellFill { uint cellFill[]; };     // per cell: slots taken (PENUMBRA_AFSM_LIST)
layout(set = 0, binding = 8, std430) buffer SampleList { uint samplePixels[]; }; // pixel index per slot
layout(set = 0, binding = 9, std430) buffer Shadowed { uint shadowed[]; };     // per pixel: 1 when a caster blocks its ray

layout(push_constant) uniform AfsmSamplesPush {
    uint lightIndex;
    uint mode;        // PENUMBRA_AFSM_COUNT, _LIST, _RESOLVE
    uint layer;       // layer of the light binned (COUNT, LIST)
    uint gridSize;    // cells per side
    float originOffset;
    uint pad0, pad1, pad2;
} push;

uvec2 samplePixel()
{
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = imageSize(visibilityImage);
    if (any(greaterThanEqual(pixel, size)))
        return uvec2(0u);
    uint index = uint(pixel.y * size.x + pixel.x);
    vec4 position = imageLoad(gPosition, pixel);
    if (push.mode == PENUMBRA_AFSM_RESOLVE) {
        if (position.w == 0.0) {
            imageStore(visibilityImage, pixel, vec4(-1.0));
            marks[index] = 0u;
            return uvec2(0u);
        }
        ShadowRay ray;
        bool facing = afsmSampleRay(frame.lights[push.lightIndex], position.xyz, imageLoad(gNormal, pixel).xyz, push.originOffset, ray);
        imageStore(visibilityImage, pixel, vec4(facing && shadowed[index] == 0u ? 1.0 : 0.0));
        marks[index] = 0u;
        return uvec2(1u, 0u);
    }
    if (position.w == 0.0)
        return uvec2(0u);
    LightData light = frame.lights[push.lightIndex];
    ShadowRay ray;
    if (!afsmSampleRay(light, position.xyz, imageLoad(gNormal, pixel).xyz, push.originOffset, ray))
        return uvec2(0u);
    uint cell = afsmCell(light, push.layer, position.xyz, ray.origin, push.gridSize);
    if (cell == AFSM_NOT_BINNED)
        return uvec2(0u);
    if (push.mode == PENUMBRA_AFSM_COUNT)
        atomicAdd(cellCount[cell], 1u);
    else
        samplePixels[cellCount[cell] + atomicAdd(cellFill[cell], 1u)] = index;
    return uvec2(0u);
}

void main()
{
    samplePixel(); // covered pixels are counted by shade
}
