// Alias-free shadow maps, hard shadows: the casters the compute path
// (afsm_bin.comp.glsl) does not take, tested without the rasterizer (Sintorn
// et al. 2008, section 3.2: "conservative rasterization" of each caster over
// the sample grid, here row by row in compute). afsm_bin lists them (their
// world-space vertices, AfsmWideCaster); here each lane sets up one caster
// (its rectangle and edges: one caster per invocation makes eight times fewer
// workgroups than one per subgroup, and setting up eight casters costs a
// SIMD register what one does), then the subgroup takes its casters one after
// another and its lanes test the samples of each row of its cells together
// (interior and plant at 640^2: afsm_rows 20-25% less than one per subgroup). The
// cells of a grid row are consecutive in the sample lists (the prefix sum
// runs over the cells row by row), so the samples of the cells a caster can
// cover on a row are one range of slots: the lanes walk that range eight (a
// subgroup) at a time. On lavapipe the raster path pays a triangle setup per
// caster and a fragment invocation per cell with about half of its SIMD lanes
// live, and each fragment loops over its own cell's samples; here every lane
// of the subgroup tests a sample on every step but the last of a row.
//
// Which cells a row takes: those whose square can meet the caster's
// projection grown by the light's margin (afsmCellMayMeetTriangle's test,
// solved for the row's cell centres along x), within the caster's grown
// rectangle (afsmHardRect). Every sample a caster can block lies in such a
// cell, so the samples tested include every sample the caster shadows; each
// is tested exactly (afsmSlotHits, the tracer's watertight test; a
// directional light's sheared slots: afsmParallelHits). A hit sets the
// pixel's flag alone (afsm_casters.glsli: afsmShadowSlot, AFSM_UNCOUNTED):
// slotShadowed is the raster path's, and leaving it unset keeps the raster
// path's cell counts exact (afsm_rows on the interior and the plant at 640^2
// about 12% less than setting both).
//
// Bounded: the list holds at most push.capacity casters. The casters a
// subgroup reaches past its loop budget (lavapipe's loop limit,
// PENUMBRA_AFSM_WIDE_ITERATIONS, for its casters together) go to a second
// pass, one caster per subgroup, stored from the list's end down. A caster
// past the capacity, one that does not fit there, or one that alone takes
// more than the budget marks its cluster in the overflow bits, and the
// raster path then draws that cluster's casters (afsm_casters.geom.glsl; the
// frame reads the marks back): a caster tested by two paths changes nothing.
//
// kPhase (PENUMBRA_AFSM_WIDE_*): the first pass's indirect dispatch from the
// list's length; the first pass; the second pass's dispatch; the second pass
// (the casters the first reached past a subgroup's loop budget, one caster
// per subgroup with a budget of its own); and, apart from those, the pixels
// shadowed so far (AfsmPass's two-pass choice, recordCasters).
#version 460
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_shuffle : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_shader_subgroup_arithmetic : require

#include "config.h"
#include "shadow_common.glsli"
#include "shadow_ray.glsli"
#include "penumbra/light_sampling.h"
#define AFSM_SLOTS 1
#define AFSM_UNCOUNTED 1 // afsm_casters.glsli: afsmShadowSlot
#include "afsm.glsli"

layout(local_size_x = PENUMBRA_AFSM_WIDE_GROUP) in;
layout(constant_id = 0) const uint kPhase = PENUMBRA_AFSM_WIDE_TEST;
// 1: a directional light's sheared slots (afsm.glsli: AfsmParallel): each caster's vertices sheared once, one
// texel a sample (interior and plant at 640^2: afsm_rows about 30% less).
layout(constant_id = 1) const uint kParallel = 0u;
#define AFSM_PARALLEL (kParallel != 0u)
#define AFSM_ORTHOGRAPHIC AFSM_PARALLEL // afsm_casters.glsli
// 1: the second of two passes, rows narrowed to the cells still holding a sample beyond the caster (afsm_bin.comp's kTrimRows).
layout(constant_id = 2) const uint kTrimRows = 0u;

// C++: runtime/src/passes/afsm.h (AfsmBinBinding: the compute path's set).
layout(set = 0, binding = 0, std140) uniform Frame { FrameData frame; };
layout(set = 0, binding = 1) uniform usamplerBuffer cellFirstTexels;
layout(set = 0, binding = 2) uniform usamplerBuffer cellCountTexels;
layout(set = 0, binding = 3, std430) buffer Shadowed { uint shadowed[]; };
layout(set = 0, binding = 4, std430) readonly buffer Far { AFSM_FAR_FIELDS; }; // afsm_samples.comp.glsl
layout(set = 0, binding = 5) uniform usamplerBuffer cellDepthTexels;
layout(set = 0, binding = 6, std430) buffer SlotShadowed { uint slotShadowed[]; };
layout(set = 0, binding = 7, std430) buffer CellAlive { uint cellAlive[]; };
layout(set = 0, binding = 9, std430) readonly buffer ClosedBits { uint closedBits[]; };
layout(set = 0, binding = 10) uniform usamplerBuffer slotTexels;

#include "afsm_casters.glsli"
#include "afsm_wide.glsli"

layout(push_constant) uniform AfsmWidePush {
    mat4 viewProj;   // the layer's grid projection
    uint64_t list;   // AfsmWideList
    uint gridSize;
    uint lightIndex;
    uint capacity;   // casters the list holds
    uint casters;    // byte offset of the casters in the list (after the overflow bits)
    uint iterations; // most loop iterations of a subgroup (PENUMBRA_AFSM_WIDE_ITERATIONS; lavapipe: 65535 in all)
    uint pad;
} push;

// A caster's setup: its cells' rectangle [first, last] and its rows' edges (afsm_casters.glsli: afsmRowEdges).
struct WideSetup {
    ivec4 cells; // first.xy, last.xy
    AfsmRowEdges edges;
    float nearest; // its nearest depth (afsmTrimRow)
};

WideSetup wideSetup(vec3 v0, vec3 v1, vec3 v2, float margin)
{
    vec2 v[3];
    bool behind;
    AfsmDepthBound depth;
    const AfsmRect r = afsmHardRect(push.viewProj, v0, v1, v2, push.gridSize, margin, v, behind, depth);
    ivec2 first, last;
    afsmRectCellRange(r, push.gridSize, first, last);
    return WideSetup(ivec4(first, r.empty ? first - 1 : last), afsmRowEdges(v, behind, margin), depth.nearest);
}

// Tests one caster (the same values in every lane) against the samples of its rows; counts the loop
// iterations and stops once they pass push.iterations (over).
void testCaster(vec3 v0, vec3 v1, vec3 v2, ivec4 cells, AfsmRowEdges edges, float nearest, inout uint iterations, inout bool over)
{
    const uint lane = gl_SubgroupInvocationID, width = gl_SubgroupSize;
    const ivec2 first = cells.xy, last = cells.zw;
    const AfsmParallel f = afsmUnpackParallel(AFSM_PARALLEL ? parallel : uvec4(0u));
    const vec3 w0 = afsmShearPoint(f, v0), w1 = afsmShearPoint(f, v1), w2 = afsmShearPoint(f, v2);
    // Eight rows (a subgroup's width) at a time: each lane finds its row's range of the list, then the
    // lanes test the ranges that hold samples one after another, together (on lavapipe a loop's entry
    // and exit cost about as much as a few of its iterations: a row per lane finding its range makes
    // eight rows one loop, and skipping the empty ones saved another 10-20% on the suite scenes).
    for (int rows = first.y; rows <= last.y && !over; rows += int(width)) {
        const int y = rows + int(lane);
        int lo = first.x, hi = last.x;
        afsmRowCells(edges, y, lo, hi);
        const uint row = uint(min(y, last.y)) * push.gridSize;
        if (kTrimRows != 0u && y <= last.y)
            afsmTrimRow(row, nearest, lo, hi);
        const uvec2 slots = afsmRowSlots(row, lo, y <= last.y ? hi : lo - 1);
        const uint rowBegin = slots.x, rowEnd = slots.y;
        iterations += 5u; // the rows' loop and their edges
        // The rows holding samples, one after another (a ballot's words: one on lavapipe and NVIDIA).
        const uvec4 holding = subgroupBallot(rowEnd > rowBegin);
        for (uint word = 0u; word < (width + 31u) / 32u && !over; ++word)
        for (uint pending = holding[word]; pending != 0u && !over; pending &= pending - 1u) {
            const uint j = 32u * word + uint(findLSB(pending));
            const uint begin = subgroupShuffle(rowBegin, j), end = subgroupShuffle(rowEnd, j);
            iterations += 2u + (end - begin + width - 1u) / width;
            over = iterations > push.iterations;
            const uint from = over ? end : begin + lane;
            if (AFSM_PARALLEL)
                afsmTestSlotsParallel(0u, from, end, width, w0, w1, w2, f.shear.z);
            else
                afsmTestSlotsHard(0u, from, end, width, v0, v1, v2);
        }
    }
}

// The indirect dispatch of `casters` casters, `perGroup` a workgroup; 2-D above 65535 workgroups.
void writeDispatch(uint casters, uint perGroup, out uint dispatch[3])
{
    const uint groups = (casters + perGroup - 1u) / perGroup;
    const uint x = min(groups, 65535u);
    dispatch = uint[3](x, x == 0u ? 1u : (groups + x - 1u) / x, 1u);
}

void main()
{
    AfsmWideList list = AfsmWideList(push.list);
    AfsmWideCasters casters = AfsmWideCasters(push.list + push.casters);
    const uint listed = min(list.count, push.capacity);
    const uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    const float margin = afsmCellMargin(frame.lights[push.lightIndex]);
    uint iterations = 0u;
    bool over = false;
    if (kPhase == PENUMBRA_AFSM_WIDE_DISPATCH) { // the first pass's dispatch: one caster per invocation
        if (gl_GlobalInvocationID.x == 0u)
            writeDispatch(listed, PENUMBRA_AFSM_WIDE_GROUP, list.dispatch);
    } else if (kPhase == PENUMBRA_AFSM_WIDE_ALONE_DISPATCH) { // the second's: one caster per subgroup
        if (gl_GlobalInvocationID.x == 0u)
            writeDispatch(min(list.alone, push.capacity - listed), gl_NumSubgroups, list.aloneDispatch);
    } else if (kPhase == PENUMBRA_AFSM_WIDE_TEST) {
        // Each lane sets up one caster (its rectangle and edges); then the subgroup tests them one after
        // another. Those it reaches past its loop budget go to the second pass, stored from the list's end
        // down (those that do not fit there: the raster path's).
        const uint lane = gl_SubgroupInvocationID, width = gl_SubgroupSize;
        const uint firstCaster = group * PENUMBRA_AFSM_WIDE_GROUP + gl_SubgroupID * width;
        const AfsmWideCaster caster = casters.casters[min(firstCaster + lane, max(listed, 1u) - 1u)];
        const WideSetup setup = wideSetup(caster.v0Cluster.xyz, caster.v1.xyz, caster.v2.xyz, margin);
        for (uint k = 0u; k < width && firstCaster + k < listed; ++k) {
            // Caster k of the subgroup's, in every lane.
            const vec3 v0 = subgroupShuffle(caster.v0Cluster.xyz, k), v1 = subgroupShuffle(caster.v1.xyz, k), v2 = subgroupShuffle(caster.v2.xyz, k);
            const uint cluster = subgroupShuffle(floatBitsToUint(caster.v0Cluster.w), k);
            ++iterations;
            const AfsmRowEdges edges = AfsmRowEdges(subgroupShuffle(setup.edges.normals01, k), subgroupShuffle(setup.edges.normal2Edges, k),
                                                    subgroupShuffle(setup.edges.reach, k));
            const float nearest = kTrimRows != 0u ? subgroupShuffle(setup.nearest, k) : 0.0;
            testCaster(v0, v1, v2, subgroupShuffle(setup.cells, k), edges, nearest, iterations, over);
            if (over && subgroupElect()) {
                const uint alone = atomicAdd(list.alone, 1u);
                if (alone < push.capacity - listed)
                    casters.casters[push.capacity - 1u - alone] = AfsmWideCaster(vec4(v0, uintBitsToFloat(cluster)), vec4(v1, 0.0), vec4(v2, 0.0));
                else
                    afsmWideMark(list, cluster);
            }
        }
    } else if (kPhase == PENUMBRA_AFSM_WIDE_COUNT_SHADOWED) {
        // Four pixels' flags an invocation, one atomic a subgroup (AfsmPass reads the sum back).
        const uint first = 4u * gl_GlobalInvocationID.x, pixels = uint(shadowed.length());
        uint count = 0u;
        for (uint k = 0u; k < 4u; ++k)
            count += first + k < pixels && shadowed[first + k] != 0u ? 1u : 0u;
        count = subgroupAdd(count);
        if (subgroupElect() && count != 0u)
            atomicAdd(list.shadowedPixels, count);
    } else { // PENUMBRA_AFSM_WIDE_TEST_ALONE: one caster per subgroup, its own loop budget; past it, the raster path's
        const uint index = group * gl_NumSubgroups + gl_SubgroupID;
        if (index < min(list.alone, push.capacity - listed)) {
            const AfsmWideCaster caster = casters.casters[push.capacity - 1u - index];
            const WideSetup setup = wideSetup(caster.v0Cluster.xyz, caster.v1.xyz, caster.v2.xyz, margin);
            testCaster(caster.v0Cluster.xyz, caster.v1.xyz, caster.v2.xyz, setup.cells, setup.edges, setup.nearest, iterations, over);
            if (over && subgroupElect())
                afsmWideMark(list, floatBitsToUint(caster.v0Cluster.w));
        }
    }
}
