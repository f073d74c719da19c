#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
// Cone ray hierarchies, the rays of one layer of the light (rh.glsli): every
// light-facing pixel whose point lies in the layer (a point light's cube
// face by the major axis of its direction from the light; inside a spot
// light's cone) is listed. Each 8x8 tile lists its rays in Morton order, its
// range padded to a multiple of 4 with RH_NO_RAY, so the hierarchy's leaves
// (4 consecutive rays) never span two tiles and are 2x2 blocks of pixels
// where all four are lit; the tiles follow each other in Morton order too
// (push.mode: PENUMBRA_RH_RAYS_COUNT writes each tile's padded count at its
// Morton index, afsm_scan.comp turns the counts into offsets, then
// PENUMBRA_RH_RAYS_LIST writes the rays there), so the levels above are
// quads of tiles: the screen-space hierarchy of the paper's unsorted
// variant. The sorted variant (section 3.5) lists the rays by direction
// instead: the ray's point in the layer's projection from the light (a cube
// face, or the spot's cone) falls in one cell of a 1024 x 1024 grid, whose
// index on a Hilbert curve is the ray's key; a counting sort over the keys
// (PENUMBRA_RH_RAYS_SORT_COUNT: rays per key, afsm_scan.comp: offsets,
// PENUMBRA_RH_RAYS_SORT_LIST: each ray at its key's next slot) puts rays of
// one cell together in any order, and the cells along the curve. A cell is
// 0.09 degrees of a cube face: about a pixel's angle at 1024^2, so the order
// inside a cell costs little. The ray itself is never stored: rh_build and
// rh_traverse rebuild it from the G-buffer and the light.

#include "config.h"
#include "shadow_common.glsli"
#include "shadow_ray.glsli"
#include "afsm.glsli"

layout(local_size_x = 64) in;

// C++: runtime/src/passes/rh.h (RhRaysBinding).
layout(set = 0, binding = 0, rgba32f) uniform readonly image2D gPosition;
layout(set = 0, binding = 1, rgba32f) uniform readonly image2D gNormal;
layout(set = 0, binding = 2, std140) uniform Frame { FrameData frame; };
layout(set = 0, binding = 3, std430) writeonly buffer Rays { uint rayPixels[]; };
layout(set = 0, binding = 5, std430) buffer TileOffsets { uint tileOffsets[]; }; // per tile at its Morton index: count, then offset
layout(set = 0, binding = 6, std430) buffer KeySlots { uint keySlots[]; };       // per key: rays, then (scan) next slot
#include "rh.glsli"
#define RH_STATE_BINDING 4
RH_STATE_DECLARE();

layout(push_constant) uniform RhRaysPush {
    uint lightIndex;
    uint layer;
    float originOffset;
    uint mode; // PENUMBRA_RH_RAYS_*
} push;

shared uint subgroupTotals[64];

// The tile's index on a Morton curve over the tiles (16 bits per axis).
uint mortonIndex(uvec2 tile)
{
    uvec2 v = tile & 0xFFFFu;
    v = (v | (v << 8u)) & 0x00FF00FFu;
    v = (v | (v << 4u)) & 0x0F0F0F0Fu;
    v = (v | (v << 2u)) & 0x33333333u;
    v = (v | (v << 1u)) & 0x55555555u;
    return v.x | (v.y << 1u);
}

// The cell's index on a Hilbert curve over a 2^order square (Hilbert's
// rotations, as xy2d in the usual formulation), without branches.
uint hilbertIndex(uvec2 p, uint order)
{
    uint n = 1u << order;
    uint d = 0u;
    for (uint s = n >> 1u; s > 0u; s >>= 1u) {
        uint rx = (p.x & s) != 0u ? 1u : 0u;
        uint ry = (p.y & s) != 0u ? 1u : 0u;
        d += s * s * ((3u * rx) ^ ry);
        bool flip = ry == 0u && rx == 1u;
        p = flip ? uvec2(n - 1u) - p : p;
        p = ry == 0u ? p.yx : p;
    }
    return d;
}

// The sorted variant's key of a ray from the light to p: its cell in the layer's projection.
uint directionKey(LightData light, vec3 p)
{
    vec4 clip = lightViewProj(light, push.layer) * vec4(p, 1.0);
    vec2 ndc = clamp(clip.xy / max(clip.w, 1e-30), vec2(-1.0), vec2(1.0));
    uvec2 cell = uvec2(min((ndc * 0.5 + 0.5) * float(PENUMBRA_RH_SORT_CELLS), vec2(float(PENUMBRA_RH_SORT_CELLS) - 1.0)));
    return hilbertIndex(cell, PENUMBRA_RH_SORT_ORDER);
}

// Morton order inside the tile: bits of x and y interleaved.
uvec2 mortonPixel(uint i)
{
    uint x = (i & 1u) | ((i >> 1u) & 2u) | ((i >> 2u) & 4u);
    uint y = ((i >> 1u) & 1u) | ((i >> 2u) & 2u) | ((i >> 3u) & 4u);
    return uvec2(x, y);
}

void main()
{
    uint local = gl_LocalInvocationIndex;
    ivec2 pixel = ivec2(gl_WorkGroupID.xy * 8u + mortonPixel(local));
    ivec2 size = imageSize(gPosition);
    bool listed = false;
    uint index = 0u, key = 0u;
    if (all(lessThan(pixel, size))) {
        index = uint(pixel.y * size.x + pixel.x);
        vec4 position = imageLoad(gPosition, pixel);
        if (position.w != 0.0) {
            LightData light = frame.lights[push.lightIndex];
            ShadowRay ray;
            if (afsmSampleRay(light, position.xyz, imageLoad(gNormal, pixel).xyz, push.originOffset, ray))
                listed = afsmCell(light, push.layer, position.xyz, ray.origin, 2u) != AFSM_NOT_BINNED;
            if (listed && push.mode >= PENUMBRA_RH_RAYS_SORT_COUNT)
                key = directionKey(light, position.xyz);
        }
    }
    if (push.mode == PENUMBRA_RH_RAYS_SORT_LIST) {
        if (listed)
            rayPixels[atomicAdd(keySlots[key], 1u)] = index;
        return;
    }
    // Prefix in the subgroup (a ballot), then over the subgroups (in order).
    uvec4 ballot = subgroupBallot(listed);
    uint before = subgroupBallotExclusiveBitCount(ballot);
    if (subgroupElect())
        subgroupTotals[gl_SubgroupID] = subgroupBallotBitCount(ballot);
    barrier();
    uint offset = 0u, total = 0u;
    for (uint s = 0u; s < gl_NumSubgroups; ++s) {
        uint count = subgroupTotals[s];
        offset += s < gl_SubgroupID ? count : 0u;
        total += count;
    }
    if (push.mode == PENUMBRA_RH_RAYS_SORT_COUNT) {
        if (listed)
            atomicAdd(keySlots[key], 1u);
        if (local == 0u && total != 0u) {
            atomicAdd(state.rayCount, total);
            atomicAdd(state.raysListed, total);
        }
        return;
    }
    uint padded = (total + 3u) & ~3u;
    uint tile = mortonIndex(gl_WorkGroupID.xy);
    if (push.mode == PENUMBRA_RH_RAYS_COUNT) {
        if (local == 0u)
            tileOffsets[tile] = padded;
        return;
    }
    if (padded == 0u)
        return;
    if (local == 0u) {
        atomicAdd(state.rayCount, padded);
        atomicAdd(state.raysListed, total);
    }
    uint tileBase = tileOffsets[tile];
    if (listed)
        rayPixels[tileBase + offset + before] = index;
    if (local < padded - total)
        rayPixels[tileBase + total + local] = RH_NO_RAY;
}
