// Shadow methods as data: each method is one entry of one table
// (shadow_methods.cpp) that names it and lists the passes the frame script
// (renderer.cpp) runs for each light, with the modes it pushes to their
// shaders (named constants of config.h). Adding a method: its entry here,
// its value in ShadowMethod (penumbra.h), its new passes and shaders, and
// the bench's method list (runtime/README.md, "Adding a shadow method").
#pragma once

#include <cstdint>
#include <vector>

#include "penumbra/penumbra.h"

namespace penumbra {

// The frame's passes, in the order stats report them.
enum class PassId : uint32_t {
    Camera, ViewFit, ViewFitReadback, ShadowMap, ThinTriangles, PenumbraMask, AfsmSamples, AfsmBin, AfsmRows, AfsmCasters, RhBuild, RhTraverse, Classify,
    Compact, Trace, Shade,
    Readback,
    // RenderSettings::measureFloors: the null twins of the per-pixel passes and the raster passes' uncompressed depth-only draws.
    CameraFloor, ViewFitFloor, ShadowMapFloor, ClassifyFloor, CompactFloor, ShadeFloor,
    Count
};
const char* passName(PassId pass);

// One step of a light's sequence. mode: what the pass's shader is told to do
// (classify: PENUMBRA_CLASSIFY_*; classify of an area light's map:
// PENUMBRA_SOFT_*, cornerMode for the maps from the light's corners).
enum class Step : uint32_t {
    ClearMarks,    // every pixel's marks to 0 (an area light's maps OR into them)
    ShadowMap,     // the map of the layer or area-light map from the light (culled by the BVH)
    ThinTriangles, // thin triangles rasterized conservatively into the thin map
    PenumbraMask,  // the deepest receivers per tile (classify), then the map's penumbra mask
    Classify,      // visibility from the map; marks the pixels that get rays
    Compact,       // marked pixels into the ray list
    Trace,         // the ray list through the BVH (area lights: the light samples)
    Shade,         // the light's contribution added to the colour
    AliasFree,     // per layer: the view samples binned into the light's grid, then the casters tested against them
    AfsmResolve,   // the light's visibility from the samples' shadow flags
    RayHierarchy,  // per layer: the rays listed, their cone hierarchy built, the casters traversing it (sets afsm's shadow flags)
};

struct MethodStep {
    Step step;
    uint32_t mode = 0;
    uint32_t cornerMode = 0;
};

// MethodStep::mode of Step::Shade: the visibility from the light's shadow map
// (shade.comp.lookup), for a hard light; 0: from the visibility image.
inline constexpr uint32_t kShadeLookup = 1;

// Where an area light's shadow maps are taken from (lights.cpp).
enum class AreaMapEyes {
    Centre,       // the centre only
    CentreAndRim, // the centre; with --penumbra-maps 5 also four points on the rim
    Strata,       // the centres of K strata of the light (K = --sm-maps)
};

struct ShadowMethodSpec {
    ShadowMethod method;
    const char* name;        // CLI, stats and bench: "srt"
    const char* description; // one line for --help
    std::vector<MethodStep> hard;      // per directional, point or spot light
    std::vector<MethodStep> softBegin; // per area light, before its maps
    std::vector<MethodStep> softMap;   // per shadow map of an area light: corner maps first, the centre's last
    std::vector<MethodStep> softEnd;   // per area light, after its maps
    AreaMapEyes areaEyes = AreaMapEyes::Centre;
    bool widenAreaMaps = false; // area maps fitted to the view keep room for penumbra thrown from beside it
    bool shadowViewOcclusion = true; // the light's views may be culled by occlusion queries (they draw a depth map)
    bool lightViews = true; // a directional, point or spot light is seen from its position (maps, grids, culled casters);
                            // false: the method needs nothing from the light's side but its rays (frt)

    bool uses(Step step) const; // some sequence of the method has this step
    bool traces() const { return uses(Step::Trace); } // the frame's ray offset and samples apply
    bool drawsAreaMaps() const; // an area light's maps are drawn (so they are fitted to the view)
    bool softShadows() const;   // has a sequence for area lights
};

// Every method, in the order of the ShadowMethod enum.
const std::vector<ShadowMethodSpec>& shadowMethods();
const ShadowMethodSpec& shadowMethodSpec(ShadowMethod method);

} // namespace penumbra
