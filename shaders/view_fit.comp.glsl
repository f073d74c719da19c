#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_EXT_control_flow_attributes : require
// Bounds of what the camera sees in the clip space of each model-fitted
// shadow map of the lights being fitted to the view: a directional light's
// orthographic map, and each perspective map of an area light (x/w, y/w).
// The renderer reads them back before the shadow pass and narrows the maps
// to them (light_space.h: fitDirectionalToView, fitAreaMapToView). Every
// covered G-buffer pixel is a receiver.
// Output per map k of light l: 8 uints at 8 (6 l + k): order keys of min x,
// y, z, then of -max x, y, z (so that one atomicMin and one clear value serve
// all six); then 0 when some pixel lies behind a perspective map's eye plane.
// Lights in gridMask (directional, point, spot) also get a receiver grid per
// shadow-map layer: one bit per cell of a PENUMBRA_RECEIVER_GRID^2 grid over
// the layer's clip x, y in [-1, 1] (a directional light's model-fitted map;
// row y, bit x), set where a pixel's point is looked up (projectToShadowMap:
// the layer of its cube face, clamped to the border cells; a point or spot
// light's points outside the map read nothing and are left out). The shadow
// views cull the casters whose footprint, grown by the texels the
// classification reads, covers no set cell (culling.h: ReceiverMask).
// With kCountCovered, the pass also adds the covered pixels to the frame's
// PENUMBRA_STAT_COVERED counter (one atomic per subgroup of blocks; the
// shade pass would pay one per 8 pixels).

#include "config.h"
// The light masks are specialization constants (runtime/src/passes/view_fit.cpp):
// the loops over the lights unroll and a pipeline holds only the code its
// lights need (lavapipe pays for every instruction a shader holds).
layout(constant_id = 0) const uint kFitMask = 0u;   // push.lightMask
layout(constant_id = 1) const uint kGridMask = 0u;  // push.gridMask
layout(constant_id = 2) const uint kPointMask = 0u;       // bit l: light l is a point light (cube faces)
layout(constant_id = 3) const uint kDirectionalMask = 0u; // bit l: light l is directional (orthographic)
#define kAreaMask (kFitMask & ~kDirectionalMask) // fitted lights are directional or area lights
#include "shadow_common.glsli"

layout(local_size_x = PENUMBRA_SHADE_GROUP_SIZE, local_size_y = PENUMBRA_SHADE_GROUP_SIZE) in;

// Pixels per invocation, a side: a workgroup covers PENUMBRA_SHADE_GROUP_SIZE *
// VIEW_BOUNDS_BLOCK pixels a side; each subgroup adds its bounds with one atomic per key.
// PENUMBRA_VIEW_FIT_BLOCK_CPU or _GPU, chosen by the device type (view_fit.cpp).
layout(constant_id = 4) const int kBlock = PENUMBRA_VIEW_FIT_BLOCK_GPU;
#define VIEW_BOUNDS_BLOCK kBlock
layout(constant_id = 5) const uint kCountCovered = 0u; // push.covered != 0

// C++: runtime/src/passes/view_fit.h (ViewFitBinding).
#include "surface.glsli"
layout(set = 0, binding = 0, rgba32ui) uniform readonly uimage2D gSurface;
layout(set = 0, binding = 1, std140) uniform Frame { FrameData frame; };

layout(buffer_reference, std430) buffer Keys { uint keys[]; };

layout(buffer_reference, std430) buffer Grid { uint bits[]; };

layout(buffer_reference, std430, buffer_reference_align = 8) buffer Counter { uint64_t count; };

layout(push_constant) uniform ViewBoundsPush {
    uint64_t keys;   // Keys, PENUMBRA_MAX_LIGHTS * 6 * 8 uints, cleared to 0xFFFFFFFF
    uint64_t grid;   // Grid, PENUMBRA_RECEIVER_GRID_WORDS uints per layer 6 l + k, cleared to 0
    uint lightMask;  // bit l: light l is fitted (directional, area)
    uint gridMask;   // bit l: light l writes its receiver grids (directional, point, spot)
    uint64_t covered; // Counter: the frame's PENUMBRA_STAT_COVERED (kCountCovered)
} push;


// Unsigned key with the order of the float.
uint orderKey(float f)
{
    uint bits = floatBitsToUint(f);
    return (bits & 0x80000000u) != 0u ? ~bits : bits | 0x80000000u;
}

// Point i of the invocation's block of pixels; false where there is none
// (outside the image, or background).
bool blockPoint(ivec2 origin, ivec2 size, int i, out vec3 p)
{
    // Past the image's edge the nearest pixel is read and left out (no early return: on lavapipe
    // it would put the rest of the loop under an execution mask).
    ivec2 pixel = origin + ivec2(i % VIEW_BOUNDS_BLOCK, i / VIEW_BOUNDS_BLOCK);
    const uvec4 g = imageLoad(gSurface, min(pixel, size - 1));
    p = surfacePosition(g);
    return all(lessThan(pixel, size)) && surfaceCovered(g);
}

// Bounds keys of map k of light l from the subgroup's lanes' bounds: one
// atomic per key and subgroup (no workgroup barrier: on lavapipe each one
// switches between the workgroup's subgroups).
void writeBounds(uint l, uint k, vec3 lo, vec3 negHi, bool behind)
{
    const float inf = uintBitsToFloat(0x7F800000u);
    Keys out_ = Keys(push.keys);
    lo = subgroupMin(lo);
    negHi = subgroupMin(negHi);
    behind = subgroupMax(behind ? 1u : 0u) != 0u; // the device offers arithmetic, not vote
    uint base = 8u * (6u * l + k);
    if (subgroupElect() && lo.x != inf) {
        atomicMin(out_.keys[base + 0u], orderKey(lo.x));
        atomicMin(out_.keys[base + 1u], orderKey(lo.y));
        atomicMin(out_.keys[base + 2u], orderKey(lo.z));
        atomicMin(out_.keys[base + 3u], orderKey(negHi.x));
        atomicMin(out_.keys[base + 4u], orderKey(negHi.y));
        atomicMin(out_.keys[base + 5u], orderKey(negHi.z));
    }
    if (subgroupElect() && behind)
        atomicMin(out_.keys[base + 6u], 0u);
}

// Light l, a directional, point or spot light: its receiver grids (kGridMask)
// and the bounds of a directional light's map (kFitMask), both from the
// model-fitted projection, in one walk over the block's points. The lookup
// is projectToShadowMap's (and shadowLayer's), written out on the uniform's
// fields: passing the LightData to them copies it per pixel, which made this
// pass about 30 ms slower on lavapipe at 1024^2. Keep the two in step.
// Returns the block's covered pixels when `count` (the frame's counter), else 0.
uint fitPointLikeLight(uint l, ivec2 origin, ivec2 size, bool count)
{
    const float inf = uintBitsToFloat(0x7F800000u);
    const bool grid = (kGridMask & (1u << l)) != 0u, fit = (kFitMask & (1u << l)) != 0u;
    const bool pointLight = (kPointMask & (1u << l)) != 0u;
    const bool directional = (kDirectionalMask & (1u << l)) != 0u; // orthographic: w = 1
    const vec3 lightPosition = frame.lights[l].positionType.xyz;
    // Read once: uniform-buffer reads in the loop below would be repeated per point.
    const mat4 viewProj0 = frame.lights[l].viewProj[0];
    Grid cells = Grid(push.grid);
    // Cells are ORed into one word of the grid (32 cells of a row) per lane,
    // written with an atomic when the next point's cell lies in another word,
    // and at the end once per subgroup when all its lanes share the word.
    uint word = ~0u, bits = 0u, covered = 0u;
    vec3 lo = vec3(inf), negHi = vec3(inf);
    for (int i = 0; i < VIEW_BOUNDS_BLOCK * VIEW_BOUNDS_BLOCK; ++i) {
        vec3 p;
        bool valid = blockPoint(origin, size, i, p);
        covered += count && valid ? 1u : 0u;
        uint layer = 0u; // shadowLayer: a point light's cube face
        if (pointLight) {
            vec3 d = p - lightPosition;
            vec3 a = abs(d);
            if (a.x >= a.y && a.x >= a.z)
                layer = d.x >= 0.0 ? 0u : 1u;
            else if (a.y >= a.z)
                layer = d.y >= 0.0 ? 2u : 3u;
            else
                layer = d.z >= 0.0 ? 4u : 5u;
        }
        vec4 clip = pointLight ? frame.lights[l].viewProj[layer] * vec4(p, 1.0) : viewProj0 * vec4(p, 1.0);
        vec3 ndc = directional ? clip.xyz : clip.xyz / clip.w;
        if (fit) { // directional: orthographic, nothing behind the eye
            lo = valid ? min(lo, ndc) : lo;
            negHi = valid ? min(negHi, -ndc) : negHi;
        }
        if (grid) {
            bool inside = clip.w > 0.0 && all(lessThanEqual(abs(ndc.xy), vec2(1.0))) && ndc.z <= 1.0;
            ivec2 cell = clamp(ivec2((ndc.xy * 0.5 + 0.5) * float(PENUMBRA_RECEIVER_GRID)), ivec2(0), ivec2(PENUMBRA_RECEIVER_GRID - 1));
            uint bit = ((6u * l + layer) * PENUMBRA_RECEIVER_GRID + uint(cell.y)) * PENUMBRA_RECEIVER_GRID + uint(cell.x);
            bool marks = valid && (inside || directional);
            if (marks && word != ~0u && (bit >> 5u) != word) {
                atomicOr(cells.bits[word], bits);
                bits = 0u;
            }
            word = marks ? bit >> 5u : word;
            bits |= marks ? 1u << (bit & 31u) : 0u;
        }
    }
    if (grid) {
        bool oneWord = subgroupMin(word) == subgroupMax(word);
        uint sharedBits = subgroupOr(bits);
        if (oneWord && word != ~0u && subgroupElect())
            atomicOr(cells.bits[word], sharedBits);
        if (!oneWord && word != ~0u)
            atomicOr(cells.bits[word], bits);
    }
    if (fit)
        writeBounds(l, 0u, lo, negHi, false);
    return covered;
}

// Light l, an area light: the bounds of each of its perspective maps; the
// block's covered pixels when `count`, else 0.
uint fitAreaLight(uint l, ivec2 origin, ivec2 size, bool count)
{
    const float inf = uintBitsToFloat(0x7F800000u);
    const uint maps = uint(frame.lights[l].spotCosLayers.w);
    uint covered = 0u;
    for (uint k = 0u; k < maps; ++k) {
        const mat4 viewProj = frame.lights[l].viewProj[k];
        vec3 lo = vec3(inf), negHi = vec3(inf);
        bool behind = false;
        for (int i = 0; i < VIEW_BOUNDS_BLOCK * VIEW_BOUNDS_BLOCK; ++i) {
            vec3 q;
            bool used = blockPoint(origin, size, i, q);
            covered += count && k == 0u && used ? 1u : 0u;
            vec4 clip = viewProj * vec4(q, 1.0);
            behind = behind || (used && clip.w <= 0.0);
            used = used && clip.w > 0.0;
            vec3 c = clip.xyz / clip.w;
            lo = used ? min(lo, c) : lo;
            negHi = used ? min(negHi, -c) : negHi;
        }
        writeBounds(l, k, lo, negHi, behind);
    }
    return covered;
}

#ifdef PENUMBRA_FLOOR
#include "floor.glsli"
void main()
{
    const ivec2 size = imageSize(gSurface);
    const ivec2 origin = ivec2(gl_GlobalInvocationID.xy) * VIEW_BOUNDS_BLOCK;
    float sum = frame.lights[0].viewProj[0][0].x;
    for (int i = 0; i < VIEW_BOUNDS_BLOCK * VIEW_BOUNDS_BLOCK; ++i) {
        vec3 p;
        blockPoint(origin, size, i, p);
        sum += p.x;
    }
    // The bounds keep their values: the keys are only lowered when never.
    if (floorNever(subgroupAdd(sum)) && subgroupElect())
        atomicMin(Keys(push.keys).keys[0], 0u);
}
#else
void main()
{
    const ivec2 size = imageSize(gSurface);
    const ivec2 origin = ivec2(gl_GlobalInvocationID.xy) * VIEW_BOUNDS_BLOCK;
    // The block's points are read again for every light and map: a private
    // array of them, indexed in a loop, costs far more on lavapipe (so does
    // unrolling the loops over the points).
    // The first light's walk over the block also counts its covered pixels (kCountCovered).
    uint covered = 0u;
    bool count = kCountCovered != 0u;
    // Unrolled over the lights: each light index is a constant, so that the
    // compiler drops the code of the other light types (fitPointLikeLight's
    // cube-face matrices are per-lane uniform loads).
    [[unroll]] for (uint l = 0u; l < PENUMBRA_MAX_LIGHTS; ++l)
        if ((((kFitMask | kGridMask) & ~kAreaMask) & (1u << l)) != 0u) {
            covered += fitPointLikeLight(l, origin, size, count);
            count = false;
        }
    [[unroll]] for (uint l = 0u; l < PENUMBRA_MAX_LIGHTS; ++l)
        if ((kFitMask & kAreaMask & (1u << l)) != 0u) {
            covered += fitAreaLight(l, origin, size, count);
            count = false;
        }
    if (kCountCovered != 0u) {
        covered = subgroupAdd(covered);
        if (subgroupElect() && covered != 0u)
            atomicAdd(Counter(push.covered).count, uint64_t(covered));
    }
}
#endif
