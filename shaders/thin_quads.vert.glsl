#version 460
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
// Thin-triangle pass, draw: the conservative rectangles written by
// thin_detect.comp.glsl (layout there), 6 vertices (two triangles) per
// rectangle, pulled from the thin quads buffer by gl_VertexIndex; the
// rectangle lies at its triangle's nearest depth (drawn indirectly, no
// vertex input).

layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer ThinQuads
{
    uint draw[4];
    uint claimed;
    uint overflow;
    uint reserved[2];
    vec4 quads[];
};

layout(push_constant) uniform ThinDrawPush {
    uint64_t thinQuads;
} push;

layout(location = 0) out float nearestDepth;

const uint kCorner[6] = uint[6](0u, 1u, 2u, 2u, 1u, 3u);

void main()
{
    uint quad = uint(gl_VertexIndex) / 6u;
    uint corner = kCorner[uint(gl_VertexIndex) % 6u];
    ThinQuads buffer_ = ThinQuads(push.thinQuads);
    vec4 pair = buffer_.quads[3u * quad + corner / 2u];
    float z = buffer_.quads[3u * quad + 2u].x;
    gl_Position = vec4((corner & 1u) == 0u ? pair.xy : pair.zw, z, 1.0);
    nearestDepth = z;
}
