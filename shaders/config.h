// Limits and GPU struct layouts shared by C++ (runtime/src) and GLSL (shaders/).
// Every tunable here has one line of explanation. Keep std140/std430-compatible.
#ifndef PENUMBRA_SHADERS_CONFIG_H
#define PENUMBRA_SHADERS_CONFIG_H

#ifndef __cplusplus
// Runs the statement after it when cond holds, as a loop of at most one
// iteration. Meant to let lavapipe skip work no lane needs, but it does not:
// llvmpipe 22.3 runs a loop's body once before it tests whether any lane is
// still in it, so this costs what an `if` costs (measured: view_fit's unused
// cube-face lookup, 9 ms at 1024^2 either way). On lavapipe a shader pays for
// every instruction it holds: code that a dispatch never needs is removed with
// specialization constants (vk::Specialization), rare work goes to its own
// pass over a compacted list. Kept for the shaders that still use it.
#define PENUMBRA_SKIP_UNLESS(cond) for (bool skipUnless_ = (cond); skipUnless_; skipUnless_ = false)
#endif

// Workgroup order of the passes whose work is uneven along their chunks (BVH nodes in spatial order:
// one part of the model holds most slivers or casters): lavapipe gives each of its threads one
// contiguous share of a dispatch's workgroups (llvmpipe's lp_cs_tpool: groups / threads each), so
// such a dispatch lasts as long as its busiest share. Consecutive workgroups take chunks from this
// many stripes of the range in turn (interleavedChunk), so a share of at least this many workgroups
// holds chunks from the whole range.
#define PENUMBRA_GROUP_INTERLEAVE 16u
#define PENUMBRA_MAX_LIGHTS 8            // lights shaded per frame
#define PENUMBRA_SHADE_GROUP_SIZE 8      // shade.comp and classify.comp workgroups are 8x8 pixels
#define PENUMBRA_THIN_TRIANGLES_GROUP_SIZE 64 // thin_triangles.comp: BVH nodes per workgroup, strip bytes decoded at once

#define PENUMBRA_TRACE_GROUP_SIZE 64     // trace.comp: invocations per workgroup
#define PENUMBRA_TRACE_RAYS_CPU 16       // trace.comp, hard shadows on a CPU device: list entries per invocation, in rounds
                                         // of a subgroup's consecutive entries, each round first testing the leaves that
                                         // blocked the round before (TracePass::raysPerInvocation)
#define PENUMBRA_TRACE_RAYS_GPU 1        // ... on a GPU: one ray an invocation (the GPU needs the invocations)
#define PENUMBRA_TRACE_HINT_BACKOFF 2    // ... rounds without hint tests after one whose tests left a ray to traverse
#define PENUMBRA_TRACE_ROUNDS_PER_DISPATCH 4 // ... those rounds in dispatches of this many: lavapipe ends every loop of an
                                         // invocation after 65,535 iterations in all, and the 16 rounds of an invocation
                                         // on the 1 M suite scenes at 1024^2 took up to 7,806 loop iterations
#define PENUMBRA_TRACE_SAMPLES_PER_DISPATCH 32 // trace.comp: an area light's samples traced per dispatch (lavapipe's loop limit)
#define PENUMBRA_TRACE_STACK_SIZE 100    // BVH traversal stack entries (3 x model::kMaxBvhDepth + 4: 4-wide nodes)
#define PENUMBRA_COMPACT_GROUP_SIZE 256  // compact.comp: pixels per workgroup
#define PENUMBRA_VIEW_FIT_BLOCK_CPU 16   // view_fit.comp on a CPU device: pixels a side of each invocation's block (its
                                         // subgroup reductions are loops over the lanes: 1024^2 tiny model 13.6 -> 8.3 ms CPU against 4)
#define PENUMBRA_VIEW_FIT_BLOCK_GPU 4    // ... on a GPU: more invocations
#define PENUMBRA_AFSM_SCAN_GROUP 256     // afsm_scan.comp: invocations per workgroup (16 counts each)
#define PENUMBRA_AFSM_MAX_GRID 4096      // afsm: most grid cells per side (one level of block totals in the scan)
#define PENUMBRA_AFSM_MIN_SAMPLES 128    // afsm soft shadows: fewest light samples (bits per view sample; section 4.2)
#define PENUMBRA_AFSM_MAX_SAMPLES 1024   // ... and most
#define PENUMBRA_AFSM_TABLE_WORDS (1u << 23) // afsm: lookup table of plane -> sample bitmask, at most this many uints (32 MiB)
#define PENUMBRA_AFSM_TABLE_GROUP 64     // afsm_table.comp: table entries per workgroup (one word of each)
#define PENUMBRA_AFSM_BIN_GROUP 64       // afsm_bin.comp: BVH nodes per workgroup (their leaves then decoded one per invocation)
#define PENUMBRA_AFSM_COMPUTE_CELLS 12.0 // afsm: casters whose grown rectangle (afsmHardRect) spans at most this many grid cells are tested in compute
#define PENUMBRA_AFSM_COMPUTE_BUDGET 384u // ... when their cells and samples take at most this many loop iterations (lavapipe: 65535 per invocation)
#define PENUMBRA_AFSM_FRAGMENT_ITERATIONS 60000u // afsm raster path: most loop iterations one fragment spends on a cell's samples
#define PENUMBRA_AFSM_WIDE_GROUP 64        // afsm_wide.comp: invocations per workgroup (one listed caster each)
#define PENUMBRA_AFSM_WIDE_ITERATIONS 60000u // afsm_wide.comp: most loop iterations one subgroup spends on its casters (lavapipe: 65535)
#define PENUMBRA_AFSM_WIDE_CAPACITY 1048576u // afsm_wide.comp: most casters one layer's list holds (48 bytes each; the model's triangles if fewer); past it, the raster path
#define PENUMBRA_AFSM_WIDE_DISPATCH 0u        // afsm_wide.comp's phases: the first pass's indirect dispatch,
#define PENUMBRA_AFSM_WIDE_TEST 1u            // ... the first pass (one caster per invocation, tested by its subgroup),
#define PENUMBRA_AFSM_WIDE_ALONE_DISPATCH 2u  // ... the second pass's dispatch,
#define PENUMBRA_AFSM_WIDE_TEST_ALONE 3u      // ... the second pass (one caster per subgroup)
#define PENUMBRA_AFSM_WIDE_COUNT_SHADOWED 4u  // ... the pixels shadowed so far (AfsmWideHeader::shadowedPixels)
                                         // (lavapipe silently ends an invocation's loops after 65535 in all); a cell with more
                                         // samples is tested in slices, one more draw per slice (afsm.h: afsmSliceSamples)
#define PENUMBRA_RH_GROUP_SIZE 64       // rh_traverse.comp, rh_build.comp: records or nodes per workgroup
#define PENUMBRA_RH_MAX_LEVELS 16        // rh: most levels of a cone hierarchy (4^15 leaves: far more than any image's rays)
#define PENUMBRA_RH_MAX_SORT_ORDER 10u   // rh sorted: at most 2^10 x 2^10 Hilbert cells per face (about 2 cells per pixel's ray, rh.cpp)
#define PENUMBRA_RH_SORT_SAVING 40.0    // rh --rh-sort auto: cone tests sorting saves a caster per unit of 1 + incoherence (rh_build.comp)
#define PENUMBRA_RH_SORT_COST 3.0       // rh --rh-sort auto: the sort's cost per ray, in cone tests' time
#define PENUMBRA_RH_FACE_SPLIT 24u      // rh sorted point lights: each face starts on a subtree of at most 1/24 of the rays (rh_build.comp)
#define PENUMBRA_RH_MAX_INCOHERENCE 4096.0 // rh: one tile's incoherence counts at most this much
#define PENUMBRA_RH_MAX_DEPTH_ORDER 9u   // rh: the receivers' depth grid per face: up to 2^9 cells a side (about 4 cells per ray, rh.cpp)
#define PENUMBRA_PIP_DELTA_FRACTION 0.002 // PIP: depth discontinuity threshold, fraction of the light's depth range
#define PENUMBRA_CULL_GROUP_SIZE 64     // cull_predicates.comp: draw commands per workgroup
#define PENUMBRA_CULL_GROUP_CLUSTERS 64 // occlusion culling: largest BVH subtree (clusters) without history queried with one box
#define PENUMBRA_CULL_CELL_CLUSTERS 8   // occlusion culling: largest subtree whose history is kept and tested as one box
#define PENUMBRA_CULL_RETEST_FRAMES 4   // occlusion culling: a visible cell's box is tested against the final depth every this many frames
#define PENUMBRA_CULL_MIN_OCCLUDED 0.1  // occlusion culling: a view that occludes less of its frustum's clusters than this
#define PENUMBRA_CULL_RETRY_FRAMES 16   // ... is culled by its frustum only for this many frames, then tried again
#define PENUMBRA_CULL_MIN_TRIANGLES 65536 // occlusion culling: a view whose frustum holds fewer triangles is culled by its frustum only
#define PENUMBRA_THIN_TEXELS 1.5         // thin-triangle pass: triangles narrower than this (texels) are rasterized conservatively
#define PENUMBRA_THIN_ASPECT 3.0         // ... if at least this many times longer than high, in the light's view and in model space
#define PENUMBRA_MASK_GROUP_SIZE 8       // penumbra_mask.comp: workgroups of 8x8 texels of the coarser level
#define PENUMBRA_MASK_TARGET_TEXELS 16.0 // penumbra splats are drawn at the mask level where they span at most this many texels
#define PENUMBRA_RECEIVER_TILE 8u        // penumbra mask: camera pixels' deepest map depth is kept per tile of this many texels a side
#define PENUMBRA_VIEW_FIT_MARGIN_TEXELS 4 // directional maps fitted to the view: texels added around the receivers' bounds
#define PENUMBRA_RECEIVER_GRID 512       // directional maps fitted to the view: cells a side of the receiver grid over the model-fitted map
#define PENUMBRA_RECEIVER_GRID_WORDS (PENUMBRA_RECEIVER_GRID * PENUMBRA_RECEIVER_GRID / 32) // its bits, in uints per light
#define PENUMBRA_AREA_MAX_HALF_FOV 60.0  // area-light shadow maps: widest half field of view (degrees); pixels outside get rays
#define PENUMBRA_MAX_SAMPLES 256         // soft shadows: most light samples per pixel

// Ray list written by compaction and read by the tracer (std430):
// uint count; uint dispatch[3] (indirect dispatch of trace.comp, one entry an invocation);
// uint roundsDispatch[3] (the same, PENUMBRA_TRACE_RAYS_CPU entries an invocation); uint pad; uint pixels[count]
// where pixels[i] = y * width + x of a pixel to trace, | PENUMBRA_RAY_ONE_SAMPLE when
// the pixel was marked PENUMBRA_MARK_ONE_SAMPLE (area lights: trace light sample 0 only).
#define PENUMBRA_RAY_LIST_HEADER_UINTS 8
#define PENUMBRA_MARK_ONE_SAMPLE 2u      // marks[]: outside the penumbra, all light samples agree (1: trace all)
#define PENUMBRA_RAY_ONE_SAMPLE 0x80000000u

// Modes of the passes, pushed to their shaders (never C++ enum positions).
// classify.comp.glsl, hard shadows: what the shadow map decides.
#define PENUMBRA_CLASSIFY_LOOKUP 0u      // sm: visibility from the map's depth test, no rays
#define PENUMBRA_CLASSIFY_PIP 1u         // srt: the map's visibility, and rays for potentially incorrect pixels
#define PENUMBRA_CLASSIFY_ALL 2u         // frt: a ray for every light-facing pixel
// classify_soft.comp.glsl, area lights (see the shader for each).
#define PENUMBRA_SOFT_AVERAGE 0u         // sm: visibility += weight x the depth test in one map of the light
#define PENUMBRA_SOFT_CORNER_MASK 1u     // srt --penumbra-maps 5: mark the pixels in a corner map's penumbra mask
#define PENUMBRA_SOFT_CENTRE_MASK 2u     // srt: the centre map's mask and hard-shadow tests; umbra or lit elsewhere
#define PENUMBRA_SOFT_ALL 3u             // frt: mark every pixel with a light sample above its plane
#define PENUMBRA_SOFT_RECEIVERS 4u       // before a penumbra mask: the deepest receiver per tile of the map
// afsm_samples.comp.glsl: the view samples of an alias-free shadow map.
#define PENUMBRA_AFSM_COUNT 0u           // count the samples per grid cell
#define PENUMBRA_AFSM_LIST 1u            // list them per cell (after the prefix sum)
#define PENUMBRA_AFSM_RESOLVE 2u         // the light's visibility from the samples' shadow flags (soft: their masks)
#define PENUMBRA_AFSM_REFRESH 3u         // hard shadows: the cells' farthest depths again, over the samples no caster has shadowed yet
#define PENUMBRA_AFSM_BLOCKS 4u          // each block of 8x8 cells: its farthest sample depth, from its cells' (after the count or the refresh)
// afsm_table.comp.glsl phases.
#define PENUMBRA_AFSM_TABLE_SAMPLES 0u   // the light samples' 2-D positions (penumbra/light_sampling.h)
#define PENUMBRA_AFSM_TABLE_MASKS 1u     // per (angle, distance) entry, the bitmask of the samples in front of the line
// rh_rays.comp.glsl modes.
#define PENUMBRA_RH_RAYS_COUNT 0u        // each tile's padded ray count at its Morton index (and its incoherence)
#define PENUMBRA_RH_RAYS_KEYS 1u         // sorted (section 3.5): rays per direction key
#define PENUMBRA_RH_RAYS_LIST 2u         // after the scan: the rays at their key's next slot, or at their tile's offset
// rh_build.comp.glsl modes.
#define PENUMBRA_RH_BUILD_DECIDE 0u      // whether to sort, and the sort's indirect dispatches (one invocation)
#define PENUMBRA_RH_BUILD_INIT 1u        // the hierarchy's levels from the ray count (one invocation)
#define PENUMBRA_RH_BUILD_LEAVES 2u      // leaves: cones (slabs) of 4 consecutive rays
#define PENUMBRA_RH_BUILD_LEVEL 3u       // a level from the 4 children of each node
#define PENUMBRA_RH_BUILD_RESOLVE 4u     // early accept: the rays under covered nodes shadowed
#define PENUMBRA_RH_BUILD_FACES 5u       // sorted: each face of the list aligned to whole subtrees (one invocation)
#define PENUMBRA_RH_BUILD_GRID 6u        // a level of the receivers' depth grid from the one below
// RenderSettings::rhSort, pushed to rh_build.comp's decide mode.
#define PENUMBRA_RH_SORT_OFF 0u
#define PENUMBRA_RH_SORT_ON 1u
#define PENUMBRA_RH_SORT_AUTO 2u
// rh_casters.geom.glsl: which casters a batch gathers.
#define PENUMBRA_RH_CASTERS_ALL 0u       // every caster
#define PENUMBRA_RH_CASTERS_LARGE 1u     // two-pass traversal, first pass: the large ones (good occluders)
#define PENUMBRA_RH_CASTERS_SMALL 2u     // second pass: the others
#define PENUMBRA_RH_LARGE_ANGLE 0.02     // two-pass: "large" is a bounding sphere wider than this (radius / distance from the light)
// rh_traverse.comp.glsl: the cone/triangle test (RenderSettings::rhTest).
#define PENUMBRA_RH_TEST_PRECISE 0u      // Olsson and Assarsson 2011, section 3.2: edge planes, tangent planes, the plane's range
#define PENUMBRA_RH_TEST_SPHERES 1u      // the triangle's bounding sphere against the cone (Roger et al. 2007)
// thin_triangles.comp.glsl phases (a specialization constant).
#define PENUMBRA_THIN_LIST 0u            // decode the leaves near receivers, list the slivers
#define PENUMBRA_THIN_DISPATCH 1u        // the fill's indirect dispatch from the list's length
#define PENUMBRA_THIN_FILL 2u            // fill each listed sliver's conservative rectangle
#define PENUMBRA_THIN_LIST_HEADER_UINTS 8 // thin list: count, dispatch[3], capacity, rectangles' capacity, padding; then uvec2 entries
#define PENUMBRA_THIN_LIST_MAX (1u << 24) // most slivers listed per light layer (the list is sized min(triangles, this))
#define PENUMBRA_THIN_RECTS_MAX (1u << 20) // thin list: most hard-map entries whose rectangle is kept (32 bytes each) for the fill
#define PENUMBRA_THIN_HARD_SCALE 2       // hard-shadow thin maps: shadow-map texels per thin-map texel side (thin_triangles.comp, classify.comp)
#define PENUMBRA_THIN_RUN_MAX 32767u     // most strip bytes from a run's first sliver to its last (15 bits of its list entry)
#define PENUMBRA_THIN_ALONE_ROWS 6.0   // thin fill: a rectangle at most this many rows high is filled by its own lane; taller ones by the subgroup
// compact.comp.glsl phases.
#define PENUMBRA_COMPACT_LIST 0u         // marked pixels into the ray list
#define PENUMBRA_COMPACT_DISPATCH 1u     // the tracer's indirect dispatch size from the list's count
// penumbra_mask.comp.glsl: values of its push constant `level` past the reductions' levels.
#define PENUMBRA_MASK_STAGE_EDGES 0u          // penumbra_mask.comp stages: edges of the map, level 0 -> 1
#define PENUMBRA_MASK_STAGE_REDUCE 1u         // a level of the min-depth pyramid, level -> level + 1
#define PENUMBRA_MASK_STAGE_WRITE_DISPATCH 2u // write the splat jobs' indirect dispatch size
#define PENUMBRA_MASK_STAGE_SPLAT 3u          // splat the listed jobs
#define PENUMBRA_MASK_STAGE_PUSH_DOWN 4u      // a mask level's minimum into the finer level, level + 1 -> level

// Counters of one frame (std430 uint64_t array, atomically accumulated).
#define PENUMBRA_STAT_RAYS 0             // rays traced
#define PENUMBRA_STAT_NODES 1            // BVH nodes visited (children tested)
#define PENUMBRA_STAT_LEAVES 2           // strip-range leaves tested
#define PENUMBRA_STAT_TRIANGLES 3        // ray/triangle tests
#define PENUMBRA_STAT_PIP 4              // pixels marked potentially incorrect (srt) or light-facing (frt)
#define PENUMBRA_STAT_COVERED 5          // covered pixels (counted once per light)
#define PENUMBRA_STAT_PENUMBRA 6         // pixels whose visibility of an area light is strictly between 0 and 1
#define PENUMBRA_STAT_AFSM_CELL_MOST 7   // afsm: the most samples listed in one grid cell of any layer (atomicMax)
#define PENUMBRA_STAT_COUNT 8

#define PENUMBRA_LIGHT_POINT 0
#define PENUMBRA_LIGHT_SPOT 1
#define PENUMBRA_LIGHT_DIRECTIONAL 2
#define PENUMBRA_LIGHT_RECTANGLE 3
#define PENUMBRA_LIGHT_DISK 4
#define PENUMBRA_LIGHT_SPHERE 5

#ifdef __cplusplus
#include <cstdint>
#include <glm/mat4x4.hpp>
#include <glm/vec4.hpp>
namespace penumbra::gpu {
using mat4 = glm::mat4;
using vec4 = glm::vec4;
using uint = uint32_t;
#define PENUMBRA_STRUCT(name) struct alignas(16) name
#define PENUMBRA_SHARED_FUNCTION inline
#else
#define PENUMBRA_STRUCT(name) struct name
#define PENUMBRA_SHARED_FUNCTION
#endif

// One light as the shade pass sees it (std140 array element).
PENUMBRA_STRUCT(LightData)
{
    mat4 viewProj[6];        // light-space projection per shadow-map layer (6 for point lights)
    vec4 positionType;       // xyz position (point-like lights), w = PENUMBRA_LIGHT_* as float
    vec4 directionRange;     // xyz direction light travels, w = range (0 = infinite)
    vec4 colorIntensity;     // rgb colour, w = intensity
    vec4 spotCosLayers;      // x = cos(inner), y = cos(outer), z = shadow-map layers, w = shadow maps of an area light,
                             // other lights: texel size over the model-fitted map's (the PIP threshold's scale)
    vec4 shadowParams;       // x = near, y = far (light-view depth), z = 1 perspective / 0 orthographic,
                             // w = footprint: perspective 2 tan(fov/2) (map width at depth 1), orthographic map width in model units
    // Area lights (penumbra/light_sampling.h): half-extent vectors; areaU.w = 1 when it emits on one side only (rectangle,
    // disk: along directionRange.xyz); areaV.w = bounding radius of the shape.
    vec4 areaU;
    vec4 areaV;
    // Area lights: one single-layer perspective shadow map per viewProj[k] (k < spotCosLayers.w): from the centre (k = 0) and
    // the corners (srt --penumbra-maps 5), or from K points of the light (sm). mapEye: xyz eye, w = near;
    // mapRange: x = far, y = footprint 2 tan(fov/2), z = 1 when the field of view was capped (geometry outside the map), w unused.
    vec4 mapEye[6];
    vec4 mapRange[6];
};

// Per-frame constants of the shade pass (std140).
PENUMBRA_STRUCT(FrameData)
{
    vec4 cameraPosition;     // xyz camera position, w unused
    vec4 shading;            // x = ambient, y = albedo, z and w unused (the material colour: shade.comp's kColours)
    vec4 background;         // rgb background colour, a = 1
    vec4 pip;                // x = depth-discontinuity threshold (fraction of the light's depth range), yzw unused
    LightData lights[PENUMBRA_MAX_LIGHTS];
};

// The chunk of work of workgroup `group` of a dispatch over `chunks` chunks,
// in interleaved order (PENUMBRA_GROUP_INTERLEAVE): the chunks form I stripes
// of consecutive chunks (the first chunks mod I stripes one longer), and
// workgroup g takes chunk g / I of stripe g mod I. A bijection of
// [0, chunks), with shifts, masks and multiplies only: llvmpipe divides lane
// by lane. A workgroup past the chunks (the last row of a 2-D layout) keeps
// its index, past them too. Shared with C++ (tests).
PENUMBRA_SHARED_FUNCTION uint interleavedChunk(uint group, uint chunks)
{
    const uint stripe = group % PENUMBRA_GROUP_INTERLEAVE, offset = group / PENUMBRA_GROUP_INTERLEAVE;
    const uint shortLength = chunks / PENUMBRA_GROUP_INTERLEAVE, longer = chunks % PENUMBRA_GROUP_INTERLEAVE;
    const uint chunk = stripe < longer ? stripe * (shortLength + 1u) + offset : longer * (shortLength + 1u) + (stripe - longer) * shortLength + offset;
    return group < chunks ? chunk : group;
}

#ifdef __cplusplus
static_assert(sizeof(LightData) == 6 * 64 + 7 * 16 + 12 * 16, "LightData layout must match std140");
static_assert(sizeof(FrameData) == 4 * 16 + PENUMBRA_MAX_LIGHTS * sizeof(LightData), "FrameData layout must match std140");
} // namespace penumbra::gpu
#endif

#endif
