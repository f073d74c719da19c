#version 450
#extension GL_GOOGLE_include_directive : require
// Test pass: the model drawn exactly as the raster passes draw it (indexed
// 8-bit strips, restart, per-cluster instance data), with the rasterizer
// discarded; every vertex writes its decoded position for comparison with the
// CPU decoder.

#include "model_vertex.glsli"

layout(set = 0, binding = 0, std430) writeonly buffer Decoded { float decoded[]; };

layout(push_constant) uniform DecodePush {
    uint vertexBase; // first global vertex of the chunk being drawn
} push;

void main()
{
    vec3 p = modelPosition();
    uint i = push.vertexBase + uint(gl_VertexIndex);
    decoded[3 * i + 0] = p.x;
    decoded[3 * i + 1] = p.y;
    decoded[3 * i + 2] = p.z;
    gl_Position = vec4(0.0, 0.0, 0.0, 1.0);
}
