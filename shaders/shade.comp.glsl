#version 450
#extension GL_GOOGLE_include_directive : require
// Shade pass: one light per dispatch, accumulated into the colour image,
// with the light's visibility from the classify pass (shadow map) or the
// tracer (srt/frt). The light's type, whether it is the first light shaded,
// the PIP tint and the count are specialization constants
// (runtime/src/passes/shade.cpp): lavapipe pays for every instruction a
// shader holds. The first light shaded counts the covered pixels
// (PENUMBRA_STAT_COVERED, once per frame) when view_fit did not.
// The variant shade.comp.lookup (PENUMBRA_SHADE_LOOKUP, `sm`'s hard lights)
// takes the visibility from the shadow map itself, the lookup classify.comp
// does in its PENUMBRA_CLASSIFY_LOOKUP mode, so that an sm frame reads the
// G-buffer once per light instead of twice; it stores the visibility only
// when the frame reads it back (kStoreVisibility).

#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#include "config.h"
layout(constant_id = 0) const uint kLightType = PENUMBRA_LIGHT_POINT; // PENUMBRA_LIGHT_*
layout(constant_id = 1) const uint kFirstLight = 0u;                  // push.firstLight
layout(constant_id = 2) const uint kDebugPip = 0u;                    // push.debugPip
layout(constant_id = 3) const uint kCountCovered = 0u;                // 1: add the covered pixels to PENUMBRA_STAT_COVERED
layout(constant_id = 4) const uint kColours = 0u;                     // push.colours: read the G-buffer's albedo
#ifdef PENUMBRA_SHADE_LOOKUP
layout(constant_id = 5) const uint kStoreVisibility = 1u;             // 1: write the visibility image (read back)
#define PENUMBRA_LIGHT_TYPE kLightType
#include "shadow_common.glsli"
#endif

layout(local_size_x = PENUMBRA_SHADE_GROUP_SIZE, local_size_y = PENUMBRA_SHADE_GROUP_SIZE) in;

#ifdef PENUMBRA_SHADE_LOOKUP
#define PIXEL_VISIBILITY_ACCESS writeonly
#else
#define PIXEL_VISIBILITY_ACCESS readonly
#endif
#define PIXEL_MARKS_ACCESS readonly
#include "pixel_bindings.glsli"
layout(set = 0, binding = PIXEL_BINDING_COUNT, rgba16f) uniform image2D outColor;
#ifdef PENUMBRA_SHADE_LOOKUP
layout(set = 0, binding = PIXEL_BINDING_COUNT + 1) uniform sampler2DArray shadowMap; // C++: kShadeShadowMap
#endif

layout(push_constant) uniform ShadePush {
    uint lightIndex;    // which light of frame.lights
    uint firstLight;    // 1: initialise colour with ambient/background
    uint debugPip;      // 1: tint marked pixels red (--debug-image pip)
    uint countCovered;  // kCountCovered's value
    uint colours;       // kColours's value
} push;

#ifdef PENUMBRA_FLOOR
#define PENUMBRA_FLOOR_ALBEDO (kColours != 0u) // the one pass that reads the G-buffer's albedo
#include "floor.glsli"
void main()
{
    ivec2 size = imageSize(outColor), pixel;
    float sum;
    const bool inside = floorPixel(size, pixel, sum);
#ifdef PENUMBRA_SHADE_LOOKUP
    // The shadow map's texel (the lookup's one fetch) instead of the visibility image; the visibility is written.
    sum += texelFetch(shadowMap, ivec3(pixel * textureSize(shadowMap, 0).xy / size, 0), 0).r;
    if (inside)
        imageStore(visibilityImage, pixel, vec4(floorNever(sum) ? 0.5 : 1.0));
#else
    sum += imageLoad(visibilityImage, pixel).r;
#endif
    sum += frame.lights[push.lightIndex].colorIntensity.x;
    // Later lights add to the colour: written unchanged.
    vec4 color = imageLoad(outColor, pixel);
    if (inside)
        imageStore(outColor, pixel, floorNever(sum) ? vec4(0.5) : color);
}
#else
void main()
{
    ivec2 size = imageSize(outColor), pixel;
    const bool inside = pixelOfInvocation(size, pixel);

    const uvec4 surface = imageLoad(gSurface, pixel);
    const bool covered = surfaceCovered(surface);
    if (kCountCovered != 0u) {
        uint coveredPixels = subgroupAdd(covered && inside ? 1u : 0u);
        if (subgroupElect() && coveredPixels != 0u)
            atomicAdd(stats[PENUMBRA_STAT_COVERED], uint64_t(coveredPixels));
    }
    vec3 n = surfaceNormal(surface);
    vec3 albedo = vec3(frame.shading.y);
    if (kColours != 0u) // colours shown: the material's colour packed by gbuffer.frag.albedo
        albedo *= vec3(uvec3(imageLoad(gAlbedo, pixel).r) >> uvec3(0u, 8u, 16u) & 255u) / 255.0;
    // The first light shaded writes ambient (and the background); later ones add to the colour.
    vec3 color = kFirstLight != 0u ? vec3(albedo * frame.shading.x * (0.75 + 0.25 * n.y)) : imageLoad(outColor, pixel).rgb;

    const LightData light = frame.lights[push.lightIndex];
    const uint type = kLightType;
    vec3 p = surfacePosition(surface);
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
        if (type == PENUMBRA_LIGHT_RECTANGLE || type == PENUMBRA_LIGHT_DISK)
            if (light.areaU.w != 0.0)
                attenuation *= max(dot(-toLight, normalize(light.directionRange.xyz)), 0.0);
        if (type == PENUMBRA_LIGHT_SPOT) {
            float cosAngle = dot(-toLight, normalize(light.directionRange.xyz));
            attenuation *= smoothstep(light.spotCosLayers.y, light.spotCosLayers.x, cosAngle);
        }
    }

#ifdef PENUMBRA_SHADE_LOOKUP
    // classify.comp's PENUMBRA_CLASSIFY_LOOKUP: the standard depth test. A
    // point light's cube face: its matrix read at the pixel's layer.
    ivec2 mapSize = textureSize(shadowMap, 0).xy;
    const uint layer = shadowLayer(light, p);
    ShadowLookup s = type == PENUMBRA_LIGHT_POINT ? projectToLayer(frame.lights[push.lightIndex].viewProj[layer], layer, p, mapSize)
                                                  : projectToShadowMap(light, p, mapSize);
    float visibility = !s.inside || s.depth <= texelFetch(shadowMap, ivec3(s.texel, s.layer), 0).r ? 1.0 : 0.0;
    if (kStoreVisibility != 0u && inside)
        imageStore(visibilityImage, pixel, vec4(covered ? visibility : -1.0));
#else
    float visibility = max(imageLoad(visibilityImage, pixel).r, 0.0);
#endif
    const bool area = type == PENUMBRA_LIGHT_RECTANGLE || type == PENUMBRA_LIGHT_DISK || type == PENUMBRA_LIGHT_SPHERE;
    if (area && covered && inside && visibility > 0.0 && visibility < 1.0)
        atomicAdd(stats[PENUMBRA_STAT_PENUMBRA], uint64_t(1));
    float nDotL = max(dot(n, toLight), 0.0);
    color += albedo * light.colorIntensity.rgb * light.colorIntensity.w * attenuation * nDotL * visibility;
    if (kDebugPip != 0u && marks[pixel.y * size.x + pixel.x] != 0u)
        color = mix(color, vec3(1.0, 0.0, 0.0), 0.75);
    // Background pixels keep the background (the first light writes it).
    // The colour image holds half floats (frame_targets.h): clamped to the largest finite one, not infinity.
    color = min(color, vec3(65504.0));
    if (inside)
        imageStore(outColor, pixel, covered ? vec4(color, 1.0) : kFirstLight != 0u ? frame.background : imageLoad(outColor, pixel));
}
#endif
