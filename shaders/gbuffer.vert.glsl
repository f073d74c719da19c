#version 450
#extension GL_GOOGLE_include_directive : require
// Camera pass: world position and a facing normal per pixel (the G-buffer).

#include "model_vertex.glsli"

layout(push_constant) uniform CameraPush {
    mat4 viewProj;
    vec4 cameraPosition;
} camera;

layout(location = 0) out vec3 worldPosition;

void main()
{
    worldPosition = modelPosition();
    gl_Position = camera.viewProj * vec4(worldPosition, 1.0);
}
