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
//    conservatively into the thin map (thin_detect.comp.glsl), lies in front
//    of it within its texel (a dropped thin occluder can only darken a pixel).
// frt mode marks every light-facing pixel; sm mode marks none.

#include "config.h"
#include "shadow_common.glsli"

layout(local_size_x = PENUMBRA_SHADE_GROUP_SIZE, local_size_y = PENUMBRA_SHADE_GROUP_SIZE) in;

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D gPosition;
layout(set = 0, binding = 1, rgba32f) uniform readonly image2D gNormal;
layout(set = 0, binding = 2) uniform sampler2DArray shadowMap;
layout(set = 0, binding = 3, r32ui) uniform readonly uimage2DArray thinMap; // float bits of the nearest thin depth
layout(set = 0, binding = 4, r32f) uniform writeonly image2D outVisibility;
layout(set = 0, binding = 5, std140) uniform Frame { FrameData frame; };
layout(set = 0, binding = 6, std430) writeonly buffer Marks { uint marks[]; };
layout(set = 0, binding = 7, std430) buffer Stats { uint64_t stats[]; };

layout(push_constant) uniform ClassifyPush {
    uint lightIndex;
    uint mode;     // 0 sm, 1 srt, 2 frt
} push;

// Returns (covered, marked) for this invocation's pixel.
uvec2 classifyPixel()
{
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    ivec2 imageSizeXY = imageSize(outVisibility);
    if (any(greaterThanEqual(pixel, imageSizeXY)))
        return uvec2(0u);
    uint index = uint(pixel.y * imageSizeXY.x + pixel.x);
    vec4 position = imageLoad(gPosition, pixel);
    if (position.w == 0.0) {
        imageStore(outVisibility, pixel, vec4(-1.0));
        marks[index] = 0u;
        return uvec2(0u);
    }
    LightData light = frame.lights[push.lightIndex];
    vec3 p = position.xyz;
    vec3 n = imageLoad(gNormal, pixel).xyz;
    float distance;
    vec3 L = towardLight(light, p, distance);
    bool lightFacing = dot(n, L) > 0.0;

    ivec2 size = textureSize(shadowMap, 0).xy;
    ShadowLookup s = projectToShadowMap(light, p, size);
    float visibility = 1.0;
    if (s.inside)
        visibility = s.depth <= texelFetch(shadowMap, ivec3(s.texel, s.layer), 0).r ? 1.0 : 0.0;
    imageStore(outVisibility, pixel, vec4(visibility));

    bool mark = false;
    if (lightFacing && push.mode == 2u)
        mark = true;
    else if (lightFacing && push.mode == 1u && s.inside) {
        // A thin occluder the shadow map dropped can only darken a pixel the map calls lit.
        mark = depthDiscontinuityMayAffect(shadowMap, frame.pip.x, light, s, size, n, L) ||
               (visibility == 1.0 && thinOccluderMayAffect(uintBitsToFloat(imageLoad(thinMap, ivec3(s.texel, s.layer)).r), light, s, size, n, L));
    }
    marks[index] = mark ? 1u : 0u;
    return uvec2(1u, mark ? 1u : 0u);
}

#include "pixel_counts.glsli"

void main()
{
    countPixels(classifyPixel());
}
