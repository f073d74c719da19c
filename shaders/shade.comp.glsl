#version 450
#extension GL_GOOGLE_include_directive : require
// Shade pass: one light per dispatch, accumulated into the colour image.
// Shadow test: standard depth comparison against the light's shadow map
// (the raster pass already applied slope-scaled depth bias).

#include "config.h"

layout(local_size_x = PENUMBRA_SHADE_GROUP_SIZE, local_size_y = PENUMBRA_SHADE_GROUP_SIZE) in;

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D gPosition;
layout(set = 0, binding = 1, rgba32f) uniform readonly image2D gNormal;
layout(set = 0, binding = 2) uniform sampler2DArray shadowMap;
layout(set = 0, binding = 3, rgba32f) uniform image2D outColor;
layout(set = 0, binding = 4, r32f) uniform image2D outVisibility;
layout(set = 0, binding = 5, std140) uniform Frame { FrameData frame; };

layout(push_constant) uniform ShadePush {
    uint lightIndex;    // which light of frame.lights
    uint firstLight;    // 1: initialise colour with ambient/background
    uint writeVisibility; // 1: store this light's shadow visibility
    uint pad;
} push;

// Shadow-map layer for a point light: +X, -X, +Y, -Y, +Z, -Z.
uint cubeFace(vec3 d)
{
    vec3 a = abs(d);
    if (a.x >= a.y && a.x >= a.z)
        return d.x >= 0.0 ? 0u : 1u;
    if (a.y >= a.z)
        return d.y >= 0.0 ? 2u : 3u;
    return d.z >= 0.0 ? 4u : 5u;
}

// 1 when the shadow map sees p, 0 when something nearer to the light covers it.
float shadowMapVisibility(LightData light, vec3 p)
{
    uint type = uint(light.positionType.w);
    uint layer = type == PENUMBRA_LIGHT_DIRECTIONAL || type == PENUMBRA_LIGHT_SPOT ? 0u : cubeFace(p - light.positionType.xyz);
    vec4 clip = light.viewProj[layer] * vec4(p, 1.0);
    if (clip.w <= 0.0)
        return 1.0;
    vec3 ndc = clip.xyz / clip.w;
    if (any(greaterThan(abs(ndc.xy), vec2(1.0))) || ndc.z > 1.0)
        return 1.0; // outside the light's frustum: nothing there casts a shadow
    ivec2 size = textureSize(shadowMap, 0).xy;
    ivec2 texel = clamp(ivec2((ndc.xy * 0.5 + 0.5) * vec2(size)), ivec2(0), size - 1);
    float s = texelFetch(shadowMap, ivec3(texel, layer), 0).r;
    return ndc.z <= s ? 1.0 : 0.0;
}

void main()
{
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = imageSize(outColor);
    if (any(greaterThanEqual(pixel, size)))
        return;

    vec4 position = imageLoad(gPosition, pixel);
    vec3 color = push.firstLight != 0u ? vec3(0.0) : imageLoad(outColor, pixel).rgb;
    if (position.w == 0.0) {
        if (push.firstLight != 0u)
            imageStore(outColor, pixel, frame.background);
        if (push.writeVisibility != 0u)
            imageStore(outVisibility, pixel, vec4(-1.0));
        return;
    }

    vec3 n = imageLoad(gNormal, pixel).xyz;
    float albedo = frame.shading.y;
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
        if (type == PENUMBRA_LIGHT_SPOT) {
            float cosAngle = dot(-toLight, normalize(light.directionRange.xyz));
            attenuation *= smoothstep(light.spotCosLayers.y, light.spotCosLayers.x, cosAngle);
        }
    }

    float visibility = shadowMapVisibility(light, p);
    float nDotL = max(dot(n, toLight), 0.0);
    color += albedo * light.colorIntensity.rgb * light.colorIntensity.w * attenuation * nDotL * visibility;
    imageStore(outColor, pixel, vec4(color, 1.0));
    if (push.writeVisibility != 0u)
        imageStore(outVisibility, pixel, vec4(visibility));
}
