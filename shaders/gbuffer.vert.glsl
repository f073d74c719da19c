#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
// Camera pass: world position, a facing normal and the albedo per pixel (the G-buffer).

#include "model_vertex.glsli"
#include "gbuffer_push.glsli"

layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer ClusterAlbedo { uint packed[]; };

layout(location = 0) out vec3 worldPosition;
layout(location = 1) flat out uint albedo;

void main()
{
    // The draw's instance is the cluster (firstInstance = cluster index).
    albedo = camera.albedoAddress != uvec2(0) ? ClusterAlbedo(camera.albedoAddress).packed[gl_InstanceIndex] : 0xFFFFFFu;
    worldPosition = modelPosition();
    gl_Position = camera.viewProj * vec4(worldPosition, 1.0);
}
