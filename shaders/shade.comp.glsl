#version 450
#extension GL_GOOGLE_include_directive : require
// Shade pass: one light per dispatch, accumulated into the colour image,
// with the light's visibility from the classify pass (shadow map) or the
// tracer (srt/frt).

#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "config.h"

layout(local_size_x = PENUMBRA_SHADE_GROUP_SIZE, local_size_y = PENUMBRA_SHADE_GROUP_SIZE) in;

#define PIXEL_VISIBILITY_ACCESS readonly
#define PIXEL_MARKS_ACCESS readonly
#include "pixel_bindings.glsli"
layout(set = 0, binding = PIXEL_BINDING_COUNT, rgba32f) uniform image2D outColor;

layout(push_constant) uniform ShadePush {
    uint lightIndex;    // which light of frame.lights
    uint firstLight;    // 1: initialise colour with ambient/background
    uint debugPip;      // 1: tint marked pixels red (--debug-image pip)
    uint pad;
} push;

#ifdef PENUMBRA_FLOOR
#include "floor.glsli"
void main()
{
    ivec2 size = imageSize(outColor), pixel;
    float sum;
    if (!floorPixel(size, pixel, sum))
        return;
    sum += imageLoad(visibilityImage, pixel).r + frame.lights[push.lightIndex].colorIntensity.x;
    // Later lights add to the colour: written unchanged.
    vec4 color = imageLoad(outColor, pixel);
    imageStore(outColor, pixel, floorNever(sum) ? vec4(0.5) : color);
}
#else
void main()
{
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = imageSize(outColor);
    if (any(greaterThanEqual(pixel, size)))
        return;

    vec4 position = imageLoad(gPosition, pixel);
    vec3 color = vec3(0.0);
    PENUMBRA_SKIP_UNLESS(push.firstLight == 0u) // later lights add to the colour
        color = imageLoad(outColor, pixel).rgb;
    if (position.w == 0.0) {
        if (push.firstLight != 0u)
            imageStore(outColor, pixel, frame.background);
        return;
    }

    vec4 normal = imageLoad(gNormal, pixel);
    vec3 n = normal.xyz;
    vec3 albedo = vec3(frame.shading.y);
    if (frame.shading.z != 0.0) // --colors on: the material's colour packed by gbuffer.frag
        albedo *= vec3(uvec3(uint(normal.w)) >> uvec3(0u, 8u, 16u) & 255u) / 255.0;
    if (push.firstLight != 0u)
        color = vec3(albedo * frame.shading.x * (0.75 + 0.25 * n.y));

    LightData light = frame.lights[push.lightIndex];
    uint type = uint(light.positionType.w);
    vec3 p = position.xyz;
    vec3 toLight;
    float attenuation = 1.0;
    if (type == PENUMBRA_LIGHT_DIRECTIONAL) {
        toLight = -normalize(light.directionRange.xyz);
    } else {
        vec3 d = light.positionType.xyz - p;
        float dist2 = max(dot(d, d), 1e-8);
        toLight = d * inversesqrt(dist2);
        attenuation = 1.0 / dist2;
        float range = light.directionRange.w;
        if (range > 0.0) {
            float r = sqrt(dist2) / range;
            attenuation *= clamp(1.0 - r * r * r * r, 0.0, 1.0);
        }
        // One-sided area emitters (rectangle, disk): Lambertian, cosine at the light.
        if (light.areaU.w != 0.0)
            attenuation *= max(dot(-toLight, normalize(light.directionRange.xyz)), 0.0);
        if (type == PENUMBRA_LIGHT_SPOT) {
            float cosAngle = dot(-toLight, normalize(light.directionRange.xyz));
            attenuation *= smoothstep(light.spotCosLayers.y, light.spotCosLayers.x, cosAngle);
        }
    }

    float visibility = max(imageLoad(visibilityImage, pixel).r, 0.0);
    bool area = type == PENUMBRA_LIGHT_RECTANGLE || type == PENUMBRA_LIGHT_DISK || type == PENUMBRA_LIGHT_SPHERE;
    PENUMBRA_SKIP_UNLESS(area && visibility > 0.0 && visibility < 1.0)
        atomicAdd(stats[PENUMBRA_STAT_PENUMBRA], uint64_t(1));
    float nDotL = max(dot(n, toLight), 0.0);
    color += albedo * light.colorIntensity.rgb * light.colorIntensity.w * attenuation * nDotL * visibility;
    PENUMBRA_SKIP_UNLESS(push.debugPip != 0u && marks[pixel.y * size.x + pixel.x] != 0u)
        color = mix(color, vec3(1.0, 0.0, 0.0), 0.75);
    imageStore(outColor, pixel, vec4(color, 1.0));
}
#endif
