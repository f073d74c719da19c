#version 450
// Camera pass: world position and a facing normal per pixel (the G-buffer).

layout(location = 0) in vec3 inPosition;

layout(push_constant) uniform CameraPush {
    mat4 viewProj;
    vec4 cameraPosition;
} camera;

layout(location = 0) out vec3 worldPosition;

void main()
{
    worldPosition = inPosition;
    gl_Position = camera.viewProj * vec4(inPosition, 1.0);
}
