// Records shared by the suite's measuring code (suite.cpp) and its report
// writers (report.cpp).
#pragma once

#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "penumbra/bench.h"
#include "penumbra/penumbra.h"
#include "shadow_adapter.h"

namespace penumbra::bench {

inline constexpr double kNoValue = std::numeric_limits<double>::quiet_NaN();

struct PassSummary {
    std::string name; // FrameStats pass name: camera, shadow_map, thin_triangles, ...
    double medianMs = 0;
    double bestMs = 0;
};

// A stage against its floor, medians over the floor frames (RenderSettings::measureFloors).
struct FloorSummary {
    std::string stage;    // pass name: camera, view_fit, shadow_map, classify, compact, shade
    double ms = 0;        // the pass
    double floorMs = 0;   // its floor
};

// One measured case (or one that could not run in this build).
struct Record {
    // "methods", "point" (a point light among the geometry), "rh_variants", "scalability", "light_size", or afsm's
    // soft-shadow sweeps "afsm_triangles" (Figure 11) and "afsm_samples" (Figure 13)
    std::string section;
    std::string scene;        // generator name
    uint64_t triangles = 0;   // triangles stored in the model
    double level = 1.0;       // scalability: triangle ratio of the simplification level
    double lightRadius = 0.0; // soft: sphere-light radius as a fraction of the scene diagonal; 0 for hard
    uint32_t lightSamples = 0; // soft: light samples per pixel (afsm: bits per view sample)
    std::string method;       // "sm", "srt", "frt" or "oracle"
    ShadowKind kind = ShadowKind::Hard;
    bool available = true; // false: not run; note says why
    std::string note;
    uint32_t width = 0, height = 0;
    uint32_t frames = 0;           // timed frames (after one warm-up, on a GPU half a second of them, and settleFrames)
    uint32_t settleFrames = 0;     // untimed frames after the warm-up until the culling was steady and srt had chosen (0: at once)
    double medianMs = kNoValue;    // GPU ms per frame (oracle: CPU ms), median of the timed frames
    double bestMs = kNoValue;      // best of the timed frames
    double cpuMedianMs = kNoValue; // wall clock per frame: record + submit + wait + readback
    std::vector<PassSummary> passes;
    std::vector<FloorSummary> floors; // methods section, sm and srt: every stage against its floor
    double pipFraction = kNoValue;      // pixels given rays / covered pixels
    double penumbraFraction = kNoValue; // soft: covered pixels in the penumbra
    uint64_t rays = 0;
    uint64_t nodesVisited = 0;        // rh: cone tests
    uint64_t rhPeakPairBytes = 0;     // rh: the traversal's peak pair memory
    double error = kNoValue;            // mean |visibility - oracle| over light-facing pixels (hard: mismatch share)
    double bytesPerTriangle = kNoValue; // geometry + BVH of the compressed model
    double simplifyError = kNoValue;    // scalability: meshoptimizer's relative error of the level
    uint64_t deviceBytes = 0;           // Renderer::modelDeviceBytes()
    uint64_t peakRssBytes = 0;          // process peak resident set so far (getrusage)
    std::string device, driver;
};

// The triangles each raster view drew, frame after frame, since a light was set (any method's
// frames: the renderer keeps one culling history per view whatever the method). The suite times
// a case only once steady() holds (suite.cpp, warmUp).
struct CullLog {
    std::map<std::string, std::vector<uint64_t>> drawn;

    // Adds a frame. The occlusion culling learns what each view hides over its first frames: a
    // group of clusters whose box passes its query is drawn whole and becomes cells, each tested
    // again only every PENUMBRA_CULL_RETEST_FRAMES frames (culling.h). The 1 M interior's sun view
    // drew 89% of its triangles in the first two frames and 39-44% from the tenth on (its shadow
    // map 396 -> 211 ms on lavapipe), going round an uneven cycle of 4 to 6 frames as hidden
    // groups pass their query again. So a view is steady once the most it drew in a window of
    // PENUMBRA_CULL_RETEST_FRAMES + 1 frames has stopped falling: the window ending at this frame,
    // and the one ending at the frame before, drew what the window before each drew, within 1%.
    bool steady(const FrameStats& stats);
};

// Per-stage groups of Figure 9, from FrameStats pass names.
inline constexpr const char* kStageGroups[] = {"raster", "pip", "compaction", "trace", "shading", "transfers", "other"};
inline constexpr size_t kStageGroupCount = sizeof(kStageGroups) / sizeof(kStageGroups[0]);
// Index into kStageGroups: camera, shadow_map and afsm_casters are raster; thin_triangles, penumbra_mask (soft
// shadows), classify and afsm_samples PIP; compact compaction; trace trace; shade shading; readback transfers; any other pass other.
size_t stageGroupOf(const std::string& passName);

struct SuiteResults {
    SuiteOptions options;
    std::string date; // UTC, ISO 8601
    DeviceInfo device;
    std::vector<Record> records;
    std::vector<std::string> images; // written images, relative to the results folder
    std::vector<std::string> notes;  // one line each, for the summary
};

// Writes methods.csv, methods.json, scalability.csv, light_size.csv,
// stages.csv, the plot data and *.gp scripts, the PNG plots (when gnuplot is
// installed) and summary.md into options.outDir. Returns a one-line note
// about the plots.
std::string writeReport(SuiteResults& results);

// Writes a PNG (through penumbra::writeImage) of the panels side by side,
// separated by a few background pixels. Every panel has the same size.
void writeSideBySide(const std::vector<Image>& panels, const std::string& path);

} // namespace penumbra::bench
