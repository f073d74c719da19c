#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
// Camera pass: world position, a facing normal and the albedo per pixel (the G-buffer).

#include "model_vertex.glsli"
#include "gbuffer_push.glsli"

layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer ClusterAlbedo { uint packed[]; };
layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer ClosedBits { uint bits[]; };

layout(location = 0) out vec3 worldPosition;
layout(location = 1) flat out uint albedo;

void main()
{
    // The draw's instance is the cluster (firstInstance = cluster index).
    albedo = camera.albedoAddress != uvec2(0) ? ClusterAlbedo(camera.albedoAddress).packed[gl_InstanceIndex] : 0xFFFFFFu;
    // Bit 24: the cluster is flagged kClusterClosed (only with gbuffer.frag.outside).
    if (camera.closedAddress != uvec2(0) && (ClosedBits(camera.closedAddress).bits[uint(gl_InstanceIndex) >> 5u] & (1u << (uint(gl_InstanceIndex) & 31u))) != 0u)
        albedo |= 1u << 24u;
    worldPosition = modelPosition();
    gl_Position = camera.viewProj * vec4(worldPosition, 1.0);
}
