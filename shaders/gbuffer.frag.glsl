#version 450
#extension GL_GOOGLE_include_directive : require
// Camera pass: writes the surface image (surface.glsli): the world position
// and the geometric normal, flipped to face the camera (models may be open or
// two-sided), in one RGBA32UI texel. gbuffer.frag.albedo
// (PENUMBRA_GBUFFER_ALBEDO) also writes the material colour (the packed
// albedo, below 2^24) to a second R32UI target: only frames that show colours
// of a model with more than white (runtime/src/passes/gbuffer.h) pay for it.
//
// gbuffer.frag.outside (PENUMBRA_GBUFFER_OUTSIDE): the frames in which afsm's
// closed clusters cast only their light-back-facing triangles (the camera is
// outside every closed mesh: AfsmPass::closedBackFaces). A triangle of a
// closed cluster (bit 24 of albedo, from gbuffer.vert) seen from behind is not
// drawn: from outside, the camera can see one only through the rasterizer's
// imprecision (the two sides of a solid thinner than the depth buffer resolves
// at that distance, a crack between separately quantized clusters, a near
// plane cutting a solid open). Such a pixel would hold a point inside a closed
// solid, whose shadow ray leaves it through a front face alone, which does not
// cast then; without it the pixel shows what lies behind, seen from outside.

#include "gbuffer_push.glsli"
#include "surface.glsli"

layout(location = 0) in vec3 worldPosition;
layout(location = 1) flat in uint albedo;

layout(location = 0) out uvec4 outSurface;
#ifdef PENUMBRA_GBUFFER_ALBEDO
layout(location = 1) out uint outAlbedo;
#endif

void main()
{
#ifdef PENUMBRA_GBUFFER_OUTSIDE
    // The model's winding is counter-clockwise seen from outside (pipelines.cpp: frontFace).
    if (albedo >= (1u << 24u) && !gl_FrontFacing)
        discard;
#endif
    // Not normalized: the octahedral encoding divides by the L1 norm anyway.
    vec3 n = cross(dFdx(worldPosition), dFdy(worldPosition));
    vec3 toCamera = camera.cameraPosition.xyz - worldPosition;
    if (abs(n.x) + abs(n.y) + abs(n.z) == 0.0)
        n = toCamera;
    if (dot(n, toCamera) < 0.0)
        n = -n;
    outSurface = uvec4(floatBitsToUint(worldPosition), encodeSurfaceNormal(n));
#ifdef PENUMBRA_GBUFFER_ALBEDO
    outAlbedo = albedo & 0xFFFFFFu;
#endif
}
