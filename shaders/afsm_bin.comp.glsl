// Alias-free shadow maps, the compute path of the casters (Sintorn et al.
// 2008, section 3.2; the issue's "bin each triangle to the texels its
// light-space footprint touches"): the small casters of one layer's culled
// view, binned to their grid cells and tested there without the rasterizer.
// On lavapipe every rasterized caster costs a triangle setup and fragment
// shader invocations for its whole bounding rectangle of 2x2-pixel quads,
// however few cells it covers; most casters of a large model cover a few
// cells. So each caster whose grown rectangle (afsm_casters.glsli) spans at
// most PENUMBRA_AFSM_COMPUTE_CELLS cells and whose cells hold little work is
// tested here, cell by cell, exactly as the fragment shader would
// (afsmTestCellHard, afsmTestCellSoft); the raster path (afsm_casters.geom,
// afsm_soft.geom) draws the others. Leaves are decoded as the thin-triangle
// pass decodes them (thin_triangles.comp.glsl: one invocation per strip
// byte, the tracer's decoding), those of clusters outside the view skipped.
// Built twice: hard shadows, and soft shadows with PENUMBRA_AFSM_SOFT
// (afsm_bin.comp.soft).
#version 460
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_8bit_storage : require
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
#include "afsm.glsli"

layout(local_size_x = PENUMBRA_AFSM_BIN_GROUP) in;

// C++: runtime/src/passes/afsm.h (AfsmBinBinding).
layout(set = 0, binding = 0, std140) uniform Frame { FrameData frame; };
layout(set = 0, binding = 1, std430) readonly buffer CellFirst { uint cellFirst[]; };
layout(set = 0, binding = 2, std430) readonly buffer CellCount { uint cellCount[]; };
layout(set = 0, binding = 3, std430) buffer Shadowed { uint shadowed[]; };
layout(set = 0, binding = 4, std430) readonly buffer Far { uint farBits; };
layout(set = 0, binding = 5, std430) readonly buffer CellDepth { uint cellDepth[]; };
layout(set = 0, binding = 6, std430) buffer SlotShadowed { uint slotShadowed[]; };
layout(set = 0, binding = 7, std430) buffer CellAlive { uint cellAlive[]; };
// Where the slots (and, soft, the masks and the table) are (AfsmPass: AfsmParams).
layout(set = 0, binding = 8, std430) readonly buffer Params {
    uint64_t slots, softMasks, softTable;
    uint softSamples, softTableSize;
};

#include "afsm_casters.glsli"

layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer ClusterMask { uint bits[]; };

layout(push_constant) uniform AfsmBinPush {
    mat4 viewProj;        // the layer's grid projection
    uint64_t modelTable;  // bvh_traversal.glsli
    uint64_t clusterMask; // bit per cluster: in the layer's culled view
    uint nodeCount;
    uint lightIndex;
    uint gridSize;
    float originOffset;
    float computeCells;   // PENUMBRA_AFSM_COMPUTE_CELLS
    uint pad;
} push;

void binCaster(vec3 v0, vec3 v1, vec3 v2)
{
#ifdef PENUMBRA_AFSM_SOFT
    LightData light = frame.lights[push.lightIndex];
    float nearest;
    AfsmRect r = afsmSoftRect(push.viewProj, light, uintBitsToFloat(farBits), v0, v1, v2, push.gridSize, nearest);
    uint perSample = 1u + afsmQuads(softSamples);
    AfsmSoftTable table = AfsmSoftTable(slots, softMasks, softTable, softSamples, softTableSize);
#else
    vec2 projected[3];
    bool behind;
    AfsmDepthBound depth;
    AfsmRect r = afsmHardRect(push.viewProj, v0, v1, v2, push.gridSize, projected, behind, depth);
    float nearest = depth.nearest;
    uint perSample = 1u;
#endif
    // The cells one by one, counting the work as afsmComputeWork does (the
    // raster path's mirror of this choice); past the budget the raster path
    // takes the caster (the cells tested so far are tested twice).
    if (r.empty || !(afsmRectCells(r, push.gridSize) <= push.computeCells))
        return;
    ivec2 first, last;
    afsmRectCellRange(r, push.gridSize, first, last);
    uint work = 0u;
    for (int y = first.y; y <= last.y; ++y)
        for (int x = first.x; x <= last.x; ++x) {
            uint cell = uint(y) * push.gridSize + uint(x);
            uint count = cellCount[cell];
#ifdef PENUMBRA_AFSM_SOFT
            bool beyond = afsmCellBehind(cell, nearest);
#else
            vec2 corner = vec2(x, y);
            bool beyond = afsmCellBehind(cell, afsmNearestOver(depth, corner, 0.5));
#endif
            work += 1u + (beyond ? 0u : perSample * count);
            if (work > PENUMBRA_AFSM_COMPUTE_BUDGET)
                return;
            if (count == 0u || beyond || cellAlive[cell] == 0u)
                continue;
#ifdef PENUMBRA_AFSM_SOFT
            afsmTestCellSoft(cell, light, table, v0, v1, v2);
#else
            if (afsmCellMayMeetTriangle(corner + 0.5, projected, !behind))
                afsmTestCellHard(cell, slots, v0, v1, v2);
#endif
        }
}

shared uvec4 passingLeaves[PENUMBRA_AFSM_BIN_GROUP];
shared uint passingCount;

// As thin_triangles.comp.glsl: each workgroup takes PENUMBRA_AFSM_BIN_GROUP
// BVH nodes and keeps the leaves of the view's clusters; each subgroup then
// decodes its share of them, one invocation per strip byte (a byte's place
// in its strip, which decides the winding, from the last restart before it).
void main()
{
    const uint lane = gl_LocalInvocationIndex;
    if (lane == 0u)
        passingCount = 0u;
    barrier();
    uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    uint index = group * PENUMBRA_AFSM_BIN_GROUP + lane;
    ModelTable table = ModelTable(push.modelTable);
    NodeChunks nodeChunks = NodeChunks(table, table.nodeChunks[0], table.nodeChunkShift);
    if (index < push.nodeCount) {
        uvec4 node = loadNode(nodeChunks, index);
        if (((node.y >> 16) & 0xFFu) == PENUMBRA_NODE_LEAF && (ClusterMask(push.clusterMask).bits[node.z >> 5u] & (1u << (node.z & 31u))) != 0u)
            passingLeaves[atomicAdd(passingCount, 1u)] = node;
    }
    barrier();
    const uint leafCount = passingCount;
    GeometryChunks chunks = geometryChunksOf(push.modelTable, table);
    for (uint j = gl_SubgroupID; j < leafCount; j += gl_NumSubgroups) {
        uvec4 leaf = passingLeaves[j];
        ClusterInfo cluster = loadCluster(table, leaf.z);
        LeafStrips leafStrips = openLeaf(table, chunks, cluster, leaf);
        ByteArray strips = leafStrips.strips;
        uvec4 lanes = subgroupBallot(true);
        uint width = subgroupBallotBitCount(lanes), slot = subgroupBallotExclusiveBitCount(lanes);
        int lastRestart = -1; // of the bytes before this chunk
        for (uint chunkStart = 0u; chunkStart < leafStrips.count; chunkStart += width) {
            uint k = chunkStart + slot;
            bool inside = k < leafStrips.count;
            uint i2 = inside ? uint(strips.bytes[k]) : 0u;
            int restart = inside && i2 == 0xFFu ? int(k) : -1;
            int before = max(lastRestart, subgroupExclusiveMax(restart)); // last restart before k
            lastRestart = max(lastRestart, subgroupMax(restart));
            uint position = k - uint(before + 1); // bytes of this strip before k
            if (inside && i2 != 0xFFu && position >= 2u) {
                uint i0 = uint(strips.bytes[k - 2u]), i1 = uint(strips.bytes[k - 1u]);
                if (i0 != i1 && i1 != i2 && i0 != i2) {
                    vec3 p0 = decodeVertex(loadVertex(leafStrips.vertices, i0), cluster.boxMin, cluster.step);
                    vec3 p1 = decodeVertex(loadVertex(leafStrips.vertices, i1), cluster.boxMin, cluster.step);
                    vec3 p2 = decodeVertex(loadVertex(leafStrips.vertices, i2), cluster.boxMin, cluster.step);
                    bool odd = ((position - 2u) & 1u) != 0u;
                    binCaster(odd ? p1 : p0, odd ? p0 : p1, p2);
                }
            }
        }
    }
}
