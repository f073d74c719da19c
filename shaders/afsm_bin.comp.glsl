// Alias-free shadow maps, the compute path of the casters (Sintorn et al.
// 2008, section 3.2; the issue's "bin each triangle to the texels its
// light-space footprint touches"): the small casters of one layer's culled
// view, binned to their grid cells and tested there without the rasterizer.
// On lavapipe every rasterized caster costs a triangle setup and fragment
// shader invocations for its whole bounding rectangle of 2x2-pixel quads,
// however few cells it covers; most casters of a large model cover a few
// cells. So each caster whose grown rectangle (afsm_casters.glsli) spans at
// most PENUMBRA_AFSM_COMPUTE_CELLS cells and whose cells hold little work is
// tested here with the fragment shader's per-sample tests: hard casters row
// by row (afsmTestSlotsHard, afsmTestSlotsParallel), soft ones cell by cell
// (afsmTestCellSoft); the row pass (afsm_wide.comp, hard shadows) and the
// raster path (afsm_casters.geom, afsm_soft.geom) take the others. Leaves are decoded as the thin-triangle
// pass decodes them (thin_triangles.comp.glsl: one invocation per leaf, the
// tracer's strip walk), those of clusters outside the view skipped.
// Under a geometry budget (kGeometryBudget, geometry_pages.h) the frame
// script dispatches it once per range of the view's clusters whose pages fit
// the pool, that range resident: the nodes are read through the node table
// from their records in the pool, and only the range's clusters
// ([rangeBegin, rangeEnd) of the view's) are binned, so every caster
// cluster is binned once over the ranges (its tests OR into the samples'
// flags and masks, in any order). In core, a directional light's hard
// shadows may take two passes (AfsmPass::recordCasters' two-pass choice):
// the leaves nearest the light first, then, after the cells' depths were
// counted again over the samples still lit (recordRefresh), the others with
// their rows narrowed to the cells still holding such a sample (afsmTrimRow).
// Built twice: hard shadows, and soft shadows with PENUMBRA_AFSM_SOFT
// (afsm_bin.comp.soft).
#version 460
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_8bit_storage : require
#extension GL_EXT_shader_16bit_storage : require
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_ballot : require

#include "config.h"
#include "bvh_traversal.glsli"
#include "shadow_common.glsli"
#include "penumbra/light_sampling.h"
#ifdef PENUMBRA_AFSM_SOFT
#define AFSM_SOFT 1
#endif
#define AFSM_SLOTS 1
#ifndef PENUMBRA_AFSM_SOFT
#define AFSM_UNCOUNTED 1 // afsm_casters.glsli: afsmShadowSlot
#endif
#include "afsm.glsli"

layout(local_size_x = PENUMBRA_AFSM_BIN_GROUP) in;

// 1: paged geometry (geometry_pages.h): nodes through the node table, clusters of
// [rangeBegin, rangeEnd) only; 0 (no budget): compiled out.
layout(constant_id = 0) const uint kGeometryBudget = 0u;
// 1: hard shadows of a directional light, sheared slots (afsm.glsli: AfsmParallel); afsm_casters.glsli's AFSM_PARALLEL.
layout(constant_id = 1) const uint kParallel = 0u;
#define AFSM_PARALLEL (kParallel != 0u)
#define AFSM_ORTHOGRAPHIC AFSM_PARALLEL // afsm_casters.glsli
// 1: the model is read through texel buffers (GpuGeometry::texelsComplete, in core): on lavapipe a texel fetch
// is a gather, a strip byte's or a vertex's load by device address a loop over the lanes (the 2 M scan at
// 1024^2: afsm_bin 244-263 -> 209 CPU ms, the 1 M interior 141-157 -> 127-129); 0: by device address.
layout(constant_id = 2) const uint kTexelAccess = 0u;
// 1: the vertices' texel view is R16_UINT, three texels a vertex (GpuGeometry::vertexTexelsSplit).
layout(constant_id = 3) const uint kSplitVertexTexels = 0u;
// 1: hard shadows, the second of two passes: each row narrowed to its cells holding a sample beyond the caster
// (afsmTrimRow). A constant, not a flag: the first pass's and the single pass's loops stay as they were (a
// branch not taken there still cost the plant's afsm_bin and afsm_rows 5-8% at 1024^2).
layout(constant_id = 4) const uint kTrimRows = 0u;

// C++: runtime/src/passes/afsm.h (AfsmBinBinding).
layout(set = 0, binding = 0, std140) uniform Frame { FrameData frame; };
layout(set = 0, binding = 1) uniform usamplerBuffer cellFirstTexels;  // R32UI: first slot per cell (afsm_casters.glsli: afsmCellFirst)
layout(set = 0, binding = 2) uniform usamplerBuffer cellCountTexels;  // R32UI: samples per cell (afsmCellCount)
layout(set = 0, binding = 3, std430) buffer Shadowed { uint shadowed[]; };
layout(set = 0, binding = 4, std430) readonly buffer Far { AFSM_FAR_FIELDS; }; // afsm_samples.comp.glsl
layout(set = 0, binding = 5) uniform usamplerBuffer cellDepthTexels;  // R32UI: per cell, its farthest sample depth (afsmCellDepth)
layout(set = 0, binding = 6, std430) buffer SlotShadowed { uint slotShadowed[]; };
layout(set = 0, binding = 7, std430) buffer CellAlive { uint cellAlive[]; };
// Soft shadows: where the masks and the table are (AfsmPass: AfsmParams).
layout(set = 0, binding = 8, std430) readonly buffer Params {
    uint64_t softMasks, softTable;
    uint softSamples, softTableSize;
    uint64_t wideList;   // hard shadows: AfsmWideList (afsm_wide.glsli) of the casters left to afsm_wide.comp; 0: none (the raster path's)
    uint wideCasters;    // byte offset of its casters
    uint wideCapacity;   // casters it holds
};
layout(set = 0, binding = 9, std430) readonly buffer ClosedBits { uint closedBits[]; }; // bit per cluster: kClusterClosed
layout(set = 0, binding = 10) uniform usamplerBuffer slotTexels;                      // RGBA32UI over the slots (afsm_casters.glsli: afsmRaySlotAt)
// The model through uniform texel buffers (GpuGeometry::texels; bvh_texels.glsli), read when kTexelAccess.
layout(set = 0, binding = 11) uniform usamplerBuffer modelNodes;
layout(set = 0, binding = 12) uniform usamplerBuffer modelClusters;
layout(set = 0, binding = 13) uniform usamplerBuffer modelVertices;
layout(set = 0, binding = 14) uniform usamplerBuffer modelStrips;

#include "afsm_casters.glsli"
#include "afsm_wide.glsli"
#include "bvh_texels.glsli"

layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer ClusterMask { uint bits[]; };
// kGeometryBudget: per node, its record's first 16-byte texel in the pool, or cluster | PENUMBRA_NODE_ABSENT
// (bvh_texels.glsli; GpuGeometry::nodeTable).
layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer NodeTable { uint words[]; };
#define PENUMBRA_NODE_ABSENT 0x80000000u

layout(push_constant) uniform AfsmBinPush {
    mat4 viewProj;        // the layer's grid projection
    uint64_t modelTable;  // bvh_traversal.glsli
    uint64_t clusterMask; // bit per cluster: in the layer's culled view
    uint nodeCount;
    uint lightIndex;
    uint gridSize;
    float originOffset;
    float computeCells;   // PENUMBRA_AFSM_COMPUTE_CELLS
    uint rangeBegin;      // kGeometryBudget: the clusters [rangeBegin, rangeEnd) binned by this dispatch; in core: the
    uint rangeEnd;        // leaves whose box's nearest depth lies in [rangeBegin, rangeEnd) (float bits; the two passes)
    uint closedBackFaces; // closed clusters cast only light-back-facing triangles (afsm_casters.glsli)
    uint64_t nodeTable;   // kGeometryBudget: NodeTable's device address
    uint64_t nodeRecords; // kGeometryBudget: the pool's (node records, 16-byte texels: NodeArray)
} push;

// No early return: a caster that takes no cells gets an empty cell range, a cell with nothing to
// test an empty sample range, and the budget ends the loops by their condition (lavapipe runs the
// code after an early return under an execution mask).
// closed: the caster's cluster is closed and casts its light-back-facing
// triangles only (afsmCastsIn; read once per node, not per caster). A
// directional light's hard casters are sheared by f (the layer's, read once).
void binCaster(uint cluster, bool closed, LightData light, AfsmParallel f, vec3 v0, vec3 v1, vec3 v2)
{
    const bool casts = afsmCastsIn(light, closed, v0, v1, v2);
#ifdef PENUMBRA_AFSM_SOFT
    float nearest;
    AfsmRect r = afsmSoftRect(push.viewProj, light, uintBitsToFloat(farBits), v0, v1, v2, push.gridSize, nearest);
    uint perSample = 1u + afsmQuads(softSamples);
    AfsmSoftTable table = AfsmSoftTable(softMasks, softTable, softSamples, softTableSize);
#else
    vec2 projected[3];
    bool behind;
    AfsmDepthBound depth;
    const float margin = afsmCellMargin(light);
    AfsmRect r = afsmHardRect(push.viewProj, v0, v1, v2, push.gridSize, margin, projected, behind, depth);
    float nearest = depth.nearest;
    // A directional light's sheared slots: the caster's vertices sheared once, not once per cell.
    const vec3 w0 = afsmShearPoint(f, v0), w1 = afsmShearPoint(f, v1), w2 = afsmShearPoint(f, v2);
#endif
    const bool take = casts && !r.empty && afsmRectCells(r, push.gridSize) <= push.computeCells;
    ivec2 first, last;
    afsmRectCellRange(r, push.gridSize, first, last);
    // No sample of its cells lies beyond the caster (or none is there): nothing to test, in either path.
    const bool noneBeyond = casts && !r.empty && afsmBlocksBehind(first, last, push.gridSize, nearest);
    last = take && !noneBeyond ? last : first - 1;
    uint work = 0u;
    bool over = false;
#ifdef PENUMBRA_AFSM_SOFT
    // The cells one by one, counting the work as afsmComputeWork does (the
    // raster path's mirror of this choice); past the budget afsm_wide.comp
    // (else the raster path) takes the caster (the cells tested so far are
    // tested twice).
    for (int y = first.y; y <= last.y && !over; ++y)
        for (int x = first.x; x <= last.x && !over; ++x) {
            uint cell = uint(y) * push.gridSize + uint(x);
            uint count = afsmCellCount(cell);
            bool beyond = afsmCellBehind(cell, nearest);
            work += 1u + (beyond ? 0u : perSample * count);
            over = work > PENUMBRA_AFSM_COMPUTE_BUDGET;
            const bool test = !over && count != 0u && !beyond && cellAlive[cell] != 0u;
            afsmTestCellSoft(cell, 0u, test ? count : 0u, light, table, v0, v1, v2); // at most PENUMBRA_AFSM_COMPUTE_BUDGET iterations
        }
#else
    // Row by row, as afsm_wide.comp tests its casters: the cells of a grid
    // row are consecutive in the sample list, so the samples of the row's
    // cells the caster can meet (afsmRowCells) are one range of slots
    // (afsmRowSlots: three texel fetches a row), and each lane walks its
    // caster's range. The work counts each row's cells and the samples of
    // its range, never more than afsmComputeWork counts for the raster
    // path's mirror of this choice (every cell and sample of the rectangle:
    // nearest -1); past the budget afsm_wide.comp (else the raster path)
    // takes the caster (the rows tested so far are tested twice). On the 2 M scan at 1024^2 the cell-by-cell
    // loop (a cell's count, depth and edge tests, then its samples) was about
    // half of afsm_bin; by rows afsm_bin went 300 -> 261 CPU ms.
    const AfsmRowEdges edges = afsmRowEdges(projected, behind, margin);
    const uint columns = uint(last.x - first.x + 1);
    for (int y = first.y; y <= last.y && !over; ++y) {
        const uint row = uint(y) * push.gridSize;
        int lo = first.x, hi = last.x;
        afsmRowCells(edges, y, lo, hi);
        if (kTrimRows != 0u)
            afsmTrimRow(row, nearest, lo, hi);
        const uvec2 slots = afsmRowSlots(row, lo, hi);
        work += columns + (slots.y - slots.x);
        over = work > PENUMBRA_AFSM_COMPUTE_BUDGET;
        const uint begin = slots.x, end = over ? slots.x : slots.y;
        if (AFSM_PARALLEL)
            afsmTestSlotsParallel(0u, begin, end, 1u, w0, w1, w2, f.shear.z);
        else
            afsmTestSlotsHard(0u, begin, end, 1u, v0, v1, v2);
    }
#endif
#ifndef PENUMBRA_AFSM_SOFT
    // The casters the loop above did not test to the end: afsm_wide.comp's.
    if (wideList != 0ul && casts && !r.empty && !noneBeyond && (!take || over))
        afsmWideAppend(wideList, wideCasters, wideCapacity, cluster, v0, v1, v2);
#endif
}

// Hard shadows: a leaf's box on the grid, grown as afsmHardRect grows a
// caster's (so that it holds its triangles' rectangles), and the depth of
// its nearest corner, no farther than their nearest vertices; false when the
// box reaches behind a perspective grid's eye. A directional light's grid is
// orthographic: each clip coordinate is affine in the point, so its range
// over the box is the centre's value plus or minus the half extents'
// absolute weights (three dot products instead of eight corners).
bool afsmLeafRect(WideNode node, vec3 steps, uint slot, out AfsmRect r, out float nearest)
{
    vec3 boxMin, boxMax;
    decodeChildBox(node, steps, slot, boxMin, boxMax);
    bool front = true; // every corner in front of the eye
    if (AFSM_ORTHOGRAPHIC) {
        const vec4 mid = push.viewProj * vec4(0.5 * (boxMin + boxMax), 1.0);
        const mat3 m = mat3(push.viewProj);
        const vec3 reach = mat3(abs(m[0]), abs(m[1]), abs(m[2])) * (0.5 * (boxMax - boxMin));
        r = AfsmRect(mid.xy - reach.xy, mid.xy + reach.xy, false, false);
        nearest = mid.z - reach.z;
    } else {
        r = AfsmRect(vec2(3.0e38), vec2(-3.0e38), false, false);
        nearest = 1.0;
        for (int i = 0; i < 8; ++i) {
            const vec3 corner = vec3((i & 1) != 0 ? boxMax.x : boxMin.x, (i & 2) != 0 ? boxMax.y : boxMin.y, (i & 4) != 0 ? boxMax.z : boxMin.z);
            const vec4 clip = push.viewProj * vec4(corner, 1.0);
            front = front && clip.w > 1e-20;
            const float w = max(clip.w, 1e-20);
            nearest = min(nearest, clip.z / w);
            r.lo = min(r.lo, clip.xy / w);
            r.hi = max(r.hi, clip.xy / w);
        }
    }
    r = afsmGrow(r, push.gridSize, 0.5 + afsmCellMargin(frame.lights[push.lightIndex]) + 1.0 / 64.0);
    return front;
}

// Hard shadows: whether no sample of the blocks under a leaf's rectangle
// (afsmLeafRect) lies beyond its nearest corner (afsmBlocksBehind), so that
// none of its triangles can shadow one. Not for a box reaching behind a
// perspective grid's eye (front false).
bool afsmLeafBehind(AfsmRect r, float nearest, bool front)
{
    ivec2 first, last;
    afsmRectCellRange(r, push.gridSize, first, last);
    return front && !r.empty && afsmBlocksBehind(first, last, push.gridSize, nearest - 1e-6);
}

shared uvec2 passingLeaves[4 * PENUMBRA_AFSM_BIN_GROUP]; // cluster | kClosedLeaf, leaf reference (start | count << 16)
const uint kClosedLeaf = 0x80000000u; // the leaf's cluster is closed and casts back faces only (afsmCasts)
shared uint passingCount;

// As thin_triangles.comp.glsl (format version 4): each workgroup takes
// PENUMBRA_AFSM_BIN_GROUP BVH nodes and lists their leaf children (a node's
// children belong to its one cluster) whose cluster is in the layer's culled
// view; then each invocation decodes whole leaves of the list, one after
// another, with the tracer's strip walk (leafOccludes: the last two decoded
// vertices kept, the first two swapped for odd strip positions, triangles
// with a repeated index skipped), and bins each triangle.
void main()
{
    const uint lane = gl_LocalInvocationIndex;
    if (lane == 0u)
        passingCount = 0u;
    barrier();
    // The nodes in interleaved chunks (config.h): the casters lie in some parts of the model.
    const uint group = interleavedChunk(gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x,
                                        (push.nodeCount + PENUMBRA_AFSM_BIN_GROUP - 1u) / PENUMBRA_AFSM_BIN_GROUP);
    uint index = group * PENUMBRA_AFSM_BIN_GROUP + lane;
    ModelTable table = ModelTable(push.modelTable);
    if (index < push.nodeCount) {
        WideNode node;
        bool present = true; // kGeometryBudget: its cluster is resident
        if (kGeometryBudget != 0u) {
            const uint word = NodeTable(push.nodeTable).words[index];
            present = (word & PENUMBRA_NODE_ABSENT) == 0u;
            NodeArray records = NodeArray(push.nodeRecords);
            const uint texel = present ? word : 0u;
            node = WideNode(unpackWords(records.nodes[texel]), unpackWords(records.nodes[texel + 1u]), unpackWords(records.nodes[texel + 2u]),
                            unpackWords(records.nodes[texel + 3u]));
        } else if (kTexelAccess != 0u)
            node = nodeTexels(index);
        else
            node = loadNode(NodeChunks(table, table.nodeChunks[0], table.nodeChunkShift), index);
        const uint cluster = present ? nodeCluster(node) : PENUMBRA_NO_CLUSTER;
        bool inView = cluster != PENUMBRA_NO_CLUSTER && (ClusterMask(push.clusterMask).bits[cluster >> 5u] & (1u << (cluster & 31u))) != 0u;
        if (kGeometryBudget != 0u)
            inView = inView && cluster >= push.rangeBegin && cluster < push.rangeEnd;
        // Its leaves' casters cast their light-back-facing triangles only (afsmCasts): one read a node.
        const bool closed = inView && push.closedBackFaces != 0u && afsmClusterClosed(cluster);
        const vec3 steps = nodeSteps(node);
        for (uint slot = 0u; slot < 4u; ++slot) {
            bool take = inView && childKindOf(node, slot) == PENUMBRA_CHILD_LEAF;
#ifndef PENUMBRA_AFSM_SOFT // soft shadows: every leaf of the view (an influence region reaches past the box's projection)
            AfsmRect r;
            float nearest;
            const bool front = afsmLeafRect(node, steps, slot, r, nearest);
            // In core: this pass's leaves only, by their nearest depth (AfsmPass::CasterLayer::nearFrom); the
            // blocks are read only where the leaf is still taken (a loop no lane runs is skipped).
            take = take && (kGeometryBudget != 0u || (nearest >= uintBitsToFloat(push.rangeBegin) && nearest < uintBitsToFloat(push.rangeEnd)));
            if (take)
                take = !afsmLeafBehind(r, nearest, front);
#endif
            if (take)
                passingLeaves[atomicAdd(passingCount, 1u)] = uvec2(cluster | (closed ? kClosedLeaf : 0u), node.w3[slot]);
        }
    }
    barrier();
    const uint leafCount = passingCount;
    GeometryChunks chunks = kTexelAccess != 0u ? GeometryChunks(0ul) : geometryChunksOf(push.modelTable, table);
    const LightData light = frame.lights[push.lightIndex];
#ifdef PENUMBRA_AFSM_SOFT
    const AfsmParallel f = afsmUnpackParallel(uvec4(0u));
#else
    const AfsmParallel f = afsmUnpackParallel(AFSM_PARALLEL ? parallel : uvec4(0u)); // read once, not per caster
#endif
    // Each invocation walks the leaves lane, lane + PENUMBRA_AFSM_BIN_GROUP,
    // ..., one triangle an iteration: where its leaf ended it opens its next
    // one, then the inner loop reads strip bytes up to the leaf's next
    // triangle, so every lane bins a triangle in almost every iteration until
    // the list runs out. A loop over a leaf's bytes with binCaster inside ran
    // the caster's code, masked, for every strip byte of the longest leaf of
    // the 8 lanes (restarts, a strip's first two bytes: strips are about four
    // triangles long on the scan; the shorter leaves' lanes): the 2 M scan's
    // afsm_bin at 1024^2 212 -> 158 CPU ms, interior 95 -> 69, plant 153 ->
    // 114; opening the leaf here rather than in the inner loop (that runs as
    // long as its longest lane) 154 -> 146. Reading a strip's first three
    // bytes in one step measured slower (146 -> 158: more code masked in
    // every step).
    uint next = lane;          // the next leaf of the list to open
    bool open = false;         // a leaf is open, its bytes [k, count) still to read
    uint leafCluster = 0u, firstByte = 0u, count = 0u, k = 0u;
    ClusterInfo cluster;
    LeafStrips strips;
    uint i0 = 0u, i1 = 0u;
    vec3 p0 = vec3(0.0), p1 = vec3(0.0);
    uint position = 0u; // bytes of the current strip so far
    for (;;) {
        bool formed = false; // a triangle (v0, v1, v2) is ready
        vec3 v0 = vec3(0.0), v1 = vec3(0.0), v2 = vec3(0.0);
        // A lane whose leaf ended opens its next one here, once an iteration (not in the byte loop below:
        // that runs as long as its longest lane).
        if (!open && next < leafCount) {
            const uvec2 leaf = passingLeaves[next];
            next += PENUMBRA_AFSM_BIN_GROUP;
            leafCluster = leaf.x;
            cluster = kTexelAccess != 0u ? clusterTexels(leaf.x & ~kClosedLeaf) : loadCluster(table, leaf.x & ~kClosedLeaf);
            count = leaf.y >> 16;
            firstByte = uint(cluster.firstIndex) + (leaf.y & 0xFFFFu); // kTexelAccess: the leaf's first strip byte
            if (kTexelAccess == 0u) {
                strips = openLeaf(table, chunks, cluster, leaf.y);
                count = strips.count;
            }
            k = 0u;
            position = 0u;
            i0 = 0u;
            i1 = 0u;
            open = true;
        }
        while (!formed && open) {
            if (k == count) {
                open = false;
                break;
            }
            uint i2;
            if (kTexelAccess != 0u)
                i2 = stripByte(texelFetch(modelStrips, int((firstByte + k) >> 4u)), firstByte + k);
            else
                i2 = uint(strips.strips.bytes[k]);
            ++k;
            if (i2 == 0xFFu) {
                position = 0u;
                continue;
            }
            uvec3 q;
            if (kTexelAccess != 0u)
                q = vertexTexel(uint(cluster.firstVertex) + i2);
            else
                q = loadVertex(strips.vertices, i2);
            const vec3 p2 = decodeVertex(q, cluster.boxMin, cluster.step);
            if (position >= 2u && i0 != i1 && i1 != i2 && i0 != i2) {
                const bool odd = ((position - 2u) & 1u) != 0u;
                v0 = odd ? p1 : p0;
                v1 = odd ? p0 : p1;
                v2 = p2;
                formed = true;
            }
            i0 = i1;
            p0 = p1;
            i1 = i2;
            p1 = p2;
            ++position;
        }
        if (!formed && !open && next >= leafCount)
            break;
        if (formed)
            binCaster(leafCluster & ~kClosedLeaf, (leafCluster & kClosedLeaf) != 0u, light, f, v0, v1, v2);
    }
}
