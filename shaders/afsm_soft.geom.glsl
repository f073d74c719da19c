#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
// Alias-free shadow maps, soft shadows (Sintorn et al. 2008, section 4.1):
// each caster is drawn over the sample grid as the convex hull of its
// influence region (afsm_casters.glsli: afsmSoftRect, afsmHull), each edge
// moved out by half a cell's extent (conservative: every cell whose square
// the region touches has its centre inside; lavapipe has no conservative
// rasterization), within the region's rectangle grown by one cell, and
// afsm_soft.frag.glsl tests every sample listed there. With
// push.computeCells > 0 the casters whose rectangle spans at most that many
// cells were tested by the compute path (afsm_bin.comp.glsl) and are left out.
//
// Slices (push.sliceBegin > 0): a fragment tests at most afsmSliceSamples
// of its cell's samples (lavapipe silently ends an invocation's loops after
// 65535 iterations in all, afsm.glsli), so when some cell holds more
// (crowded; afsm_samples.comp.glsl counts them), the layer's casters are
// drawn again once per further slice, each draw's fragments testing the
// samples from push.sliceBegin on; those draws cover only the rectangle of
// the crowded cells and leave out the casters that miss it.

#include "config.h"
#include "shadow_common.glsli"
#include "shadow_ray.glsli"
#include "penumbra/light_sampling.h"
#define AFSM_SOFT 1
#include "afsm.glsli"
layout(triangles) in;
layout(triangle_strip, max_vertices = 32) out;

layout(location = 0) in vec3 worldPosition[];
layout(location = 1) flat in uint cluster[];
layout(location = 0) flat out vec3 vertex0;
layout(location = 1) flat out vec3 vertex1;
layout(location = 2) flat out vec3 vertex2;

// C++: runtime/src/passes/afsm.h (AfsmSoftBinding).
layout(set = 0, binding = 0, std140) uniform Frame { FrameData frame; };
layout(set = 0, binding = 2) uniform usamplerBuffer cellCountTexels;  // R32UI: samples per cell (afsmCellCount)
layout(set = 0, binding = 4, std430) readonly buffer Far { AFSM_FAR_FIELDS; }; // afsm_samples.comp.glsl
layout(set = 0, binding = 5) uniform usamplerBuffer cellDepthTexels;  // R32UI: per cell, its farthest sample depth (afsmCellDepth)
layout(set = 0, binding = 8, std430) readonly buffer ClosedBits { uint closedBits[]; };  // bit per cluster: kClusterClosed

#define AFSM_RECTANGLES_ONLY 1
#define AFSM_POLYGONS 1
#include "afsm_casters.glsli"

layout(push_constant) uniform AfsmSoftPush {
    mat4 viewProj;     // the layer's grid projection (perspective from the light's centre)
    uint64_t masks;
    uint64_t table;
    uint lightIndex;
    uint gridSize;
    float originOffset;
    uint samples;
    uint tableSize;
    float computeCells; // rectangles of at most this many cells: the compute path's (0: none)
    uint closedBackFaces; // closed clusters cast only light-back-facing triangles (afsm_casters.glsli)
    uint sliceBegin;      // > 0: a later slice of the crowded cells (see above)
} push;

void main()
{
    if (!afsmCasts(frame.lights[push.lightIndex], cluster[0], push.closedBackFaces != 0u, worldPosition[0], worldPosition[1], worldPosition[2]))
        return;
    float nearest;
    AfsmRect r = afsmSoftRect(push.viewProj, frame.lights[push.lightIndex], uintBitsToFloat(farBits), worldPosition[0], worldPosition[1],
                              worldPosition[2], push.gridSize, nearest);
    if (r.empty || afsmComputeTakes(r, push.gridSize, push.computeCells, 1u + afsmQuads(push.samples), nearest, true))
        return;
    // The region's hull grown by half a cell, within the rectangle.
    vec2 lo = (r.lo * 0.5 + 0.5) * float(push.gridSize), hi = (r.hi * 0.5 + 0.5) * float(push.gridSize);
    if (push.sliceBegin > 0u) { // the crowded cells' rectangle only
        lo = max(lo, vec2(crowded[0], crowded[1]));
        hi = min(hi, vec2(crowded[2] + 1u, crowded[3] + 1u));
        if (any(greaterThan(lo, hi)))
            return;
    }
    afsmRectPolygon(lo, hi);
    if (!r.whole) {
        for (int i = 0; i < afsmPointCount; ++i)
            afsmPoints[i] = (afsmPoints[i] * 0.5 + 0.5) * float(push.gridSize);
        afsmHull();
        if (afsmPolygonCount >= 3)
            afsmOffsetAndClip(0.0, lo, hi);
        else
            afsmRectPolygon(lo, hi);
    }
    // Depth: the caster's nearest vertex (the depth test drops the cells whose samples all lie nearer the light).
    for (int i = 0; i < afsmPolygonCount; ++i) {
        gl_Position = afsmStripVertex(i, push.gridSize, nearest);
        vertex0 = worldPosition[0];
        vertex1 = worldPosition[1];
        vertex2 = worldPosition[2];
        EmitVertex();
    }
    EndPrimitive();
}
