#version 450
#extension GL_GOOGLE_include_directive : require
// Alias-free shadow maps, casters (afsm_casters.geom.glsl,
// afsm_soft.geom.glsl): the model's vertices in world space, decoded exactly
// as the tracer decodes them, and the cluster they belong to (each cluster is
// drawn with firstInstance = its index), whose kClusterClosed flag decides
// which faces cast.

#include "model_vertex.glsli"

layout(location = 0) out vec3 worldPosition;
layout(location = 1) flat out uint cluster;

void main()
{
    worldPosition = modelPosition();
    cluster = uint(gl_InstanceIndex);
    gl_Position = vec4(worldPosition, 1.0);
}
