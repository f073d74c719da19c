#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_ballot : require
// Penumbra mask of an area light (Lauterbach et al. 2009, 3.2): edge texels of
// a shadow map from a point of the light, found as for hard shadows (depth
// discontinuity over the 3x3 neighbourhood, or a thin triangle in front), are
// splatted with the light's projected shape into a mask; camera pixels that
// project into the mask, behind the splat's occluder far enough for the
// splat to reach them, get light samples traced; the others are umbra or lit
// by the shadow map.
//
// Splat of an edge at occluder point E (relative to the map's eye, e): a
// receiver P is in the penumbra of that edge when E lies on a segment from P
// to a light point S, so P's direction is that of e - k s', s' = S - eye,
// k = 1 - depth(E - eye, s') / depth(P - eye, s') in [0, kmax],
// kmax = (far - z) / (far - Rbig) with z the edge's depth and Rbig the
// farthest light point from the eye. The light shape contains the eye's point
// (centre or corner), so the union over k is the convex polygon e - kmax (shape
// - eye), projected into the map exactly (rectangle: 4 corners; disk: the
// octagon around it; sphere: the octagon around its silhouette).
//
// Cost is kept bounded with a min-depth pyramid: the splat of a block of
// texels at the nearest depth in it covers every edge of the block (nearer
// edges splat wider, and the block's extent is added as dilation). An edge
// splats at level 0 when its splat is under 4 texels in radius, otherwise its
// level-L block does when that block's splat is 2..4 level-L texels (the top
// level: 2 or more). Each splat is written at the mask level where it spans at
// most PENUMBRA_MASK_TARGET_TEXELS texels.
//
// The mask is receiver-aware: the splat for receivers at depth d is the
// polygon scaled by k(d) / kmax about e's texel (k grows with d), so each mask
// texel keeps the smallest receiver depth any splat reaches it at (atomicMin
// on the float bits): lambda, the smallest scale at which the dilated polygon
// touches the texel, from the separating axes; then with k = lambda kmax,
// d >= (z - k Rbig) / (1 - k). A pixel is in the mask when its depth in the
// map is at least the value of its texel on some level: a last stage pushes
// each level's minimum down to the finer one (PENUMBRA_MASK_STAGE_PUSH_DOWN,
// coarsest first, as far as level 1), so a pixel reads two values.
//
// PENUMBRA_MASK_STAGE_EDGES: one invocation per level-1 texel (its 2x2 children);
// writes the level-1 minimum. PENUMBRA_MASK_STAGE_REDUCE: the children at `level` of one
// level+1 texel; writes the level+1 minimum. Both append the blocks that
// splat (and the top level's) to a job list: splats vary in cost, so they run
// in a pass of their own over the dense list (PENUMBRA_MASK_STAGE_SPLAT, dispatched
// indirectly; PENUMBRA_MASK_STAGE_WRITE_DISPATCH writes its size) rather than idling the
// neighbouring invocations of a SIMD group.
// Splats skip regions where no camera pixel lies behind the occluder (the
// receivers buffer, written by classify_soft mode 4 before this pass), and
// are drawn only as far as the deepest such pixel can reach (the polygon
// scaled down about its centre), at the mask level that extent asks for.
//
// Thin triangles splat into a mask of their own that classify_soft applies
// only to pixels the map does not hide: a pixel deeper than every depth of
// its texel's 3x3 neighbourhood (by the edge threshold) lies behind a
// surface of the map, so a ray from it toward the light can reach the light
// only where the map's depths break (a depth-discontinuity edge, whose
// splats are in the first mask); an occluder in front of that surface
// changes nothing. The deepest receiver per tile is kept for both sets of
// pixels (receivers[] then receivers[tiles^2 + ...]).

#include "config.h"
#include "shadow_common.glsli"
#include "penumbra_mask.glsli"

layout(local_size_x = PENUMBRA_MASK_GROUP_SIZE, local_size_y = PENUMBRA_MASK_GROUP_SIZE) in;

// One pipeline per stage, light type and thin-triangle use: llvmpipe runs
// every branch of a shader masked, so a stage chosen by a push constant would
// pay for the splat code in every reduction invocation (and for all three
// light shapes in every splat).
layout(constant_id = 0) const uint kStage = PENUMBRA_MASK_STAGE_EDGES; // PENUMBRA_MASK_STAGE_*
layout(constant_id = 1) const uint kLightType = PENUMBRA_LIGHT_SPHERE;  // rectangle, disk or sphere
layout(constant_id = 2) const uint kUseThin = 0u;                       // push.useThin
const uint kKinds = kUseThin != 0u ? 2u : 1u; // edge kinds that can splat: discontinuities, thin triangles

layout(set = 0, binding = 0) uniform sampler2DArray shadowMap;
layout(set = 0, binding = 1, r32ui) uniform readonly uimage2DArray thinMap; // last layer: per-texel sliver depths
layout(set = 0, binding = 2, std140) uniform Frame { FrameData frame; };
layout(set = 0, binding = 3, std430) buffer Pyramid { float pyramid[]; }; // min occluder depth, levels 1..top, per edge kind
layout(set = 0, binding = 6, std430) buffer Jobs
{
    uint jobCount;
    uint jobDispatch[3];   // indirect dispatch of the splat pass
    uvec2 jobs[];          // x: level << 28 | y << 14 | x of the block; y: float bits of its nearest edge depth,
                           // | 0x80000000 for thin triangles
};
layout(set = 0, binding = 5, std430) readonly buffer Receivers { uint receivers[]; }; // per tile: float bits of the deepest camera
                                                                                     // pixel; then of those the map does not hide
layout(set = 0, binding = 4, std430) buffer Mask { uint mask[]; };        // word 0: flags; then per texel of levels 0..top the
                                                                          // float bits of the nearest receiver depth reached
layout(set = 0, binding = 7, std430) buffer ThinMask { uint thinMask[]; }; // the same for thin triangles' splats (no flags)

layout(push_constant) uniform MaskPush {
    mat4 invViewProj;  // inverse of the map's viewProj
    uint lightIndex;
    uint slot;         // which map of the light (viewProj[slot], mapEye[slot])
    uint level;        // STAGE_EDGES: 0; STAGE_REDUCE: the source level of this reduction
    uint mapSize;      // texels per side
    uint topLevel;     // level of size 1
    uint useThin;      // 1: thin triangles (thin map) are edges too (= kUseThin)
    float edgeDelta;   // depth discontinuity threshold, model units
    uint maxJobs;      // capacity of the job list
} push;


const float kNoEdge = 3.0e38;

LightData gLight;
float gNear, gFar, gRbig, gTexelAngle;

float kMax(float z)
{
    return clamp((gFar - z) / max(gFar - gRbig, 1e-6 * gFar), 0.0, 1.0);
}

// Splat radius in level-L texels (map-centre texel angle; monotone in z, all the level choice needs).
float splatRadius(float z, uint level)
{
    return kMax(z) * gRbig / max(z, 1e-30) / (gTexelAngle * float(1u << level));
}

void setReceiverDepth(uint kind, uint texel, float depth)
{
    uint bits = floatBitsToUint(max(depth, 0.0));
    // Most splats overlap: skip the atomic when it would change nothing.
    if (kind == 0u) {
        if (mask[1u + texel] > bits)
            atomicMin(mask[1u + texel], bits);
    } else if (thinMask[texel] > bits)
        atomicMin(thinMask[texel], bits);
}

// Deepest camera pixel (light-view depth) over the texels [lo, hi) of the map,
// of all pixels (kind 0) or of those the map does not hide (kind 1); +inf
// when the region spans too many tiles to look at.
float deepestReceiver(uint kind, vec2 lo, vec2 hi)
{
    uint tiles = (push.mapSize + PENUMBRA_RECEIVER_TILE - 1u) / PENUMBRA_RECEIVER_TILE;
    uint base = kind * tiles * tiles;
    uvec2 first = uvec2(max(lo, vec2(0.0))) / PENUMBRA_RECEIVER_TILE;
    uvec2 last = min(uvec2(max(hi - 1e-3, lo)) / PENUMBRA_RECEIVER_TILE, uvec2(tiles - 1u));
    if ((last.x - first.x + 1u) * (last.y - first.y + 1u) > 64u)
        return 3.0e38;
    float deepest = 0.0;
    for (uint y = first.y; y <= last.y; ++y)
        for (uint x = first.x; x <= last.x; ++x)
            deepest = max(deepest, uintBitsToFloat(receivers[base + y * tiles + x]));
    return deepest;
}

void markWholeMap()
{
    atomicOr(mask[0], 1u);
}

// Splats the block c of `level` whose nearest edge of `kind` lies at light-view
// depth z. Level 0: c is the occluder's texel.
void splat(uvec2 c, uint level, float z, uint kind)
{
    uint S = push.mapSize;
    float blockSize = float(1u << level);
    vec2 lo = vec2(c) * blockSize;
    vec2 hi = min(lo + blockSize, vec2(float(S)));
    vec2 centreTexel = 0.5 * (lo + hi);
    // The occluder lies within the block; the margin covers the splat's departure from a projected polygon.
    float dilation = 0.5 * max(hi.x - lo.x, hi.y - lo.y) + (level == 0u ? 0.25 : 0.0);
    if (z <= gRbig * 1.0001) {
        markWholeMap(); // an occluder within the light's reach: its penumbra can cover anything
        return;
    }
    vec3 eye = lightMapEye(gLight, push.slot).xyz;
    float ndcZ = gFar * (z - gNear) / (z * (gFar - gNear));
    vec4 world = push.invViewProj * vec4(centreTexel / float(S) * 2.0 - 1.0, ndcZ, 1.0);
    vec3 e = world.xyz / world.w - eye;
    float k = kMax(z);
    vec3 toCentre = gLight.positionType.xyz - eye;
    const uint type = kLightType;

    vec3 corners[8];
    uint count = 8u;
    const float octagon = 1.0823922; // 1 / cos(pi / 8): the octagon around the unit circle
    if (type == PENUMBRA_LIGHT_RECTANGLE) {
        count = 4u;
        vec3 u = gLight.areaU.xyz, v = gLight.areaV.xyz;
        corners[0] = e - k * (toCentre + u + v);
        corners[1] = e - k * (toCentre - u + v);
        corners[2] = e - k * (toCentre - u - v);
        corners[3] = e - k * (toCentre + u - v);
    } else if (type == PENUMBRA_LIGHT_DISK) {
        for (uint j = 0u; j < 8u; ++j) {
            float angle = float(j) * 0.78539816;
            corners[j] = e - k * (toCentre + octagon * (cos(angle) * gLight.areaU.xyz + sin(angle) * gLight.areaV.xyz));
        }
    } else {
        // The ball e - k (toCentre + s), |s| <= R, seen from the eye: its silhouette disk.
        vec3 ballCentre = e - k * toCentre;
        float radius = k * gLight.areaU.x;
        float d = length(ballCentre);
        if (d <= radius * 1.0001) {
            markWholeMap();
            return;
        }
        float silhouette = radius * d / sqrt(d * d - radius * radius);
        vec3 w = ballCentre / d;
        vec3 b1 = normalize(abs(w.x) < 0.9 ? cross(w, vec3(1, 0, 0)) : cross(w, vec3(0, 1, 0)));
        vec3 b2 = cross(w, b1);
        for (uint j = 0u; j < 8u; ++j) {
            float angle = float(j) * 0.78539816;
            corners[j] = ballCentre + octagon * silhouette * (cos(angle) * b1 + sin(angle) * b2);
        }
    }

    SplatPolygon polygon;
    polygon.count = count;
    for (uint j = 0u; j < count; ++j) {
        vec4 clip = lightViewProj(gLight, push.slot) * vec4(eye + corners[j], 1.0);
        if (clip.w <= 1e-6 * gNear) {
            markWholeMap(); // reaches behind the eye: unbounded in the map
            return;
        }
        polygon.points[j] = (clip.xy / clip.w * 0.5 + 0.5) * float(S);
    }
    preparePolygon(polygon);
    vec4 centreClip = lightViewProj(gLight, push.slot) * vec4(eye + e, 1.0);
    vec2 centre = (centreClip.xy / centreClip.w * 0.5 + 0.5) * float(S);
    // The polygon's interval on each axis relative to the centre (scales linearly).
    vec2 relative[8];
    for (uint j = 0u; j < count; ++j)
        relative[j] = polygon.range[j] - dot(centre, polygon.axes[j]);
    vec2 relativeLo = polygon.lo - centre, relativeHi = polygon.hi - centre;
    vec2 boxMin = max(polygon.lo - dilation, vec2(0.0));
    vec2 boxMax = min(polygon.hi + dilation, vec2(float(S)));
    if (any(greaterThanEqual(boxMin, boxMax)))
        return;
    // Only camera pixels behind the occluder can be in its penumbra, and a
    // receiver at depth d reaches the polygon scaled by at most k(d) / (0.9 k)
    // (see the receiver depth below): the deepest one bounds the extent.
    float deepest = deepestReceiver(kind, boxMin, boxMax);
    if (deepest < z)
        return;
    if (deepest < 1.0e38) {
        float reach = min((deepest - z) / max(deepest - gRbig, 1e-30) / (0.9 * max(k, 1e-30)), 1.0);
        boxMin = max(centre + reach * relativeLo - dilation, boxMin);
        boxMax = min(centre + reach * relativeHi + dilation, boxMax);
        if (any(greaterThanEqual(boxMin, boxMax)))
            return;
    }
    float extent = max(boxMax.x - boxMin.x, boxMax.y - boxMin.y);
    uint target = uint(clamp(ceil(log2(max(extent / PENUMBRA_MASK_TARGET_TEXELS, 1.0))), 0.0, float(push.topLevel)));
    float targetSize = float(1u << target);
    uint size = maskLevelSize(S, target);
    uvec2 first = uvec2(boxMin / targetSize);
    uvec2 last = min(uvec2(max(ceil(boxMax / targetSize) - 1.0, vec2(0.0))), uvec2(size - 1u));
    uint base = maskLevelOffset(S, target);
    for (uint y = first.y; y <= last.y; ++y)
        for (uint x = first.x; x <= last.x; ++x) {
            float deepestHere = deepestReceiver(kind, vec2(x, y) * targetSize, vec2(x + 1u, y + 1u) * targetSize);
            if (deepestHere < z)
                continue;
            vec2 texelLo = vec2(x, y) * targetSize - dilation;
            vec2 texelHi = vec2(x + 1u, y + 1u) * targetSize + dilation;
            if (!polygonOverlapsBox(polygon, texelLo, texelHi))
                continue;
            // Smallest scale of the polygon about the centre that reaches the texel.
            float lambda = 0.0;
            for (uint a = 0u; a < 2u; ++a) {
                float lo = texelLo[a] - centre[a], hi = texelHi[a] - centre[a];
                if (lo > 0.0)
                    lambda = max(lambda, lo / max(relativeHi[a], 1e-30));
                if (hi < 0.0)
                    lambda = max(lambda, hi / min(relativeLo[a], -1e-30));
            }
            vec2 texelCentre = 0.5 * (texelLo + texelHi), texelHalf = 0.5 * (texelHi - texelLo);
            for (uint j = 0u; j < count; ++j) {
                float c = dot(texelCentre - centre, polygon.axes[j]);
                float r = dot(texelHalf, abs(polygon.axes[j]));
                if (c - r > 0.0)
                    lambda = max(lambda, (c - r) / max(relative[j].y, 1e-30));
                if (c + r < 0.0)
                    lambda = max(lambda, (c + r) / min(relative[j].x, -1e-30));
            }
            // 10% slack for the projection's departure from a uniform scaling.
            float kReach = min(lambda * 0.9, 1.0) * k;
            float receiver = kReach >= 1.0 ? 3.0e38 : (z - kReach * gRbig) / (1.0 - kReach);
            if (receiver <= deepestHere)
                setReceiverDepth(kind, base + y * size + x, receiver);
        }
}

float linearDepth(float ndc)
{
    return gFar * gNear / (gFar - ndc * (gFar - gNear));
}

// The 4x4 map depths around the 2x2 level-0 children of level-1 texel p
// (texels 2p - 1 .. 2p + 2 per axis, clamped to the map as texelFetch would:
// the sampler clamps to the edge), as four rows, from four gathers (a gather
// costs about what one fetch does on llvmpipe; nine fetches per child cost
// 2.2x more).
void loadBlock(uvec2 p, out vec4 rows[4])
{
    vec2 texelSize = 1.0 / vec2(float(push.mapSize));
    vec2 corner = vec2(2u * p) * texelSize; // gather footprint: the texels either side of each corner coordinate
    vec4 g00 = textureGather(shadowMap, vec3(corner, 0.0));
    vec4 g10 = textureGather(shadowMap, vec3(corner + vec2(2.0 * texelSize.x, 0.0), 0.0));
    vec4 g01 = textureGather(shadowMap, vec3(corner + vec2(0.0, 2.0 * texelSize.y), 0.0));
    vec4 g11 = textureGather(shadowMap, vec3(corner + 2.0 * texelSize, 0.0));
    // Gather components: w (i0, j0), z (i1, j0), x (i0, j1), y (i1, j1).
    rows[0] = vec4(g00.w, g00.z, g10.w, g10.z);
    rows[1] = vec4(g00.x, g00.y, g10.x, g10.y);
    rows[2] = vec4(g01.w, g01.z, g11.w, g11.z);
    rows[3] = vec4(g01.x, g01.y, g11.x, g11.y);
}

// Level 0: the depth of texel t when it is the near side of an edge (it
// occludes, so it splats), else kNoEdge; x: depth discontinuities, y: thin
// triangles. r0, r1, r2: the map depths of its 3x3 neighbourhood, rows
// y - 1, y, y + 1. An edge is a depth discontinuity: a
// neighbour of the 3x3 neighbourhood deeper by more than the threshold, where
// the depths are not the slope of one plane. NDC depth is affine in the texel
// coordinates over a plane, so its second difference along each of the four
// lines through the centre vanishes there (receivers seen at grazing angles
// are no edges); it is scaled back to model units with the derivative of
// linear depth by NDC depth at the centre. The far side of an edge does not
// splat: its occluder is the neighbour, which does. linearDepth is monotonic
// (in floating point too), so the largest and smallest linear depths of the
// nine are those of the largest and smallest map depths.
vec2 edgeDepths(ivec2 t, vec3 r0, vec3 r1, vec3 r2)
{
    float centre = r1.y;
    float zc = linearDepth(centre);
    vec3 hi3 = max(max(r0, r1), r2), lo3 = min(min(r0, r1), r2);
    float deeper = max(linearDepth(max(max(hi3.x, hi3.y), hi3.z)) - zc, 0.0);
    float scale = zc * zc * (gFar - gNear) / (gFar * gNear);
    float bend = max(max(abs(r1.x + r1.z - 2.0 * centre), abs(r0.y + r2.y - 2.0 * centre)),
                     max(abs(r0.x + r2.z - 2.0 * centre), abs(r0.z + r2.x - 2.0 * centre)));
    vec2 edges = vec2(deeper > push.edgeDelta && bend * scale > push.edgeDelta ? zc : kNoEdge, kNoEdge);
    // A thin triangle is an edge where it lies in front of everything the map
    // sampled around it: an occluder the rasterizer dropped (slivers of
    // surfaces seen at grazing angles are in the map's neighbourhood). No
    // threshold: a thin occluder just above a surface (a railing's bars near
    // the ground) has a penumbra there too, and its splats reach only the
    // pixels the map does not hide (the second mask).
    if (kUseThin != 0u) {
        // The last layer: each texel's own depth of the slivers over it (thin_triangles.comp.glsl).
        float thin = linearDepth(uintBitsToFloat(imageLoad(thinMap, ivec3(t, imageSize(thinMap).z - 1)).r));
        float nearest = min(zc, linearDepth(min(min(lo3.x, lo3.y), lo3.z)));
        if (thin < nearest)
            edges.y = thin;
    }
    return edges;
}

// Appends a splat job; one atomic per subgroup. A full list marks the whole map (conservative).
void appendJob(bool valid, uvec2 c, uint level, float z, uint kind)
{
    uvec4 ballot = subgroupBallot(valid);
    uint total = subgroupBallotBitCount(ballot);
    if (total == 0u)
        return;
    uint base = 0u;
    if (subgroupElect())
        base = atomicAdd(jobCount, total);
    base = subgroupBroadcastFirst(base);
    if (!valid)
        return;
    uint slot = base + subgroupBallotExclusiveBitCount(ballot);
    if (slot < push.maxJobs)
        jobs[slot] = uvec2(level << 28u | c.y << 14u | c.x, floatBitsToUint(z) | kind << 31u);
    else
        markWholeMap();
}

void main()
{
    gLight = frame.lights[push.lightIndex];
    gNear = lightMapEye(gLight, push.slot).w;
    gFar = lightMapRange(gLight, push.slot).x;
    gRbig = length(gLight.positionType.xyz - lightMapEye(gLight, push.slot).xyz) + gLight.areaV.w;
    gTexelAngle = lightMapRange(gLight, push.slot).y / float(push.mapSize);
    uint S = push.mapSize;

    if (kStage == PENUMBRA_MASK_STAGE_WRITE_DISPATCH) {
        if (gl_GlobalInvocationID.x == 0u && gl_GlobalInvocationID.y == 0u) {
            uint groups = (min(jobCount, push.maxJobs) + 63u) / 64u;
            uint x = min(groups, 65535u);
            jobDispatch[0] = x;
            jobDispatch[1] = x == 0u ? 1u : (groups + x - 1u) / x;
            jobDispatch[2] = 1u;
        }
        return;
    }
    if (kStage == PENUMBRA_MASK_STAGE_PUSH_DOWN) {
        uint size = maskLevelSize(S, push.level), parentSize = maskLevelSize(S, push.level + 1u);
        uvec2 t = gl_GlobalInvocationID.xy;
        if (t.x >= size || t.y >= size)
            return;
        uint texel = maskLevelOffset(S, push.level) + t.y * size + t.x;
        uint parent = maskLevelOffset(S, push.level + 1u) + (t.y >> 1u) * parentSize + (t.x >> 1u);
        // Non-negative float bits order as the floats do (+inf: not reached).
        mask[1u + texel] = min(mask[1u + texel], mask[1u + parent]);
        if (kUseThin != 0u)
            thinMask[texel] = min(thinMask[texel], thinMask[parent]);
        return;
    }
    if (kStage == PENUMBRA_MASK_STAGE_SPLAT) {
        uint index = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * 64u + gl_LocalInvocationIndex;
        if (index >= min(jobCount, push.maxJobs))
            return;
        uvec2 job = jobs[index];
        splat(uvec2(job.x & 0x3FFFu, (job.x >> 14u) & 0x3FFFu), job.x >> 28u, uintBitsToFloat(job.y & 0x7FFFFFFFu), job.y >> 31u);
        return;
    }

    uint parentLevel = push.level + 1u;
    uint parentSize = maskLevelSize(S, parentLevel);
    uvec2 p = gl_GlobalInvocationID.xy;
    bool inside = p.x < parentSize && p.y < parentSize;
    uint childSize = maskLevelSize(S, push.level);
    vec2 nearest = vec2(kNoEdge);
    vec4 rows[4];
    if (kStage == PENUMBRA_MASK_STAGE_EDGES)
        loadBlock(p, rows);
    for (uint j = 0u; j < 4u; ++j) {
        uvec2 c = p * 2u + uvec2(j & 1u, j >> 1u);
        vec2 z = vec2(kNoEdge);
        if (inside && c.x < childSize && c.y < childSize) {
            if (kStage == PENUMBRA_MASK_STAGE_EDGES) {
                // Rows y - 1 .. y + 1 of child c and its columns x - 1 .. x + 1 (selects, not indexing).
                bool right = (j & 1u) != 0u, up = j >= 2u;
                vec4 a = up ? rows[1] : rows[0], b = up ? rows[2] : rows[1], d = up ? rows[3] : rows[2];
                z = edgeDepths(ivec2(c), right ? a.yzw : a.xyz, right ? b.yzw : b.xyz, right ? d.yzw : d.xyz);
            } else
                z = vec2(pyramid[pyramidIndex(S, 0u, push.level, c)], pyramid[pyramidIndex(S, 1u, push.level, c)]);
        }
        nearest = min(nearest, z);
        for (uint kind = 0u; kind < kKinds; ++kind) {
            float r = z[kind] < kNoEdge ? splatRadius(z[kind], push.level) : 0.0;
            appendJob(z[kind] < kNoEdge && (kStage == PENUMBRA_MASK_STAGE_EDGES ? r < 4.0 : (r >= 2.0 && r < 4.0)), c, push.level, z[kind], kind);
        }
    }
    if (inside) {
        pyramid[pyramidIndex(S, 0u, parentLevel, p)] = nearest.x;
        pyramid[pyramidIndex(S, 1u, parentLevel, p)] = nearest.y;
    }
    for (uint kind = 0u; kind < kKinds; ++kind)
        appendJob(inside && parentLevel == push.topLevel && nearest[kind] < kNoEdge && splatRadius(nearest[kind], parentLevel) >= 2.0, p,
                  parentLevel, nearest[kind], kind);
}
