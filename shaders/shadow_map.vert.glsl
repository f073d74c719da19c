#version 450
#extension GL_GOOGLE_include_directive : require
// Shadow-map pass: depth only, from the light. Slope-scaled bias is set as
// dynamic depth-bias state by the runtime.

#include "model_vertex.glsli"

layout(push_constant) uniform LightPush {
    mat4 viewProj;
} light;

void main()
{
    gl_Position = light.viewProj * vec4(modelPosition(), 1.0);
}
