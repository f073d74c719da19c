#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_KHR_shader_subgroup_arithmetic : require
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

#include "config.h"
#include "shadow_common.glsli"

layout(local_size_x = PENUMBRA_SHADE_GROUP_SIZE, local_size_y = PENUMBRA_SHADE_GROUP_SIZE) in;

// Pixels per invocation, a side: a workgroup covers PENUMBRA_SHADE_GROUP_SIZE *
// VIEW_BOUNDS_BLOCK pixels a side; each subgroup adds its bounds with one atomic per key.
#define VIEW_BOUNDS_BLOCK 4

// C++: runtime/src/passes/view_fit.h (ViewFitBinding).
layout(set = 0, binding = 0, rgba32f) uniform readonly image2D gPosition;
layout(set = 0, binding = 1, std140) uniform Frame { FrameData frame; };

layout(buffer_reference, std430) buffer Keys { uint keys[]; };

layout(buffer_reference, std430) buffer Grid { uint bits[]; };

layout(push_constant) uniform ViewBoundsPush {
    uint64_t keys;   // Keys, PENUMBRA_MAX_LIGHTS * 6 * 8 uints, cleared to 0xFFFFFFFF
    uint64_t grid;   // Grid, PENUMBRA_RECEIVER_GRID_WORDS uints per layer 6 l + k, cleared to 0
    uint lightMask;  // bit l: light l is fitted (directional, area)
    uint gridMask;   // bit l: light l writes its receiver grids (directional, point, spot)
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
    ivec2 pixel = origin + ivec2(i % VIEW_BOUNDS_BLOCK, i / VIEW_BOUNDS_BLOCK);
    p = vec3(0.0);
    if (any(greaterThanEqual(pixel, size)))
        return false;
    vec4 g = imageLoad(gPosition, pixel);
    p = g.xyz;
    return g.w > 0.0;
}

// The receiver grids of light l for the block's points. The lookup is
// projectToShadowMap's (and shadowLayer's), written out on the uniform's
// fields: passing the LightData to them copies it per pixel, which made this
// pass about 30 ms slower on lavapipe at 1024^2. Keep the two in step.
void markReceivers(uint l, vec3 points[VIEW_BOUNDS_BLOCK * VIEW_BOUNDS_BLOCK], uint valid)
{
    const uint type = uint(frame.lights[l].positionType.w);
    const vec3 lightPosition = frame.lights[l].positionType.xyz;
    // Read once: uniform-buffer reads in the loop below would be repeated per point.
    const mat4 viewProj0 = frame.lights[l].viewProj[0];
    Grid cells = Grid(push.grid);
    // Cells are ORed into one word of the grid (32 cells of a row) per lane,
    // written with an atomic when the next point's cell lies in another word,
    // and at the end once per subgroup when all its lanes share the word.
    uint word = ~0u, bits = 0u;
    for (int i = 0; i < VIEW_BOUNDS_BLOCK * VIEW_BOUNDS_BLOCK; ++i) {
        vec3 p = points[i];
        uint layer = 0u; // shadowLayer: a point light's cube face
        if (type == PENUMBRA_LIGHT_POINT) {
            vec3 d = p - lightPosition;
            vec3 a = abs(d);
            if (a.x >= a.y && a.x >= a.z)
                layer = d.x >= 0.0 ? 0u : 1u;
            else if (a.y >= a.z)
                layer = d.y >= 0.0 ? 2u : 3u;
            else
                layer = d.z >= 0.0 ? 4u : 5u;
        }
        vec4 clip = viewProj0 * vec4(p, 1.0);
        PENUMBRA_SKIP_UNLESS(layer != 0u) // cube faces other than +X: only point lights
            clip = frame.lights[l].viewProj[layer] * vec4(p, 1.0);
        vec3 ndc = clip.xyz / clip.w;
        bool inside = clip.w > 0.0 && all(lessThanEqual(abs(ndc.xy), vec2(1.0))) && ndc.z <= 1.0;
        ivec2 cell = clamp(ivec2((ndc.xy * 0.5 + 0.5) * float(PENUMBRA_RECEIVER_GRID)), ivec2(0), ivec2(PENUMBRA_RECEIVER_GRID - 1));
        uint bit = ((6u * l + layer) * PENUMBRA_RECEIVER_GRID + uint(cell.y)) * PENUMBRA_RECEIVER_GRID + uint(cell.x);
        bool marks = (valid & (1u << i)) != 0u && (inside || type == PENUMBRA_LIGHT_DIRECTIONAL);
        PENUMBRA_SKIP_UNLESS(marks && word != ~0u && (bit >> 5u) != word) {
            atomicOr(cells.bits[word], bits);
            bits = 0u;
        }
        word = marks ? bit >> 5u : word;
        bits |= marks ? 1u << (bit & 31u) : 0u;
    }
    bool oneWord = subgroupMin(word) == subgroupMax(word);
    uint sharedBits = subgroupOr(bits);
    PENUMBRA_SKIP_UNLESS(oneWord && word != ~0u && subgroupElect())
        atomicOr(cells.bits[word], sharedBits);
    PENUMBRA_SKIP_UNLESS(!oneWord && word != ~0u)
        atomicOr(cells.bits[word], bits);
}

#ifdef PENUMBRA_FLOOR
#include "floor.glsli"
void main()
{
    const ivec2 size = imageSize(gPosition);
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
    const float inf = uintBitsToFloat(0x7F800000u);
    const ivec2 size = imageSize(gPosition);
    const ivec2 origin = ivec2(gl_GlobalInvocationID.xy) * VIEW_BOUNDS_BLOCK;
    // The block's points, read once for every light and map.
    vec3 points[VIEW_BOUNDS_BLOCK * VIEW_BOUNDS_BLOCK];
    uint valid = 0u;
    for (int i = 0; i < VIEW_BOUNDS_BLOCK * VIEW_BOUNDS_BLOCK; ++i)
        if (blockPoint(origin, size, i, points[i]))
            valid |= 1u << i;
    // Only the lights in the masks (lavapipe would run the body of a skipped
    // iteration masked): one iteration per set bit.
    for (uint lights = push.gridMask; lights != 0u; lights &= lights - 1u)
        markReceivers(uint(findLSB(lights)), points, valid);
    Keys out_ = Keys(push.keys);
    for (uint lights = push.lightMask; lights != 0u; lights &= lights - 1u) {
        const uint l = uint(findLSB(lights));
        const bool perspective = isAreaLight(frame.lights[l]);
        const uint maps = perspective ? uint(frame.lights[l].spotCosLayers.w) : 1u;
        for (uint k = 0u; k < maps; ++k) {
            const mat4 viewProj = frame.lights[l].viewProj[k];
            vec3 lo = vec3(inf), negHi = vec3(inf);
            bool behind = false;
            for (int i = 0; i < VIEW_BOUNDS_BLOCK * VIEW_BOUNDS_BLOCK; ++i) {
                vec4 clip = viewProj * vec4(points[i], 1.0); // orthographic: w = 1
                bool used = (valid & (1u << i)) != 0u;
                behind = behind || (used && clip.w <= 0.0);
                used = used && clip.w > 0.0;
                vec3 c = clip.xyz / clip.w;
                lo = used ? min(lo, c) : lo;
                negHi = used ? min(negHi, -c) : negHi;
            }
            // One atomic per key and subgroup (no workgroup barrier: on lavapipe
            // each one switches between the workgroup's subgroups).
            lo = subgroupMin(lo);
            negHi = subgroupMin(negHi);
            behind = subgroupMax(behind ? 1u : 0u) != 0u; // the device offers arithmetic, not vote
            uint base = 8u * (6u * l + k);
            PENUMBRA_SKIP_UNLESS(subgroupElect() && lo.x != inf) {
                atomicMin(out_.keys[base + 0u], orderKey(lo.x));
                atomicMin(out_.keys[base + 1u], orderKey(lo.y));
                atomicMin(out_.keys[base + 2u], orderKey(lo.z));
                atomicMin(out_.keys[base + 3u], orderKey(negHi.x));
                atomicMin(out_.keys[base + 4u], orderKey(negHi.y));
                atomicMin(out_.keys[base + 5u], orderKey(negHi.z));
            }
            PENUMBRA_SKIP_UNLESS(subgroupElect() && behind)
                atomicMin(out_.keys[base + 6u], 0u);
        }
    }
}
#endif
