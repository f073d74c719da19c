#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
// Soft shadows of an area light (Lauterbach et al. 2009, 3.2), per camera pixel:
//  PENUMBRA_SOFT_AVERAGE (sm): visibility += weight x the depth test in map `slot`, a point-light
//    shadow map from one point of the light (sm soft averages K of them);
//  PENUMBRA_SOFT_CORNER_MASK (penumbra mask of a corner map, srt --penumbra-maps 5): mark pixels
//    inside the mask of map `slot` (penumbra_mask.comp.glsl; OR into the marks);
//  PENUMBRA_SOFT_CENTRE_MASK (srt, the centre map): mark pixels inside the centre map's mask, outside
//    the map, whose plane cuts the light (self-shadowing terminator), or that the
//    hard-shadow tests mark (a discontinuity that may affect the pixel, a thin
//    triangle in front), and give every other pixel the centre map's umbra or lit;
//    pixels only the hard-shadow tests mark get PENUMBRA_MARK_ONE_SAMPLE (one ray);
//  PENUMBRA_SOFT_ALL (frt): mark every pixel with a light sample above its plane;
//  PENUMBRA_SOFT_RECEIVERS (before the mask of map `slot` is built): per tile of the map, the
//    deepest light-view depth of the pixels that project there, and of those
//    the map does not hide (mapHides).
// Pixels with no light sample above their plane, or behind a one-sided emitter,
// get visibility 0 and no rays.

#include "config.h"
layout(constant_id = 1) const uint kLightType = PENUMBRA_LIGHT_SPHERE; // rectangle, disk or sphere
#define PENUMBRA_LIGHT_TYPE kLightType
#include "shadow_common.glsli"
#include "penumbra_mask.glsli"

layout(local_size_x = PENUMBRA_SHADE_GROUP_SIZE, local_size_y = PENUMBRA_SHADE_GROUP_SIZE) in;

#include "pixel_bindings.glsli"
#include "classify_bindings.glsli"

// One pipeline per mode: llvmpipe runs every branch masked, so a mode read
// from the push constants would pay for all five.
layout(constant_id = 0) const uint kMode = PENUMBRA_SOFT_ALL; // push.mode

layout(push_constant) uniform ClassifySoftPush {
    uint lightIndex;
    uint slot;       // map of the light
    uint mode;       // PENUMBRA_SOFT_* (see above; = kMode)
    uint first;      // AVERAGE: 1 for the first map (writes instead of adding; counts pixels)
    float weight;    // AVERAGE: 1 / K
    uint mapSize;
    uint topLevel;
    uint pad;
} push;

// The map hides the pixel: it lies deeper than every depth of its texel's 3x3
// neighbourhood by more than the edge threshold, so behind a surface of the
// map; thin triangles' splats do not apply to it (penumbra_mask.comp.glsl).
bool mapHides(LightData light, ShadowLookup s)
{
    // Four gathers (the sampler clamps to the edge) instead of nine fetches.
    vec2 texelSize = 1.0 / vec2(textureSize(shadowMap, 0).xy);
    vec2 corner = vec2(s.texel) * texelSize;
    vec4 q = max(max(textureGather(shadowMap, vec3(corner, 0.0)), textureGather(shadowMap, vec3(corner + vec2(texelSize.x, 0.0), 0.0))),
                 max(textureGather(shadowMap, vec3(corner + vec2(0.0, texelSize.y), 0.0)), textureGather(shadowMap, vec3(corner + texelSize, 0.0))));
    float deepest = max(max(q.x, q.y), max(q.z, q.w));
    float threshold = frame.pip.x * (lightMapRange(light, push.slot).x - lightMapEye(light, push.slot).w);
    return areaMapLinearDepth(light, push.slot, s.depth) > areaMapLinearDepth(light, push.slot, deepest) + threshold;
}

// Some splat of `kind` (0: depth discontinuities, 1: thin triangles) over texel
// t, on any level, reaches light-view depth `depth`: level 1 holds the
// minimum over the levels above it (penumbra_mask.comp.glsl pushes them down).
bool splatReaches(uint kind, uvec2 t, float depth)
{
    uint S = push.mapSize;
    uint texel0 = t.y * S + t.x, texel1 = S * S + (t.y >> 1u) * maskLevelSize(S, 1u) + (t.x >> 1u);
    uint nearest = kind == 0u ? min(mask[1u + texel0], mask[1u + texel1]) : min(thinMask[texel0], thinMask[texel1]);
    return depth >= uintBitsToFloat(nearest);
}

// In the penumbra mask of the map: some splat over the pixel's texel reaches
// its depth (thin triangles' splats only where the map does not hide it).
bool inMask(LightData light, ShadowLookup s)
{
    if ((mask[0] & 1u) != 0u)
        return true;
    float depth = areaMapLinearDepth(light, push.slot, s.depth) * (1.0 + 1e-3);
    return splatReaches(0u, uvec2(s.texel), depth) || (!mapHides(light, s) && splatReaches(1u, uvec2(s.texel), depth));
}

// One exit, every store guarded by `inside` and by the pixel's case rather
// than returned from: on lavapipe an early return puts the rest of the
// shader under an execution mask (pixelOfInvocation).
void classifyPixel()
{
    ivec2 imageSizeXY = imageSize(visibilityImage), pixel;
    const bool inside = pixelOfInvocation(imageSizeXY, pixel);
    uint index = uint(pixel.y * imageSizeXY.x + pixel.x);
    const uvec4 surface = imageLoad(gSurface, pixel);
    // Background: visibility -1, no mark, in every mode.
    const bool covered = surfaceCovered(surface);
    LightData light = frame.lights[push.lightIndex];
    vec3 p = surfacePosition(surface);
    vec3 n = surfaceNormal(surface);
    vec2 heights = areaLightHeightRange(light, p, n);
    bool reached = covered && heights.y > 0.0 && inFrontOfEmitter(light, p);
    ivec2 size = textureSize(shadowMap, 0).xy;
    ShadowLookup s = projectToAreaMap(light, push.slot, p, size);

    // The modes that store nothing for a covered pixel's visibility (below) store the background's here.
    if ((kMode == PENUMBRA_SOFT_RECEIVERS || kMode == PENUMBRA_SOFT_CORNER_MASK) && inside && !covered) {
        imageStore(visibilityImage, pixel, vec4(-1.0));
        marks[index] = 0u;
    }
    if (kMode == PENUMBRA_SOFT_AVERAGE) {
        // One point-light shadow map of K: the point must be above the pixel's plane.
        vec3 eye = lightMapEye(light, push.slot).xyz;
        bool lit = reached && dot(n, eye - p) > 0.0 && s.inside && s.depth <= texelFetch(shadowMap, ivec3(s.texel, 0), 0).r;
        float previous = push.first != 0u ? 0.0 : imageLoad(visibilityImage, pixel).r;
        if (inside) {
            imageStore(visibilityImage, pixel, vec4(covered ? previous + (lit ? push.weight : 0.0) : -1.0));
            if (push.first != 0u || !covered)
                marks[index] = 0u;
        }
    } else if (kMode == PENUMBRA_SOFT_RECEIVERS) {
        if (inside && reached && s.inside) {
            uint tiles = (push.mapSize + PENUMBRA_RECEIVER_TILE - 1u) / PENUMBRA_RECEIVER_TILE;
            uvec2 tile = uvec2(s.texel) / PENUMBRA_RECEIVER_TILE;
            uint depthBits = floatBitsToUint(areaMapLinearDepth(light, push.slot, s.depth));
            atomicMax(receivers[tile.y * tiles + tile.x], depthBits);
            if (!mapHides(light, s))
                atomicMax(receivers[tiles * tiles + tile.y * tiles + tile.x], depthBits);
        }
    } else if (kMode == PENUMBRA_SOFT_CORNER_MASK) {
        if (inside && reached && (!s.inside || inMask(light, s)))
            marks[index] = 1u;
    } else {
        bool mark;
        uint markValue = 1u;
        float visibility = unlitOrBackground(covered);
        if (kMode == PENUMBRA_SOFT_ALL) {
            mark = reached;
        } else {
            // The shadow map's own umbra/lit boundary is as uncertain as for hard shadows (3.1): the
            // mask leaves the occluder texel's neighbourhood to the hard-shadow tests.
            float distance;
            vec3 L = towardLight(light, p, distance);
            bool lit = s.depth <= texelFetch(shadowMap, ivec3(s.texel, 0), 0).r;
            // As for hard shadows, a thin occluder the map dropped matters only where the map says lit.
            bool boundary = depthDiscontinuityMayAffect(shadowMap, frame.pip.x, light, s, size, n, L) ||
                            (lit && thinOccluderMayAffect(uintBitsToFloat(imageLoad(thinMap, ivec3(s.texel, 0)).r), light, s, size, n, L));
            bool penumbra = marks[index] != 0u || heights.x <= 0.0 || !s.inside || inMask(light, s);
            mark = reached && (penumbra || boundary);
            // Outside the mask no penumbra reaches the pixel: every light sample agrees, so one of
            // them (sample 0, as frt traces it) decides the map's uncertain umbra/lit boundary.
            markValue = mark && !penumbra ? PENUMBRA_MARK_ONE_SAMPLE : 1u;
            if (reached && !mark)
                visibility = lit ? 1.0 : 0.0;
        }
        if (inside) {
            imageStore(visibilityImage, pixel, vec4(visibility));
            marks[index] = mark ? markValue : 0u;
        }
    }
}

#ifdef PENUMBRA_FLOOR
#include "floor.glsli"
void main()
{
    ivec2 size = imageSize(visibilityImage), pixel;
    float sum;
    const bool inside = floorPixel(size, pixel, sum);
    uint index = uint(pixel.y * size.x + pixel.x);
    ivec2 mapSize = textureSize(shadowMap, 0).xy;
    ivec2 texel = pixel * mapSize / size;
    float depth = texelFetch(shadowMap, ivec3(texel, 0), 0).r;
    if (push.mode == PENUMBRA_SOFT_CENTRE_MASK) {
        // The boundary tests' inputs: the thin map's texel and the 3x3 texels as four gathers (shadow_common.glsli).
        depth += uintBitsToFloat(imageLoad(thinMap, ivec3(texel, 0)).r);
        vec2 corner = vec2(texel) / vec2(mapSize), texelSize = 1.0 / vec2(mapSize);
        vec4 q = textureGather(shadowMap, vec3(corner, 0.0)) + textureGather(shadowMap, vec3(corner + vec2(texelSize.x, 0.0), 0.0)) +
                 textureGather(shadowMap, vec3(corner + vec2(0.0, texelSize.y), 0.0)) + textureGather(shadowMap, vec3(corner + texelSize, 0.0));
        depth += q.x + q.y + q.z + q.w;
    }
    uint maskWord = push.mode == PENUMBRA_SOFT_AVERAGE ? 0u : mask[(uint(texel.y) * push.mapSize + uint(texel.x)) >> 5u];
    sum += depth + uintBitsToFloat(maskWord) + frame.lights[push.lightIndex].positionType.x;
    // The averaged visibility and the marks are read back by later maps: written unchanged.
    vec4 visibility = imageLoad(visibilityImage, pixel);
    uint marked = marks[index];
    if (inside) {
        imageStore(visibilityImage, pixel, floorNever(sum) ? vec4(0.5) : visibility);
        marks[index] = marked | (floorNever(sum) ? 1u : 0u);
    }
}
#else
void main()
{
    classifyPixel(); // covered pixels are counted by shade, marked ones by compaction
}
#endif
