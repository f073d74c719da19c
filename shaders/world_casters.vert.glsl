#version 450
#extension GL_GOOGLE_include_directive : require
// Casters in world space, for the passes whose geometry shaders test them
// against the samples (afsm_casters.geom.glsl, afsm_soft.geom.glsl,
// rh_casters.geom.glsl): the model's vertices decoded exactly as the tracer
// decodes them, and the cluster they belong to (the instance: each cluster's
// draw is its own; afsm reads its kClusterClosed flag).

#include "model_vertex.glsli"

layout(location = 0) out vec3 worldPosition;
layout(location = 1) flat out uint cluster;

void main()
{
    worldPosition = modelPosition();
    cluster = uint(gl_InstanceIndex);
    gl_Position = vec4(worldPosition, 1.0);
}
