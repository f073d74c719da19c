// The model tools of the command line: preprocess (in core, streamed within a
// memory limit, or one chunk of a distributed build), merge, generate and
// info. Shared by `penumbra` and the lean `penumbra-preprocess`, which links
// neither Vulkan nor the image libraries (a process baseline of a few MiB
// instead of about 130 MiB: preprocess/README.md, "Streamed builds").
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "penumbra/preprocess.h"

namespace penumbra {

struct PreprocessArgs {
    std::string input;
    std::string output;
    std::string simplify = "1";
    uint32_t clusterVertices = PreprocessOptions{}.maxClusterVertices;
    uint32_t clusterTriangles = PreprocessOptions{}.maxClusterTriangles;
    uint32_t leafTriangles = PreprocessOptions{}.maxLeafTriangles;
    unsigned threads = 0;
    bool separateClosed = false;
    bool quiet = false;
    uint64_t memoryLimitMiB = 0; // 0: in core
    std::string chunk;           // "I/N": one chunk of a distributed build
    std::string tempDir;
};

struct MergeArgs {
    std::vector<std::string> chunks;
    std::string output;
    bool quiet = false;
};

struct GenerateArgs {
    std::string name;
    uint64_t triangles = 1'000'000;
    uint64_t seed = 1;
    std::string output;
    bool draco = false;
    bool ascii = false;
};

struct ToolCommands {
    PreprocessArgs preprocess;
    MergeArgs merge;
    GenerateArgs generate;
    std::string infoPath;
    CLI::App* preprocessCommand = nullptr;
    CLI::App* mergeCommand = nullptr;
    CLI::App* infoCommand = nullptr;
    CLI::App* generateCommand = nullptr;
};

// Adds the preprocess, merge, info and generate subcommands to app.
void addToolCommands(CLI::App& app, ToolCommands& tools);

// Runs the tool subcommand that was parsed, if any: returns true and its exit code in rc.
// Throws Error for failures (the caller prints them as one line).
bool runToolCommands(const ToolCommands& tools, int& rc);

// Fails unless a file can be created at path: its folder exists and can be
// written, and the path itself is not a folder. Outputs are written to a
// temporary name in that folder and renamed, so this is all they need.
void checkWritable(const std::string& path);

} // namespace penumbra
