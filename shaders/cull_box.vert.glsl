#version 460
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
// Occlusion-query boxes (culling.h): the 12 triangles of box gl_InstanceIndex
// (firstInstance of the draw) of the query-box array. Drawn with depth test,
// no depth or colour writes, no fragment shader; the query counts the samples
// that pass.

layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer Boxes
{
    vec4 corners[]; // per box: min (xyz), max (xyz)
};

layout(push_constant) uniform BoxPush
{
    mat4 viewProj;
    uint64_t boxes;
} push;

// Corner i: x from bit 0, y from bit 1, z from bit 2 (0 min, 1 max).
const uint kCorners[36] = uint[36](0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                                   2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5);

void main()
{
    Boxes boxes = Boxes(push.boxes);
    vec3 lo = boxes.corners[2 * gl_InstanceIndex].xyz;
    vec3 hi = boxes.corners[2 * gl_InstanceIndex + 1].xyz;
    uint corner = kCorners[gl_VertexIndex];
    vec3 p = vec3((corner & 1u) != 0u ? hi.x : lo.x, (corner & 2u) != 0u ? hi.y : lo.y, (corner & 4u) != 0u ? hi.z : lo.z);
    gl_Position = push.viewProj * vec4(p, 1.0);
}
