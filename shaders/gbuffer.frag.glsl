#version 450
#extension GL_GOOGLE_include_directive : require
// Camera pass: writes world position (w = 1 marks covered pixels) and the
// geometric normal, flipped to face the camera (models may be open or two-sided),
// with the packed albedo in its w (an integer below 2^24, exact as a float).

#include "gbuffer_push.glsli"

layout(location = 0) in vec3 worldPosition;
layout(location = 1) flat in uint albedo;

layout(location = 0) out vec4 outPosition;
layout(location = 1) out vec4 outNormal;

void main()
{
    vec3 n = cross(dFdx(worldPosition), dFdy(worldPosition));
    float len = length(n);
    vec3 toCamera = camera.cameraPosition.xyz - worldPosition;
    n = len > 0.0 ? n / len : normalize(toCamera);
    if (dot(n, toCamera) < 0.0)
        n = -n;
    outPosition = vec4(worldPosition, 1.0);
    outNormal = vec4(n, float(albedo));
}
