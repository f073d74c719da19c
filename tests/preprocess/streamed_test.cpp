// Streamed and distributed builds (streamed.h): small models split into many
// chunks give a valid file with every input triangle once (decoded within the
// quantization error), the closed flag stays conservative, the chunk + merge
// path run as separate processes gives the same bytes as the in-process build,
// and bad chunk files or an interrupted build leave no model behind.
#include <glm/common.hpp>
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

#include "penumbra/chunk_file.h"
#include "penumbra/error.h"
#include "penumbra/generate.h"
#include "penumbra/io.h"
#include "penumbra/streamed.h"

using namespace penumbra;

namespace {

std::string tmp(const std::string& name)
{
    return std::string(PENUMBRA_TEST_TMP) + "/" + name;
}

std::string readBytes(const std::string& path)
{
    std::ifstream file(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>());
}

void writeBytes(const std::string& path, const std::string& bytes)
{
    std::ofstream file(path, std::ios::binary | std::ios::trunc);
    file.write(bytes.data(), std::streamsize(bytes.size()));
}

Scene scene(const std::string& name, uint64_t triangles)
{
    GenerateOptions options;
    options.triangles = triangles;
    return generateScene(name, options);
}

std::string writeInput(const std::string& file, const Scene& s)
{
    const std::string path = tmp(file);
    exportScene(s, path);
    return path;
}

StreamedOptions smallChunks(uint64_t triangles)
{
    StreamedOptions options;
    options.memoryLimit = uint64_t(64) << 20;
    options.chunkTriangles = triangles;
    options.tempDirectory = PENUMBRA_TEST_TMP;
    options.build.threads = 2;
    return options;
}

// Matches the decoded triangles (clusters in order, strips in order) with the input's: each
// non-degenerate input triangle must have exactly one decoded twin, with its winding, each corner
// within the model's maxPositionError (plus a rounding). Returns the input triangle of each decoded
// one (-1 when none).
std::vector<int64_t> matchTriangles(const Mesh& mesh, const CompressedModel& model)
{
    struct Decoded {
        glm::vec3 p[3];
        int64_t source = -1;
    };
    std::vector<Decoded> decoded;
    decoded.reserve(model.header.triangleCount);
    for (const model::ClusterRecord& c : model.clusters) {
        const uint8_t* strips = model.indices.data() + c.firstIndex;
        forEachStripTriangle(strips, strips + c.indexBytes, [&](uint32_t a, uint32_t b, uint32_t d) {
            Decoded t;
            t.p[0] = decodePosition(c, model.vertices[c.firstVertex + a]);
            t.p[1] = decodePosition(c, model.vertices[c.firstVertex + b]);
            t.p[2] = decodePosition(c, model.vertices[c.firstVertex + d]);
            decoded.push_back(t);
        });
    }
    const float tolerance = model.header.maxPositionError * 1.001f + 1e-7f;
    const float cell = std::max(tolerance * 4.0f, 1e-6f);
    auto key = [cell](const glm::vec3& p, int dx, int dy, int dz) {
        const int64_t x = int64_t(std::floor(p.x / cell)) + dx, y = int64_t(std::floor(p.y / cell)) + dy,
                      z = int64_t(std::floor(p.z / cell)) + dz;
        return uint64_t(x * 73856093) ^ uint64_t(y * 19349663) ^ uint64_t(z * 83492791);
    };
    std::unordered_multimap<uint64_t, uint32_t> byCorner;
    for (uint32_t i = 0; i < decoded.size(); ++i)
        byCorner.emplace(key(decoded[i].p[0], 0, 0, 0), i);
    auto near = [tolerance](const glm::vec3& a, const glm::vec3& b) {
        return std::abs(a.x - b.x) <= tolerance && std::abs(a.y - b.y) <= tolerance && std::abs(a.z - b.z) <= tolerance;
    };
    uint64_t inputTriangles = 0, missing = 0;
    for (size_t t = 0; t < mesh.triangleCount(); ++t) {
        const uint32_t* idx = &mesh.indices[3 * t];
        if (idx[0] == idx[1] || idx[1] == idx[2] || idx[0] == idx[2])
            continue;
        ++inputTriangles;
        const glm::vec3 q[3] = {mesh.position(idx[0]), mesh.position(idx[1]), mesh.position(idx[2])};
        bool found = false;
        for (int r = 0; r < 3 && !found; ++r) // decoded corner 0 is input corner r
            for (int dx = -1; dx <= 1 && !found; ++dx)
                for (int dy = -1; dy <= 1 && !found; ++dy)
                    for (int dz = -1; dz <= 1 && !found; ++dz) {
                        auto range = byCorner.equal_range(key(q[r], dx, dy, dz));
                        for (auto it = range.first; it != range.second && !found; ++it) {
                            Decoded& d = decoded[it->second];
                            if (d.source < 0 && near(d.p[0], q[r]) && near(d.p[1], q[(r + 1) % 3]) && near(d.p[2], q[(r + 2) % 3])) {
                                d.source = int64_t(t);
                                found = true;
                            }
                        }
                    }
        missing += !found;
    }
    EXPECT_EQ(model.header.triangleCount, inputTriangles);
    EXPECT_EQ(missing, 0u) << "input triangles without their decoded twin";
    std::vector<int64_t> source(decoded.size());
    for (size_t i = 0; i < decoded.size(); ++i)
        source[i] = decoded[i].source;
    return source;
}

void expectSameTriangles(const Mesh& mesh, const CompressedModel& model)
{
    matchTriangles(mesh, model);
}

// Every decoded vertex of a leaf lies in the header's bounds and in every decoded child box on
// the path to it (the merge lays new nodes out above the chunks' roots and rebases theirs).
void expectBoxesContainGeometry(const CompressedModel& model)
{
    struct Visit {
        uint32_t node;
        glm::vec3 min, max; // the intersection of the boxes on the path
    };
    const model::FileHeader& h = model.header;
    std::vector<Visit> stack{{0, {h.boundsMin[0], h.boundsMin[1], h.boundsMin[2]}, {h.boundsMax[0], h.boundsMax[1], h.boundsMax[2]}}};
    uint64_t leaves = 0, outside = 0;
    while (!stack.empty()) {
        const Visit v = stack.back();
        stack.pop_back();
        const model::Node& n = model.nodes[v.node];
        for (uint32_t k = 0; k < model::childCount(n); ++k) {
            glm::vec3 min, max;
            decodeChildBox(n, k, min, max);
            min = glm::max(min, v.min);
            max = glm::min(max, v.max);
            if (model::childKind(n, k) != model::ChildKind::Leaf) {
                stack.push_back({n.child[k], min, max});
                continue;
            }
            ++leaves;
            const model::ClusterRecord& c = model.clusters[n.cluster];
            const uint8_t* strips = model.indices.data() + c.firstIndex + (n.child[k] & 0xFFFF);
            forEachStripTriangle(strips, strips + (n.child[k] >> 16), [&](uint32_t a, uint32_t b, uint32_t d) {
                for (uint32_t i : {a, b, d}) {
                    const glm::vec3 p = decodePosition(c, model.vertices[c.firstVertex + i]);
                    for (int ax = 0; ax < 3; ++ax)
                        outside += p[ax] < min[ax] || p[ax] > max[ax];
                }
            });
        }
    }
    EXPECT_GT(leaves, 0u);
    EXPECT_EQ(outside, 0u) << "decoded vertices outside a decoded box on their leaf's path";
}

CompressedModel streamed(const std::string& input, const std::string& output, const StreamedOptions& options,
                         StreamedStats* stats = nullptr)
{
    StreamedStats s = preprocessStreamed(input, output, options);
    if (stats)
        *stats = s;
    return openModelFile(output); // validates every byte
}

// Per input triangle: whether a build flags its cluster kClusterClosed (source: matchTriangles).
std::vector<uint8_t> flaggedTriangles(const Mesh& mesh, const CompressedModel& model, uint64_t* count = nullptr)
{
    const std::vector<int64_t> source = matchTriangles(mesh, model);
    std::vector<uint8_t> flagged(mesh.triangleCount(), 0);
    uint64_t k = 0, n = 0;
    for (const model::ClusterRecord& c : model.clusters)
        for (uint32_t i = 0; i < c.triangleCount; ++i, ++k)
            if ((c.flags & model::kClusterClosed) && source[k] >= 0) {
                flagged[size_t(source[k])] = 1;
                ++n;
            }
    if (count)
        *count = n;
    return flagged;
}

TEST(Streamed, ScenesInManyChunksKeepEveryTriangle)
{
    for (const char* name : {"city", "plant", "scan", "interior"}) {
        SCOPED_TRACE(name);
        const Scene s = scene(name, 30'000);
        const std::string input = writeInput(std::string("streamed_") + name + ".ply", s);
        StreamedStats stats;
        CompressedModel model = streamed(input, tmp(std::string("streamed_") + name + ".penumbra"), smallChunks(4'000), &stats);
        EXPECT_GE(stats.chunks, 6u);
        EXPECT_EQ(stats.inputTriangles, s.mesh.triangleCount());
        EXPECT_EQ(model.header.sourceTriangleCount, s.mesh.triangleCount());
        EXPECT_LE(model.header.bvhDepth, model::kMaxBvhDepth);
        expectSameTriangles(s.mesh, model);
        expectBoxesContainGeometry(model);
    }
    // The source's cameras and lights are kept, as by the in-core build.
    Scene gltf = scene("city", 8'000);
    const std::string input = writeInput("streamed_scene.glb", gltf);
    CompressedModel model = streamed(input, tmp("streamed_scene.penumbra"), smallChunks(2'000));
    ASSERT_EQ(model.cameras.size(), 1u);
    ASSERT_EQ(model.lights.size(), 1u);
    const Scene imported = importScene(input);
    EXPECT_EQ(cameraFromRecord(model.cameras[0]).position, imported.cameras[0].position);
    EXPECT_EQ(cameraFromRecord(model.cameras[0]).target, imported.cameras[0].target);
    EXPECT_EQ(lightFromRecord(model.lights[0]).direction, imported.lights[0].direction);
    {
    }
}

// Seventy chunks of one or two clusters each: the merge lays 4-wide nodes out above their roots
// (the layout stage's collapse, level by level), each root at most at the depth it was built for.
TEST(Streamed, ManySmallChunksUnderFourWideTopNodes)
{
    const Scene s = scene("scan", 12'000);
    const std::string input = writeInput("streamed_many.ply", s);
    StreamedOptions options = smallChunks(400);
    options.chunks = 70;
    StreamedStats stats;
    CompressedModel model = streamed(input, tmp("streamed_many.penumbra"), options, &stats);
    EXPECT_GE(stats.chunks, 60u);
    expectSameTriangles(s.mesh, model);
    expectBoxesContainGeometry(model);
    EXPECT_EQ(model::childCount(model.nodes[0]), 4u) << "the top is collapsed into 4-wide nodes";
    // The nodes above the clusters: each chunk's root (here mostly over one cluster) and the top's
    // (1 + 4 + 16 + 6 for 70 leaves of 7 binary levels, against 69 binary nodes).
    uint64_t above = 0;
    for (const model::Node& n : model.nodes)
        above += n.cluster == model::kNoCluster ? 1 : 0;
    EXPECT_LE(above, uint64_t(stats.chunks) + uint64_t(stats.chunks) / 2);
    // A chunk's root sits at depth <= subtreeRootDepth(70) = 5: its clusters' roots at most one below.
    std::vector<uint32_t> depth(model.nodes.size(), 0);
    depth[0] = 1;
    uint32_t deepestClusterRoot = 0;
    for (size_t n = 0; n < model.nodes.size(); ++n)
        for (uint32_t c = 0; c < model::childCount(model.nodes[n]); ++c) {
            if (model::childKind(model.nodes[n], c) == model::ChildKind::Leaf)
                continue;
            depth[model.nodes[n].child[c]] = depth[n] + 1;
            if (model::childKind(model.nodes[n], c) == model::ChildKind::Cluster)
                deepestClusterRoot = std::max(deepestClusterRoot, depth[n] + 1);
        }
    EXPECT_LE(deepestClusterRoot, 5u + 4u);
    EXPECT_LE(model.header.bvhDepth, model::kMaxBvhDepth);
}

// Exponentially spaced triangles in clusters of 4 and leaves of 1 make the deepest trees SAH
// builds (Preprocess.DepthLimit): in chunks below 4-wide top nodes, each chunk's binary build
// and layout keep to the levels left below its root, so the merged BVH stays within 32 levels.
// (Their ever wider gaps also once dragged the partition's cut to the end of every range.)
TEST(Streamed, DepthBudgetHoldsBelowTheTopNodes)
{
    Scene s;
    float x = 1.0f;
    for (uint32_t i = 0; i < 8000; ++i) { // sizes grow with x: no two corners round to one position
        const uint32_t base = uint32_t(s.mesh.vertexCount());
        s.mesh.positions.insert(s.mesh.positions.end(), {x, 0, 0, x * 1.001f, 0, 0, x, x * 1e-3f, 0});
        s.mesh.indices.insert(s.mesh.indices.end(), {base, base + 1, base + 2});
        x *= 1.008f;
    }
    const std::string input = writeInput("streamed_deep.ply", s);
    StreamedOptions options = smallChunks(600);
    options.build.maxClusterTriangles = 4;
    options.build.maxLeafTriangles = 1;
    StreamedStats stats;
    CompressedModel model = streamed(input, tmp("streamed_deep.penumbra"), options, &stats); // validates the depth
    EXPECT_GE(stats.chunks, 10u);
    EXPECT_LE(stats.largestChunk, 600u);
    EXPECT_LE(model.header.bvhDepth, model::kMaxBvhDepth);
    // (expectSameTriangles' hash grid does not fit coordinates from 1 to 1e27: the count instead.)
    EXPECT_EQ(model.header.triangleCount, s.mesh.triangleCount());
}

TEST(Streamed, EveryFormatAndChunksTooLargeAreSplit)
{
    Scene s = scene("city", 20'000);
    for (const char* file : {"streamed_fmt.obj", "streamed_fmt.stl", "streamed_fmt.glb", "streamed_fmt_ascii.ply"}) {
        SCOPED_TRACE(file);
        ExportOptions exportOptions;
        exportOptions.binary = std::string(file).find("ascii") == std::string::npos;
        const std::string input = tmp(file);
        exportScene(s, input, exportOptions);
        StreamedOptions options = smallChunks(3'000);
        options.chunks = 2; // each of the two chunks is larger than 3000 triangles: built in parts
        StreamedStats stats;
        CompressedModel model = streamed(input, input + ".penumbra", options, &stats);
        EXPECT_GT(stats.chunks, 2u) << "the chunks were split";
        expectBoxesContainGeometry(model);
        EXPECT_LE(stats.largestChunk, 3'000u);
        // STL has no shared vertices: the welded in-core mesh is the reference.
        expectSameTriangles(std::string(file).find(".stl") != std::string::npos ? importScene(input).mesh : s.mesh, model);
    }
}

TEST(Streamed, ClosedFlagStaysConservative)
{
    // Many small closed parts (city buildings) across chunk boundaries, beside open ground.
    const Scene s = scene("city", 40'000);
    const std::string input = writeInput("streamed_closed.ply", s);
    CompressedModel model = streamed(input, tmp("streamed_closed.penumbra"), smallChunks(5'000));
    const std::vector<uint8_t> closed = findClosedTriangles(s.mesh, 2);
    // Every triangle of a flagged cluster is a triangle of a closed component of the input.
    const std::vector<int64_t> source = matchTriangles(s.mesh, model);
    uint64_t flagged = 0, k = 0;
    for (const model::ClusterRecord& c : model.clusters) {
        for (uint32_t i = 0; i < c.triangleCount; ++i, ++k) {
            if (!(c.flags & model::kClusterClosed))
                continue;
            ASSERT_GE(source[k], 0);
            EXPECT_EQ(closed[size_t(source[k])], 1) << "a flagged cluster holds a triangle of an open component";
            ++flagged;
        }
    }
    uint64_t inCore = 0;
    for (uint8_t c : closed)
        inCore += c;
    std::printf("[ closed ] streamed in 5k-triangle chunks: %llu triangles in closed clusters; in core: %llu in closed "
                "components of %zu\n",
                (unsigned long long)flagged, (unsigned long long)inCore, s.mesh.triangleCount());
    // One chunk: no boundary, so the closed components are exactly the in-core ones.
    StreamedStats one;
    streamed(input, tmp("streamed_closed1.penumbra"), smallChunks(1'000'000), &one);
    EXPECT_EQ(one.chunks, 1u);
    EXPECT_EQ(one.closedTriangles, inCore);
    // The clearance rule (crowdedComponents) with the same bound in both: a streamed build with
    // closed parts kept apart flags no triangle that the in-core build does not (every city part
    // touches the ground or another part: neither flags any).
    StreamedOptions separate = smallChunks(5'000);
    separate.build.separateClosed = true;
    uint64_t streamedFlags = 0, inCoreFlags = 0;
    const std::vector<uint8_t> chunked = flaggedTriangles(s.mesh, streamed(input, tmp("streamed_closed_sep.penumbra"), separate), &streamedFlags);
    PreprocessOptions build = separate.build;
    const std::vector<uint8_t> whole = flaggedTriangles(s.mesh, buildCompressedModel(s.mesh, build), &inCoreFlags);
    for (size_t t = 0; t < chunked.size(); ++t)
        ASSERT_LE(chunked[t], whole[t]) << "triangle " << t << " flagged only by the streamed build";
    std::printf("[ closed ] separated: %llu triangles flagged streamed, %llu in core\n", (unsigned long long)streamedFlags,
                (unsigned long long)inCoreFlags);
}

// Closed parts that no chunk boundary cuts stay closed: a field of small spheres.
TEST(Streamed, ClosedPartsInsideChunksStayClosed)
{
    Scene field;
    const int rings = 8, segments = 12;
    for (int gx = 0; gx < 12; ++gx)
        for (int gz = 0; gz < 12; ++gz) {
            const uint32_t base = uint32_t(field.mesh.vertexCount());
            const glm::vec3 centre(float(gx) * 3.0f, 0.0f, float(gz) * 3.0f);
            auto put = [&](glm::vec3 p) { field.mesh.positions.insert(field.mesh.positions.end(), {p.x, p.y, p.z}); };
            put(centre + glm::vec3(0, 1, 0));
            for (int r = 1; r < rings; ++r)
                for (int sgm = 0; sgm < segments; ++sgm) {
                    const float theta = 3.14159265f * float(r) / float(rings), phi = 6.2831853f * float(sgm) / float(segments);
                    put(centre + glm::vec3(std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi)));
                }
            put(centre + glm::vec3(0, -1, 0));
            const uint32_t south = uint32_t(field.mesh.vertexCount() - 1);
            auto ring = [&](int r, int sgm) { return base + uint32_t(1 + (r - 1) * segments + (sgm % segments)); };
            auto& idx = field.mesh.indices;
            for (int sgm = 0; sgm < segments; ++sgm)
                idx.insert(idx.end(), {base, ring(1, sgm + 1), ring(1, sgm)});
            for (int r = 1; r + 1 < rings; ++r)
                for (int sgm = 0; sgm < segments; ++sgm) {
                    idx.insert(idx.end(), {ring(r, sgm), ring(r, sgm + 1), ring(r + 1, sgm)});
                    idx.insert(idx.end(), {ring(r, sgm + 1), ring(r + 1, sgm + 1), ring(r + 1, sgm)});
                }
            for (int sgm = 0; sgm < segments; ++sgm)
                idx.insert(idx.end(), {south, ring(rings - 1, sgm), ring(rings - 1, sgm + 1)});
        }
    const std::string input = writeInput("streamed_spheres.ply", field);
    StreamedStats stats;
    CompressedModel model = streamed(input, tmp("streamed_spheres.penumbra"), smallChunks(3'000), &stats);
    EXPECT_GE(stats.chunks, 4u);
    const uint64_t total = field.mesh.triangleCount();
    std::printf("[ closed ] 144 spheres in %u chunks: %llu of %llu triangles in closed components\n", stats.chunks,
                (unsigned long long)stats.closedTriangles, (unsigned long long)total);
    // At most the spheres that a cell boundary cuts are lost: a handful per plane.
    EXPECT_GE(stats.closedTriangles, total * 3 / 4);
    EXPECT_LT(stats.closedTriangles, total) << "some sphere must straddle a boundary";
    // The spheres are 1 apart, far beyond the shadow rays' offset: every closed one is flagged
    // (separated from nothing open) unless it comes within the offset of its cell's faces, where
    // a neighbour in the next chunk could lie outside the halo; in core every sphere is flagged.
    StreamedOptions separate = smallChunks(3'000);
    separate.build.separateClosed = true;
    uint64_t flagged = 0, inCore = 0;
    flaggedTriangles(field.mesh, streamed(input, tmp("streamed_spheres_sep.penumbra"), separate), &flagged);
    flaggedTriangles(field.mesh, buildCompressedModel(field.mesh, separate.build), &inCore);
    std::printf("[ closed ] 144 spheres, closed parts separated: %llu triangles flagged streamed, %llu in core\n",
                (unsigned long long)flagged, (unsigned long long)inCore);
    EXPECT_EQ(inCore, total);
    EXPECT_GE(flagged, total * 3 / 4);
    EXPECT_LE(flagged, stats.closedTriangles);
}

// ---- chunk files and the merge as separate processes -----------------------------------------

int run(const std::vector<std::string>& args, std::string* err = nullptr)
{
    std::string command;
    for (const std::string& a : args)
        command += "'" + a + "' ";
    // One file per call: ctest runs the tests of this binary as parallel processes.
    static int calls = 0;
    const std::string errFile = tmp("streamed_stderr_" + std::to_string(::getpid()) + "_" + std::to_string(calls++) + ".txt");
    command += "> /dev/null 2> '" + errFile + "'";
    const int status = std::system(command.c_str());
    if (err)
        *err = readBytes(errFile);
    std::filesystem::remove(errFile);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(Streamed, ChunkProcessesAndMergeGiveTheInProcessBytes)
{
    const Scene s = scene("plant", 30'000);
    const std::string input = writeInput("streamed_dist.ply", s);
    const uint32_t n = 5;
    std::vector<std::string> chunks;
    for (uint32_t i = 0; i < n; ++i) {
        const std::string chunk = tmp("streamed_dist.chunk" + std::to_string(i));
        chunks.push_back(chunk);
        std::string err;
        ASSERT_EQ(run({PENUMBRA_PREPROCESS_CLI, "preprocess", input, "--chunk", std::to_string(i) + "/" + std::to_string(n), "-o",
                       chunk, "--memory-limit", "64", "--threads", "2", "--quiet"},
                      &err),
                  0)
            << err;
    }
    // Merged in another order than built.
    const std::string merged = tmp("streamed_dist.penumbra");
    std::string err;
    ASSERT_EQ(run({PENUMBRA_PREPROCESS_CLI, "merge", chunks[3], chunks[0], chunks[4], chunks[1], chunks[2], "-o", merged, "--quiet"},
                  &err),
              0)
        << err;
    CompressedModel model = openModelFile(merged);
    expectSameTriangles(s.mesh, model);
    StreamedOptions options;
    options.memoryLimit = uint64_t(64) << 20;
    options.chunks = n;
    options.build.threads = 2;
    options.tempDirectory = PENUMBRA_TEST_TMP;
    preprocessStreamed(input, tmp("streamed_inprocess.penumbra"), options);
    EXPECT_TRUE(readBytes(merged) == readBytes(tmp("streamed_inprocess.penumbra")))
        << "the distributed build differs from the in-process one";
}

TEST(Streamed, BadChunkFilesGiveOneLineNamingTheFile)
{
    const Scene s = scene("city", 10'000);
    const std::string input = writeInput("streamed_bad.ply", s);
    const std::string other = writeInput("streamed_bad_other.ply", scene("scan", 10'000));
    StreamedOptions options = smallChunks(100'000);
    std::vector<std::string> chunks;
    for (uint32_t i = 0; i < 3; ++i) {
        chunks.push_back(tmp("streamed_bad.chunk" + std::to_string(i)));
        preprocessChunk(input, chunks.back(), i, 3, options);
    }
    const std::string foreign = tmp("streamed_bad_other.chunk1");
    preprocessChunk(other, foreign, 1, 3, options);
    const std::string output = tmp("streamed_bad.penumbra");
    auto mergeError = [&](const std::vector<std::string>& files) {
        std::filesystem::remove(output);
        std::string message;
        try {
            mergeChunkFiles(files, output, {});
        } catch (const Error& e) {
            message = e.what();
        }
        if (!message.empty()) {
            EXPECT_FALSE(std::filesystem::exists(output)) << "a failed merge left " << output;
        }
        EXPECT_EQ(message.find('\n'), std::string::npos);
        return message;
    };
    auto expectPrefix = [](const std::string& message, const std::string& path, const std::string& problem) {
        EXPECT_EQ(message.rfind(path + ": ", 0), 0u) << message;
        EXPECT_NE(message.find(problem), std::string::npos) << message;
    };
    EXPECT_EQ(mergeError(chunks), "");
    // Missing, duplicated, from another build.
    expectPrefix(mergeError({chunks[0], chunks[2]}), output, "chunk 1 of 3 is missing");
    expectPrefix(mergeError({chunks[0], chunks[1], chunks[2], chunks[1]}), chunks[1], "chunk 1 of 3 again");
    expectPrefix(mergeError({chunks[0], foreign, chunks[2]}), foreign, "belongs to another build");
    expectPrefix(mergeError({chunks[0], tmp("streamed_no_such.chunk"), chunks[2]}), tmp("streamed_no_such.chunk"), "file not found");
    // Corrupt: truncated, a flipped byte in the header, in the model, in its nodes; trailing bytes; not a chunk file.
    const std::string bytes = readBytes(chunks[1]);
    const std::string bad = tmp("streamed_bad_corrupt.chunk1");
    auto corrupt = [&](const std::string& content) {
        writeBytes(bad, content);
        return mergeError({chunks[0], bad, chunks[2]});
    };
    expectPrefix(corrupt(bytes.substr(0, bytes.size() / 2)), bad, "truncated");
    expectPrefix(corrupt(bytes.substr(0, 100)), bad, "truncated");
    std::string flipped = bytes;
    flipped[40] ^= 1;
    expectPrefix(corrupt(flipped), bad, "chunk header checksum mismatch");
    flipped = bytes;
    flipped[bytes.size() / 2] ^= 0x20;
    const std::string modelMessage = corrupt(flipped);
    EXPECT_EQ(modelMessage.rfind(bad + ": ", 0), 0u) << modelMessage;
    // A flipped byte in the model's node section: its checksum (the reader's check, in one line).
    chunk::ChunkHeader header;
    std::memcpy(&header, bytes.data(), sizeof(header));
    model::FileHeader image;
    std::memcpy(&image, bytes.data() + header.modelOffset, sizeof(image));
    for (const model::SectionEntry& section : image.sections)
        if (section.type == uint32_t(model::SectionType::Nodes)) {
            flipped = bytes;
            flipped[header.modelOffset + section.offset + 17] ^= 0x40;
            expectPrefix(corrupt(flipped), bad, "checksum");
        }
    expectPrefix(corrupt(bytes + std::string(64, '\0')), bad, "trailing data");
    expectPrefix(corrupt(readBytes(input)), bad, "not a Penumbra chunk file (bad magic)");
    // The CLI: the same, as one line, exit status 1.
    std::string err;
    EXPECT_EQ(run({PENUMBRA_PREPROCESS_CLI, "merge", chunks[0], chunks[2], "-o", output}, &err), 1);
    EXPECT_EQ(err, "penumbra-preprocess: error: " + output + ": chunk 1 of 3 is missing (no chunk file given holds it; the 2 given include " +
                       chunks[0] + ")\n");
}

TEST(Streamed, OptionErrorsAndUnstreamableInputs)
{
    const std::string input = writeInput("streamed_opts.ply", scene("city", 5'000));
    std::string err;
    EXPECT_EQ(run({PENUMBRA_PREPROCESS_CLI, "preprocess", input, "-o", tmp("streamed_opts.penumbra"), "--memory-limit", "64",
                   "--simplify", "0.5"},
                  &err),
              1);
    EXPECT_EQ(err, "penumbra-preprocess: error: --simplify 0.5: cannot be combined with --memory-limit or --chunk (simplification "
                   "needs the whole mesh in memory); simplify without them, or preprocess the model whole\n");
    EXPECT_EQ(run({PENUMBRA_PREPROCESS_CLI, "preprocess", input, "-o", tmp("streamed_opts.chunk"), "--chunk", "5/5"}, &err), 1);
    EXPECT_NE(err.find("--chunk 5/5: expected I/N with 0 <= I < N"), std::string::npos) << err;
    Scene s = scene("city", 5'000);
    const std::string drc = tmp("streamed_opts.drc");
    exportScene(s, drc);
    EXPECT_EQ(run({PENUMBRA_PREPROCESS_CLI, "preprocess", drc, "-o", tmp("streamed_opts.penumbra"), "--memory-limit", "64"}, &err), 1);
    EXPECT_EQ(err, "penumbra-preprocess: error: " + drc + ": a Draco file is one compressed mesh and cannot be streamed; preprocess "
                   "it without --memory-limit or convert it, e.g. to PLY\n");
    EXPECT_FALSE(std::filesystem::exists(tmp("streamed_opts.penumbra")));
}

// An interrupted build (SIGKILL in the middle) leaves no output; the next run succeeds.
TEST(Streamed, InterruptedBuildLeavesNoModel)
{
    const std::string input = writeInput("streamed_kill.ply", scene("scan", 300'000));
    const std::string output = tmp("streamed_kill.penumbra");
    std::filesystem::remove(output);
    for (int delayMs : {150, 600}) {
        const pid_t pid = fork();
        ASSERT_GE(pid, 0);
        if (pid == 0) {
            std::freopen("/dev/null", "w", stdout);
            std::freopen("/dev/null", "w", stderr);
            execl(PENUMBRA_PREPROCESS_CLI, PENUMBRA_PREPROCESS_CLI, "preprocess", input.c_str(), "-o", output.c_str(),
                  "--memory-limit", "32", "--threads", "1", "--quiet", static_cast<char*>(nullptr));
            _exit(127);
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(delayMs));
        kill(pid, SIGKILL);
        int status = 0;
        waitpid(pid, &status, 0);
        if (WIFEXITED(status))
            continue; // finished before the signal (a fast machine): nothing to check this time
        // Killed between the rename and the exit, the model is complete; else there is none.
        if (std::filesystem::exists(output)) {
            EXPECT_NO_THROW(openModelFile(output)) << "a killed build left a partial " << output;
        }
        std::filesystem::remove(output);
    }
    std::string err;
    EXPECT_EQ(run({PENUMBRA_PREPROCESS_CLI, "preprocess", input, "-o", output, "--memory-limit", "32", "--quiet"}, &err), 0) << err;
    EXPECT_NO_THROW(openModelFile(output));
    // The killed builds' chunk files and temporary outputs are gone too (the next build of the
    // output removes those of processes that no longer run).
    for (const auto& entry : std::filesystem::directory_iterator(PENUMBRA_TEST_TMP))
        EXPECT_EQ(entry.path().filename().string().find("streamed_kill.penumbra."), std::string::npos) << entry.path();

    // A killed chunk process (penumbra preprocess --chunk I/N) leaves no chunk file, and a
    // killed merge no model: both write to a temporary name and rename when complete (a process
    // killed after its rename, before it exits, leaves a complete file: it must validate).
    const std::string chunk0 = tmp("streamed_kill.chunk0"), chunk1 = tmp("streamed_kill.chunk1");
    const std::string merged = tmp("streamed_kill_merged.penumbra");
    for (const std::string& path : {chunk0, chunk1, merged})
        std::filesystem::remove(path);
    auto killAfter = [](int delayMs, std::vector<std::string> args) {
        const pid_t pid = fork();
        if (pid == 0) {
            std::freopen("/dev/null", "w", stdout);
            std::freopen("/dev/null", "w", stderr);
            std::vector<char*> argv;
            for (std::string& a : args)
                argv.push_back(a.data());
            argv.push_back(nullptr);
            execv(argv[0], argv.data());
            _exit(127);
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(delayMs));
        kill(pid, SIGKILL);
        int status = 0;
        waitpid(pid, &status, 0);
        return !WIFEXITED(status); // killed before it finished
    };
    for (int delayMs : {150, 500})
        if (killAfter(delayMs, {PENUMBRA_PREPROCESS_CLI, "preprocess", input, "--chunk", "0/2", "-o", chunk0, "--memory-limit", "32",
                                "--threads", "1", "--quiet"}))
            if (std::filesystem::exists(chunk0)) {
                EXPECT_NO_THROW(openChunkFile(chunk0)) << "a killed chunk process left a partial " << chunk0;
                std::filesystem::remove(chunk0);
            }
    for (const char* index : {"0/2", "1/2"})
        EXPECT_EQ(run({PENUMBRA_PREPROCESS_CLI, "preprocess", input, "--chunk", index, "-o", index[0] == '0' ? chunk0 : chunk1,
                       "--memory-limit", "32", "--quiet"}, &err), 0) << err;
    for (int delayMs : {20, 60})
        if (killAfter(delayMs, {PENUMBRA_PREPROCESS_CLI, "merge", chunk0, chunk1, "-o", merged, "--quiet"}))
            if (std::filesystem::exists(merged)) {
                EXPECT_NO_THROW(openModelFile(merged)) << "a killed merge left a partial " << merged;
                std::filesystem::remove(merged);
            }
    EXPECT_EQ(run({PENUMBRA_PREPROCESS_CLI, "merge", chunk0, chunk1, "-o", merged, "--quiet"}, &err), 0) << err;
    EXPECT_NO_THROW(openModelFile(merged));
}

// An interrupted build (SIGINT, SIGTERM: Ctrl-C, a job scheduler's stop) removes its chunk files
// and its unfinished output at once, says so in one line and ends by the signal; no next run needed.
// Each signal is sent once the build's chunk file named by `waitFor` exists.
TEST(Streamed, SignalledBuildRemovesItsTemporaryFiles)
{
    const std::string input = writeInput("streamed_signal.ply", scene("scan", 300'000));
    const std::string output = tmp("streamed_signal.penumbra"), errors = tmp("streamed_signal.err");
    auto leftovers = [] {
        std::vector<std::string> files;
        for (const auto& entry : std::filesystem::directory_iterator(PENUMBRA_TEST_TMP))
            if (entry.path().filename().string().rfind("streamed_signal.penumbra.", 0) == 0)
                files.push_back(entry.path().filename().string());
        return files;
    };
    for (const std::string& file : leftovers())
        std::filesystem::remove(tmp(file));
    int interrupted = 0;
    for (auto [signalNumber, waitFor] : {std::pair{SIGINT, ".chunk0."}, std::pair{SIGTERM, ".chunk1."}}) {
        std::filesystem::remove(output);
        const pid_t pid = fork();
        ASSERT_GE(pid, 0);
        if (pid == 0) {
            std::freopen("/dev/null", "w", stdout);
            std::freopen(errors.c_str(), "w", stderr);
            signal(signalNumber, SIG_DFL); // as in a terminal's foreground (a background job inherits SIGINT ignored)
            execl(PENUMBRA_PREPROCESS_CLI, PENUMBRA_PREPROCESS_CLI, "preprocess", input.c_str(), "-o", output.c_str(),
                  "--memory-limit", "32", "--threads", "1", "--quiet", static_cast<char*>(nullptr));
            _exit(127);
        }
        int status = 0;
        bool seen = false, ended = false;
        for (int i = 0; i < 60'000 && !seen && !ended; ++i) {
            for (const std::string& file : leftovers())
                seen = seen || file.find(waitFor) != std::string::npos;
            ended = waitpid(pid, &status, WNOHANG) == pid;
            if (!seen && !ended)
                std::this_thread::sleep_for(std::chrono::milliseconds(1));
        }
        if (!ended) {
            kill(pid, seen ? signalNumber : SIGKILL);
            waitpid(pid, &status, 0);
        }
        ASSERT_TRUE(seen) << "the build never wrote a chunk file named *" << waitFor << "*";
        if (WIFEXITED(status)) { // finished between the chunk file and the signal (a fast machine)
            EXPECT_EQ(WEXITSTATUS(status), 0) << readBytes(errors);
            continue;
        }
        ++interrupted;
        ASSERT_TRUE(WIFSIGNALED(status));
        EXPECT_EQ(WTERMSIG(status), signalNumber);
        EXPECT_EQ(readBytes(errors), std::string("penumbra-preprocess: interrupted (") + (signalNumber == SIGINT ? "SIGINT" : "SIGTERM") +
                                         "); its temporary files removed\n");
        EXPECT_FALSE(std::filesystem::exists(output));
        EXPECT_EQ(leftovers(), std::vector<std::string>{});
    }
    EXPECT_GT(interrupted, 0) << "every build ended before its signal: nothing was tested";
}

// Runs the preprocessing CLI with its address space limited to `bytes` (RLIMIT_AS, as `ulimit -v`
// does): its exit status, or minus the signal that ended it; its stderr in *err.
int runWithAddressLimit(const std::vector<std::string>& args, rlim_t bytes, std::string* err)
{
    const std::string errors = tmp("address_limit.err");
    const pid_t pid = fork();
    if (pid == 0) {
        std::freopen("/dev/null", "w", stdout);
        std::freopen(errors.c_str(), "w", stderr);
        const rlimit limit{bytes, bytes};
        setrlimit(RLIMIT_AS, &limit);
        std::vector<char*> argv;
        for (const std::string& a : args)
            argv.push_back(const_cast<char*>(a.c_str()));
        argv.push_back(nullptr);
        execv(argv[0], argv.data());
        _exit(127);
    }
    int status = 0;
    waitpid(pid, &status, 0);
    *err = readBytes(errors);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status);
}

// Out of memory (an allocation refused under a limit), with many threads: one line naming the
// input, exit status 1, no model; never std::terminate (a worker thread's std::bad_alloc, or a
// thread that could not be started, once aborted the process).
TEST(PreprocessCli, OutOfMemoryIsOneLineNamingTheInput)
{
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
    GTEST_SKIP() << "the sanitizers' shadow memory does not fit under an address-space limit";
#endif
    const std::string input = writeInput("address_limit.ply", scene("plant", 300'000));
    const std::string output = tmp("address_limit.penumbra");
    int built = 0, refused = 0;
    for (rlim_t mib : {96, 160, 224, 320, 448, 640, 1024}) {
        std::filesystem::remove(output);
        std::string err;
        const int status = runWithAddressLimit({PENUMBRA_PREPROCESS_CLI, "preprocess", input, "-o", output, "--threads", "16", "--quiet"},
                                               mib << 20, &err);
        ASSERT_GE(status, 0) << mib << " MiB: ended by signal " << -status << ": " << err;
        if (status == 0) {
            ++built;
            EXPECT_NO_THROW(openModelFile(output)) << mib << " MiB";
            continue;
        }
        EXPECT_EQ(status, 1) << mib << " MiB: " << err;
        EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << mib << " MiB: " << err;
        EXPECT_FALSE(std::filesystem::exists(output)) << mib << " MiB";
        if (err.rfind("penumbra-preprocess: error: " + input + ": out of memory preprocessing it whole; build it out of core with "
                      "--memory-limit MIB, or with fewer --threads\n", 0) == 0)
            ++refused;
        else
            EXPECT_EQ(err.rfind("penumbra-preprocess: error: ", 0), 0u) << mib << " MiB: " << err;
    }
    EXPECT_GT(refused, 0) << "no limit was too small: nothing was tested";
    EXPECT_GT(built, 0) << "no limit was large enough";
}

} // namespace

namespace {

// The scan written row by row (inputs larger than memory) is byte for byte what the in-memory
// generator and the PLY exporter write; other scenes and formats are not streamed.
TEST(Streamed, StreamedScanGeneratorWritesTheSameBytes)
{
    for (uint64_t triangles : {uint64_t(1'000), uint64_t(54'321)}) {
        GenerateOptions options;
        options.triangles = triangles;
        const std::string streamedPath = tmp("streamed_gen.ply"), memoryPath = tmp("memory_gen.ply");
        uint64_t t = 0, v = 0;
        ASSERT_TRUE(writeSceneStreamed("scan", options, streamedPath, true, &t, &v));
        const Scene s = generateScene("scan", options);
        exportScene(s, memoryPath);
        EXPECT_EQ(t, s.mesh.triangleCount());
        EXPECT_EQ(v, s.mesh.vertexCount());
        EXPECT_TRUE(readBytes(streamedPath) == readBytes(memoryPath)) << triangles << " triangles";
    }
    GenerateOptions options;
    options.triangles = 5'000;
    EXPECT_FALSE(writeSceneStreamed("city", options, tmp("streamed_gen_city.ply"), true));
    EXPECT_FALSE(writeSceneStreamed("scan", options, tmp("streamed_gen.obj"), true));
    EXPECT_FALSE(writeSceneStreamed("scan", options, tmp("streamed_gen_ascii.ply"), false));
    EXPECT_FALSE(std::filesystem::exists(tmp("streamed_gen_city.ply")));
    options.triangles = 9'000'000'000ull;
    EXPECT_THROW(writeSceneStreamed("scan", options, tmp("streamed_gen_huge.ply"), true), Error);
}

} // namespace
