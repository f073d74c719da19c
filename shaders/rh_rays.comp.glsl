#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_shuffle : require
#extension GL_EXT_shader_atomic_int64 : require
// Cone ray hierarchies, the rays of one light (rh.glsli): every light-facing
// pixel the light reaches (a spot light: inside its frustum) is a ray. One
// workgroup per 8x8 tile, its pixels in Morton order (4 consecutive
// invocations are a 2x2 block). Modes (kMode, a specialization constant: one
// pipeline each, as rh_build.comp's):
//  PENUMBRA_RH_RAYS_COUNT: each tile's ray count, padded to a multiple of 4,
//    at the tile's Morton index (rh_scan.comp turns the counts into offsets);
//    the receivers' depth grid (rh.glsli);
//    with push.measure, the tile's incoherence for the per-frame choice of
//    order (below);
//  PENUMBRA_RH_RAYS_KEYS: the rays per direction key and per face
//    (dispatched only when the rays are sorted; rh_scan.comp turns the
//    counts into each key's first slot, rh_build.comp's faces mode moves
//    each face to the start of a whole subtree, padding the one before);
//  PENUMBRA_RH_RAYS_LIST: the rays listed: sorted, each at its key's next
//    slot (the keys in order; a key's rays from one subgroup together, in
//    pixel order, the subgroups' in any order), moved by its face's shift; else at their
//    tile's offset, in Morton order, the tile padded with RH_NO_RAY, so the
//    hierarchy's leaves are 2x2 blocks and the levels above quads of tiles
//    (the paper's screen-space hierarchy).
// The key (section 3.5): a point light's ray falls on the face of its
// direction's major axis, a spot or directional light's in its shadow-map
// projection; the face is split into 2^order x 2^order cells, and the key is
// the face and the cell's index on a Hilbert curve. The ray itself is never
// stored: rh_build and rh_traverse rebuild it from the G-buffer and the light.
//
// Incoherence (RenderSettings::rhSort auto): the tile's rays' spread (the
// largest distance of a ray's coordinate, its unit direction from the light
// or its origin across a directional light, from the tile's first ray's)
// against the spread of one pixel (the smallest, over the tile, of a ray's
// larger distance to its horizontal and vertical neighbours). On one smooth
// surface the tile spans about 10 pixels' spread (7 sqrt 2), so
// (spread / (10 pixel)))^2, the tile's cone area over what its rays would
// need in direction order, is about 1; a tile across a depth discontinuity
// mixes far-apart directions and scores orders of magnitude more.
// rh_build.comp's decide mode weighs the tiles by their rays.

#include "config.h"
#include "shadow_common.glsli"
#include "shadow_ray.glsli"
#include "rh.glsli"

layout(local_size_x = 64) in;

// C++: runtime/src/passes/rh.h (RhRaysBinding).
#include "surface.glsli"
layout(set = 0, binding = 0, rgba32ui) uniform readonly uimage2D gSurface; // binding 1, the G-buffer's albedo, is not read
layout(set = 0, binding = 2, std140) uniform Frame { FrameData frame; };
layout(set = 0, binding = 3, std430) writeonly buffer Rays { uint rayPixels[]; };
#define RH_STATE_BINDING 4
RH_STATE_DECLARE();
layout(set = 0, binding = 5, std430) buffer TileOffsets { uint tileOffsets[]; }; // per tile at its Morton index: count, then offset
layout(set = 0, binding = 6, std430) buffer KeySlots { uint keySlots[]; };       // per key: rays, then (scan) next slot
layout(set = 0, binding = 7, std430) buffer DepthGrid { uint depthGrid[]; };     // the receivers' depth grid (rh.glsli)

layout(constant_id = 0) const uint kMode = PENUMBRA_RH_RAYS_COUNT; // PENUMBRA_RH_RAYS_*

layout(push_constant) uniform RhRaysPush {
    uint lightIndex;
    uint mode;      // PENUMBRA_RH_RAYS_*: kMode's value
    float originOffset;
    uint order;     // keys: 2^order x 2^order cells per face
    uint measure;   // PENUMBRA_RH_RAYS_COUNT: 1 measures the incoherence
    uint gridFaces; // PENUMBRA_RH_RAYS_COUNT: the depth grid's faces (0: none, spot lights)
    uint gridOrder; // ... and its order (2^order cells a side)
    uint pad0;
} push;

shared uint subgroupTotals[64];
shared vec4 tileCoords[64]; // incoherence: xyz the ray's coordinate, w 1 when listed
shared uint firstListed, pixelSpread, tileSpread;

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
    ivec2 size = imageSize(gSurface);
    uint type = uint(frame.lights[push.lightIndex].positionType.w);
    vec3 light = frame.lights[push.lightIndex].positionType.xyz;
    vec3 toLight = -normalize(frame.lights[push.lightIndex].directionRange.xyz);
    bool listed = false;
    uint index = 0u;
    vec3 p = vec3(0.0), origin = vec3(0.0);
    if (all(lessThan(pixel, size))) {
        index = uint(pixel.y * size.x + pixel.x);
        const uvec4 surface = imageLoad(gSurface, pixel);
        if (surfaceCovered(surface)) {
            p = surfacePosition(surface);
            vec3 n = surfaceNormal(surface);
            ShadowRay ray;
            listed = type == PENUMBRA_LIGHT_DIRECTIONAL ? rhParallelRay(toLight, p, n, push.originOffset, ray)
                                                        : rhShadowRay(light, p, n, push.originOffset, ray);
            origin = ray.origin;
            if (listed && type == PENUMBRA_LIGHT_SPOT) {
                // Inside the spot's frustum (its map's), as the other methods light it.
                vec4 clip = frame.lights[push.lightIndex].viewProj[0] * vec4(origin, 1.0);
                listed = clip.w > 0.0 && all(lessThanEqual(abs(clip.xy), vec2(clip.w)));
            }
        }
    }
    bool sorted = state.sorted != 0u; // rh_build.comp's decide mode
    // The key: the face and the Hilbert index of the ray's cell on it.
    uint key = 0u;
    PENUMBRA_SKIP_UNLESS(kMode == PENUMBRA_RH_RAYS_KEYS || (kMode == PENUMBRA_RH_RAYS_LIST && sorted))
    {
        uint face = 0u;
        vec2 ndc;
        if (type == PENUMBRA_LIGHT_POINT) {
            vec3 d = p - light;
            face = cubeFace(d);
            uint axis = face % 3u;
            ndc = (axis == 0u ? d.yz : axis == 1u ? d.zx : d.xy) / max(abs(d[axis]), 1e-30);
        } else {
            vec4 clip = frame.lights[push.lightIndex].viewProj[0] * vec4(p, 1.0);
            ndc = clip.xy / max(clip.w, 1e-30);
        }
        float cells = float(1u << push.order);
        uvec2 cell = uvec2(clamp((ndc * 0.5 + 0.5) * cells, vec2(0.0), vec2(cells - 1.0)));
        key = (face << (2u * push.order)) + hilbertIndex(cell, push.order);
    }
    uint face = key >> (2u * push.order);
    if (kMode == PENUMBRA_RH_RAYS_KEYS) {
        if (listed) {
            atomicAdd(keySlots[key], 1u);
            atomicAdd(state.faceCount[face >> 2u][face & 3u], 1u);
        }
        return;
    }
    if (kMode == PENUMBRA_RH_RAYS_LIST && sorted) {
        // The subgroup's rays of one key take consecutive slots, in pixel order (one atomic per key):
        // a key's cell holds several rays where they are dense, and neighbouring pixels among them
        // then stay together, so the leaves over them are tight.
        uint mine = listed ? key : 0xFFFFFFFFu;
        uvec4 same = uvec4(0u);
        for (uint lane = 0u; lane < gl_SubgroupSize; ++lane) {
            uvec4 ballot = subgroupBallot(subgroupShuffle(mine, lane) == mine);
            same = lane == gl_SubgroupInvocationID ? ballot : same;
        }
        uint leader = subgroupBallotFindLSB(same);
        uint rank = subgroupBallotExclusiveBitCount(same);
        uint base = 0u;
        if (listed && leader == gl_SubgroupInvocationID)
            base = atomicAdd(keySlots[key], subgroupBallotBitCount(same));
        base = subgroupShuffle(base, leader);
        if (listed)
            rayPixels[base + rank + state.faceShift[face >> 2u][face & 3u]] = index;
        uint count = subgroupAdd(listed ? 1u : 0u);
        if (subgroupElect() && count != 0u)
            atomicAdd(state.raysListed, count); // the list's length: rh_build.comp's faces mode
        return;
    }
    // Prefix in the subgroup (a ballot), then over the subgroups (in order).
    uvec4 ballot = subgroupBallot(listed);
    uint before = subgroupBallotExclusiveBitCount(ballot);
    if (subgroupElect())
        subgroupTotals[gl_SubgroupID] = subgroupBallotBitCount(ballot);
    if (local == 0u) {
        firstListed = 64u;
        pixelSpread = floatBitsToUint(uintBitsToFloat(0x7F800000u));
        tileSpread = 0u;
    }
    barrier();
    uint offset = 0u, total = 0u;
    for (uint s = 0u; s < gl_NumSubgroups; ++s) {
        uint count = subgroupTotals[s];
        offset += s < gl_SubgroupID ? count : 0u;
        total += count;
    }
    uint padded = (total + 3u) & ~3u;
    uint tile = mortonIndex(gl_WorkGroupID.xy);
    if (kMode == PENUMBRA_RH_RAYS_COUNT) {
        // The receivers' depth grid: the deepest ray per cell (rh.glsli).
        PENUMBRA_SKIP_UNLESS(listed && push.gridFaces != 0u)
        {
            uint face = 0u;
            vec2 coordinates;
            float depth;
            if (type == PENUMBRA_LIGHT_POINT) {
                vec3 d = p - light;
                face = cubeFace(d);
                coordinates = cubeFaceCoordinates(d, face);
                depth = length(d);
            } else {
                coordinates = (frame.lights[push.lightIndex].viewProj[0] * vec4(origin, 1.0)).xy;
                depth = -dot(origin, toLight);
            }
            uint side = 1u << push.gridOrder;
            uvec2 cell = uvec2(clamp((coordinates * 0.5 + 0.5) * float(side), vec2(0.0), vec2(float(side) - 1.0)));
            atomicMax(depthGrid[(face * side + cell.y) * side + cell.x], orderedDepth(depth));
        }
        if (local == 0u) {
            tileOffsets[tile] = padded;
            if (total != 0u)
                atomicAdd(state.countedRays, total);
        }
        PENUMBRA_SKIP_UNLESS(push.measure != 0u)
        {
            vec3 coordinate = type == PENUMBRA_LIGHT_DIRECTIONAL ? vec3(toParallel(parallelFrame(toLight), origin).xy, 0.0)
                                                                 : normalize(p - light);
            tileCoords[local] = vec4(coordinate, listed ? 1.0 : 0.0);
            if (listed)
                atomicMin(firstListed, local);
            barrier();
            const float none = uintBitsToFloat(0x7F800000u);
            vec4 across = tileCoords[local ^ 1u], down = tileCoords[local ^ 2u], first = tileCoords[min(firstListed, 63u)];
            float mine = listed && across.w != 0.0 && down.w != 0.0
                             ? max(distance(coordinate, across.xyz), distance(coordinate, down.xyz)) : none;
            float spread = listed ? distance(coordinate, first.xyz) : 0.0;
            mine = subgroupMin(mine);
            spread = subgroupMax(spread);
            if (subgroupElect()) {
                atomicMin(pixelSpread, floatBitsToUint(mine));
                atomicMax(tileSpread, floatBitsToUint(spread));
            }
            barrier();
            if (local == 0u && total >= 16u && pixelSpread < 0x7F800000u) {
                float ratio = uintBitsToFloat(tileSpread) / (10.0 * max(uintBitsToFloat(pixelSpread), 1e-30));
                float incoherence = min(ratio * ratio, float(PENUMBRA_RH_MAX_INCOHERENCE));
                atomicAdd(state.incoherence, uint64_t(incoherence * 256.0) * uint64_t(total));
                atomicAdd(state.coherenceRays, uint64_t(total));
            }
        }
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
