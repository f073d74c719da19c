#version 450
#extension GL_GOOGLE_include_directive : require
// Alias-free shadow maps, casters (afsm_casters.geom.glsl): the model's
// vertices in world space, decoded exactly as the tracer decodes them.

#include "model_vertex.glsli"

layout(location = 0) out vec3 worldPosition;

void main()
{
    worldPosition = modelPosition();
    gl_Position = vec4(worldPosition, 1.0);
}
