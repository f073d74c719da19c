#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_buffer_reference : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_basic : require
// Alias-free shadow maps, the view samples' passes (Sintorn et al. 2008,
// section 3; afsm.glsli). Per camera pixel, one of:
//  PENUMBRA_AFSM_COUNT: the sample's grid cell in layer `layer` gets one more
//    sample (atomicAdd on cellCount) and keeps its farthest sample's depth
//    (afsmDepth of the ray origin: the casters' depth test), and the layer
//    its farthest sample's clip.w (soft: the influence regions' far plane),
//    its most samples in one cell (cellMost; also the frame's counter
//    PENUMBRA_STAT_AFSM_CELL_MOST) and the rectangle of its cells holding
//    more than push.sliceSamples (crowded: the raster path tests those in
//    slices, one more draw per slice; afsm_casters.glsli);
//  PENUMBRA_AFSM_LIST: after the prefix sum (afsm_scan.comp.glsl) turned the
//    counts into offsets, the sample writes its ray and pixel index
//    (AfsmRaySlot, afsm.glsli) into its cell's range of the flat list of
//    slots (cellFill counts the cell's slots taken);
//  PENUMBRA_AFSM_REFRESH (hard shadows, after a first pass of casters): the
//    cells' farthest depths again (cleared by AfsmPass), over the samples no
//    caster has shadowed yet; nothing else changes;
//  PENUMBRA_AFSM_BLOCKS (after the count and the refresh): each block of
//    8x8 cells its farthest depth, from its cells' (one invocation a block);
//  PENUMBRA_AFSM_RESOLVE: after every layer's casters (afsm_casters), the
//    light's visibility: 0 where a caster blocked the sample's ray or the
//    surface faces away, 1 elsewhere; -1 for background. Clears the marks
//    (nothing is traced); shade counts the covered pixels.
// Built a second time with PENUMBRA_AFSM_SOFT (afsm_samples.comp.soft) for
// area lights (section 4): a pixel is a sample when some point of the light
// lies above its plane and it is in front of a one-sided emitter; the list writes the slot's ray origin and
// the light's jittered axes (AfsmSlot); the resolve counts the light samples
// above the pixel's plane that no caster's mask holds, and clears the mask.

#include "config.h"
#include "shadow_common.glsli"
#include "shadow_ray.glsli"
#include "penumbra/light_sampling.h"
#ifdef PENUMBRA_AFSM_SOFT
#define AFSM_SOFT 1
#endif
#define AFSM_SLOTS 1
#include "afsm.glsli"

layout(local_size_x = PENUMBRA_SHADE_GROUP_SIZE, local_size_y = PENUMBRA_SHADE_GROUP_SIZE) in;

#define PIXEL_MARKS_ACCESS writeonly
#include "pixel_bindings.glsli"
// C++: runtime/src/passes/afsm.h (AfsmSamplesBinding).
layout(set = 0, binding = 6, std430) buffer CellCount { uint cellCount[]; };   // per cell: samples, then (scan) first slot
layout(set = 0, binding = 7, std430) buffer CellFill { uint cellFill[]; };     // per cell: slots taken (PENUMBRA_AFSM_LIST)
layout(set = 0, binding = 8, std430) buffer Shadowed { uint shadowed[]; };     // per pixel: 1 when a caster blocks its ray (soft: all its samples)
// The layer's farthest sample's clip.w (float bits), its most samples in a cell, and its crowded cells' rectangle
// (min x, min y, max x, max y; cleared to ~0, ~0, 0, 0). C++: afsm.h (AfsmFar).
// Hard shadows of a directional light: the layer's permutation and shear (afsm.glsli: AfsmParallel), written by the list.
layout(set = 0, binding = 9, std430) buffer Far { AFSM_FAR_FIELDS; };
layout(set = 0, binding = 10, std430) buffer CellDepth { uint cellDepth[]; };  // per cell: its farthest sample depth (float bits)
layout(set = 0, binding = 11, std430) buffer SlotShadowed { uint slotShadowed[]; }; // per slot: shadowed[] of its pixel (cleared by AfsmPass before the list)
layout(set = 0, binding = 12, std430) buffer CellAlive { uint cellAlive[]; };     // per cell: samples not yet shadowed (AfsmPass copies the counts after the list)

// The mode (PENUMBRA_AFSM_*) is a specialization constant, push.mode its copy: one pipeline per mode
// (llvmpipe runs both sides of an if, masked: every mode's code at each subgroup; rh_build.comp measures it).
layout(constant_id = 0) const uint kMode = PENUMBRA_AFSM_COUNT;
// 1: hard shadows of a directional light, the list writes the sheared slots (afsm.glsli: AfsmParallel).
layout(constant_id = 1) const uint kParallel = 0u;

layout(push_constant) uniform AfsmSamplesPush {
    mat4 viewProj;      // the layer's grid projection
    uint64_t slots;     // AfsmRaySlot (soft: AfsmSlot) per slot
    uint64_t masks;     // soft: afsmWords(samples) uints per pixel
    uint64_t table;     // soft: the lookup table (afsm_table.comp.glsl)
    uint lightIndex;
    uint mode;          // PENUMBRA_AFSM_COUNT, _LIST, _RESOLVE: kMode's value
    uint layer;         // layer of the light binned (COUNT, LIST)
    uint gridSize;      // cells per side
    float originOffset;
    uint cube;          // 1: the layers are the six cube faces around the light's position
    uint samples;       // soft: light samples n
    uint tableSize;     // soft: angles | distances << 16
    uint sliceSamples;  // COUNT: a cell with more samples is crowded (afsmSliceSamples)
    uint pad;
} push;

#ifdef PENUMBRA_AFSM_SOFT
// Whether the pixel at p (normal n) sees some point of the area light: in
// front of a one-sided emitter, and some point of the light above its plane.
bool softSample(LightData light, vec3 p, vec3 n)
{
    return inFrontOfEmitter(light, p) && areaLightHeightRange(light, p, n).y > 0.0;
}

uint areaShape(LightData light)
{
    return uint(light.positionType.w);
}

// The light's fraction of samples above the pixel's plane that no caster's
// mask holds; clears the pixel's mask for the next light.
float softVisibility(LightData light, uvec2 pixel, uint index, vec3 p, vec3 n)
{
    uint shape = areaShape(light);
    vec4 jitter = afsmJitter(shape, sampleSeed(pixel.x, pixel.y, push.lightIndex));
    vec3 c = light.positionType.xyz;
    vec3 axisU = afsmAxisU(shape, c, light.areaU.xyz, light.areaV.xyz, p, jitter);
    vec3 axisV = afsmAxisV(shape, c, light.areaU.xyz, light.areaV.xyz, p, jitter);
    // Samples above the plane through p: n . (x - p) > 0 (as the tracer's dot(normal, direction) > 0).
    uint above = afsmPlaneThrough(n, p, c, axisU, axisV, shape == PENUMBRA_AREA_RECTANGLE, push.tableSize);
    uint quads = afsmQuads(push.samples);
    AfsmQuadArray masks = AfsmQuadArray(push.masks);
    bool blocked = shadowed[index] != 0u;
    uvec4 visible = uvec4(0u);
    for (uint q = 0u; q < quads; ++q) {
        uvec4 mask = masks.quads[index * quads + q];
        masks.quads[index * quads + q] = uvec4(0u);
        visible += uvec4(bitCount(afsmPlaneQuad(push.table, above, q, quads, afsmValidBits(q, push.samples)) & ~mask));
    }
    return blocked ? 0.0 : float(visible.x + visible.y + visible.z + visible.w) / float(push.samples);
}
#endif

// One exit: a pixel that lists no sample (background, facing away, another
// layer, not binned, outside a spot light's cone) is a flag, not a return:
// on lavapipe an early return puts the rest of the shader under an execution
// mask (pixelOfInvocation).
uvec2 samplePixel()
{
    ivec2 size = imageSize(visibilityImage), pixel;
    const bool inside = pixelOfInvocation(size, pixel);
    uint index = uint(pixel.y * size.x + pixel.x);
    const uvec4 surface = imageLoad(gSurface, pixel);
    const vec3 position = surfacePosition(surface);
    const bool covered = surfaceCovered(surface);
    LightData light = frame.lights[push.lightIndex];
    vec3 n = surfaceNormal(surface);
    if (kMode == PENUMBRA_AFSM_RESOLVE) {
#ifdef PENUMBRA_AFSM_SOFT
        // softVisibility clears the pixel's masks: once per pixel, by its own invocation.
        float visibility = unlitOrBackground(covered);
        PENUMBRA_SKIP_UNLESS(inside && covered && softSample(light, position.xyz, n))
            visibility = softVisibility(light, uvec2(pixel), index, position.xyz, n);
#else
        ShadowRay ray;
        bool facing = afsmSampleRay(light, position.xyz, n, push.originOffset, ray);
        const bool lit = covered && facing && shadowed[index] == 0u;
        float visibility = lit ? 1.0 : unlitOrBackground(covered); // not nested selects: see unlitOrBackground
#endif
        if (inside) {
            imageStore(visibilityImage, pixel, vec4(visibility));
            marks[index] = 0u;
        }
        return uvec2(0u);
    }
#ifdef PENUMBRA_AFSM_SOFT
    bool listed = inside && covered && softSample(light, position.xyz, n);
    vec3 origin = position.xyz + n * push.originOffset;
    listed = listed && afsmLayer(light, position.xyz, push.cube != 0u) == push.layer;
#else
    ShadowRay ray;
    bool listed = inside && covered && afsmSampleRay(light, position.xyz, n, push.originOffset, ray);
    vec3 origin = ray.origin;
    listed = listed && shadowLayer(light, position.xyz) == push.layer;
#endif
    float depth, w;
    uvec2 cellXY;
    uint cell = afsmGridCell(push.viewProj, origin, push.gridSize, depth, w, cellXY);
    listed = listed && cell != AFSM_NOT_BINNED;
#ifndef PENUMBRA_AFSM_SOFT
    // A spot light's grid is its cone: samples outside it get no light (shade), nothing to list.
    if (uint(light.positionType.w) != PENUMBRA_LIGHT_POINT) {
        vec4 clip = push.viewProj * vec4(origin, 1.0);
        listed = listed && !any(greaterThan(abs(clip.xy), vec2(clip.w)));
    }
#endif
    uvec2 counts = uvec2(0u);
    if (kMode == PENUMBRA_AFSM_REFRESH) {
        if (listed && shadowed[index] == 0u) // as the count below (the blocks' after it: PENUMBRA_AFSM_BLOCKS)
            atomicMax(cellDepth[cell], floatBitsToUint(clamp(depth, 0.0, 1.0)));
    } else if (kMode == PENUMBRA_AFSM_COUNT) {
        if (listed) {
            uint before = atomicAdd(cellCount[cell], 1u);
            if (before == push.sliceSamples) { // the cell's first sample past one slice: once per crowded cell
                atomicMin(crowded[0], cell % push.gridSize);
                atomicMin(crowded[1], cell / push.gridSize);
                atomicMax(crowded[2], cell % push.gridSize);
                atomicMax(crowded[3], cell / push.gridSize);
            }
            // Depths lie in [0, 1] (the grid's depth range holds the model) but for a hair past it; clamped as the casters' depth
            // test clamps; non-negative floats order as uints.
            // Its block's after this pass, from the cells' (PENUMBRA_AFSM_BLOCKS: one atomic a sample fewer).
            atomicMax(cellDepth[cell], floatBitsToUint(clamp(depth, 0.0, 1.0)));
            counts = uvec2(before + 1u, floatBitsToUint(w)); // the cell's last sample sees its count
        }
    } else if (listed) {
        uint slot = cellCount[cell] + atomicAdd(cellFill[cell], 1u); // slotShadowed: cleared, cellAlive: the count (AfsmPass)
#ifndef PENUMBRA_AFSM_SOFT
        // As two 16-byte words of two 64-bit components (AfsmRaySlotWords): four stores a lane, not eight
        // (afsm_samples 39-43 -> 36-37 CPU ms on the 250k scan at 640^2, plant 31-32 -> 30-31).
        AfsmRaySlotWords words = AfsmRaySlotWords(push.slots);
        if (kParallel != 0u) { // the sheared origin and the pixel: one word
            const uvec4 a = uvec4(floatBitsToUint(afsmShearPoint(afsmParallelOf(light), ray.origin)), index * 4u + uint(ray.k.z));
            words.words[slot] = u64vec2(packUint2x32(a.xy), packUint2x32(a.zw));
        } else {
            const AfsmRaySlot written = afsmRaySlot(ray, index);
            const uvec4 a = floatBitsToUint(written.originTMax), b = floatBitsToUint(written.shearPixel);
            words.words[2u * slot] = u64vec2(packUint2x32(a.xy), packUint2x32(a.zw));
            words.words[2u * slot + 1u] = u64vec2(packUint2x32(b.xy), packUint2x32(b.zw));
        }
#else
        uint shape = areaShape(light);
        vec4 jitter = afsmJitter(shape, sampleSeed(uint(pixel.x), uint(pixel.y), push.lightIndex));
        vec3 c = light.positionType.xyz;
        // As 64-bit words (see the hard slot above).
        const uvec4 a = floatBitsToUint(vec4(origin, uintBitsToFloat(index)));
        const uvec4 u = floatBitsToUint(vec4(afsmAxisU(shape, c, light.areaU.xyz, light.areaV.xyz, position.xyz, jitter), 0.0));
        const uvec4 v = floatBitsToUint(vec4(afsmAxisV(shape, c, light.areaU.xyz, light.areaV.xyz, position.xyz, jitter), 0.0));
        AfsmRaySlotWords words = AfsmRaySlotWords(push.slots);
        words.words[3u * slot] = u64vec2(packUint2x32(a.xy), packUint2x32(a.zw));
        words.words[3u * slot + 1u] = u64vec2(packUint2x32(u.xy), packUint2x32(u.zw));
        words.words[3u * slot + 2u] = u64vec2(packUint2x32(v.xy), packUint2x32(v.zw));
#endif
    }
    return counts;
}

// PENUMBRA_AFSM_BLOCKS: invocation (x, y) takes block (x, y) of 8x8 cells
// (those of it inside the grid) and stores its cells' farthest depth as the
// block's (afsm_casters.glsli: afsmBlocksBehind). Once per block instead of
// an atomic per sample in the count (and the refresh): the 1-2 M scenes'
// afsm_samples at 1024^2 about 5 CPU ms less.
void blockDepth()
{
    const uint blocks = (push.gridSize + 7u) >> 3u;
    const uvec2 block = gl_GlobalInvocationID.xy;
    const bool inside = block.x < blocks && block.y < blocks;
    const uvec2 first = block * 8u, end = inside ? min(first + 8u, uvec2(push.gridSize)) : first;
    uint farthest = 0u; // an empty cell's (and block's) depth
    for (uint y = first.y; y < end.y; ++y)
        for (uint x = first.x; x < end.x; ++x)
            farthest = max(farthest, cellDepth[y * push.gridSize + x]);
    if (inside)
        cellDepth[afsmBlockDepthIndex(block, push.gridSize)] = farthest;
}

void main()
{
    if (kMode == PENUMBRA_AFSM_BLOCKS) {
        blockDepth();
        return;
    }
    uvec2 counts = samplePixel(); // covered pixels are counted by shade
#ifndef PENUMBRA_AFSM_SOFT
    // The layer's permutation and shear, for the casters (the list's own values: afsmParallelOf).
    if (kMode == PENUMBRA_AFSM_LIST && kParallel != 0u && gl_GlobalInvocationID.xy == uvec2(0u))
        parallel = afsmPackParallel(afsmParallelOf(frame.lights[push.lightIndex]));
#endif
    // The layer's farthest sample (clip.w) and its most samples in a cell: one atomic each per subgroup.
    if (kMode == PENUMBRA_AFSM_COUNT) {
        uint farthest = subgroupMax(counts.y);
        uint most = subgroupMax(counts.x);
        if (subgroupElect() && farthest != 0u)
            atomicMax(farBits, farthest);
        if (subgroupElect() && most != 0u) {
            atomicMax(cellMost, most);
            atomicMax(stats[PENUMBRA_STAT_AFSM_CELL_MOST], uint64_t(most));
        }
    }
}
