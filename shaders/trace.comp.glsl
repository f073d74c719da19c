// Shadow rays of the listed pixels toward one light (Lauterbach et al. 2009,
// section 3.1: the ray-traced pass of selective shadows; section 5.1: traversal
// of the compressed model). One invocation per ray of the list written by
// compaction; writes visibility 1 (lit) or 0 (shadowed or facing away from the
// light) for every listed pixel; accumulates traversal counters.
#version 460
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_8bit_storage : require
#extension GL_EXT_shader_16bit_storage : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_vote : require
#extension GL_KHR_shader_subgroup_shuffle : require
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_int64 : require

#include "config.h"
// 1: the model is read through texel buffers (bvh_texels.glsli, GpuGeometry::texelsComplete); 0: by device address.
layout(constant_id = 0) const uint kTexelAccess = 0u;
// 1: the vertices' texel view is R16_UINT, three texels a vertex (GpuGeometry::vertexTexelsSplit).
layout(constant_id = 1) const uint kSplitVertexTexels = 0u;
// Specialized per light as well: llvmpipe runs every branch of a shader, taken or not.
layout(constant_id = 2) const uint kSoft = 0u;                          // push.samples != 0
layout(constant_id = 3) const uint kLightType = PENUMBRA_LIGHT_POINT; // PENUMBRA_LIGHT_*
// 1: paged geometry (RendererOptions::geometryBudgetBytes, geometry_pages.h): a ray that reaches a
// cluster that is not resident is parked; 0 (no budget): the check is compiled out.
layout(constant_id = 4) const uint kGeometryBudget = 0u;
// List entries per invocation: hard shadows without paging PENUMBRA_TRACE_RAYS_CPU or _GPU by the device type
// (TracePass::raysPerInvocation), in rounds (traceHardRounds); 1 otherwise.
layout(constant_id = 5) const uint kRays = 1u;
layout(set = 0, binding = 6) uniform usamplerBuffer modelNodes;
layout(set = 0, binding = 7) uniform usamplerBuffer modelClusters;
layout(set = 0, binding = 8) uniform usamplerBuffer modelVertices;
layout(set = 0, binding = 9) uniform usamplerBuffer modelStrips;
// kGeometryBudget: per node, its record's first texel in modelNodes (the pool), or cluster | PENUMBRA_NODE_ABSENT.
layout(set = 0, binding = 10) uniform usamplerBuffer modelNodeTable;
#include "bvh_traversal.glsli"
#include "bvh_texels.glsli"

// GeometryPages' parking buffer: the parked count, one bit per cluster any ray of the dispatch
// visited (resident or not), then the parked rays' list entries.
layout(buffer_reference, std430, buffer_reference_align = 16) buffer Parking
{
    uint parkedCount;
    uint parkingPad[3];
    uint parkingWords[]; // push.clusterWords visited bits, then the parked entries
};
bool gParked = false;
uint gMarked = PENUMBRA_NO_CLUSTER; // the cluster this lane marked visited last (marks repeat within a cluster's subtree)
void markVisited(uint cluster);

// The model's access for bvh_wide.glsli: texel fetches, or device addresses
// through the model table (set up in main).
ModelTable gTable;
GeometryChunks gChunks;
NodeChunks gNodeChunks;

// Paged: a node of a cluster that is not resident reads as a node without
// children; the ray is parked and the cluster marked, so that the frame
// script makes it resident before tracing the ray again. Every cluster the
// ray enters is marked: what a parked ray needs resident is what it visited.
WideNode traversalNode(uint index)
{
    if (kGeometryBudget != 0u) {
        const uint word = texelFetch(modelNodeTable, int(index)).x;
        const bool absent = (word & PENUMBRA_NODE_ABSENT) != 0u;
        WideNode node = nodeTexelsAt(absent ? 0u : word);
        const uint cluster = absent ? word & ~PENUMBRA_NODE_ABSENT : nodeCluster(node);
        if (cluster != PENUMBRA_NO_CLUSTER)
            markVisited(cluster);
        if (absent) {
            gParked = true;
            node.w0.w &= 0x00FFFFFFu; // every child slot empty
        }
        return node;
    }
    return kTexelAccess != 0u ? nodeTexels(index) : loadNode(gNodeChunks, index);
}
ClusterInfo traversalCluster(uint cluster)
{
    return kTexelAccess != 0u ? clusterTexels(cluster) : loadCluster(gTable, cluster);
}
bool traversalResident(ClusterInfo cluster);
bool traversalLeaf(ShadowRay ray, ClusterInfo cluster, uint leaf, inout TraceCounters counters)
{
    return kTexelAccess != 0u ? leafOccludesTexels(ray, cluster, leaf, counters) : leafOccludes(gTable, gChunks, ray, cluster, leaf, counters);
}
#include "bvh_wide.glsli"
#include "shadow_common.glsli"
#include "penumbra/light_sampling.h"

layout(local_size_x = PENUMBRA_TRACE_GROUP_SIZE) in;

#include "surface.glsli"
layout(set = 0, binding = 0, rgba32ui) uniform readonly uimage2D surfaceImage; // binding 1, the G-buffer's albedo, is not read
layout(set = 0, binding = 2, r32f) uniform image2D visibilityImage; // read back by the later sample dispatches
layout(set = 0, binding = 3, std140) uniform Frame { FrameData frame; };
layout(set = 0, binding = 4, std430) readonly buffer RayList
{
    uint rayCount;
    uint dispatch[3];       // one entry an invocation
    uint roundsDispatch[3]; // kRays entries an invocation
    uint listPad;
    uint rayPixels[];
};
layout(set = 0, binding = 5, std430) buffer Stats { uint64_t stats[]; };
// Hard shadows in rounds (traceHardRounds): the rounds whose rays all had hints to test, and those of
// them whose tests left a ray to traverse (cleared before the first dispatch), then each invocation's
// hint between its dispatches.
layout(set = 0, binding = 11, std430) buffer Hints
{
    uint hintRounds;
    uint hintMisses;
    uint hintPad[2];
    uvec2 hints[];
};

layout(push_constant) uniform Push
{
    uint64_t modelTable;  // device address of the model table (bvh_traversal.glsli)
    uint lightIndex;      // into frame.lights
    float originOffset;   // model units along the normal
    uint samples;         // area lights: light samples per pixel (soft shadows); 0: one ray to the light
    uint clusterWords;    // kGeometryBudget: words of the visited bits
    uint64_t parking;     // kGeometryBudget: Parking's device address
    vec4 boundsMin;       // the root node's box (xyz)
    vec4 boundsMax;
    uint sampleBegin;     // area lights: the light samples [sampleBegin, sampleEnd) of this dispatch (see traceSoftVisibility)
    uint sampleEnd;
    uint roundBegin;      // hard shadows in rounds: the rounds [roundBegin, roundBegin + PENUMBRA_TRACE_ROUNDS_PER_DISPATCH) of this dispatch
    uint pad1;
} push;

void markVisited(uint cluster)
{
    if (cluster == gMarked)
        return;
    gMarked = cluster;
    Parking parking = Parking(push.parking);
    atomicOr(parking.parkingWords[cluster >> 5], 1u << (cluster & 31u));
}

// A node's leaves are in its page, resident with it (traversalNode parks rays at absent nodes).
bool traversalResident(ClusterInfo cluster)
{
    return true;
}

// Paged geometry: a ray that skipped a cluster that is not resident is parked,
// unless it hit (any-hit: a hit is exact whatever it skipped).
bool occluded(ShadowRay ray, inout TraceCounters counters)
{
    uvec2 hitLeaf = uvec2(PENUMBRA_NO_CLUSTER, 0u);
    if (kGeometryBudget == 0u)
        return modelOccludes(push.boundsMin.xyz, push.boundsMax.xyz, ray, counters, hitLeaf);
    const bool parkedBefore = gParked;
    gParked = false;
    const bool hit = modelOccludes(push.boundsMin.xyz, push.boundsMax.xyz, ray, counters, hitLeaf);
    gParked = parkedBefore || (gParked && !hit);
    return hit;
}

// Soft shadows (area lights): the fraction of the pixel's light samples
// (penumbra/light_sampling.h, seeded by the pixel) that no triangle blocks;
// samples below the pixel's plane count as blocked and get no ray. This
// dispatch traces samples [push.sampleBegin, push.sampleEnd) and returns
// their share of the fraction (the dispatches add up: TracePass::record):
// lavapipe stops every loop of an invocation after 65,535 iterations in all,
// which 256 traversals of a large model can exceed.
// oneSample: the pixel is outside the penumbra mask, so all samples agree: sample 0 decides (the first dispatch).
float traceSoftVisibility(ivec2 pixel, vec3 p, vec3 normal, LightData light, bool oneSample, inout uint rays, inout TraceCounters counters)
{
    if (!inFrontOfEmitter(light, p))
        return 0.0;
    const uint shape = kLightType;
    uint seed = sampleSeed(uint(pixel.x), uint(pixel.y), push.lightIndex);
    uint visible = 0u;
    uint traced = oneSample ? 1u : push.samples;
    for (uint i = push.sampleBegin; i < min(traced, push.sampleEnd); ++i) {
        vec3 target = areaLightPoint(shape, light.positionType.xyz, light.areaU.xyz, light.areaV.xyz, p,
                                     stratifiedSample(seed, i, push.samples));
        vec3 direction = target - p;
        float distance = length(direction);
        direction /= max(distance, 1e-30);
        if (dot(normal, direction) <= 0.0)
            continue;
        ++rays;
        ShadowRay ray = makeShadowRay(p + normal * push.originOffset, direction, distance - push.originOffset);
        if (!occluded(ray, counters))
            ++visible;
    }
    return float(visible) / float(traced);
}

// A hard light's ray for a listed pixel: false when none is needed, with
// the pixel's visibility (background 1; facing away from the light 0).
bool hardRay(uint pixelIndex, out ShadowRay ray, out float visibility)
{
    uint width = uint(imageSize(surfaceImage).x);
    ivec2 pixel = ivec2(pixelIndex % width, pixelIndex / width);
    const uvec4 surface = imageLoad(surfaceImage, pixel);
    const vec3 position = surfacePosition(surface);
    vec3 normal = surfaceNormal(surface);
    LightData light = frame.lights[push.lightIndex];
    const uint type = kLightType;
    vec3 direction;
    float tMax;
    if (type == PENUMBRA_LIGHT_DIRECTIONAL) {
        direction = -normalize(light.directionRange.xyz);
        tMax = uintBitsToFloat(0x7F800000u); // +inf
    } else {
        direction = light.positionType.xyz - position.xyz;
        float distance = length(direction);
        direction /= max(distance, 1e-30);
        tMax = distance - push.originOffset;
    }
    ray = makeShadowRay(position.xyz + normal * push.originOffset, direction, tMax);
    // The G-buffer normal faces the camera: a surface seen from its side
    // facing away from the light is unlit (no ray).
    visibility = !surfaceCovered(surface) ? 1.0 : 0.0;
    return surfaceCovered(surface) && dot(normal, direction) > 0.0;
}

// 1 lit, 0 shadowed; counts the ray when one is traced.
float traceVisibility(uint pixelIndex, bool oneSample, inout uint rays, inout TraceCounters counters)
{
    if (kSoft != 0u) {
        uint width = uint(imageSize(surfaceImage).x);
        ivec2 pixel = ivec2(pixelIndex % width, pixelIndex / width);
        const uvec4 surface = imageLoad(surfaceImage, pixel);
        if (!surfaceCovered(surface))
            return 1.0; // background: nothing to shadow (compaction never lists it)
        LightData light = frame.lights[push.lightIndex];
        return traceSoftVisibility(pixel, surfacePosition(surface), surfaceNormal(surface), light, oneSample, rays, counters);
    }
    ShadowRay ray;
    float visibility;
    if (!hardRay(pixelIndex, ray, visibility))
        return visibility;
    ++rays;
    return occluded(ray, counters) ? 0.0 : 1.0;
}

void storeVisibility(uint pixelIndex, float visibility)
{
    uint width = uint(imageSize(visibilityImage).x);
    imageStore(visibilityImage, ivec2(pixelIndex % width, pixelIndex / width), vec4(visibility));
}

// The list entry of round k of this invocation (kRays > 1): a subgroup takes
// kRays x its size consecutive entries (neighbouring pixels: compaction lists
// 2x2 quads of 8x8 tiles), its lanes the subgroup's size of consecutive ones
// each round, so that a SIMD register's rays stay as coherent as with one ray
// an invocation. Only CPU devices (lavapipe: 8 lanes, workgroups of whole
// subgroups) get kRays > 1.
uint roundEntry(uint group, uint k)
{
    const uint lane = gl_LocalInvocationIndex % gl_SubgroupSize;
    return group * PENUMBRA_TRACE_GROUP_SIZE * kRays + (gl_LocalInvocationIndex - lane) * kRays + k * gl_SubgroupSize + lane;
}

// A hint shuffled from lane ^ mask of the subgroup, when that lane exists.
uvec2 laneHint(uvec2 hint, uint mask)
{
    const uvec2 other = subgroupShuffleXor(hint, mask);
    return mask < gl_SubgroupSize ? other : uvec2(PENUMBRA_NO_CLUSTER, 0u);
}

// Hard shadows in rounds (kRays > 1): a shadow ray is most often blocked by
// what blocked the rays a few pixels away. Each lane keeps the leaf that held
// its last hit (the hint); a lane without one takes its neighbour's (lane ^
// 1, ^ 2, ^ 4). When every lane with a ray holds a hint, each tests its
// hint's leaf first, and only the rays it does not block are traversed: a
// round whose rays are all blocked by their hints skips the traversal. When
// some lane has no hint the traversal runs anyway (on a CPU device a SIMD
// register runs as long as its slowest lane), so no hint is tested. Every
// lane takes part in every round (the shuffles read every lane).
// A dispatch runs PENUMBRA_TRACE_ROUNDS_PER_DISPATCH rounds (lavapipe's loop
// limit); between dispatches an invocation keeps its hint in `hints`.
void traceHardRounds(uint group, inout uint rays, inout TraceCounters counters)
{
    // An invocation holds a hint when its first entry is listed (a 2-D dispatch has groups past the list's end;
    // TracePass::hintBytes counts the others).
    const uint invocation = group * PENUMBRA_TRACE_GROUP_SIZE + gl_LocalInvocationIndex;
    const bool holds = roundEntry(group, 0u) < rayCount;
    uvec2 hint = uvec2(PENUMBRA_NO_CLUSTER, 0u);
    if (push.roundBegin != 0u && holds)
        hint = hints[invocation];
    // After the first dispatch, the hints are tested only where they have spared the traversal in at
    // least a quarter of the rounds that tested them so far (scenes whose rays are mostly lit, or
    // blocked by small triangles, lose the tests).
    const bool hinting = push.roundBegin == 0u || 4u * (hintRounds - hintMisses) >= hintRounds;
    const uint roundEnd = min(push.roundBegin + PENUMBRA_TRACE_ROUNDS_PER_DISPATCH, kRays);
    uint wait = hinting ? 0u : kRays; // rounds left without hint tests (after one that failed)
    for (uint k = push.roundBegin; k < roundEnd; ++k) {
        const uint index = roundEntry(group, k);
        const bool listed = index < rayCount;
        const uint pixelIndex = listed ? rayPixels[index] & ~PENUMBRA_RAY_ONE_SAMPLE : 0u;
        ShadowRay ray;
        float visibility;
        bool pending = hardRay(pixelIndex, ray, visibility) && listed;
        rays += pending ? 1u : 0u;
        const uvec2 h1 = laneHint(hint, 1u), h2 = laneHint(hint, 2u), h4 = laneHint(hint, 4u); // every lane takes part
        hint = hint.x != PENUMBRA_NO_CLUSTER ? hint : h1.x != PENUMBRA_NO_CLUSTER ? h1 : h2.x != PENUMBRA_NO_CLUSTER ? h2 : h4;
        const bool test = wait == 0u && subgroupAny(pending) && subgroupAll(!pending || hint.x != PENUMBRA_NO_CLUSTER);
        if (test && pending) {
            ++counters.leaves;
            pending = !traversalLeaf(ray, traversalCluster(hint.x), hint.y, counters);
            visibility = 0.0;
        }
        const bool traverse = subgroupAny(pending);
        if (test && subgroupElect()) {
            atomicAdd(hintRounds, 1u);
            if (traverse)
                atomicAdd(hintMisses, 1u);
        }
        wait = test && traverse ? PENUMBRA_TRACE_HINT_BACKOFF : wait > 0u ? wait - 1u : 0u;
        if (pending) {
            hint = uvec2(PENUMBRA_NO_CLUSTER, 0u);
            visibility = modelOccludes(push.boundsMin.xyz, push.boundsMax.xyz, ray, counters, hint) ? 0.0 : 1.0;
        }
        if (listed)
            storeVisibility(pixelIndex, visibility);
    }
    if (roundEnd < kRays && holds)
        hints[invocation] = hint;
}

void main()
{
    if (kTexelAccess == 0u) {
        gTable = ModelTable(push.modelTable);
        gChunks = geometryChunksOf(push.modelTable, gTable);
        gNodeChunks = NodeChunks(gTable, gTable.nodeChunks[0], gTable.nodeChunkShift);
    }
    // Groups may be laid out in 2D when the list exceeds maxComputeWorkGroupCount[0].
    uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    uint rays = 0u;
    TraceCounters counters = TraceCounters(0u, 0u, 0u);
    // TracePass::record gives kRays > 1 to hard shadows without paging alone.
    uint index = group * PENUMBRA_TRACE_GROUP_SIZE + gl_LocalInvocationIndex;
    if (kRays > 1u) {
        traceHardRounds(group, rays, counters);
    } else if (index < rayCount) {
        uint entry = rayPixels[index];
        uint pixelIndex = entry & ~PENUMBRA_RAY_ONE_SAMPLE;
        float visibility = traceVisibility(pixelIndex, (entry & PENUMBRA_RAY_ONE_SAMPLE) != 0u, rays, counters);
        uint width = uint(imageSize(visibilityImage).x);
        ivec2 pixel = ivec2(pixelIndex % width, pixelIndex / width);
        // A later dispatch of an area light's samples adds its share (fractions k / samples: exact).
        if (kSoft != 0u && push.sampleBegin != 0u)
            visibility += imageLoad(visibilityImage, pixel).r;
        imageStore(visibilityImage, pixel, vec4(visibility));
        if (kGeometryBudget != 0u && gParked) {
            // Its visibility is written again when it is traced again (an any-hit ray that hit is exact and never parked).
            Parking parking = Parking(push.parking);
            parking.parkingWords[push.clusterWords + atomicAdd(parking.parkedCount, 1u)] = entry;
        }
    }
    uint totalRays = subgroupAdd(rays);
    uint totalNodes = subgroupAdd(counters.nodes);
    uint totalLeaves = subgroupAdd(counters.leaves);
    uint totalTriangles = subgroupAdd(counters.triangles);
    if (subgroupElect() && totalRays > 0u) {
        atomicAdd(stats[PENUMBRA_STAT_RAYS], uint64_t(totalRays));
        atomicAdd(stats[PENUMBRA_STAT_NODES], uint64_t(totalNodes));
        atomicAdd(stats[PENUMBRA_STAT_LEAVES], uint64_t(totalLeaves));
        atomicAdd(stats[PENUMBRA_STAT_TRIANGLES], uint64_t(totalTriangles));
    }
}
