// Thin-triangle detection for the conservative rasterization of thin
// triangles in the light view (Lauterbach et al. 2009, section 3.1; no
// conservative-rasterization extension on lavapipe). Leaves are decoded
// one invocation per strip byte (see main), exactly as the tracer does
// (bvh_traversal.glsli: forEachStripTriangle, decodeVertex, degenerate
// triangles skipped) unless the leaf's data (computed at upload over its long
// and narrow triangles) rules out slivers at this light's texel size, projects
// every triangle with the layer's viewProj and keeps those long and narrow in
// model space (thinInModelSpace) and in the view: under PENUMBRA_THIN_TEXELS
// texels high over their longest edge, at least that long and
// PENUMBRA_THIN_ASPECT times longer than high. Such a triangle may be missed by the
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
#extension GL_EXT_shader_16bit_storage : require
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_shader_subgroup_shuffle : require

#include "config.h"
// 1: the model is read through texel buffers (GpuGeometry::texelsComplete), 0: by device address.
layout(constant_id = 0) const uint kTexelAccess = 0u;
// 1: an area light's map, whose slivers also write their per-texel depths (push.localLayer).
layout(constant_id = 1) const uint kLocalDepths = 0u;
// PENUMBRA_THIN_LIST: decode the leaves and list the slivers; PENUMBRA_THIN_DISPATCH: the fill's
// indirect dispatch from the list's length; PENUMBRA_THIN_FILL: fill each listed sliver's rectangle.
layout(constant_id = 2) const uint kPhase = PENUMBRA_THIN_LIST;
// 1: the vertices' texel view is R16_UINT, three texels a vertex (GpuGeometry::vertexTexelsSplit).
layout(constant_id = 3) const uint kSplitVertexTexels = 0u;
// 1: paged geometry (geometry_pages.h): clusters that are not resident are skipped. The frame
// script made every cluster that can reach this view resident (clusterMayReachView); the others
// write no texel of it.
layout(constant_id = 4) const uint kGeometryBudget = 0u;
// 1: push.viewProj's last row is (0, 0, 0, 1) (an orthographic map: a directional light's), so clip w
// is exactly 1 and projectVertex divides by nothing (the same values: x / 1 = x).
layout(constant_id = 5) const uint kAffine = 0u;
// The slivers of this view: count, the fill's indirect dispatch, then per run of slivers of one
// leaf (stripByte) its cluster and its first sliver's strip position (the byte of its third
// vertex, relative to the cluster's strips) | odd << 16 | (bytes from it to its last sliver's) << 17.
// Written by the host once: capacity (entries the list holds); cleared per view: count.
layout(set = 0, binding = 5, std430) buffer ThinList
{
    uint thinCount;
    uint thinDispatch[3];
    uint thinCapacity;
    uint thinRectCapacity; // entries below it of a hard map also keep their rectangle in ThinRects
    uint thinPad[2];
    uvec2 thinTriangles[];
};
// A hard map's listed runs' rectangles (the first thinRectCapacity entries), two texels each: corner
// (d0, n0) and d, then the lengths d1 - d0, n1 - n0 and zMin. The fill reads them instead of decoding
// the run's vertices again.
layout(set = 0, binding = 7, std430) writeonly buffer ThinRects { vec4 thinRects[]; };
layout(set = 0, binding = 8) uniform samplerBuffer thinRectTexels; // RGBA32F view of ThinRects
layout(set = 0, binding = 1) uniform usamplerBuffer modelNodes;
layout(set = 0, binding = 2) uniform usamplerBuffer modelClusters;
layout(set = 0, binding = 3) uniform usamplerBuffer modelVertices;
layout(set = 0, binding = 4) uniform usamplerBuffer modelStrips;
// kGeometryBudget: per node, its record's first texel in modelNodes (the pool), or cluster | PENUMBRA_NODE_ABSENT.
layout(set = 0, binding = 6) uniform usamplerBuffer modelNodeTable;
#include "bvh_traversal.glsli"
#include "bvh_texels.glsli"

layout(local_size_x = PENUMBRA_THIN_TRIANGLES_GROUP_SIZE) in;

layout(set = 0, binding = 0, r32ui) uniform uimage2DArray thinMap;

layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer LeafAltitudes
{
    float altitude[]; // per node: its 4 slots' smallest triangle altitudes, then their longest edges (model units)
};

layout(push_constant) uniform ThinDetectPush
{
    mat4 viewProj;
    vec2 mapSize;        // texels
    uint nodeCount;
    uint layer;          // thin-map layer (cube face) being written
    uint64_t modelTable; // bvh_traversal.glsli
    uint64_t leafAltitudes; // LeafAltitudes, 0: skip no leaf (kGeometryBudget: 1: in the pool's node records)
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

// A vertex in the light's view: texel coordinates (xy), NDC depth (z), and
// w > 0 (1) or not (0), projected once per strip byte.
vec4 projectVertex(vec3 v)
{
    vec4 clip = push.viewProj * vec4(v, 1.0);
    vec3 ndc = kAffine != 0u ? clip.xyz : clip.xyz / clip.w;
    return vec4((ndc.xy * 0.5 + 0.5) * push.mapSize, ndc.z, kAffine != 0u || clip.w > 0.0 ? 1.0 : 0.0);
}

// A sliver's conservative rectangle {A + d t + nrm u : t in [d0, d1], u in
// [n0, n1]} (texels) around its longest edge A -> B, grown by the texel
// square's half width in each direction of the edge's frame, so that it
// holds the centre of every texel the triangle touches; zMin: its nearest
// NDC depth; area: (d1 - d0) (n1 - n0). The depths of A, B and the third
// vertex C, |B - A| and C's t serve the per-texel depths of area lights'
// maps (a single sliver's; a merged run keeps its first sliver's).
struct SliverRect {
    vec2 A, d, nrm;
    float d0, d1, n0, n1, zMin;
    float zA, zB, zC, longest, along;
};

float rectArea(SliverRect r)
{
    return (r.d1 - r.d0) * (r.n1 - r.n0);
}

// Whether triangle (a, b, c) (model space) is long and narrow: its longest
// edge at least PENUMBRA_THIN_ASPECT times its height over that edge. A
// triangle that is not (a well-shaped triangle of a surface, seen edge-on or
// small) is no sliver in any light's view: its neighbours in the surface cover
// the texels around it, and where it is the surface's silhouette the
// depth-discontinuity test marks the receivers beside it; mayHoldSlivers'
// leaf data counts only the long and narrow ones (nodeLeafAltitudes).
bool thinInModelSpace(vec3 a, vec3 b, vec3 c)
{
    const vec3 ab = b - a, bc = c - b, ca = a - c;
    const float longest2 = max(dot(ab, ab), max(dot(bc, bc), dot(ca, ca)));
    // height = |n| / longest, so longest >= aspect height <=> longest^2 >= aspect |n|
    return longest2 >= PENUMBRA_THIN_ASPECT * length(cross(ab, ca));
}

// False unless triangle (v0, v1, v2) (projectVertex; m0, m1, m2: the same vertices in model space, in
// any order) is long and narrow in model space (thinInModelSpace) and a sliver whose
// rectangle is filled: in front of the light's eye plane (its depth clamped
// at the near plane's), under PENUMBRA_THIN_TEXELS texels high over its longest edge, at
// least that long and at least PENUMBRA_THIN_ASPECT times longer than high.
// Slivers only (long and narrow: wires, poles, bars): triangles small in
// every direction belong to dense surfaces whose neighbours cover the
// texels; the depth-discontinuity test handles their silhouettes. (Without
// the aspect rule, the well-shaped triangles of the 2 M scan a texel or two
// across were slivers: 27.7% of its pixels got rays at 1024^2, 14.8% with it
// and thinInModelSpace.)
bool sliverRect(vec4 v0, vec4 v1, vec4 v2, vec3 m0, vec3 m1, vec3 m2, out SliverRect r)
{
    // Every test computed and the rectangle filled whatever they say, their results combined at the
    // end: on lavapipe an early return puts the rest under an execution mask, for every triangle.
    const bool modelThin = thinInModelSpace(m0, m1, m2);
    // Crossing the light's eye plane: left out (its projection is not a triangle's).
    const bool front = v0.w != 0.0 && v1.w != 0.0 && v2.w != 0.0;
    // A vertex between the eye and the near plane (NDC depth below 0) lies outside the map's frustum:
    // nothing inside is nearer than the near plane (light_space.h: the nearest triangle's depth), so
    // the part of the sliver inside is at depth 0 or more, and 0 is its conservative depth. Such a
    // sliver was left out once; with near planes at the nearest triangle, a long sliver reaching past
    // the light from beside it (a cable by a street light) would have been lost for every face.
    const float zNearest = min(min(min(1.0, v0.z), v1.z), v2.z);
    r.zMin = max(zNearest, 0.0);
    // Longest edge A -> B (the first of equally long ones), third vertex C: chosen with selects, not
    // by indexing an array with the lane's edge (llvmpipe keeps such an array in per-lane memory).
    const float l0 = distance(v0.xy, v1.xy), l1 = distance(v1.xy, v2.xy), l2 = distance(v2.xy, v0.xy);
    const bool e0 = l0 >= l1 && l0 >= l2, e1 = !e0 && l1 >= l2;
    const float longest = e0 ? l0 : e1 ? l1 : l2;
    const vec3 vA = e0 ? v0.xyz : e1 ? v1.xyz : v2.xyz, vB = e0 ? v1.xyz : e1 ? v2.xyz : v0.xyz, vC = e0 ? v2.xyz : e1 ? v0.xyz : v1.xyz;
    const vec2 A = vA.xy, B = vB.xy, C = vC.xy;
    float twiceArea = abs((B.x - A.x) * (C.y - A.y) - (B.y - A.y) * (C.x - A.x));
    float height = longest > 0.0 ? twiceArea / longest : 0.0;
    const bool shape = height < PENUMBRA_THIN_TEXELS && longest >= PENUMBRA_THIN_TEXELS && longest >= PENUMBRA_THIN_ASPECT * height;
    vec2 d = longest > 1e-12 ? (B - A) / longest : vec2(1.0, 0.0);
    vec2 nrm = vec2(-d.y, d.x);
    float c = dot(C - A, nrm);
    float along = dot(C - A, d);
    float e_d = 0.5 * (abs(d.x) + abs(d.y)), e_n = 0.5 * (abs(nrm.x) + abs(nrm.y));
    r.A = A;
    r.d = d;
    r.nrm = nrm;
    r.d0 = min(0.0, along) - e_d;
    r.d1 = max(longest, along) + e_d;
    r.n0 = min(0.0, c) - e_n;
    r.n1 = max(0.0, c) + e_n;
    // Area lights' per-texel depths, interpolated along the edges: with a vertex clamped they would
    // not be conservative, so the whole sliver takes depth 0 then.
    r.zA = zNearest < 0.0 ? 0.0 : vA.z;
    r.zB = zNearest < 0.0 ? 0.0 : vB.z;
    r.zC = zNearest < 0.0 ? 0.0 : vC.z;
    r.longest = longest;
    r.along = along;
    return modelThin && front && shape;
}

// `into` grown to hold rectangle r, in into's frame (r's corners projected
// onto into's axes: the result holds both rectangles).
SliverRect unionRect(SliverRect into, SliverRect r)
{
    for (int k = 0; k < 4; ++k) {
        vec2 corner = r.A + r.d * ((k & 1) != 0 ? r.d1 : r.d0) + r.nrm * ((k & 2) != 0 ? r.n1 : r.n0) - into.A;
        float t = dot(corner, into.d), u = dot(corner, into.nrm);
        into.d0 = min(into.d0, t);
        into.d1 = max(into.d1, t);
        into.n0 = min(into.n0, u);
        into.n1 = max(into.n1, u);
    }
    into.zMin = min(into.zMin, r.zMin);
    return into;
}

// Fills rectangle r (a hard map's run of slivers, or an area light's single
// sliver with its edges' depths): rows first, first + step, ... of it
// (fillListedShared: the lanes of a subgroup share one rectangle's rows).
void fillRect(int first, int step, SliverRect r)
{
    const bool local = kLocalDepths != 0u;
    // A hard map's thin texels are PENUMBRA_THIN_HARD_SCALE shadow-map texels a side (classify reads
    // texel / scale): the rectangle in thin texels, grown by the half width of a square as wide as the
    // distance from a thin texel's centre to its shadow-map texels' centres, so that a thin texel is
    // written whenever one of those centres lies in the rectangle.
    const float scale = local ? 1.0 : float(PENUMBRA_THIN_HARD_SCALE);
    if (!local) {
        const float grow = 0.5 - 0.5 / scale; // a shadow-map texel centre's farthest offset from its thin texel's
        const float e_d = grow * (abs(r.d.x) + abs(r.d.y)), e_n = grow * (abs(r.nrm.x) + abs(r.nrm.y));
        r.A /= scale;
        r.d0 = r.d0 / scale - e_d;
        r.d1 = r.d1 / scale + e_d;
        r.n0 = r.n0 / scale - e_n;
        r.n1 = r.n1 / scale + e_n;
    }
    const vec2 A = r.A, d = r.d, nrm = r.nrm;
    const float d0 = r.d0, d1 = r.d1, n0 = r.n0, n1 = r.n1, zMin = r.zMin;
    // Area lights (never merged): the edges' depths along the longest edge.
    const float zA = r.zA, zB = r.zB, zC = r.zC, longest = r.longest, along = r.along, e_d = 0.5 * (abs(d.x) + abs(d.y));
    vec2 corners[4] = vec2[4](A + d * d0 + nrm * n0, A + d * d1 + nrm * n0, A + d * d0 + nrm * n1, A + d * d1 + nrm * n1);
    vec2 lo = min(min(corners[0], corners[1]), min(corners[2], corners[3]));
    vec2 hi = max(max(corners[0], corners[1]), max(corners[2], corners[3]));
    // Scanline fill of the texel centres inside the rectangle
    // {A + d t + nrm u : t in [d0, d1], u in [n0, n1]}.
    const ivec2 size = (ivec2(push.mapSize) + int(scale) - 1) / int(scale);
    int yBegin = max(int(ceil(lo.y - 0.5)), 0), yEnd = min(int(floor(hi.y - 0.5)), size.y - 1);
    // The edges' depths along the longest edge: A at t = 0, B at longest, C at along.
    EdgeDepth edges[3];
    if (local)
        edges = EdgeDepth[3](edgeDepth(0.0, zA, longest, zB), edgeDepth(longest, zB, along, zC), edgeDepth(along, zC, 0.0, zA));
    for (int y = yBegin + first; y <= yEnd; y += step) {
        float cy = float(y) + 0.5 - A.y;
        float xLo = lo.x - A.x - 1.0, xHi = hi.x - A.x + 1.0; // X = x + 0.5 - A.x
        clipLinear(d.x, d0 - d.y * cy, d1 - d.y * cy, xLo, xHi);     // t = d.x X + d.y cy
        clipLinear(-d.y, n0 - d.x * cy, n1 - d.x * cy, xLo, xHi);    // u = -d.y X + d.x cy
        int xBegin = max(int(ceil(xLo + A.x - 0.5)), 0), xEnd = min(int(floor(xHi + A.x - 0.5)), size.x - 1);
        // Two loops, so that the hard-shadow maps' fill stays as lean as it was.
        if (!local) {
            for (int x = xBegin; x <= xEnd; ++x) {
                ivec3 texel = ivec3(x, y, int(push.layer));
                if (imageLoad(thinMap, texel).r > floatBitsToUint(zMin))
                    imageAtomicMin(thinMap, texel, floatBitsToUint(zMin));
            }
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

shared uvec2 passingLeaves[4 * PENUMBRA_THIN_TRIANGLES_GROUP_SIZE]; // cluster, leaf reference (start | count << 16)
shared uint passingCount;

ClusterInfo clusterInfo(ModelTable table, uint cluster)
{
    return kTexelAccess != 0u ? clusterTexels(cluster) : loadCluster(table, cluster);
}

// The leaf's data cover only its long and narrow triangles (thinInModelSpace; none: the float maximum
// altitude). A leaf with none, or whose every such triangle is wider than the thin threshold in model
// space at the smallest texel size the leaf can see, holds no sliver unless seen edge-on; edge-on faces of
// closed objects are covered by their neighbours in the shadow map, so such a leaf is skipped without
// decoding. So is, in an orthographic view, a leaf whose every such triangle's edges are shorter than the
// threshold in texels: a segment of length L spans at most L x size / 2 x |the view's x, y rows| texels
// (the map fitted to the view may have oblong texels: texelSize is the longer side, so it cannot bound this).
// node, slot: the leaf's node and child slot; record: kGeometryBudget: the node record's first texel in the
// pool (its altitudes follow the node; no longest edges there).
bool mayHoldSlivers(ModelTable table, uint node, uint slot, uint clusterIndex, uint record)
{
    if (push.leafAltitudes == 0ul)
        return true;
    float altitude = kGeometryBudget != 0u ? uintBitsToFloat(texelFetch(modelNodes, int(record + 4u))[slot])
                                           : LeafAltitudes(push.leafAltitudes).altitude[8u * node + slot];
    float texel = push.texelSize;
    bool longEnough = true;
    if (push.light.w != 0.0) {
        ClusterInfo cluster = clusterInfo(table, clusterIndex);
        vec3 boxMax = cluster.boxMin + 65535.0 * cluster.step;
        texel *= distance(clamp(push.light.xyz, cluster.boxMin, boxMax), push.light.xyz) * push.light.w;
    } else if (kGeometryBudget == 0u) {
        const vec3 row0 = vec3(push.viewProj[0][0], push.viewProj[1][0], push.viewProj[2][0]);
        const vec3 row1 = vec3(push.viewProj[0][1], push.viewProj[1][1], push.viewProj[2][1]);
        float longest = LeafAltitudes(push.leafAltitudes).altitude[8u * node + 4u + slot];
        longEnough = longest * 0.5 * push.mapSize.x * sqrt(dot(row0, row0) + dot(row1, row1)) >= PENUMBRA_THIN_TEXELS;
    }
    return altitude < PENUMBRA_THIN_TEXELS * texel && longEnough;
}

// The strip walk of one leaf (forEachStripTriangle, as the tracer's leaf
// test): the last two projected vertices are kept, so each strip byte
// decodes and projects one vertex. Hard shadows: the slivers of a leaf (a
// pipe's or a bar's triangles side by side, the rings of a lathed column,
// whose rectangles cover nearly the same texels) are merged into one run
// while the rectangle holding them all is no larger than their rectangles'
// areas added, whatever lies between them in the strips (restarts,
// degenerate triangles, wider triangles); the fill draws the run's rectangle
// once. Runs of consecutive slivers only wrote each texel of the 1 M
// interior's thin map 17 times at 1024^2 (287 k runs, 78% of them one
// sliver: its strips are short); runs across the leaf, 3.3 times (63 k).
struct StripWalk {
    uint i0, i1;
    vec4 p0, p1;
    vec3 m0, m1;   // the same vertices in model space
    uint position; // bytes of the current strip so far
    uint runLength; // slivers in the open run (0: none)
    uint runEntry;  // its first sliver's strip position | odd << 16
    uint runLast;   // strip position of its last sliver
    SliverRect run; // the rectangle holding the run's, in its first sliver's frame
};

void listRun(uint cluster, inout StripWalk w)
{
    if (w.runLength == 0u)
        return;
    uint slot = atomicAdd(thinCount, 1u);
    if (slot < thinCapacity)
        thinTriangles[slot] = uvec2(cluster, w.runEntry | (w.runLast - (w.runEntry & 0xFFFFu)) << 17);
    if (kLocalDepths == 0u && slot < thinRectCapacity) {
        const SliverRect r = w.run;
        thinRects[2u * slot] = vec4(r.A + r.d * r.d0 + r.nrm * r.n0, r.d);
        thinRects[2u * slot + 1u] = vec4(r.d1 - r.d0, r.n1 - r.n0, r.zMin, 0.0);
    }
    w.runLength = 0u;
}

// byte: the strip position of i2 relative to the cluster's strips.
void stripByte(inout StripWalk w, uint cluster, uint byte, uint i2, vec3 decoded)
{
    vec4 p2 = projectVertex(decoded);
    bool restart = i2 == 0xFFu;
    bool odd = ((w.position - 2u) & 1u) != 0u;
    // Slivers are listed for the fill phase: on lavapipe a fill here would run (masked) for every
    // triangle. For the same reason the tests and the union run for every byte, their results
    // combined after (no short-circuit `&&` before sliverRect, no `if` around the union).
    SliverRect r;
    const bool rect = sliverRect(odd ? w.p1 : w.p0, odd ? w.p0 : w.p1, p2, w.m0, w.m1, decoded, r);
    const bool sliver = !restart && w.position >= 2u && w.i0 != w.i1 && w.i1 != i2 && w.i0 != i2 && rect;
    const SliverRect grown = unionRect(w.run, r);
    const bool smaller = rectArea(grown) <= rectArea(w.run) + rectArea(r);
    const bool merged = sliver && kLocalDepths == 0u && w.runLength != 0u && byte - (w.runEntry & 0xFFFFu) <= PENUMBRA_THIN_RUN_MAX && smaller;
    w.run = merged ? grown : w.run;
    // The open run is listed when a sliver does not join it (area lights: every sliver is a run of
    // its own) or at the leaf's end; the triangles that are no slivers leave it open.
    if (sliver && !merged)
        listRun(cluster, w);
    if (sliver) {
        w.runEntry = merged ? w.runEntry : byte | (odd ? 1u << 16 : 0u);
        w.run = merged ? w.run : r;
        w.runLength = merged ? w.runLength + 1u : 1u;
        w.runLast = byte;
    }
    w.i0 = w.i1;
    w.p0 = w.p1;
    w.i1 = i2;
    w.p1 = p2;
    w.m0 = w.m1;
    w.m1 = decoded;
    w.position = restart ? 0u : w.position + 1u;
}

void decodeLeaf(ModelTable table, GeometryChunks chunks, uvec2 leaf)
{
    ClusterInfo cluster = clusterInfo(table, leaf.x);
    StripWalk w;
    w.i0 = w.i1 = 0u;
    w.p0 = w.p1 = vec4(0.0);
    w.m0 = w.m1 = vec3(0.0);
    w.position = 0u;
    w.runLength = w.runEntry = w.runLast = 0u;
    if (kTexelAccess != 0u) {
        // Strip bytes 16 a texel: an outer loop over the leaf's texels, an inner one over their bytes.
        const uint begin = uint(cluster.firstIndex) + (leaf.y & 0xFFFFu), end = begin + (leaf.y >> 16);
        for (uint block = begin >> 4; begin < end && block <= (end - 1u) >> 4; ++block) {
            const uvec4 bytes = texelFetch(modelStrips, int(block));
            const uint last = min(end, (block + 1u) << 4);
            for (uint byteIndex = max(begin, block << 4); byteIndex < last; ++byteIndex) {
                uint i2 = (bytes[(byteIndex >> 2) & 3u] >> ((byteIndex & 3u) << 3)) & 0xFFu;
                uvec3 q = vertexTexel(uint(cluster.firstVertex) + (i2 == 0xFFu ? 0u : i2)); // a restart reads vertex 0, which every cluster has
                precise vec3 scaled = vec3(q) * cluster.step;
                precise vec3 decoded = cluster.boxMin + scaled;
                stripByte(w, leaf.x, byteIndex - uint(cluster.firstIndex), i2, decoded);
            }
        }
    } else {
        LeafStrips strips = openLeaf(table, chunks, cluster, leaf.y);
        for (uint k = 0u; k < strips.count; ++k) {
            uint i2 = uint(strips.strips.bytes[k]);
            stripByte(w, leaf.x, (leaf.y & 0xFFFFu) + k, i2, decodeVertex(loadVertex(strips.vertices, i2 == 0xFFu ? 0u : i2), cluster.boxMin, cluster.step));
        }
    }
    listRun(leaf.x, w);
}

// Listed run `index`: the strip bytes from its first sliver's two earlier
// vertices to its last sliver decoded again, walked as stripByte walks them
// (restarts, degenerate triangles), and the slivers among them joined in the
// first one's frame (`run`; false when none passed sliverRect): every sliver
// between a run's first and last joined it when it was listed (an area
// light's run is one sliver, whose edges' depths `run` keeps).
bool listedRun(ModelTable table, uint index, out SliverRect run)
{
    uvec2 entry = thinTriangles[index];
    ClusterInfo cluster = clusterInfo(table, entry.x);
    uint byte = entry.y & 0xFFFFu;
    bool odd = ((entry.y >> 16) & 1u) != 0u;
    uint bytes = (entry.y >> 17) + 3u;
    LeafStrips strips;
    if (kTexelAccess == 0u)
        strips = openLeaf(table, geometryChunksOf(push.modelTable, table), cluster, byte - 2u);
    vec4 p[2] = vec4[2](vec4(0.0), vec4(0.0));
    vec3 m0 = vec3(0.0), m1 = vec3(0.0);
    uint i0 = 0u, i1 = 0u;
    // Bytes of the current strip before byte k, counted so that the first sliver (k = 2) gets its parity.
    uint position = odd ? 1u : 0u;
    bool have = false; // a rectangle in `run` (each of the run's slivers passed sliverRect when listed)
    for (uint k = 0u; k < bytes; ++k) {
        uint i2;
        vec3 v;
        if (kTexelAccess != 0u) {
            uint b = uint(cluster.firstIndex) + byte - 2u + k;
            uvec4 texel = texelFetch(modelStrips, int(b >> 4));
            i2 = (texel[(b >> 2) & 3u] >> ((b & 3u) << 3)) & 0xFFu;
            uvec3 q = vertexTexel(uint(cluster.firstVertex) + (i2 == 0xFFu ? 0u : i2)); // a restart reads vertex 0
            precise vec3 scaled = vec3(q) * cluster.step;
            precise vec3 decoded = cluster.boxMin + scaled;
            v = decoded;
        } else {
            i2 = uint(strips.strips.bytes[k]);
            v = decodeVertex(loadVertex(strips.vertices, i2 == 0xFFu ? 0u : i2), cluster.boxMin, cluster.step);
        }
        vec4 p2 = projectVertex(v);
        const bool restart = i2 == 0xFFu;
        if (!restart && position >= 2u && i0 != i1 && i1 != i2 && i0 != i2) {
            // The parity alternates along the strip.
            bool flip = ((position - 2u) & 1u) != 0u;
            vec4 a = flip ? p[1] : p[0], b = flip ? p[0] : p[1];
            SliverRect r;
            if (sliverRect(a, b, p2, m0, m1, v, r)) {
                run = have ? unionRect(run, r) : r;
                have = true;
            }
        }
        i0 = i1;
        i1 = i2;
        p[0] = p[1];
        p[1] = p2;
        m0 = m1;
        m1 = v;
        position = restart ? 0u : position + 1u;
    }
    return have;
}

// PENUMBRA_THIN_FILL: the subgroup's runs one after another, the lanes
// sharing each rectangle's rows (every 8th row each), so that the loops stay
// uniform: one invocation per run looping over its own rectangle kept most
// lanes idle behind the longest (llvmpipe runs a subgroup's loop as long as
// any lane is in it). A hard map's run is kept by the list phase (up to
// thinRectCapacity) or decoded again; an area light's sliver is always
// decoded again, and its per-texel depths come from its edges (zA, zB, zC,
// longest, along), shared with the rectangle.
void fillListedShared(ModelTable table, uint index, bool valid)
{
    SliverRect run;
    bool have;
    if (kLocalDepths == 0u && index < thinRectCapacity) {
        // Kept by the list phase: no decoding.
        const vec4 a = texelFetch(thinRectTexels, int(2u * index)), b = texelFetch(thinRectTexels, int(2u * index + 1u));
        run = SliverRect(a.xy, a.zw, vec2(-a.w, a.z), 0.0, b.x, 0.0, b.y, b.z, 0.0, 0.0, 0.0, 0.0, 0.0);
        have = valid;
    } else
        have = valid && listedRun(table, index, run);
    // A rectangle a few rows high (most single slivers) is filled by its own lane, beside the
    // others; the subgroup shares the rows of the taller ones.
    const float rows = (abs(run.d.y) * (run.d1 - run.d0) + abs(run.nrm.y) * (run.n1 - run.n0)) /
                       (kLocalDepths != 0u ? 1.0 : float(PENUMBRA_THIN_HARD_SCALE));
    const bool alone = have && rows <= PENUMBRA_THIN_ALONE_ROWS;
    if (alone)
        fillRect(0, 1, run);
    uvec4 pending = subgroupBallot(have && !alone);
    const int lane = int(gl_SubgroupInvocationID), lanes = int(gl_SubgroupSize);
    while (subgroupBallotBitCount(pending) != 0u) {
        uint s = subgroupBallotFindLSB(pending);
        pending[s >> 5u] &= ~(1u << (s & 31u));
        SliverRect r = run;
        r.A = subgroupShuffle(run.A, s);
        r.d = subgroupShuffle(run.d, s);
        r.nrm = subgroupShuffle(run.nrm, s);
        r.d0 = subgroupShuffle(run.d0, s);
        r.d1 = subgroupShuffle(run.d1, s);
        r.n0 = subgroupShuffle(run.n0, s);
        r.n1 = subgroupShuffle(run.n1, s);
        r.zMin = subgroupShuffle(run.zMin, s);
        if (kLocalDepths != 0u) {
            r.zA = subgroupShuffle(run.zA, s);
            r.zB = subgroupShuffle(run.zB, s);
            r.zC = subgroupShuffle(run.zC, s);
            r.longest = subgroupShuffle(run.longest, s);
            r.along = subgroupShuffle(run.along, s);
        }
        fillRect(lane, lanes, r);
    }
}

// PENUMBRA_THIN_LIST: each workgroup takes PENUMBRA_THIN_TRIANGLES_GROUP_SIZE BVH nodes and lists their
// leaves that may hold slivers; then each invocation decodes whole leaves of the list, one after
// another, and lists the slivers. PENUMBRA_THIN_FILL: one invocation per listed run, the subgroup's
// lanes filling each run's rectangle together (fillListedShared).
void main()
{
    ModelTable table = ModelTable(push.modelTable);
    if (kPhase == PENUMBRA_THIN_DISPATCH) {
        if (gl_LocalInvocationIndex != 0u)
            return;
        uint perGroup = PENUMBRA_THIN_TRIANGLES_GROUP_SIZE;
        uint groups = (min(thinCount, thinCapacity) + perGroup - 1u) / perGroup;
        uint x = min(groups, 65535u);
        thinDispatch[0] = x;
        thinDispatch[1] = x == 0u ? 1u : (groups + x - 1u) / x;
        thinDispatch[2] = 1u;
        return;
    }
    uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (kPhase == PENUMBRA_THIN_FILL) {
        uint index = group * PENUMBRA_THIN_TRIANGLES_GROUP_SIZE + gl_LocalInvocationIndex;
        bool valid = index < min(thinCount, thinCapacity);
        fillListedShared(table, index, valid);
        return;
    }
    const uint lane = gl_LocalInvocationIndex;
    // The nodes in interleaved chunks (config.h): the slivers lie in some parts of the model.
    group = interleavedChunk(group, (push.nodeCount + PENUMBRA_THIN_TRIANGLES_GROUP_SIZE - 1u) / PENUMBRA_THIN_TRIANGLES_GROUP_SIZE);
    if (lane == 0u)
        passingCount = 0u;
    barrier();
    // Groups may be laid out in 2D when the nodes exceed maxComputeWorkGroupCount[0].
    uint index = group * PENUMBRA_THIN_TRIANGLES_GROUP_SIZE + lane;
    if (index < push.nodeCount) {
        WideNode node;
        uint record = 0u;    // kGeometryBudget: the node's record in the pool
        bool present = true; // kGeometryBudget: its cluster is resident (the pass skips the others)
        if (kGeometryBudget != 0u) {
            const uint word = texelFetch(modelNodeTable, int(index)).x;
            present = (word & PENUMBRA_NODE_ABSENT) == 0u;
            record = present ? word : 0u;
            node = nodeTexelsAt(record);
        } else if (kTexelAccess != 0u)
            node = nodeTexels(index);
        else
            node = loadNode(NodeChunks(table, table.nodeChunks[0], table.nodeChunkShift), index);
        const uint cluster = present ? nodeCluster(node) : PENUMBRA_NO_CLUSTER;
        // A cluster whose footprint lies 2 texels or more from every camera pixel's
        // point cannot write a texel that is read (receiver masks, culling.h).
        bool near = cluster != PENUMBRA_NO_CLUSTER &&
                    (push.clusterMask == 0ul || (ClusterMask(push.clusterMask).bits[cluster >> 5u] & (1u << (cluster & 31u))) != 0u);
        for (uint slot = 0u; slot < 4u; ++slot)
            if (near && childKindOf(node, slot) == PENUMBRA_CHILD_LEAF && mayHoldSlivers(table, index, slot, cluster, record))
                passingLeaves[atomicAdd(passingCount, 1u)] = uvec2(cluster, node.w3[slot]);
    }
    barrier();
    const uint leafCount = passingCount;
    GeometryChunks chunks = kTexelAccess != 0u ? GeometryChunks(0ul) : geometryChunksOf(push.modelTable, table);
    for (uint j = lane; j < leafCount; j += PENUMBRA_THIN_TRIANGLES_GROUP_SIZE)
        decodeLeaf(table, chunks, passingLeaves[j]);
}
