#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
// Shadow-map visibility and PIP classification (Lauterbach et al. 2009, 3.1).
// Per camera pixel: project into the shadow map, visibility from the standard
// depth test; in srt mode, mark the pixel potentially incorrect when
//  - the 3x3 texel neighbourhood has a depth discontinuity Delta above the
//    threshold and the receiver's depth range within one texel, [d^, d],
//    overlaps [s - Delta, s + Delta] (d^ from the texel angle alpha and the
//    angle beta between surface and light: d^ = d sin(beta) / sin(alpha + beta);
//    for directional lights d^ = d - w cos(beta) / sin(beta), w the texel width), or
//  - the shadow map calls the pixel lit but a thin triangle, rasterized
//    conservatively into the thin map (thin_triangles.comp.glsl), lies in front
//    of it within its texel (a dropped thin occluder can only darken a pixel), or
//  - the map shadows the pixel from a depth within [d^, d]: what shadows it
//    may be its own surface (acne) or an occluder touching it.
// frt mode marks every light-facing pixel and reads no map (none is drawn);
// sm mode marks none.
// The mode and the light's type are specialization constants (one pipeline
// each, runtime/src/passes/classify.cpp): on lavapipe a shader pays for every
// instruction it holds, so the srt tests cost nothing in sm frames.
// Marked pixels are counted by compaction (the ray list's length).

#include "config.h"
layout(constant_id = 0) const uint kMode = PENUMBRA_CLASSIFY_LOOKUP; // PENUMBRA_CLASSIFY_*
layout(constant_id = 1) const uint kLightType = PENUMBRA_LIGHT_POINT; // PENUMBRA_LIGHT_* (not area lights)
#define PENUMBRA_LIGHT_TYPE kLightType
#include "shadow_common.glsli"

layout(local_size_x = PENUMBRA_SHADE_GROUP_SIZE, local_size_y = PENUMBRA_SHADE_GROUP_SIZE) in;

#define PIXEL_VISIBILITY_ACCESS writeonly
#define PIXEL_MARKS_ACCESS writeonly
#include "pixel_bindings.glsli"
#include "classify_bindings.glsli"

layout(push_constant) uniform ClassifyPush {
    uint lightIndex;
    uint mode;     // PENUMBRA_CLASSIFY_LOOKUP (sm), _PIP (srt), _ALL (frt): kMode's value (checked by the pass)
} push;

void classifyPixel()
{
    ivec2 imageSizeXY = imageSize(visibilityImage), pixel;
    const bool inside = pixelOfInvocation(imageSizeXY, pixel);
    uint index = uint(pixel.y * imageSizeXY.x + pixel.x);
    const uvec4 surface = imageLoad(gSurface, pixel);
    // Background pixels take the same path (one store of each output per
    // pixel: lavapipe would run a separate early-out path for every pixel).
    bool covered = surfaceCovered(surface);
    LightData light = frame.lights[push.lightIndex];
    vec3 p = surfacePosition(surface);
    vec3 n = surfaceNormal(surface);
    float distance;
    vec3 L = towardLight(light, p, distance);
    bool lightFacing = covered && dot(n, L) > 0.0;

    ivec2 size = textureSize(shadowMap, 0).xy;
    // A point light's cube face: its matrix read from the uniform buffer at the
    // pixel's layer (projectToShadowMap's switch over the six costs far more).
    const uint layer = shadowLayer(light, p);
    ShadowLookup s = kLightType == PENUMBRA_LIGHT_POINT ? projectToLayer(frame.lights[push.lightIndex].viewProj[layer], layer, p, size)
                                                          : projectToShadowMap(light, p, size);
    // frt draws no map: a light-facing pixel's visibility is its ray's, the others' 0 (as afsm and rh store it).
    const float mapNdc = kMode == PENUMBRA_CLASSIFY_ALL ? 1.0 : texelFetch(shadowMap, ivec3(s.texel, s.layer), 0).r;
    float visibility = kMode == PENUMBRA_CLASSIFY_ALL ? (lightFacing ? 1.0 : 0.0) : !s.inside || s.depth <= mapNdc ? 1.0 : 0.0;
    if (inside)
        imageStore(visibilityImage, pixel, vec4(covered ? visibility : -1.0));

    bool mark = lightFacing && kMode == PENUMBRA_CLASSIFY_ALL;
    if (kMode == PENUMBRA_CLASSIFY_PIP) {
        // Both tests for every pixel, their results masked after: on lavapipe the tests inside an
        // `if` on the pixel (or behind a short-circuit) run under an execution mask, which costs more
        // than testing the pixels that need no test. The thin texel is clamped into the map for those.
        float d = linearLightDepth(light, s.depth);
        float dHat = receiverNearestDepth(light, d, size, n, L);
        const bool discontinuity = depthDiscontinuityNear(shadowMap, frame.pip.x, light, s, size, d, dHat);
        const ivec2 thinTexel = clamp(s.texel / int(PENUMBRA_THIN_HARD_SCALE), ivec2(0), imageSize(thinMap).xy - 1);
        const float thinDepth = uintBitsToFloat(imageLoad(thinMap, ivec3(thinTexel, s.layer)).r);
        // A thin occluder the shadow map dropped can only darken a pixel the map calls lit.
        const bool thin = visibility == 1.0 && thinOccluderNearer(thinDepth, light, s, d, dHat);
        // The map shadows the pixel from a depth the receiver's own surface reaches within the texel: the
        // shadowing surface may be the receiver itself, beyond what the depth bias covers (a curved
        // surface, a map's depth precision far from a point light), or an occluder touching it.
        const bool self = visibility == 0.0 && linearLightDepth(light, mapNdc) >= min(dHat, d);
        mark = lightFacing && s.inside && (discontinuity || thin || self);
    }
    if (inside)
        marks[index] = mark ? 1u : 0u;
}

#ifdef PENUMBRA_FLOOR
#include "floor.glsli"
void main()
{
    ivec2 size = imageSize(visibilityImage), pixel;
    float sum;
    const bool inside = floorPixel(size, pixel, sum);
    ivec2 mapSize = textureSize(shadowMap, 0).xy;
    ivec2 texel = pixel * mapSize / size;
    float depth = push.mode != PENUMBRA_CLASSIFY_ALL ? texelFetch(shadowMap, ivec3(texel, 0), 0).r : 0.0; // frt reads no map
    float thin = 0.0;
    if (push.mode == PENUMBRA_CLASSIFY_PIP) {
        // The PIP test's inputs: the thin map's texel and the 3x3 texels around the pixel's, as the four
        // gathers depthDiscontinuityNear reads (shadow_common.glsli).
        thin = uintBitsToFloat(imageLoad(thinMap, ivec3(texel / int(PENUMBRA_THIN_HARD_SCALE), 0)).r);
        vec2 corner = vec2(texel) / vec2(mapSize), texelSize = 1.0 / vec2(mapSize);
        vec4 q = textureGather(shadowMap, vec3(corner, 0.0)) + textureGather(shadowMap, vec3(corner + vec2(texelSize.x, 0.0), 0.0)) +
                 textureGather(shadowMap, vec3(corner + vec2(0.0, texelSize.y), 0.0)) + textureGather(shadowMap, vec3(corner + texelSize, 0.0));
        depth += q.x + q.y + q.z + q.w;
    }
    sum += depth + thin + frame.lights[push.lightIndex].positionType.x;
    if (inside) {
        imageStore(visibilityImage, pixel, vec4(floorNever(sum) ? 0.5 : 1.0));
        marks[uint(pixel.y * size.x + pixel.x)] = floorNever(sum) ? 1u : 0u;
    }
}
#else
void main()
{
    classifyPixel();
}
#endif
