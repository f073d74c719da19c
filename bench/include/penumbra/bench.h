// The benchmark suite behind `penumbra bench SUITE` (Lauterbach et al. 2009,
// section 6): the shadow methods side by side (Figure 8), time per stage
// (Figure 9), scalability over simplification levels of one model and time
// against light size (Figure 7). Writes CSV, JSON, gnuplot scripts and PNG
// plots, images of every method beside the Embree oracle with difference
// images, and a Markdown summary into one results folder. Embree is used here
// as the reference only, never in the render path.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace penumbra {

// One procedural scene of the method comparison.
struct BenchScene {
    std::string name;       // generateScene name: city, interior, plant, scan
    uint64_t triangles = 0; // triangle budget
};

struct SuiteOptions {
    std::string suite;                  // "smoke", "quick" or "full" (see suiteOptions)
    std::string outDir;                 // results folder; created, files in it replaced
    std::string device;                 // Vulkan device: index or part of its name; empty: default
    uint32_t size = 512;                // image width and height
    uint32_t frames = 3;                // timed frames per case after one warm-up frame (a GPU: half a second of them)
    std::vector<BenchScene> scenes;     // method comparison and per-stage breakdown
    uint64_t scanTriangles = 1'000'000; // scalability: the full-resolution scan model
    std::vector<double> levels;         // scalability: triangle ratios in (0, 1], any order
    std::string sweepScene = "city";    // light-size sweep: this scene of `scenes`
    std::vector<double> lightRadii;     // light-size sweep: sphere-light radius, fraction of the scene diagonal
    double softLightRadius = 0.01;      // soft cases of the method comparison: radius, fraction of the diagonal
    uint32_t lightSamples = 16;         // soft shadows: light samples per pixel (renderer and oracle alike)
    uint32_t afsmSamples = 256;         // soft shadows, afsm: light samples (bits per view sample), 128..1024; its oracle traces the table's samples
    std::vector<uint32_t> afsmSampleCounts = {128, 256, 512, 1024}; // afsm's sample sweep (the paper's Figure 13), on sweepScene
    uint32_t penumbraMaps = 1;          // soft shadows, srt: 1 or 5 shadow maps mark the penumbra
    uint32_t softShadowMaps = 4;        // soft shadows, sm: point-light shadow maps averaged over the light, 1..6
    bool progress = true;               // progress bar on stderr when it is a terminal
    bool plots = true;                  // run gnuplot on the generated scripts when it is installed
    bool floors = true;                 // methods section, sm and srt: also N frames with every stage's floor (floors.csv)
    bool srtAdaptive = true;            // srt frames may trace every pixel where that measured cheaper (RenderSettings::srtTraceAllWhenCheaper)
    std::vector<std::string> methods;   // only these GPU methods ("sm", "srt", ...); empty: all (the oracle always runs)
    std::vector<std::string> sections;  // only these sections: methods, soft, point, rh_variants, scalability (with afsm_triangles), light_size, afsm_samples; empty: all
};

// Names accepted by suiteOptions, fastest first: smoke (CI, well under a
// minute), quick (under 5 minutes on 2 cores with lavapipe), full.
std::vector<std::string> suiteNames();

// The defaults of a suite. Throws Error for an unknown name.
SuiteOptions suiteOptions(const std::string& suite);

// "results/<suite>-<UTC date and time>".
std::string defaultResultsDir(const std::string& suite);

// Runs the suite and writes the results folder (file list: README.md,
// section Benchmarks). Prints one line per measured case to stdout. Throws
// Error for bad options or when a file cannot be written. Returns the number
// of records written.
size_t runSuite(const SuiteOptions& options);

} // namespace penumbra
