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
    uint dispatch[3];
    uint rayPixels[];
};
layout(set = 0, binding = 5, std430) buffer Stats { uint64_t stats[]; };

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
    uint pad0, pad1;
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
    if (kGeometryBudget == 0u)
        return modelOccludes(push.boundsMin.xyz, push.boundsMax.xyz, ray, counters);
    const bool parkedBefore = gParked;
    gParked = false;
    const bool hit = modelOccludes(push.boundsMin.xyz, push.boundsMax.xyz, ray, counters);
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

// 1 lit, 0 shadowed; counts the ray when one is traced.
float traceVisibility(uint pixelIndex, bool oneSample, inout uint rays, inout TraceCounters counters)
{
    uint width = uint(imageSize(surfaceImage).x);
    ivec2 pixel = ivec2(pixelIndex % width, pixelIndex / width);
    const uvec4 surface = imageLoad(surfaceImage, pixel);
    if (!surfaceCovered(surface))
        return 1.0; // background: nothing to shadow (compaction never lists it)
    const vec3 position = surfacePosition(surface);
    vec3 normal = surfaceNormal(surface);

    LightData light = frame.lights[push.lightIndex];
    if (kSoft != 0u)
        return traceSoftVisibility(pixel, position.xyz, normal, light, oneSample, rays, counters);
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
    // The G-buffer normal faces the camera: a surface seen from its side
    // facing away from the light is unlit (no ray).
    if (dot(normal, direction) <= 0.0)
        return 0.0;
    ++rays;
    ShadowRay ray = makeShadowRay(position.xyz + normal * push.originOffset, direction, tMax);
    return occluded(ray, counters) ? 0.0 : 1.0;
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
    uint index = group * PENUMBRA_TRACE_GROUP_SIZE + gl_LocalInvocationIndex;
    uint rays = 0u;
    TraceCounters counters = TraceCounters(0u, 0u, 0u);
    if (index < rayCount) {
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
