// Thin-triangle detection for the conservative rasterization of thin
// triangles in the light view (Lauterbach et al. 2009, section 3.1; no
// conservative-rasterization extension on lavapipe). Leaves are decoded
// one invocation per strip byte (see main), exactly as the tracer does
// (bvh_traversal.glsli: forEachStripTriangle, decodeVertex, degenerate
// triangles skipped) unless the leaf's smallest model-space altitude (computed at
// upload) rules out slivers at this light's texel size, projects every triangle with the layer's viewProj and
// keeps those whose height over their longest edge (or whose longest edge)
// is under PENUMBRA_THIN_TEXELS texels: such a triangle may be missed by the
// shadow map, so every texel whose centre lies in the rectangle around its
// longest edge, grown by the texel square's half width in each direction of
// the edge's frame (so every texel the triangle touches is included), takes
// the triangle's nearest NDC depth with imageAtomicMin into the thin map
// (R32_UINT: float bits of depths in [0, 1] order like the floats). For the
// penumbra mask of an area light (localLayer) each texel also takes the
// nearest depth of the part of the triangle that can lie over it: the slab
// across the longest edge as wide as the texel square along it, so a long
// sliver seen at a slant keeps its own depth along its length. The hard-
// shadow tests keep the triangle's nearest depth: they compare it with the
// receiver's nearest depth over its texel, and at grazing angles the facade
// under a window ledge spans more depth in one texel than the ledge stands
// out from it (measured: per-texel depths there let 0.14% of city's pixels
// through, against 0.018%). Triangles
// with a vertex at w <= 0 are skipped (the shadow map clips them too), as are
// rectangles whose depth would be clipped.
#version 460
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_8bit_storage : require
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_ballot : require

#include "config.h"
#include "bvh_traversal.glsli"

layout(local_size_x = PENUMBRA_THIN_TRIANGLES_GROUP_SIZE) in;

layout(set = 0, binding = 0, r32ui) uniform uimage2DArray thinMap;

layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer LeafAltitudes
{
    float altitude[]; // per node: a leaf's smallest triangle altitude, model units
};

layout(push_constant) uniform ThinDetectPush
{
    mat4 viewProj;
    vec2 mapSize;        // texels
    uint nodeCount;
    uint layer;          // thin-map layer (cube face) being written
    uint64_t modelTable; // bvh_traversal.glsli
    uint64_t leafAltitudes; // LeafAltitudes, 0: skip no leaf
    vec4 light;          // xyz position; w: 0 orthographic, else a lower bound of light-view depth / distance
    float texelSize;     // orthographic: texel size; perspective: texel size per unit of light-view depth
    uint localLayer;     // also write each texel's own depth of the sliver into this layer; ~0u: no
    uint64_t clusterMask; // ClusterMask: bit per cluster, set where its footprint may reach a receiver; 0: all may
} push;

layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer ClusterMask { uint bits[]; };

// Narrows [xLo, xHi] to the X with a * X in [lo, hi].
void clipLinear(float a, float lo, float hi, inout float xLo, inout float xHi)
{
    if (abs(a) < 1e-12) {
        if (lo > 0.0 || hi < 0.0)
            xHi = xLo - 1.0; // empty
        return;
    }
    float b0 = lo / a, b1 = hi / a;
    xLo = max(xLo, min(b0, b1));
    xHi = min(xHi, max(b0, b1));
}

// A projected edge of a triangle: its range of t (distance along the longest
// edge), and its NDC depth there, affine: depth(t) = z + slope (t - t0).
struct EdgeDepth {
    float t0, t1; // t0 <= t1
    float z, slope;
};

EdgeDepth edgeDepth(float ta, float za, float tb, float zb)
{
    EdgeDepth e;
    e.t0 = min(ta, tb);
    e.t1 = max(ta, tb);
    e.slope = tb != ta ? (zb - za) / (tb - ta) : 0.0;
    e.z = ta < tb ? za : tb < ta ? zb : min(za, zb); // across the slab (ta == tb): its nearest end
    return e;
}

// Nearest depth on the edge over t in [lo, hi]; 2 when no point of it lies there.
float nearestOnEdge(EdgeDepth e, float lo, float hi)
{
    float a = max(lo, e.t0), b = min(hi, e.t1);
    return a > b ? 2.0 : e.z + e.slope * (e.slope > 0.0 ? a - e.t0 : b - e.t0);
}

// Nearest depth of a triangle over the slab t in [lo, hi] across its longest
// edge. NDC depth is affine over the projected triangle, so the minimum over
// its part in the slab lies on a vertex of that part: a vertex of the
// triangle or where an edge leaves the slab.
float nearestDepthInSlab(EdgeDepth edges[3], float lo, float hi)
{
    return min(nearestOnEdge(edges[0], lo, hi), min(nearestOnEdge(edges[1], lo, hi), nearestOnEdge(edges[2], lo, hi)));
}

// Appends the conservative rectangle of triangle (v0, v1, v2) when it is thin.
void emitIfThin(vec3 v0, vec3 v1, vec3 v2)
{
    vec4 clip[3] = vec4[3](push.viewProj * vec4(v0, 1.0), push.viewProj * vec4(v1, 1.0), push.viewProj * vec4(v2, 1.0));
    if (clip[0].w <= 0.0 || clip[1].w <= 0.0 || clip[2].w <= 0.0)
        return; // crosses the light's near plane: the shadow map clips it too
    vec2 p[3];
    float z[3];
    float zMin = 1.0;
    for (int i = 0; i < 3; ++i) {
        vec3 ndc = clip[i].xyz / clip[i].w;
        p[i] = (ndc.xy * 0.5 + 0.5) * push.mapSize;
        z[i] = ndc.z;
        zMin = min(zMin, ndc.z);
    }
    if (!(zMin >= 0.0)) // the rectangle's depth would be clipped (zMin <= 1 by construction)
        return;
    // Longest edge a -> b, third vertex c.
    int a = 0;
    float longest = -1.0;
    for (int i = 0; i < 3; ++i) {
        float len = distance(p[i], p[(i + 1) % 3]);
        if (len > longest) {
            longest = len;
            a = i;
        }
    }
    vec2 A = p[a], B = p[(a + 1) % 3], C = p[(a + 2) % 3];
    float zA = z[a], zB = z[(a + 1) % 3], zC = z[(a + 2) % 3];
    float twiceArea = abs((B.x - A.x) * (C.y - A.y) - (B.y - A.y) * (C.x - A.x));
    float height = longest > 0.0 ? twiceArea / longest : 0.0;
    // Slivers only (long and narrow: wires, poles, bars). Triangles small in
    // every direction belong to dense surfaces whose neighbours cover the
    // texels; the depth-discontinuity test handles their silhouettes.
    if (height >= PENUMBRA_THIN_TEXELS || longest < PENUMBRA_THIN_TEXELS)
        return;
    vec2 d = longest > 1e-12 ? (B - A) / longest : vec2(1.0, 0.0);
    vec2 nrm = vec2(-d.y, d.x);
    float c = dot(C - A, nrm);
    float along = dot(C - A, d);
    float e_d = 0.5 * (abs(d.x) + abs(d.y)), e_n = 0.5 * (abs(nrm.x) + abs(nrm.y));
    float d0 = min(0.0, along) - e_d, d1 = max(longest, along) + e_d;
    float n0 = min(0.0, c) - e_n, n1 = max(0.0, c) + e_n;
    vec2 corners[4] = vec2[4](A + d * d0 + nrm * n0, A + d * d1 + nrm * n0, A + d * d0 + nrm * n1, A + d * d1 + nrm * n1);
    vec2 lo = min(min(corners[0], corners[1]), min(corners[2], corners[3]));
    vec2 hi = max(max(corners[0], corners[1]), max(corners[2], corners[3]));
    // Scanline fill of the texel centres inside the rectangle
    // {A + d t + nrm u : t in [d0, d1], u in [n0, n1]}.
    ivec2 size = ivec2(push.mapSize);
    int yBegin = max(int(ceil(lo.y - 0.5)), 0), yEnd = min(int(floor(hi.y - 0.5)), size.y - 1);
    const bool local = push.localLayer != 0xFFFFFFFFu;
    // The edges' depths along the longest edge: A at t = 0, B at longest, C at along.
    EdgeDepth edges[3];
    if (local)
        edges = EdgeDepth[3](edgeDepth(0.0, zA, longest, zB), edgeDepth(longest, zB, along, zC), edgeDepth(along, zC, 0.0, zA));
    for (int y = yBegin; y <= yEnd; ++y) {
        float cy = float(y) + 0.5 - A.y;
        float xLo = lo.x - A.x - 1.0, xHi = hi.x - A.x + 1.0; // X = x + 0.5 - A.x
        clipLinear(d.x, d0 - d.y * cy, d1 - d.y * cy, xLo, xHi);     // t = d.x X + d.y cy
        clipLinear(-d.y, n0 - d.x * cy, n1 - d.x * cy, xLo, xHi);    // u = -d.y X + d.x cy
        int xBegin = max(int(ceil(xLo + A.x - 0.5)), 0), xEnd = min(int(floor(xHi + A.x - 0.5)), size.x - 1);
        // Two loops, so that the hard-shadow maps' fill stays as lean as it was.
        if (!local) {
            for (int x = xBegin; x <= xEnd; ++x)
                imageAtomicMin(thinMap, ivec3(x, y, int(push.layer)), floatBitsToUint(zMin));
            continue;
        }
        // Area lights' slivers overlap (a grating's bars, a strip's neighbours): here skipping the
        // atomics that would change nothing pays (interior 512^2: about 350 -> 320 ms on lavapipe).
        for (int x = xBegin; x <= xEnd; ++x) {
            ivec3 texel = ivec3(x, y, int(push.layer));
            if (imageLoad(thinMap, texel).r > floatBitsToUint(zMin))
                imageAtomicMin(thinMap, texel, floatBitsToUint(zMin));
            float t = dot(vec2(float(x) + 0.5, float(y) + 0.5) - A, d);
            float depth = nearestDepthInSlab(edges, t - e_d, t + e_d);
            depth = depth > 1.0 ? zMin : depth; // rounding at the rectangle's ends
            texel.z = int(push.localLayer);
            if (imageLoad(thinMap, texel).r > floatBitsToUint(depth))
                imageAtomicMin(thinMap, texel, floatBitsToUint(depth));
        }
    }
}

shared uvec4 passingLeaves[PENUMBRA_THIN_TRIANGLES_GROUP_SIZE]; // the leaf nodes themselves
shared uint passingCount;

// A leaf whose every triangle is wider than the thin threshold in model space, at the smallest texel size
// the leaf can see, holds no sliver unless seen edge-on; edge-on faces of closed objects are covered by
// their neighbours in the shadow map, so such a leaf is skipped without decoding.
bool mayHoldSlivers(ModelTable table, uint index, uvec4 leaf)
{
    if (push.leafAltitudes == 0ul)
        return true;
    float altitude = LeafAltitudes(push.leafAltitudes).altitude[index];
    float texel = push.texelSize;
    if (push.light.w != 0.0) {
        ClusterInfo cluster = loadCluster(table, leaf.z);
        vec3 boxMax = cluster.boxMin + 65535.0 * cluster.step;
        texel *= distance(clamp(push.light.xyz, cluster.boxMin, boxMax), push.light.xyz) * push.light.w;
    }
    return altitude < PENUMBRA_THIN_TEXELS * texel;
}

// Each workgroup takes PENUMBRA_THIN_TRIANGLES_GROUP_SIZE BVH nodes and keeps the leaves that may hold
// slivers; each subgroup then decodes its share of them, one invocation per strip byte, so that the
// triangles of a leaf are projected in parallel. A byte's place in its strip (which decides the
// winding) comes from the last restart before it: an inclusive max-scan of restart positions.
void main()
{
    const uint lane = gl_LocalInvocationIndex;
    if (lane == 0u)
        passingCount = 0u;
    barrier();
    // Groups may be laid out in 2D when the nodes exceed maxComputeWorkGroupCount[0].
    uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    uint index = group * PENUMBRA_THIN_TRIANGLES_GROUP_SIZE + lane;
    ModelTable table = ModelTable(push.modelTable);
    NodeChunks nodeChunks = NodeChunks(table, table.nodeChunks[0], table.nodeChunkShift);
    if (index < push.nodeCount) {
        uvec4 node = loadNode(nodeChunks, index);
        // node.z: the leaf's cluster. A cluster whose footprint lies 2 texels or more from every
        // camera pixel's point cannot write a texel that is read (receiver masks, culling.h).
        if (((node.y >> 16) & 0xFFu) == PENUMBRA_NODE_LEAF &&
            (push.clusterMask == 0ul || (ClusterMask(push.clusterMask).bits[node.z >> 5u] & (1u << (node.z & 31u))) != 0u) &&
            mayHoldSlivers(table, index, node))
            passingLeaves[atomicAdd(passingCount, 1u)] = node;
    }
    barrier();
    const uint leafCount = passingCount;
    GeometryChunks chunks = geometryChunksOf(push.modelTable, table);
    for (uint j = gl_SubgroupID; j < leafCount; j += gl_NumSubgroups) {
        uvec4 leaf = passingLeaves[j];
        ClusterInfo cluster = loadCluster(table, leaf.z);
        // The strips, decoded as leafOccludes() in bvh_traversal.glsli does.
        LeafStrips leafStrips = openLeaf(table, chunks, cluster, leaf);
        ByteArray strips = leafStrips.strips;
        // Active invocations of the subgroup, in order (all of them, unless the subgroup is partial).
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
            // Invocations leave this iteration together (no continue): the next one's subgroup
            // operations need every invocation of the subgroup.
            uint position = k - uint(before + 1); // bytes of this strip before k
            if (inside && i2 != 0xFFu && position >= 2u) {
                uint i0 = uint(strips.bytes[k - 2u]), i1 = uint(strips.bytes[k - 1u]);
                if (i0 != i1 && i1 != i2 && i0 != i2) {
                    vec3 p0 = decodeVertex(loadVertex(leafStrips.vertices, i0), cluster.boxMin, cluster.step);
                    vec3 p1 = decodeVertex(loadVertex(leafStrips.vertices, i1), cluster.boxMin, cluster.step);
                    vec3 p2 = decodeVertex(loadVertex(leafStrips.vertices, i2), cluster.boxMin, cluster.step);
                    bool odd = ((position - 2u) & 1u) != 0u;
                    emitIfThin(odd ? p1 : p0, odd ? p0 : p1, p2);
                }
            }
        }
    }
}
