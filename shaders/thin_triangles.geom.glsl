#version 450
#extension GL_GOOGLE_include_directive : require
// Conservative rasterization of thin triangles in the light view (no
// conservative-rasterization extension on lavapipe): a triangle whose height
// over its longest edge is under PENUMBRA_THIN_TEXELS texels may be missed by
// the shadow map, so it is replaced by the rectangle around its longest edge,
// grown by the texel square's half width in each direction: every texel the
// triangle touches has its centre inside, so it is rasterized. Depth: the
// triangle's nearest vertex. Other triangles emit nothing.

#include "config.h"

layout(triangles) in;
layout(triangle_strip, max_vertices = 4) out;

layout(push_constant) uniform ThinPush {
    mat4 viewProj;
    vec2 mapSize;   // texels
} push;

layout(location = 0) out float nearestDepth;

void main()
{
    vec4 clip[3] = vec4[3](gl_in[0].gl_Position, gl_in[1].gl_Position, gl_in[2].gl_Position);
    if (clip[0].w <= 0.0 || clip[1].w <= 0.0 || clip[2].w <= 0.0)
        return; // crosses the light's near plane: the shadow map clips it too
    vec2 p[3];
    float zMin = 1.0;
    for (int i = 0; i < 3; ++i) {
        vec3 ndc = clip[i].xyz / clip[i].w;
        p[i] = (ndc.xy * 0.5 + 0.5) * push.mapSize;
        zMin = min(zMin, ndc.z);
    }
    // Longest edge a -> b, third vertex c.
    int a = 0;
    float longest = -1.0;
    for (int i = 0; i < 3; ++i) {
        float len = distance(p[i], p[(i + 1) % 3]);
        if (len > longest) {
            longest = len;
            a = i;
        }
    }
    vec2 A = p[a], B = p[(a + 1) % 3], C = p[(a + 2) % 3];
    float twiceArea = abs((B.x - A.x) * (C.y - A.y) - (B.y - A.y) * (C.x - A.x));
    float height = longest > 0.0 ? twiceArea / longest : 0.0;
    if (height >= PENUMBRA_THIN_TEXELS && longest >= PENUMBRA_THIN_TEXELS)
        return;
    vec2 d = longest > 1e-12 ? (B - A) / longest : vec2(1.0, 0.0);
    vec2 nrm = vec2(-d.y, d.x);
    float c = dot(C - A, nrm);
    float along = dot(C - A, d);
    float e_d = 0.5 * (abs(d.x) + abs(d.y)), e_n = 0.5 * (abs(nrm.x) + abs(nrm.y));
    float d0 = min(0.0, along) - e_d, d1 = max(longest, along) + e_d;
    float n0 = min(0.0, c) - e_n, n1 = max(0.0, c) + e_n;
    vec2 corners[4] = vec2[4](A + d * d0 + nrm * n0, A + d * d1 + nrm * n0, A + d * d0 + nrm * n1, A + d * d1 + nrm * n1);
    for (int i = 0; i < 4; ++i) {
        vec2 ndc = corners[i] / push.mapSize * 2.0 - 1.0;
        gl_Position = vec4(ndc, zMin, 1.0);
        nearestDepth = zMin;
        EmitVertex();
    }
    EndPrimitive();
}
