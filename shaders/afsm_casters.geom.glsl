#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
// Alias-free shadow maps, casters (Sintorn et al. 2008, section 3.2):
// conservative rasterization of each triangle over the sample grid. lavapipe
// has no conservative-rasterization extension, so the triangle is drawn
// grown: each edge moved out by half a cell's extent along its normal plus
// the light's margin (afsm_casters.glsli: afsmMovedCorner, afsmCellMargin),
// or as its bounding rectangle grown by half a cell plus the margin
// (afsmHardRect) where that is smaller (a sharp corner's moved edges meet
// far away). Every cell whose area the triangle's
// projection touches has its centre inside, so the fragment shader sees every
// cell whose samples the triangle can shadow (afsm_casters.frag.glsl tests
// them exactly). A triangle reaching behind a perspective projection's eye
// covers the whole grid. With
// push.computeCells > 0 the triangles whose rectangle spans at most that many
// cells were tested by the compute path (afsm_bin.comp.glsl) and are left out;
// with push.wideList, afsm_wide.comp.glsl tested the others but those of the
// clusters it marked (afsm_wide.glsli), and only theirs are drawn. A caster
// no sample of whose cells' blocks lies beyond it is left out too
// (afsmBlocksBehind).
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
#include "afsm.glsli"
// C++: runtime/src/passes/afsm.h (AfsmCastersBinding).
layout(set = 0, binding = 0, std140) uniform Frame { FrameData frame; };
layout(set = 0, binding = 2) uniform usamplerBuffer cellCountTexels;  // R32UI: samples per cell (afsmCellCount)
layout(set = 0, binding = 4, std430) readonly buffer Far { AFSM_FAR_FIELDS; }; // afsm_samples.comp.glsl
layout(set = 0, binding = 5) uniform usamplerBuffer cellDepthTexels;  // R32UI: per cell, its farthest sample depth (afsmCellDepth)
layout(set = 0, binding = 8, std430) readonly buffer ClosedBits { uint closedBits[]; };  // bit per cluster: kClusterClosed
#define AFSM_RECTANGLES_ONLY 1
#define AFSM_POLYGONS 1
#include "afsm_casters.glsli"
#include "afsm_wide.glsli"

layout(triangles) in;
layout(triangle_strip, max_vertices = 4) out;

layout(location = 0) in vec3 worldPosition[];
layout(location = 1) flat in uint cluster[];
layout(location = 0) flat out vec3 vertex0;
layout(location = 1) flat out vec3 vertex1;
layout(location = 2) flat out vec3 vertex2;
// The triangle's projection in grid cells, for the fragment shader's exact
// cell test; projected2.w = 0: no test (a vertex behind the eye).
layout(location = 3) flat out vec4 projected01; // xy vertex 0, zw vertex 1
layout(location = 4) flat out vec4 projected2;  // xy vertex 2, z the margin (afsmCellMargin), w = 1 when valid

layout(push_constant) uniform AfsmCastersPush {
    mat4 viewProj;     // the layer's projection (the grid's)
    uint lightIndex;
    uint gridSize;     // cells per side
    float originOffset;
    float computeCells; // rectangles of at most this many cells: the compute path's (0: none)
    uint closedBackFaces; // closed clusters cast only light-back-facing triangles (afsm_casters.glsli)
    uint sliceBegin;      // > 0: a later slice of the crowded cells (see above)
    uint64_t wideList;    // != 0: afsm_wide.comp tested the casters the compute path left, but those of the clusters marked here
} push;

void main()
{
    if (push.wideList != 0ul && !afsmWideOverflowed(push.wideList, cluster[0]))
        return;
    if (!afsmCasts(frame.lights[push.lightIndex], cluster[0], push.closedBackFaces != 0u, worldPosition[0], worldPosition[1], worldPosition[2]))
        return;
    vec2 cells[3];
    bool behind;
    AfsmDepthBound depth;
    const float margin = afsmCellMargin(frame.lights[push.lightIndex]);
    AfsmRect r = afsmHardRect(push.viewProj, worldPosition[0], worldPosition[1], worldPosition[2], push.gridSize, margin, cells, behind, depth);
    if (r.empty || afsmComputeTakes(r, push.gridSize, push.computeCells, 1u, -1.0, true)) // every sample of the rectangle (nearest -1): afsm_bin.comp counts no more
        return;
    ivec2 firstCell, lastCell;
    afsmRectCellRange(r, push.gridSize, firstCell, lastCell);
    if (afsmBlocksBehind(firstCell, lastCell, push.gridSize, depth.nearest))
        return;
    // The triangle grown by half a cell and the margin of afsmCellMayMeetTriangle (below), or the rectangle.
    vec2 lo = (r.lo * 0.5 + 0.5) * float(push.gridSize), hi = (r.hi * 0.5 + 0.5) * float(push.gridSize);
    if (push.sliceBegin > 0u) { // the crowded cells' rectangle only
        lo = max(lo, vec2(crowded[0], crowded[1]));
        hi = min(hi, vec2(crowded[2] + 1u, crowded[3] + 1u));
        if (any(greaterThan(lo, hi)))
            return;
    }
    // The grown triangle (its edges moved out, afsm_casters.glsli: afsmMovedCorner) where its area is under a quarter of the
    // rectangle's, else the rectangle, as a strip of four vertices (the triangle's last one repeated). llvmpipe
    // rasterizes an axis-aligned rectangle on a fast path, so a thin diagonal triangle pays more per cell than the
    // rectangle around it (plant at 640^2: afsm_casters 790 ms with the smaller of the two, 640-657 with half).
    // Not their intersection: clipping the one by the other (afsmOffsetAndClip) loops over arrays of vertices,
    // which llvmpipe keeps in memory, and cost more than the extra cells it saves (the fragment shader tests each
    // cell exactly).
    float area = afsmCross(cells[1] - cells[0], cells[2] - cells[0]);
    vec2 a = cells[0], b = area > 0.0 ? cells[1] : cells[2], c = area > 0.0 ? cells[2] : cells[1];
    vec2 m0 = afsmMovedCorner(c, a, b, margin), m1 = afsmMovedCorner(a, b, c, margin), m2 = afsmMovedCorner(b, c, a, margin);
    vec2 size = hi - lo;
    bool triangle = !behind && area != 0.0 && abs(afsmCross(m1 - m0, m2 - m0)) < 0.5 * size.x * size.y;
    vec2 strip[4] = vec2[](triangle ? m0 : lo, triangle ? m1 : vec2(hi.x, lo.y), triangle ? m2 : vec2(lo.x, hi.y), triangle ? m2 : hi);
    // Depth: at each cell's centre, the caster's nearest depth over the cell grown by the margin (afsmNearestOver's
    // plane, affine across the polygon); the depth test (LESS against the cells' farthest samples, 0 for empty cells;
    // clamped, not clipped) drops the cells every sample of which lies nearer the light than the caster.
    AfsmDepthBound plane = AfsmDepthBound(depth.plane, -3.0e38);
    for (int i = 0; i < 4; ++i) {
        float z = depth.plane.w == 0.0 ? depth.nearest : afsmNearestOver(plane, strip[i] - 0.5, margin);
        gl_Position = vec4(strip[i] / float(push.gridSize) * 2.0 - 1.0, z, 1.0);
        vertex0 = worldPosition[0];
        vertex1 = worldPosition[1];
        vertex2 = worldPosition[2];
        projected01 = behind ? vec4(0.0) : vec4(cells[0], cells[1]);
        projected2 = behind ? vec4(0.0) : vec4(cells[2], margin, 1.0);
        EmitVertex();
    }
    EndPrimitive();
}
