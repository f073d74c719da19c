// The model tools of the command line (tool_commands.h).
#include "tool_commands.h"

#include <sys/resource.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <new>

#include "penumbra/error.h"
#include "penumbra/generate.h"
#include "penumbra/io.h"
#include "penumbra/model_format.h"
#include "penumbra/progress_bar.h"
#include "penumbra/streamed.h"

namespace penumbra {

void checkWritable(const std::string& path)
{
    namespace fs = std::filesystem;
    std::error_code error;
    if (path.empty())
        fail("output", "empty path");
    if (fs::is_directory(path, error))
        fail(path, "is a folder, not a file");
    fs::path folder = fs::path(path).parent_path();
    if (folder.empty())
        folder = ".";
    if (!fs::is_directory(folder, error))
        fail(path, "folder '" + folder.string() + "' does not exist");
    if (::access(folder.c_str(), W_OK) != 0)
        fail(path, "folder '" + folder.string() + "' is not writable");
}


namespace {

std::vector<float> parseRatios(const std::string& text)
{
    std::vector<float> ratios;
    size_t start = 0;
    while (start <= text.size()) {
        size_t end = text.find(',', start);
        std::string part = text.substr(start, end == std::string::npos ? std::string::npos : end - start);
        char* stop = nullptr;
        float ratio = std::strtof(part.c_str(), &stop);
        if (part.empty() || *stop != '\0' || !(ratio > 0.0f && ratio <= 1.0f))
            fail("--simplify " + text, "'" + part + "' is not a ratio in (0, 1]");
        ratios.push_back(ratio);
        if (end == std::string::npos)
            break;
        start = end + 1;
    }
    return ratios;
}

// "scan.penumbra" with ratio 0.25 of several -> "scan.0.25.penumbra".
std::string levelPath(const std::string& output, float ratio, bool several)
{
    if (!several)
        return output;
    char text[32];
    std::snprintf(text, sizeof(text), "%g", double(ratio));
    size_t dot = output.find_last_of('.');
    size_t slash = output.find_last_of('/');
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash))
        return output + "." + text;
    return output.substr(0, dot) + "." + text + output.substr(dot);
}

double peakRssMiB()
{
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return double(usage.ru_maxrss) / 1024.0;
}

// "I/N" -> index, count.
void parseChunk(const std::string& text, uint32_t& index, uint32_t& count)
{
    char slash = 0, extra = 0;
    unsigned long long i = 0, n = 0;
    if (std::sscanf(text.c_str(), "%llu%c%llu%c", &i, &slash, &n, &extra) != 3 || slash != '/' || n == 0 || i >= n ||
        n > (1ull << 20))
        fail("--chunk " + text, "expected I/N with 0 <= I < N <= 1048576 (e.g. 3/16)");
    index = uint32_t(i);
    count = uint32_t(n);
}

void printStreamed(const std::string& path, const StreamedStats& stats, uint64_t limitMiB, double seconds)
{
    const double stored = double(std::max<uint64_t>(stats.triangles, 1));
    std::printf("%s: %llu triangles, %llu clusters, %llu nodes, %.2f B/tri, max error %.3g, closed %.1f%% of triangles in "
                "closed clusters (%.1f%% in closed components; a part cut by a chunk boundary counts as open), %u chunk(s) "
                "of <= %llu triangles (largest %llu), peak RSS %.0f MiB (limit %llu MiB), temporary disk %.0f MiB, vertex "
                "cache hits %.1f%%, scan %.1f s, partition %.1f s, build %.1f s, merge %.1f s, %.2f s (%.2f M tris/s)\n",
                path.c_str(), (unsigned long long)stats.triangles, (unsigned long long)stats.clusters,
                (unsigned long long)stats.nodes, double(stats.fileBytes) / stored, double(stats.maxPositionError),
                100.0 * double(stats.closedClusterTriangles) / stored, 100.0 * double(stats.closedTriangles) / stored,
                stats.chunks, (unsigned long long)stats.chunkCapacity, (unsigned long long)stats.largestChunk, peakRssMiB(),
                (unsigned long long)limitMiB, double(stats.temporaryBytes) / double(1 << 20), 100.0 * stats.vertexCacheHitRate,
                stats.scanSeconds, stats.partitionSeconds, stats.buildSeconds, stats.mergeSeconds, seconds,
                double(stats.inputTriangles) / std::max(seconds, 1e-9) * 1e-6);
}

int preprocessCommand(const PreprocessArgs& args);

// Out of memory (an allocation refused: a ulimit -v, a container's limit) names the input and
// what to change.
int runPreprocess(const PreprocessArgs& args)
{
    try {
        return preprocessCommand(args);
    } catch (const std::bad_alloc&) {
        if (args.memoryLimitMiB > 0 || !args.chunk.empty())
            fail(args.input, "out of memory with --memory-limit " + std::to_string(args.memoryLimitMiB ? args.memoryLimitMiB : 1024) +
                                 " (MiB): an allocation within that budget was refused (a ulimit or container limit below "
                                 "it?); lower --memory-limit or --threads");
        fail(args.input, "out of memory preprocessing it whole; build it out of core with --memory-limit MIB, or with fewer "
                         "--threads");
    }
}

int preprocessCommand(const PreprocessArgs& args)
{
    std::vector<float> ratios = parseRatios(args.simplify);
    const bool streamed = args.memoryLimitMiB > 0 || !args.chunk.empty();
    std::string extension = args.output.size() >= 9 ? args.output.substr(args.output.size() - 9) : "";
    if (extension != ".penumbra" && args.chunk.empty())
        fail(args.output, "the output must end in .penumbra");
    if (!args.chunk.empty() && extension == ".penumbra")
        fail(args.output, "--chunk writes a chunk file for penumbra merge, not a .penumbra model (name it e.g. model.chunk3)");
    checkWritable(args.output);
    PreprocessOptions options;
    options.maxClusterVertices = args.clusterVertices;
    options.maxClusterTriangles = args.clusterTriangles;
    options.maxLeafTriangles = args.leafTriangles;
    options.threads = args.threads;
    options.separateClosed = args.separateClosed;
    if (!streamed && !args.tempDir.empty())
        fail("--temp-dir " + args.tempDir, "only applies to streamed builds (--memory-limit or --chunk)");
    if (streamed) {
        if (ratios.size() != 1 || ratios[0] != 1.0f)
            fail("--simplify " + args.simplify, "cannot be combined with --memory-limit or --chunk (simplification needs the "
                                                "whole mesh in memory); simplify without them, or preprocess the model whole");
        if (!args.tempDir.empty() && !std::filesystem::is_directory(args.tempDir))
            fail(args.tempDir, "--temp-dir is not a folder");
        StreamedOptions streamedOptions;
        streamedOptions.build = options;
        streamedOptions.memoryLimit = (args.memoryLimitMiB ? args.memoryLimitMiB : 1024) << 20;
        streamedOptions.tempDirectory = args.tempDir;
        ProgressBar progress(!args.quiet);
        streamedOptions.progress = [&](const std::string& stage, double fraction) { progress.update(stage, fraction); };
        auto start = std::chrono::steady_clock::now();
        StreamedStats stats;
        if (args.chunk.empty()) {
            stats = preprocessStreamed(args.input, args.output, streamedOptions);
        } else {
            uint32_t index = 0, count = 0;
            parseChunk(args.chunk, index, count);
            stats = preprocessChunk(args.input, args.output, index, count, streamedOptions);
        }
        progress.finish();
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        if (args.chunk.empty())
            printStreamed(args.output, stats, streamedOptions.memoryLimit >> 20, seconds);
        else
            std::printf("%s: chunk %s of %llu input triangles (%llu in this chunk), %llu bytes, peak RSS %.0f MiB (limit %llu "
                        "MiB), temporary disk %.0f MiB, %.2f s\n",
                        args.output.c_str(), args.chunk.c_str(), (unsigned long long)stats.inputTriangles,
                        (unsigned long long)stats.triangles, (unsigned long long)stats.fileBytes, peakRssMiB(),
                        (unsigned long long)(streamedOptions.memoryLimit >> 20), double(stats.temporaryBytes) / double(1 << 20),
                        seconds);
        return 0;
    }

    ProgressBar progress(!args.quiet);
    auto start = std::chrono::steady_clock::now();
    auto seconds = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };
    progress.update("import", 0.0);
    Scene scene = importScene(args.input);
    double importSeconds = seconds();

    for (float ratio : ratios) {
        std::string path = levelPath(args.output, ratio, ratios.size() > 1);
        char label[64];
        std::snprintf(label, sizeof(label), "level %g: ", double(ratio));
        double levelStart = seconds();
        SimplifiedMesh simplified;
        const Mesh* mesh = &scene.mesh;
        if (ratio < 1.0f) {
            progress.update(std::string(label) + "simplify", 0.0);
            simplified = simplifyMesh(scene.mesh, ratio);
            mesh = &simplified.mesh;
        }
        options.progress = [&](const char* stage, double fraction) { progress.update(std::string(label) + stage, fraction); };
        PreprocessStats stats;
        CompressedModel model = withScene(buildCompressedModel(*mesh, options, &stats), scene.cameras, scene.lights, args.input);
        model.header.sourceTriangleCount = scene.mesh.triangleCount();
        model.header.build.simplifyTarget = ratio;
        model.header.simplifyError = ratio < 1.0f ? simplified.error : 0.0f;
        progress.update(std::string(label) + "write", 1.0);
        writeModelFile(model, path);
        progress.finish();
        uint64_t bytes = model.clusters.size_bytes() + model.nodes.size_bytes() + model.vertices.size_bytes() + model.indices.size_bytes() +
                         model.materials.size_bytes();
        const double stored = double(std::max<uint64_t>(model.header.triangleCount, 1));
        std::printf("%s: %llu triangles (%.4g of %zu%s), %u clusters, %u nodes, %.2f B/tri, max error %.3g, "
                    "closed %.1f%% of triangles in closed clusters (%.1f%% in closed components), %.2f s "
                    "(%.2f M tris/s incl. import %.2f s)\n",
                    path.c_str(), (unsigned long long)model.header.triangleCount, double(model.header.triangleCount) / scene.mesh.triangleCount(),
                    scene.mesh.triangleCount(), ratio < 1.0f && simplified.sloppy ? ", sloppy" : "", model.header.clusterCount,
                    model.header.nodeCount, double(bytes) / double(model.header.triangleCount), double(model.header.maxPositionError),
                    100.0 * double(stats.closedClusterTriangles) / stored, 100.0 * double(stats.closedTriangles) / stored,
                    seconds() - levelStart, double(mesh->triangleCount()) / (seconds() - levelStart + importSeconds) * 1e-6,
                    importSeconds);
    }
    return 0;
}

int runMerge(const MergeArgs& args)
{
    std::string extension = args.output.size() >= 9 ? args.output.substr(args.output.size() - 9) : "";
    if (extension != ".penumbra")
        fail(args.output, "the output must end in .penumbra");
    checkWritable(args.output);
    ProgressBar progress(!args.quiet);
    StreamedOptions options;
    options.progress = [&](const std::string& stage, double fraction) { progress.update(stage, fraction); };
    auto start = std::chrono::steady_clock::now();
    StreamedStats stats = mergeChunkFiles(args.chunks, args.output, options);
    progress.finish();
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const double stored = double(std::max<uint64_t>(stats.triangles, 1));
    std::printf("%s: %llu triangles from %u chunk files, %llu clusters, %llu nodes, depth %u, %.2f B/tri, closed %.1f%% of "
                "triangles in closed clusters, peak RSS %.0f MiB, %.2f s\n",
                args.output.c_str(), (unsigned long long)stats.triangles, stats.chunks, (unsigned long long)stats.clusters,
                (unsigned long long)stats.nodes, stats.bvhDepth, double(stats.fileBytes) / stored,
                100.0 * double(stats.closedClusterTriangles) / stored, peakRssMiB(), seconds);
    return 0;
}

int runInfo(const std::string& path)
{
    CompressedModel model = openModelFile(path);
    const model::FileHeader& h = model.header;
    double triangles = double(std::max<uint64_t>(h.triangleCount, 1));
    std::printf("%s: Penumbra model, version %u, %llu bytes\n", path.c_str(), h.version, (unsigned long long)h.fileSize);
    std::printf("  triangles        %llu (source %llu, simplify target %g, error %.3g)\n", (unsigned long long)h.triangleCount,
                (unsigned long long)h.sourceTriangleCount, double(h.build.simplifyTarget), double(h.simplifyError));
    std::printf("  vertices         %llu (%.3f per triangle)\n", (unsigned long long)h.vertexCount, double(h.vertexCount) / triangles);
    std::printf("  clusters         %u (avg %.0f triangles, %.0f vertices)\n", h.clusterCount, triangles / h.clusterCount,
                double(h.vertexCount) / h.clusterCount);
    // The 4-wide BVH (format version 4): nodes above the clusters and inside them, leaf slots.
    uint64_t topNodes = 0, slots = 0, leaves = 0;
    for (const model::Node& node : model.nodes) {
        const uint32_t children = model::childCount(node);
        topNodes += node.cluster == model::kNoCluster ? 1 : 0;
        slots += children;
        for (uint32_t c = 0; c < children; ++c)
            leaves += model::childKind(node, c) == model::ChildKind::Leaf ? 1 : 0;
    }
    std::printf("  BVH              %u nodes (%llu above the clusters), depth %u (at most %u), 4-wide: %.2f children per node\n",
                h.nodeCount, (unsigned long long)topNodes, h.bvhDepth, model::kMaxBvhDepth, double(slots) / h.nodeCount);
    std::printf("  leaves           %llu strip ranges (avg %.1f triangles)\n", (unsigned long long)leaves,
                triangles / double(std::max<uint64_t>(leaves, 1)));
    std::printf("  bounds           (%g, %g, %g) - (%g, %g, %g)\n", double(h.boundsMin[0]), double(h.boundsMin[1]), double(h.boundsMin[2]),
                double(h.boundsMax[0]), double(h.boundsMax[1]), double(h.boundsMax[2]));
    std::printf("  quantization     %u-bit positions per cluster box, max error %.3g; %u-bit node bounds\n", h.build.positionBits,
                double(h.maxPositionError), h.build.nodeBoundsBits);
    std::printf("  build            cluster <= %u vertices / %u triangles, leaves <= %u triangles, %u SAH bins\n",
                h.build.maxClusterVertices, h.build.maxClusterTriangles, h.build.maxLeafTriangles, h.build.sahBins);
    struct Row { const char* name; uint64_t bytes; } rows[] = {
        {"clusters", model.clusters.size_bytes()}, {"nodes", model.nodes.size_bytes()},
        {"vertices", model.vertices.size_bytes()}, {"indices", model.indices.size_bytes()},
        {"materials", model.materials.size_bytes()}};
    uint64_t total = 0;
    std::printf("  %-16s %14s %10s\n", "section", "bytes", "B/tri");
    for (const Row& row : rows) {
        std::printf("  %-16s %14llu %10.3f\n", row.name, (unsigned long long)row.bytes, double(row.bytes) / triangles);
        total += row.bytes;
    }
    std::printf("  %-16s %14llu %10.3f\n", "total", (unsigned long long)total, double(total) / triangles);
    std::printf("  materials        %u\n", h.materialCount);
    uint64_t closedClusters = 0, closedTriangles = 0;
    for (const model::ClusterRecord& c : model.clusters)
        if (c.flags & model::kClusterClosed) {
            ++closedClusters;
            closedTriangles += c.triangleCount;
        }
    std::printf("  closed           %llu clusters, %llu triangles (%.1f%%) of closed 2-manifold components\n",
                (unsigned long long)closedClusters, (unsigned long long)closedTriangles, 100.0 * double(closedTriangles) / triangles);
    std::printf("  scene            %u camera(s), %u light(s), %llu bytes\n", h.cameraCount, h.lightCount,
                (unsigned long long)(model.cameras.size_bytes() + model.lights.size_bytes()));
    return 0;
}

int runGenerate(const GenerateArgs& args)
{
    GenerateOptions options;
    options.triangles = args.triangles;
    options.seed = args.seed;
    auto start = std::chrono::steady_clock::now();
    formatFromPath(args.output); // reject an unknown extension or folder before the work
    checkWritable(args.output);
    // The scan as binary PLY is written row by row (inputs larger than memory); the same bytes.
    if (!args.draco) {
        uint64_t triangles = 0, vertices = 0;
        if (writeSceneStreamed(args.name, options, args.output, !args.ascii, &triangles, &vertices)) {
            double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
            std::printf("%s: %llu triangles, %llu vertices, generated and written (streamed) in %.0f ms\n", args.output.c_str(),
                        (unsigned long long)triangles, (unsigned long long)vertices, ms);
            return 0;
        }
    }
    Scene scene = generateScene(args.name, options);
    double generateMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    ExportOptions exportOptions;
    exportOptions.binary = !args.ascii;
    exportOptions.draco = args.draco;
    start = std::chrono::steady_clock::now();
    exportScene(scene, args.output, exportOptions);
    double writeMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    std::printf("%s: %zu triangles, %zu vertices, generated in %.0f ms, written in %.0f ms\n", args.output.c_str(),
                scene.mesh.triangleCount(), scene.mesh.vertexCount(), generateMs, writeMs);
    return 0;
}

} // namespace

void addToolCommands(CLI::App& app, ToolCommands& tools)
{
    tools.preprocessCommand = app.add_subcommand("preprocess", "Compress a model into a .penumbra file: strip clusters + one BVH");
    tools.preprocessCommand->add_option("input", tools.preprocess.input, "Model file: .obj .ply .stl .gltf .glb .drc")->required();
    tools.preprocessCommand->add_option("-o,--output", tools.preprocess.output, "Output .penumbra file (with several --simplify ratios: NAME.<ratio>.penumbra)")->required();
    tools.preprocessCommand->add_option("--simplify", tools.preprocess.simplify, "Comma-separated triangle ratios, one file each, e.g. 1,0.5,0.25")->capture_default_str();
    tools.preprocessCommand->add_option("--cluster-vertices", tools.preprocess.clusterVertices, "Vertices per cluster (8-bit local indices)")->capture_default_str()->check(CLI::Range(3, 255));
    tools.preprocessCommand->add_option("--cluster-triangles", tools.preprocess.clusterTriangles, "Triangles per cluster")->capture_default_str()->check(CLI::Range(1, 1024));
    tools.preprocessCommand->add_option("--leaf-triangles", tools.preprocess.leafTriangles, "Triangles per strip-range leaf of a cluster's BVH")->capture_default_str()->check(CLI::Range(1, 1024));
    tools.preprocessCommand->add_option("--threads", tools.preprocess.threads, "Worker threads (0: all cores)")->capture_default_str();
    tools.preprocessCommand->add_flag("--separate-closed", tools.preprocess.separateClosed,
                                "Clusters do not mix closed 2-manifold parts that no other surface comes near (within the "
                                "shadow-ray offset) with the rest, so those get the closed flag (changes the clusters, hence "
                                "the quantized positions, of models with both)");
    tools.preprocessCommand->add_option("--memory-limit", tools.preprocess.memoryLimitMiB,
                                  "Streamed build within this many MiB (plus the process's baseline): the input is read in "
                                  "passes, partitioned into chunks on disk, each built in memory, merged; for models larger "
                                  "than memory")
        ->check(CLI::Range(uint64_t(32), uint64_t(1) << 40));
    tools.preprocessCommand->add_option("--chunk", tools.preprocess.chunk,
                                  "I/N: build chunk I of N of a streamed build into the output (a chunk file); run the N "
                                  "chunks as independent processes, then penumbra merge");
    tools.preprocessCommand->add_option("--temp-dir", tools.preprocess.tempDir,
                                  "Folder for the streamed build's temporary files (default: the output's folder)");
    tools.preprocessCommand->add_flag("--quiet", tools.preprocess.quiet, "No progress bar");

    tools.mergeCommand = app.add_subcommand("merge", "Join the chunk files of penumbra preprocess --chunk I/N into a .penumbra file");
    tools.mergeCommand->add_option("chunks", tools.merge.chunks, "Chunk files (every I of 0..N-1 exactly once, any order)")->required();
    tools.mergeCommand->add_option("-o,--output", tools.merge.output, "Output .penumbra file")->required();
    tools.mergeCommand->add_flag("--quiet", tools.merge.quiet, "No progress bar");

    tools.infoCommand = app.add_subcommand("info", "Describe a .penumbra model file (validates it completely)");
    tools.infoCommand->add_option("model", tools.infoPath, "A .penumbra file")->required();

    tools.generateCommand = app.add_subcommand("generate", "Write a procedural benchmark scene: city, interior, plant or scan");
    tools.generateCommand->add_option("name", tools.generate.name, "Scene: city, interior, plant, scan")->required();
    tools.generateCommand->add_option("--triangles", tools.generate.triangles, "Triangle budget")->capture_default_str();
    tools.generateCommand->add_option("--seed", tools.generate.seed, "Random seed (same seed, same file)")->capture_default_str();
    tools.generateCommand->add_option("-o,--output", tools.generate.output, "Output model: .ply .glb .gltf .obj .stl .drc")->required();
    tools.generateCommand->add_flag("--draco", tools.generate.draco, "glTF/GLB: compress with KHR_draco_mesh_compression");
    tools.generateCommand->add_flag("--ascii", tools.generate.ascii, "PLY/STL: write ASCII instead of binary");

}

bool runToolCommands(const ToolCommands& tools, int& rc)
{
    if (tools.generateCommand->parsed())
        rc = runGenerate(tools.generate);
    else if (tools.preprocessCommand->parsed())
        rc = runPreprocess(tools.preprocess);
    else if (tools.mergeCommand->parsed())
        rc = runMerge(tools.merge);
    else if (tools.infoCommand->parsed())
        rc = runInfo(tools.infoPath);
    else
        return false;
    return true;
}

} // namespace penumbra
