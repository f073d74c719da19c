#version 450
// Shadow-map pass: depth only, from the light. Slope-scaled bias is set as
// dynamic depth-bias state by the runtime.

layout(location = 0) in vec3 inPosition;

layout(push_constant) uniform LightPush {
    mat4 viewProj;
} light;

void main()
{
    gl_Position = light.viewProj * vec4(inPosition, 1.0);
}
