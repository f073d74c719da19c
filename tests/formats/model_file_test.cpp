// .penumbra model file: round trip, and every kind of bad file rejected with
// its own message (truncation, corruption, hostile but checksum-valid data).
// Models are built by hand here (no dependency on preprocess/).
#include <gtest/gtest.h>
#include <xxhash.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include <glm/common.hpp>

#include "penumbra/error.h"
#include "penumbra/model_format.h"
#include "test_helpers.h"

namespace penumbra::test {
namespace {

using namespace model;

// ---------------------------------------------------------------------------
// A tiny hand-made builder: each cluster is its positions plus its leaves,
// each leaf a list of strips (local indices). Nodes: one cluster -> the root
// is the Cluster node; two clusters -> an Interior root over two Cluster
// nodes. Each Cluster node has its leaves (1 or 2) as children.

struct TestLeaf {
    std::vector<std::vector<uint8_t>> strips;
};
struct TestCluster {
    std::vector<glm::vec3> positions;
    std::vector<TestLeaf> leaves;
};

struct Box {
    glm::vec3 min{std::numeric_limits<float>::max()};
    glm::vec3 max{-std::numeric_limits<float>::max()};
    void add(const glm::vec3& p)
    {
        min = glm::min(min, p);
        max = glm::max(max, p);
    }
    void add(const Box& b)
    {
        add(b.min);
        add(b.max);
    }
};

// Child box relative to the parent's, rounded outward to 8 bits.
void quantizeBounds(Node& node, const Box& child, const Box& parent)
{
    for (int axis = 0; axis < 3; ++axis) {
        float extent = parent.max[axis] - parent.min[axis];
        if (extent <= 0.0f) {
            node.lo[axis] = 0;
            node.hi[axis] = 255;
            continue;
        }
        float lo = std::floor((child.min[axis] - parent.min[axis]) / extent * 255.0f);
        float hi = std::ceil((child.max[axis] - parent.min[axis]) / extent * 255.0f);
        node.lo[axis] = uint8_t(std::clamp(lo, 0.0f, 255.0f));
        node.hi[axis] = uint8_t(std::clamp(hi, 0.0f, 255.0f));
    }
}

std::shared_ptr<CompressedModelData> buildModel(const std::vector<TestCluster>& input)
{
    auto data = std::make_shared<CompressedModelData>();
    FileHeader& header = data->header;
    header.build = {255, 1024, 8, 16, kPositionBits, kNodeBoundsBits, 1.0f, 0};

    const uint32_t clusterCount = uint32_t(input.size());
    const uint32_t firstClusterNode = clusterCount == 1 ? 0 : 1;
    uint32_t nodeCount = firstClusterNode + clusterCount;
    for (const TestCluster& c : input)
        nodeCount += uint32_t(c.leaves.size());
    data->nodes.resize(nodeCount);

    std::vector<Box> clusterBoxes(clusterCount);
    Box rootBox;
    uint32_t nextLeafNode = firstClusterNode + clusterCount;
    uint64_t triangles = 0;
    for (uint32_t c = 0; c < clusterCount; ++c) {
        const TestCluster& in = input[c];
        ClusterRecord record{};
        Box box;
        for (const glm::vec3& p : in.positions)
            box.add(p);
        for (int axis = 0; axis < 3; ++axis) {
            record.boxMin[axis] = box.min[axis];
            record.step[axis] = (box.max[axis] - box.min[axis]) / 65535.0f;
        }
        record.firstVertex = uint32_t(data->vertices.size());
        record.firstIndex = uint32_t(data->indices.size());
        record.vertexCount = uint16_t(in.positions.size());
        record.node = firstClusterNode + c;
        Box decodedBox;
        for (const glm::vec3& p : in.positions) {
            QuantizedVertex q{};
            uint16_t* out[3] = {&q.x, &q.y, &q.z};
            for (int axis = 0; axis < 3; ++axis)
                *out[axis] = record.step[axis] > 0.0f
                                 ? uint16_t(std::lround((p[axis] - record.boxMin[axis]) / record.step[axis]))
                                 : 0;
            data->vertices.push_back(q);
            decodedBox.add(decodePosition(record, q));
        }
        clusterBoxes[c] = decodedBox;
        rootBox.add(decodedBox);

        Node& clusterNode = data->nodes[record.node];
        clusterNode.kind = uint8_t(NodeKind::Cluster);
        clusterNode.childCount = uint8_t(in.leaves.size());
        clusterNode.first = nextLeafNode;
        clusterNode.second = c;
        uint32_t clusterTriangles = 0;
        for (const TestLeaf& leaf : in.leaves) {
            if (data->indices.size() > record.firstIndex)
                data->indices.push_back(kStripRestart);
            uint32_t start = uint32_t(data->indices.size()) - record.firstIndex;
            for (size_t s = 0; s < leaf.strips.size(); ++s) {
                if (s > 0)
                    data->indices.push_back(kStripRestart);
                data->indices.insert(data->indices.end(), leaf.strips[s].begin(), leaf.strips[s].end());
            }
            uint32_t end = uint32_t(data->indices.size()) - record.firstIndex;
            const uint8_t* bytes = data->indices.data() + record.firstIndex;
            Box leafBox;
            forEachStripTriangle(bytes + start, bytes + end, [&](uint32_t a, uint32_t b, uint32_t cc) {
                ++clusterTriangles;
                for (uint32_t v : {a, b, cc})
                    leafBox.add(decodePosition(record, data->vertices[record.firstVertex + v]));
            });
            Node& leafNode = data->nodes[nextLeafNode++];
            leafNode.kind = uint8_t(NodeKind::Leaf);
            leafNode.first = c;
            leafNode.second = start | (end - start) << 16;
            quantizeBounds(leafNode, leafBox, decodedBox);
        }
        record.indexBytes = uint32_t(data->indices.size()) - record.firstIndex;
        record.triangleCount = uint16_t(clusterTriangles);
        triangles += clusterTriangles;
        data->clusters.push_back(record);
    }
    Node& root = data->nodes[0];
    if (clusterCount > 1) {
        root.kind = uint8_t(NodeKind::Interior);
        root.childCount = uint8_t(clusterCount);
        root.first = 1;
        for (uint32_t c = 0; c < clusterCount; ++c)
            quantizeBounds(data->nodes[1 + c], clusterBoxes[c], rootBox);
    }
    for (int axis = 0; axis < 3; ++axis) {
        root.lo[axis] = 0;
        root.hi[axis] = 255;
        header.boundsMin[axis] = rootBox.min[axis];
        header.boundsMax[axis] = rootBox.max[axis];
    }
    header.triangleCount = triangles;
    header.sourceTriangleCount = triangles;
    header.vertexCount = data->vertices.size();
    header.indexBytes = data->indices.size();
    header.clusterCount = clusterCount;
    header.nodeCount = nodeCount;
    header.bvhDepth = clusterCount == 1 ? 2 : 3;
    data->materials = {{{1.0f, 1.0f, 1.0f, 1.0f}}};
    header.materialCount = 1;
    return data;
}

// One cluster: a unit quad as the strip 0 1 2 3 (2 triangles), one leaf.
std::shared_ptr<CompressedModelData> quadModel()
{
    TestCluster quad;
    quad.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
    quad.leaves = {TestLeaf{{{0, 1, 2, 3}}}};
    return buildModel({quad});
}

// Two clusters: a cube (6 faces as 4-index strips, 12 triangles, two leaves
// of 3 faces) and a quad beside it.
std::shared_ptr<CompressedModelData> cubeModel()
{
    TestCluster cube;
    for (int i = 0; i < 8; ++i)
        cube.positions.push_back({float(i & 1), float((i >> 1) & 1), float((i >> 2) & 1)});
    cube.leaves = {TestLeaf{{{0, 2, 1, 3}, {4, 5, 6, 7}, {0, 1, 4, 5}}},
                   TestLeaf{{{2, 6, 3, 7}, {0, 4, 2, 6}, {1, 3, 5, 7}}}};
    TestCluster quad;
    quad.positions = {{2, 0, 0}, {3, 0, 0}, {2, 1, 0.5f}, {3, 1, 0.5f}};
    quad.leaves = {TestLeaf{{{0, 1, 2, 3}}}};
    return buildModel({cube, quad});
}

CompressedModel view(const std::shared_ptr<CompressedModelData>& data)
{
    return makeCompressedModel(data);
}

// Runs fn and returns the Error's message ("" if nothing was thrown).
template <typename Fn> std::string errorOf(Fn&& fn)
{
    try {
        fn();
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

#define EXPECT_ERROR_CONTAINS(message, expected)                                                                       \
    do {                                                                                                               \
        std::string message_ = (message);                                                                              \
        EXPECT_NE(message_.find(expected), std::string::npos) << "message: '" << message_ << "'";                      \
    } while (0)

// validateModel on a mutated copy of a model must fail naming `expected`.
template <typename Mutate>
void expectInvalid(std::shared_ptr<CompressedModelData> (*make)(), Mutate&& mutate, const std::string& expected)
{
    auto data = make();
    ASSERT_EQ(errorOf([&] { validateModel(view(data), "m"); }), "") << "the unmodified model must be valid";
    mutate(*data);
    std::string message = errorOf([&] { validateModel(view(data), "m"); });
    EXPECT_ERROR_CONTAINS(message, expected);
    EXPECT_EQ(message.rfind("m: ", 0), 0u) << message;
}

std::string writeModel(const std::string& name, const std::shared_ptr<CompressedModelData>& data)
{
    std::string path = tempPath(name);
    writeModelFile(view(data), path);
    return path;
}

FileHeader headerOf(const std::string& bytes)
{
    FileHeader header;
    std::memcpy(&header, bytes.data(), sizeof(header));
    return header;
}

void setHeader(std::string& bytes, FileHeader header, bool fixChecksum = true)
{
    if (fixChecksum) {
        header.headerChecksum = 0;
        header.headerChecksum = XXH64(&header, sizeof(header), 0);
    }
    std::memcpy(bytes.data(), &header, sizeof(header));
}

// Recomputes every in-bounds section checksum and the header checksum.
void fixChecksums(std::string& bytes)
{
    FileHeader header = headerOf(bytes);
    for (SectionEntry& entry : header.sections)
        if (entry.type != 0 && entry.offset <= bytes.size() && entry.size <= bytes.size() - entry.offset)
            entry.checksum = XXH64(bytes.data() + entry.offset, entry.size, 0);
    setHeader(bytes, header);
}

const SectionEntry& sectionOf(const FileHeader& header, SectionType type)
{
    for (const SectionEntry& entry : header.sections)
        if (entry.type == uint32_t(type))
            return entry;
    throw std::runtime_error("no such section");
}

std::string openError(const std::string& name, const std::string& bytes)
{
    std::string path = writeFile(name, bytes);
    return errorOf([&] { openModelFile(path); });
}

std::string validCubeBytes()
{
    return readFile(writeModel("model_cube_source.penumbra", cubeModel()));
}

// ---------------------------------------------------------------------------

TEST(ModelFile, BuilderMakesValidModels)
{
    EXPECT_NO_THROW(validateModel(view(quadModel()), "quad"));
    EXPECT_NO_THROW(validateModel(view(cubeModel()), "cube"));
    EXPECT_EQ(cubeModel()->header.triangleCount, 14u);
}

TEST(ModelFile, RoundTripIsIdentical)
{
    for (auto make : {quadModel, cubeModel}) {
        auto data = make();
        data->header.sourceTriangleCount = 1234;
        data->header.maxPositionError = 0.001f;
        data->header.simplifyError = 0.5f;
        data->header.build.simplifyTarget = 0.25f;
        std::string path = writeModel("model_roundtrip.penumbra", data);
        CompressedModel model = openModelFile(path);

        const FileHeader& h = model.header;
        EXPECT_EQ(std::memcmp(h.magic, kMagic, 8), 0);
        EXPECT_EQ(h.version, kVersion);
        EXPECT_EQ(h.headerSize, sizeof(FileHeader));
        EXPECT_EQ(h.fileSize, std::filesystem::file_size(path));
        EXPECT_EQ(h.fileSize % 64, 0u);
        EXPECT_EQ(h.triangleCount, data->header.triangleCount);
        EXPECT_EQ(h.sourceTriangleCount, 1234u);
        EXPECT_EQ(h.maxPositionError, 0.001f);
        EXPECT_EQ(h.simplifyError, 0.5f);
        EXPECT_EQ(h.bvhDepth, data->header.bvhDepth);
        EXPECT_EQ(std::memcmp(&h.build, &data->header.build, sizeof(BuildParameters)), 0);
        EXPECT_EQ(std::memcmp(h.boundsMin, data->header.boundsMin, 12), 0);
        EXPECT_EQ(std::memcmp(h.boundsMax, data->header.boundsMax, 12), 0);

        ASSERT_EQ(model.clusters.size(), data->clusters.size());
        ASSERT_EQ(model.nodes.size(), data->nodes.size());
        ASSERT_EQ(model.vertices.size(), data->vertices.size());
        ASSERT_EQ(model.indices.size(), data->indices.size());
        EXPECT_EQ(std::memcmp(model.clusters.data(), data->clusters.data(), model.clusters.size_bytes()), 0);
        EXPECT_EQ(std::memcmp(model.nodes.data(), data->nodes.data(), model.nodes.size_bytes()), 0);
        EXPECT_EQ(std::memcmp(model.vertices.data(), data->vertices.data(), model.vertices.size_bytes()), 0);
        EXPECT_EQ(std::memcmp(model.indices.data(), data->indices.data(), model.indices.size_bytes()), 0);

        // Sections in the documented order, 64-byte aligned, zero padding.
        SectionType order[] = {SectionType::Clusters, SectionType::Nodes, SectionType::Vertices, SectionType::Indices,
                               SectionType::Materials};
        uint64_t previousEnd = sizeof(FileHeader);
        for (int i = 5; i < int(kSectionSlots); ++i)
            EXPECT_EQ(h.sections[i].type, 0u); // no cameras or lights: unused entries
        for (int i = 0; i < 5; ++i) {
            EXPECT_EQ(h.sections[i].type, uint32_t(order[i]));
            EXPECT_EQ(h.sections[i].offset % 64, 0u);
            EXPECT_GE(h.sections[i].offset, previousEnd);
            EXPECT_LT(h.sections[i].offset, previousEnd + 64);
            previousEnd = h.sections[i].offset + h.sections[i].size;
        }
        EXPECT_EQ(h.fileSize, (previousEnd + 63) / 64 * 64);
        // No temporary file left beside it.
        for (const auto& entry : std::filesystem::directory_iterator(PENUMBRA_TEST_TMP))
            EXPECT_EQ(entry.path().filename().string().find("model_roundtrip.penumbra.tmp"), std::string::npos);
    }
}

// Version 3: the closed flag and 64-bit offsets survive the file; a flag set is valid.
TEST(ModelFile, ClusterFlagsRoundTrip)
{
    auto data = cubeModel();
    data->clusters[0].flags = kClusterClosed;
    CompressedModel model = openModelFile(writeModel("model_flags.penumbra", data));
    ASSERT_EQ(model.clusters.size(), 2u);
    EXPECT_EQ(model.clusters[0].flags, uint32_t(kClusterClosed));
    EXPECT_EQ(model.clusters[1].flags, 0u);
    EXPECT_EQ(model.clusters[1].firstVertex, 8u);
    EXPECT_EQ(model.clusters[1].firstIndex, uint64_t(model.clusters[0].indexBytes));
}

// A version-2 file (the seed corpus's cube before version 3, kept as it was
// written) is refused with one line that says what to do.
TEST(ModelFileBad, Version2FileSaysToPreprocessAgain)
{
    const std::string path = (std::filesystem::path(__FILE__).parent_path() / "data" / "cube_version2.penumbra").string();
    const std::string message = errorOf([&] { openModelFile(path); });
    EXPECT_EQ(message, path + ": unsupported version 2 (this build reads version 3; run penumbra preprocess on the source "
                              "model again)");
}

TEST(ModelFile, MappingOutlivesTheFile)
{
    std::string path = writeModel("model_unlinked.penumbra", cubeModel());
    CompressedModel model = openModelFile(path);
    std::filesystem::remove(path);
    CompressedModel copy = model;
    model = CompressedModel{};
    EXPECT_EQ(copy.clusters[1].triangleCount, 2u);
    EXPECT_NO_THROW(validateModel(copy, "copy"));
}

TEST(ModelFile, DecodedPositionsMatchInput)
{
    auto data = cubeModel();
    CompressedModel model = openModelFile(writeModel("model_decode.penumbra", data));
    const ClusterRecord& cube = model.clusters[0];
    glm::vec3 p = decodePosition(cube, model.vertices[cube.firstVertex + 7]);
    EXPECT_EQ(p, glm::vec3(1, 1, 1));
    p = decodePosition(cube, model.vertices[cube.firstVertex + 0]);
    EXPECT_EQ(p, glm::vec3(0, 0, 0));
}

TEST(ModelFile, StripWindingAlternates)
{
    const uint8_t strip[] = {0, 1, 2, 3, kStripRestart, 4, 4, 5, 6};
    std::vector<std::array<uint32_t, 3>> triangles;
    forEachStripTriangle(strip, strip + sizeof(strip), [&](uint32_t a, uint32_t b, uint32_t c) {
        triangles.push_back({a, b, c});
    });
    // 4 4 5 is degenerate and skipped; 4 5 6 is at an odd position: 5 4 6.
    std::vector<std::array<uint32_t, 3>> expected = {{0, 1, 2}, {2, 1, 3}, {5, 4, 6}};
    EXPECT_EQ(triangles, expected);
}

TEST(ModelFile, WriteIntoMissingDirectoryLeavesNothing)
{
    std::string dir = tempPath("model_no_such_dir");
    std::filesystem::remove_all(dir);
    std::string message = errorOf([&] { writeModelFile(view(cubeModel()), dir + "/out.penumbra"); });
    EXPECT_ERROR_CONTAINS(message, dir + "/out.penumbra: cannot create");
    EXPECT_FALSE(std::filesystem::exists(dir));
}

TEST(ModelFile, WriteRefusesInvalidModelAndKeepsOldFile)
{
    std::string path = tempPath("model_refused.penumbra");
    writeModelFile(view(quadModel()), path);
    std::string before = readFile(path);
    auto data = cubeModel();
    data->clusters[0].triangleCount = 11;
    std::string message = errorOf([&] { writeModelFile(view(data), path); });
    EXPECT_ERROR_CONTAINS(message, path + ": refusing to write an invalid model: cluster 0: strips hold 12 triangles, "
                                          "the record says 11");
    EXPECT_EQ(readFile(path), before);
    for (const auto& entry : std::filesystem::directory_iterator(PENUMBRA_TEST_TMP))
        EXPECT_EQ(entry.path().filename().string().find("model_refused.penumbra.tmp"), std::string::npos);
}

// ---------------------------------------------------------------------------
// Bad files.

TEST(ModelFileBad, Truncated)
{
    std::string bytes = validCubeBytes();
    const FileHeader header = headerOf(bytes);
    EXPECT_ERROR_CONTAINS(openError("model_trunc0.penumbra", ""), "model_trunc0.penumbra: empty file");
    EXPECT_ERROR_CONTAINS(openError("model_trunc10.penumbra", bytes.substr(0, 10)),
                          "truncated: file has 10 bytes, the header alone needs 448");
    EXPECT_ERROR_CONTAINS(openError("model_trunc255.penumbra", bytes.substr(0, 255)),
                          "truncated: file has 255 bytes, the header alone needs 448");
    EXPECT_ERROR_CONTAINS(openError("model_trunc447.penumbra", bytes.substr(0, 447)),
                          "truncated: file has 447 bytes, the header alone needs 448");
    EXPECT_ERROR_CONTAINS(openError("model_trunc5.penumbra", bytes.substr(0, 5)),
                          "truncated: file has 5 bytes, the header alone needs 448");
    const SectionEntry& vertices = sectionOf(header, SectionType::Vertices);
    size_t mid = size_t(vertices.offset + vertices.size / 2);
    EXPECT_ERROR_CONTAINS(openError("model_truncmid.penumbra", bytes.substr(0, mid)),
                          "truncated: header says " + std::to_string(bytes.size()) + " bytes, file has " +
                              std::to_string(mid));
    EXPECT_ERROR_CONTAINS(openError("model_trunclast.penumbra", bytes.substr(0, bytes.size() - 1)),
                          "truncated: header says " + std::to_string(bytes.size()) + " bytes, file has " +
                              std::to_string(bytes.size() - 1));
    EXPECT_ERROR_CONTAINS(openError("model_trailing.penumbra", bytes + std::string(64, '\0')), "trailing data");
    EXPECT_ERROR_CONTAINS(errorOf([] { openModelFile(tempPath("model_missing.penumbra")); }), "file not found");
}

TEST(ModelFileBad, FlippedByteInEachSection)
{
    const std::string bytes = validCubeBytes();
    const FileHeader header = headerOf(bytes);
    for (const char* name : {"Clusters", "Nodes", "Vertices", "Indices"}) {
        SectionType type = std::string(name) == "Clusters"   ? SectionType::Clusters
                           : std::string(name) == "Nodes"    ? SectionType::Nodes
                           : std::string(name) == "Vertices" ? SectionType::Vertices
                                                             : SectionType::Indices;
        const SectionEntry& entry = sectionOf(header, type);
        for (uint64_t at : {entry.offset, entry.offset + entry.size / 2, entry.offset + entry.size - 1}) {
            std::string bad = bytes;
            bad[at] = char(bad[at] ^ 0x10);
            EXPECT_ERROR_CONTAINS(openError("model_flip.penumbra", bad),
                                  std::string("checksum mismatch in section ") + name);
        }
    }
    // Padding is not covered by a checksum but must be zero.
    std::string bad = bytes;
    const SectionEntry& nodes = sectionOf(header, SectionType::Nodes);
    bad[nodes.offset + nodes.size] = 1; // 96 bytes of nodes -> 32 bytes of padding follow
    EXPECT_ERROR_CONTAINS(openError("model_padding.penumbra", bad),
                          "nonzero padding byte at offset " + std::to_string(nodes.offset + nodes.size));
}

TEST(ModelFileBad, HeaderFields)
{
    const std::string bytes = validCubeBytes();
    const FileHeader valid = headerOf(bytes);
    auto withHeader = [&](auto&& mutate, bool fixChecksum = true) {
        std::string bad = bytes;
        FileHeader header = valid;
        mutate(header);
        setHeader(bad, header, fixChecksum);
        return openError("model_header.penumbra", bad);
    };
    std::string bad = bytes;
    bad[3] = 'X';
    EXPECT_ERROR_CONTAINS(openError("model_magic.penumbra", bad),
                          "model_magic.penumbra: not a Penumbra model file (bad magic)");
    EXPECT_ERROR_CONTAINS(openError("model_text.penumbra", "solid cube\n"), "not a Penumbra model file (bad magic)");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.version = 7; }),
                          "unsupported version 7 (this build reads version 3; run penumbra preprocess on the source model again)");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.version = 2; }),
                          "model_header.penumbra: unsupported version 2 (this build reads version 3; run penumbra preprocess on the source model again)");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.version = 1; }), "unsupported version 1 (this build reads version 3");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.headerSize = 320; }), "header size 320 is not 448");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.materialCount = 0; }), "header materialCount 0 is outside 1..16777216");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.cameraCount = 300; }), "header cameraCount 300 is above 256");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.lightCount = 257; }), "header lightCount 257 is above 256");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.boundsMax[0] += 1.0f; }, false), "header checksum mismatch");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.fileSize += 64; }), "truncated: header says");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.build.maxClusterVertices = 300; }),
                          "build parameter maxClusterVertices 300 is outside 3..255");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.build.maxClusterTriangles = 2000; }),
                          "build parameter maxClusterTriangles 2000 is outside 1..1024");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.build.positionBits = 12; }),
                          "build parameter positionBits 12 is not 16");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.build.simplifyTarget = NAN; }),
                          "build parameter simplifyTarget nan is outside (0, 1]");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.reserved1[4] = 5; }), "reserved header field is not zero");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.bvhDepth = 65; }), "header bvhDepth 65 is outside 1..64");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.boundsMin[1] = INFINITY; }), "non-finite model bounds");
}

TEST(ModelFileBad, SectionTable)
{
    const std::string bytes = validCubeBytes();
    const FileHeader valid = headerOf(bytes);
    auto withHeader = [&](auto&& mutate) {
        std::string bad = bytes;
        FileHeader header = valid;
        mutate(header);
        setHeader(bad, header);
        return openError("model_table.penumbra", bad);
    };
    auto entry = [](FileHeader& h, SectionType type) -> SectionEntry& {
        for (SectionEntry& e : h.sections)
            if (e.type == uint32_t(type))
                return e;
        throw std::runtime_error("no such section");
    };
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.sections[2].type = 9; }),
                          "section table entry 2 has unknown type 9");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.sections[3].type = h.sections[1].type; }),
                          "section Nodes appears twice in the section table");
    EXPECT_ERROR_CONTAINS(withHeader([&](FileHeader& h) { entry(h, SectionType::Vertices).elementSize = 6; }),
                          "section Vertices: element size 6, expected 8");
    // Counts pointing outside the file.
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.vertexCount = uint64_t(1) << 62; }),
                          "section Vertices: 96 bytes, but the header's count 4611686018427387904 needs");
    EXPECT_ERROR_CONTAINS(withHeader([&](FileHeader& h) {
                              h.vertexCount = 1000;
                              entry(h, SectionType::Vertices).size = 8000;
                          }),
                          "section Vertices: 8000 bytes at offset");
    // Offsets outside the file, misaligned, inside the header, overlapping.
    EXPECT_ERROR_CONTAINS(withHeader([&](FileHeader& h) { entry(h, SectionType::Indices).offset = uint64_t(1) << 40; }),
                          "section Indices: 33 bytes at offset 1099511627776 run past the end of the file");
    EXPECT_ERROR_CONTAINS(withHeader([&](FileHeader& h) { entry(h, SectionType::Indices).offset = ~uint64_t(63); }),
                          "run past the end of the file");
    EXPECT_ERROR_CONTAINS(withHeader([&](FileHeader& h) { entry(h, SectionType::Nodes).offset += 8; }),
                          "section Nodes: offset 584 is not a multiple of 64");
    EXPECT_ERROR_CONTAINS(withHeader([&](FileHeader& h) { entry(h, SectionType::Clusters).offset = 256; }),
                          "section Clusters: offset 256 overlaps the header");
    EXPECT_ERROR_CONTAINS(withHeader([&](FileHeader& h) {
                              entry(h, SectionType::Nodes).offset = entry(h, SectionType::Clusters).offset + 64;
                          }),
                          "sections Clusters and Nodes overlap");
    EXPECT_ERROR_CONTAINS(withHeader([&](FileHeader& h) {
                              entry(h, SectionType::Indices).offset = entry(h, SectionType::Vertices).offset;
                          }),
                          "overlap");
}

// Version 2: materials, and the source scene's cameras and lights.
TEST(ModelFile, MaterialsCamerasAndLightsRoundTrip)
{
    auto data = cubeModel();
    data->materials = {{{1.0f, 0.5f, 0.25f, 1.0f}}, {{0.0f, 0.2f, 0.8f, 0.5f}}};
    data->header.materialCount = 2;
    data->clusters[1].material = 1;
    Camera camera;
    camera.position = {1, 2, 3};
    camera.target = {0, 0.5f, 0};
    camera.projection = Projection::Orthographic;
    camera.orthoHeight = 7.5f;
    camera.nearPlane = 0.25f;
    camera.farPlane = 90.0f;
    Light sun, spot, rectangle;
    sun.direction = {-0.4f, -1, -0.2f};
    sun.intensity = 3.0f;
    spot.type = LightType::Spot;
    spot.position = {0, 10, 0};
    spot.color = {1, 0.9f, 0.8f};
    spot.innerConeDegrees = 15;
    spot.outerConeDegrees = 25;
    spot.range = 40;
    rectangle.type = LightType::Rectangle;
    rectangle.width = 3;
    rectangle.height = 2;
    CompressedModel model = withScene(view(data), {camera}, {sun, spot, rectangle});
    const std::string path = tempPath("model_scene.penumbra");
    writeModelFile(model, path);
    CompressedModel read = openModelFile(path);
    EXPECT_EQ(read.header.materialCount, 2u);
    EXPECT_EQ(read.header.cameraCount, 1u);
    EXPECT_EQ(read.header.lightCount, 3u);
    ASSERT_EQ(read.materials.size(), 2u);
    EXPECT_EQ(std::memcmp(read.materials.data(), data->materials.data(), read.materials.size_bytes()), 0);
    EXPECT_EQ(read.clusters[1].material, 1u);
    EXPECT_EQ(sectionOf(read.header, SectionType::Cameras).elementSize, 64u);
    EXPECT_EQ(sectionOf(read.header, SectionType::Lights).size, 3u * 80u);
    std::vector<Camera> cameras = modelCameras(read);
    ASSERT_EQ(cameras.size(), 1u);
    EXPECT_EQ(cameras[0].position, camera.position);
    EXPECT_EQ(cameras[0].target, camera.target);
    EXPECT_EQ(cameras[0].up, camera.up);
    EXPECT_EQ(cameras[0].projection, Projection::Orthographic);
    EXPECT_EQ(cameras[0].orthoHeight, 7.5f);
    EXPECT_EQ(cameras[0].yfovDegrees, camera.yfovDegrees);
    EXPECT_EQ(cameras[0].nearPlane, 0.25f);
    EXPECT_EQ(cameras[0].farPlane, 90.0f);
    std::vector<Light> lights = modelLights(read);
    ASSERT_EQ(lights.size(), 3u);
    const Light* originals[] = {&sun, &spot, &rectangle};
    for (size_t i = 0; i < 3; ++i) {
        const Light& a = lights[i];
        const Light& b = *originals[i];
        EXPECT_EQ(a.type, b.type);
        EXPECT_EQ(a.position, b.position);
        EXPECT_EQ(a.direction, b.direction);
        EXPECT_EQ(a.up, b.up);
        EXPECT_EQ(a.color, b.color);
        EXPECT_EQ(a.intensity, b.intensity);
        EXPECT_EQ(a.range, b.range);
        EXPECT_EQ(a.innerConeDegrees, b.innerConeDegrees);
        EXPECT_EQ(a.outerConeDegrees, b.outerConeDegrees);
        EXPECT_EQ(a.width, b.width);
        EXPECT_EQ(a.height, b.height);
        EXPECT_EQ(a.radius, b.radius);
    }
}

TEST(ModelFileBad, MaterialsCamerasAndLights)
{
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.materials[0].baseColor[1] = 1.5f; },
        "material 0: base colour component 1.5 is outside [0, 1]");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.materials[0].baseColor[3] = NAN; }, "material 0: base colour component nan");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.materials.push_back({{1, 1, 1, 1}}); }, "header says 1 materials but there are 2");
    auto withCamera = [](auto&& mutate) {
        Camera camera;
        model::CameraRecord record = cameraRecord(camera);
        mutate(record);
        auto data = cubeModel();
        data->cameras = {record};
        data->header.cameraCount = 1;
        return errorOf([&] { validateModel(view(data), "m"); });
    };
    EXPECT_EQ(withCamera([](model::CameraRecord&) {}), "");
    EXPECT_ERROR_CONTAINS(withCamera([](model::CameraRecord& r) { r.target[0] = r.position[0], r.target[1] = r.position[1], r.target[2] = r.position[2]; }),
                          "m: camera 0: position and target are equal");
    EXPECT_ERROR_CONTAINS(withCamera([](model::CameraRecord& r) { r.up[0] = r.up[1] = r.up[2] = 0; }), "camera 0: up is zero or parallel");
    EXPECT_ERROR_CONTAINS(withCamera([](model::CameraRecord& r) { r.projection = 2; }), "camera 0: unknown projection 2");
    EXPECT_ERROR_CONTAINS(withCamera([](model::CameraRecord& r) { r.yfovDegrees = 180; }), "camera 0: field of view 180");
    EXPECT_ERROR_CONTAINS(withCamera([](model::CameraRecord& r) { r.orthoHeight = 0; }), "camera 0: orthographic height 0");
    EXPECT_ERROR_CONTAINS(withCamera([](model::CameraRecord& r) { r.nearPlane = 5, r.farPlane = 2; }), "camera 0: near 5 / far 2");
    EXPECT_ERROR_CONTAINS(withCamera([](model::CameraRecord& r) { r.position[1] = INFINITY; }), "camera 0: non-finite");
    EXPECT_ERROR_CONTAINS(withCamera([](model::CameraRecord& r) { r.reserved[1] = 3; }), "camera 0: reserved field is not zero");
    auto withLight = [](auto&& mutate) {
        Light light;
        model::LightRecord record = lightRecord(light);
        mutate(record);
        auto data = cubeModel();
        data->lights = {record};
        data->header.lightCount = 1;
        return errorOf([&] { validateModel(view(data), "m"); });
    };
    EXPECT_EQ(withLight([](model::LightRecord&) {}), "");
    EXPECT_ERROR_CONTAINS(withLight([](model::LightRecord& r) { r.type = 6; }), "m: light 0: unknown type 6");
    EXPECT_ERROR_CONTAINS(withLight([](model::LightRecord& r) { r.direction[0] = r.direction[1] = r.direction[2] = 0; }),
                          "light 0: zero direction");
    EXPECT_EQ(withLight([](model::LightRecord& r) { // a point light needs no direction, as for the renderer
                  r.type = uint32_t(LightType::Point);
                  r.direction[0] = r.direction[1] = r.direction[2] = 0;
              }),
              "");
    EXPECT_ERROR_CONTAINS(withLight([](model::LightRecord& r) { r.color[2] = INFINITY; }), "light 0: non-finite position");
    EXPECT_ERROR_CONTAINS(withLight([](model::LightRecord& r) { r.intensity = NAN; }), "light 0: non-finite intensity");
    EXPECT_ERROR_CONTAINS(withLight([](model::LightRecord& r) { r.intensity = -1; }), "light 0: intensity -1 and range 0 must be >= 0");
    EXPECT_ERROR_CONTAINS(withLight([](model::LightRecord& r) { r.type = uint32_t(LightType::Spot), r.outerConeDegrees = 95; }),
                          "light 0: spot cone inner");
    EXPECT_ERROR_CONTAINS(withLight([](model::LightRecord& r) { r.type = uint32_t(LightType::Rectangle), r.width = 0; }),
                          "width 0, height 1 and radius 0.5 > 0");
    EXPECT_ERROR_CONTAINS(withLight([](model::LightRecord& r) { r.type = uint32_t(LightType::Sphere), r.radius = 0; }),
                          "radius 0 > 0");

    // withScene leaves out what the format rejects, with a warning.
    static std::vector<std::string> warnings;
    warnings.clear();
    WarningSink previous = setWarningSink([](const std::string& line) { warnings.push_back(line); });
    Camera flat;
    flat.target = flat.position;
    Light spot;
    spot.type = LightType::Spot;
    spot.outerConeDegrees = 90.0f;
    CompressedModel kept = withScene(view(cubeModel()), {flat, Camera{}}, {spot, Light{}}, "part.glb");
    setWarningSink(previous);
    EXPECT_EQ(kept.cameras.size(), 1u);
    EXPECT_EQ(kept.lights.size(), 1u);
    ASSERT_EQ(warnings.size(), 2u);
    EXPECT_EQ(warnings[0], "part.glb: camera 0: position and target are equal (not stored)");
    EXPECT_NE(warnings[1].find("part.glb: light 0: spot cone inner 20 / outer 90 degrees"), std::string::npos) << warnings[1];

    // The section table: optional sections exactly when counted, unused entries all zero.
    auto data = cubeModel();
    CompressedModel scene = withScene(view(data), {Camera{}}, {});
    const std::string path = tempPath("model_scene_bad.penumbra");
    writeModelFile(scene, path);
    const std::string bytes = readFile(path);
    auto withHeader = [&](auto&& mutate) {
        std::string bad = bytes;
        FileHeader header = headerOf(bytes);
        mutate(header);
        setHeader(bad, header);
        return openError("model_scene_table.penumbra", bad);
    };
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.sections[7].offset = 64; }),
                          "section table entry 7 is unused (type 0) but not all zero");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.sections[5] = {}; }), "section Cameras is missing from the section table");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.sections[4] = {}; }), "section Materials is missing from the section table");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) {
                              h.sections[6] = h.sections[5];
                              h.sections[6].type = uint32_t(SectionType::Lights);
                              h.sections[6].elementSize = 80;
                          }),
                          "section Lights: 64 bytes, but the header's count 0 needs");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.sections[5].type = 8; }), "section table entry 5 has unknown type 8");
}

// A hostile file whose checksums are all valid is still rejected.
TEST(ModelFileBad, HostileFileWithValidChecksums)
{
    const std::string bytes = validCubeBytes();
    const FileHeader header = headerOf(bytes);
    const SectionEntry& indices = sectionOf(header, SectionType::Indices);
    std::string bad = bytes;
    bad[indices.offset + 1] = char(200);
    fixChecksums(bad);
    EXPECT_ERROR_CONTAINS(openError("model_hostile.penumbra", bad),
                          "model_hostile.penumbra: cluster 0: strip index 200 >= vertex count 8 (strip byte 1)");

    const SectionEntry& nodes = sectionOf(header, SectionType::Nodes);
    bad = bytes;
    Node root;
    std::memcpy(&root, bad.data() + nodes.offset, sizeof(root));
    root.first = 1000;
    std::memcpy(bad.data() + nodes.offset, &root, sizeof(root));
    fixChecksums(bad);
    EXPECT_ERROR_CONTAINS(openError("model_hostile.penumbra", bad), "node 0: child 1001 out of range (6 nodes)");
}

// ---------------------------------------------------------------------------
// Hostile but checksum-valid models: validateModel directly.

TEST(ModelValidate, Clusters)
{
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.indices[5] = 9; },
        "cluster 0: strip index 9 >= vertex count 8 (strip byte 5)");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[0].triangleCount = 13; },
        "cluster 0: strips hold 12 triangles, the record says 13");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[1].step[1] = NAN; },
        "cluster 1: step nan on axis 1 is not a finite value >= 0");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[1].step[2] = -1.0f; }, "cluster 1: step -1 on axis 2");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[1].boxMin[0] = INFINITY; },
        "cluster 1: non-finite boxMin inf on axis 0");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[1].step[0] = 1e35f; },
        "cluster 1: quantization range overflows on axis 0");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[1].vertexCount = 2; },
        "cluster 1: vertex count 2 is outside 3..maxClusterVertices (255)");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.header.build.maxClusterVertices = 6; },
        "cluster 0: vertex count 8 is outside 3..maxClusterVertices (6)");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[1].triangleCount = 0; },
        "cluster 1: triangle count 0 is outside 1..maxClusterTriangles (1024)");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[1].firstVertex = 0xFFFFFFFE; },
        "cluster 1: vertices 4294967294..4294967298 run past the 12 vertices");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[1].firstIndex = 0xFFFFFFF0; },
        "cluster 1: strip bytes 4294967280..4294967284 run past the");
    // Version 3's 64-bit offsets: far beyond 32 bits, and at the end of the 64-bit range (no wrap-around).
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[1].firstVertex = 1ull << 40; },
        "cluster 1: vertices 1099511627776..1099511627780 run past the 12 vertices");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[1].firstVertex = ~0ull - 1; },
        "cluster 1: vertices 18446744073709551614..18446744073709551614+4 run past the 12 vertices");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[1].firstIndex = ~0ull - 2; },
        "cluster 1: strip bytes 18446744073709551613..18446744073709551613+4 run past the");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[1].firstIndex = 1ull << 32; },
        "cluster 1: strip bytes 4294967296..4294967300 run past the");
    // Flags: only kClusterClosed is defined; the reserved word is zero.
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[0].flags = kClusterClosed | 4u; }, "cluster 0: unknown flag bits 0x4");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[1].flags = 0x80000000u; }, "cluster 1: unknown flag bits 0x80000000");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[1].reserved = 1; }, "cluster 1: reserved field is not zero");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[1].node = 99; },
        "cluster 1: node 99 out of range (6 nodes)");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[1].node = 1; },
        "cluster 1: node 1 is not this cluster's Cluster node");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[0].material = 1; }, "cluster 0: material 1 out of range (1 materials)");
    // Strip syntax: restart at the ends, double restarts.
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.indices[0] = kStripRestart; },
        "cluster 0: strips begin or end with a restart");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.indices[5] = kStripRestart; },
        "cluster 0: two consecutive restarts at strip byte 5");
    // Header totals.
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.header.triangleCount = 15; },
        "header says 15 triangles but the clusters hold 14");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.header.vertexCount = 11; },
        "header says 11 vertices but there are 12");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.header.clusterCount = 3; }, "header says 3 clusters but there are 2");
}

TEST(ModelValidate, NodeLinks)
{
    // Cube model nodes: 0 root (Interior, children 1 2); 1 Cluster 0 (leaves 3 4); 2 Cluster 1 (leaf 5).
    auto data = cubeModel();
    ASSERT_EQ(data->nodes.size(), 6u);
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[2].first = 6; }, "node 2: child 6 out of range (6 nodes)");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[2].first = 1; }, "node 2: child 1 is not after its parent");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[2].first = 2; }, "node 2: child 2 is not after its parent");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[2].first = 4; },
        "node 4 is referenced by two parents (nodes 1 and 2)");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[0].childCount = 3; },
        "node 0: 3 children (interior and cluster nodes have 1 or 2)");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[1].childCount = 0; }, "node 1: 0 children");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[3].kind = 7; }, "node 3: unknown kind 7");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[3].childCount = 1; }, "node 3: leaf with 1 children");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[4].lo[1] = 200, d.nodes[4].hi[1] = 100; },
        "node 4: bounds lo 200 > hi 100 on axis 1");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[0].hi[2] = 254; }, "node 0: root bounds must be lo 0, hi 255");
    // Cluster 1 unreachable: the root keeps only cluster 0.
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[0].childCount = 1; },
        "cluster 1 (node 2) is not reachable from the root");
    // Cluster node pointing at another cluster.
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[2].second = 5; },
        "cluster 1: node 2 is not this cluster's Cluster node");
}

TEST(ModelValidate, Leaves)
{
    // Cube cluster: strips 0 2 1 3 | 4 5 6 7 | 0 1 4 5 || 2 6 3 7 | 0 4 2 6 | 1 3 5 7 (| = restart);
    // leaf 3 covers bytes 0..14, leaf 4 bytes 15..29.
    auto data = cubeModel();
    ASSERT_EQ(data->nodes[3].second, 0u | 14u << 16);
    ASSERT_EQ(data->nodes[4].second, 15u | 14u << 16);
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[4].second = 15u | 20u << 16; },
        "node 4: leaf range 15..35 lies outside the 29 strip bytes of cluster 0");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[4].second = 16u | 13u << 16; },
        "node 4: leaf range 16..29 does not begin at a strip start");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[3].second = 0u | 13u << 16; },
        "node 3: leaf range 0..13 does not end at a strip end");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[3].second = 0u | 0u << 16; }, "node 3: empty leaf range");
    // Leaf 3 covering everything overlaps leaf 4 (traversal visits 3 first).
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[3].second = 0u | 29u << 16; },
        "node 4: leaf range 15..29 overlaps another leaf of cluster 0");
    // Leaf 3 covering only its first strip: the leaves hold 2 + 6 of 12 triangles.
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[3].second = 0u | 4u << 16; },
        "cluster 0: its leaves hold 8 triangles, the cluster 12");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[5].first = 0; },
        "node 5: leaf names cluster 0 but lies under cluster 1");
    // A strip of degenerate triangles only.
    expectInvalid(
        quadModel,
        [](CompressedModelData& d) {
            d.indices = {0, 1, 2, 3, kStripRestart, 1, 1, 2};
            d.header.indexBytes = 8;
            d.clusters[0].indexBytes = 8;
            d.nodes.push_back(d.nodes[1]);
            d.nodes[0].childCount = 2;
            d.nodes[2].second = 5u | 3u << 16;
            d.header.nodeCount = 3;
        },
        "node 2: leaf range 5..8 holds no triangles");
    // A leaf directly under an Interior root (outside any cluster):
    // 0 Interior (1 2), 1 Cluster 0 (3), 2 Leaf, 3 Leaf.
    expectInvalid(
        quadModel,
        [](CompressedModelData& d) {
            Node leaf = d.nodes[1];
            Node cluster = d.nodes[0];
            cluster.first = 3;
            Node root{};
            root.kind = uint8_t(NodeKind::Interior);
            root.childCount = 2;
            root.first = 1;
            root.hi[0] = root.hi[1] = root.hi[2] = 255;
            d.nodes = {root, cluster, leaf, leaf};
            d.clusters[0].node = 1;
            d.header.nodeCount = 4;
            d.header.bvhDepth = 3;
        },
        "node 2: leaf outside any cluster");
}

TEST(ModelValidate, ClusterInsideCluster)
{
    // Two-cluster model with the second cluster node hung under the first cluster.
    auto make = [] {
        TestCluster a;
        a.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
        a.leaves = {TestLeaf{{{0, 1, 2, 3}}}};
        return buildModel({a, a});
    };
    auto data = make();
    // Root 0 -> clusters 1, 2 (leaves 3, 4). Make the root's only child node 1
    // and node 1's children nodes 2 (cluster 1) and 3 (its own leaf).
    data->nodes[0].childCount = 1;
    data->nodes[1].first = 2;
    data->nodes[1].childCount = 2;
    std::string message = errorOf([&] { validateModel(view(data), "m"); });
    EXPECT_ERROR_CONTAINS(message, "node 2: cluster node inside the subtree of cluster 0");
}

// A chain of interior nodes: depth 64 is accepted, 65 rejected.
std::shared_ptr<CompressedModelData> chainModel(uint32_t depth)
{
    auto data = quadModel(); // nodes: 0 Cluster, 1 Leaf
    std::vector<Node> nodes;
    const uint32_t interiorCount = depth - 2;
    for (uint32_t i = 0; i < interiorCount; ++i) {
        Node n{};
        n.kind = uint8_t(NodeKind::Interior);
        n.childCount = 1;
        n.first = i + 1;
        n.hi[0] = n.hi[1] = n.hi[2] = 255;
        nodes.push_back(n);
    }
    Node cluster = data->nodes[0];
    cluster.first = interiorCount + 1;
    nodes.push_back(cluster);
    nodes.push_back(data->nodes[1]);
    data->nodes = nodes;
    data->clusters[0].node = interiorCount;
    data->header.nodeCount = uint32_t(nodes.size());
    data->header.bvhDepth = std::min(depth, kMaxBvhDepth);
    return data;
}

TEST(ModelValidate, Depth)
{
    EXPECT_NO_THROW(validateModel(view(chainModel(64)), "m"));
    EXPECT_ERROR_CONTAINS(errorOf([] { validateModel(view(chainModel(65)), "m"); }), "m: BVH deeper than 64 levels");
    EXPECT_ERROR_CONTAINS(errorOf([] { validateModel(view(chainModel(1000)), "m"); }), "m: BVH deeper than 64 levels");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.header.bvhDepth = 4; },
        "header says the BVH has 4 levels but it has 3");
    // The file round trip of the deepest legal BVH.
    CompressedModel model = openModelFile(writeModel("model_deep.penumbra", chainModel(64)));
    EXPECT_EQ(model.header.bvhDepth, 64u);
}

TEST(ModelValidate, HeaderBuildParameters)
{
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.header.build.nodeBoundsBits = 16; },
        "build parameter nodeBoundsBits 16 is not 8");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.header.build.maxLeafTriangles = 0; },
        "build parameter maxLeafTriangles 0 is outside 1..maxClusterTriangles (1024)");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.header.maxPositionError = NAN; },
        "maxPositionError nan is not a finite value >= 0");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.header.boundsMin[2] = 5.0f; },
        "model bounds min 5 > max 1 on axis 2");
}

// Writes the fuzzer's seed corpus (run by hand after a format change:
// formats_tests --gtest_also_run_disabled_tests --gtest_filter='*FuzzSeeds*',
// then copy tmp/fuzz_seed_*.penumbra to tests/fuzz/corpus/).
TEST(ModelFile, DISABLED_WriteFuzzSeeds)
{
    writeModelFile(view(quadModel()), tempPath("fuzz_seed_quad.penumbra"));
    auto cube = cubeModel();
    cube->clusters[0].flags = kClusterClosed; // the cube is closed: a seed with the flag set
    writeModelFile(view(cube), tempPath("fuzz_seed_cube.penumbra"));
}

} // namespace
} // namespace penumbra::test

namespace penumbra::test {
namespace {

// A large synthetic model (2^k clusters of 128 vertices and 210 triangles in
// 7 strips, 2 leaves each, a complete binary tree above the Cluster nodes in
// heap order) to time writing and opening. PENUMBRA_MODEL_CLUSTER_BITS sets k
// (default 19: ~720 MB).
std::shared_ptr<CompressedModelData> largeModel(uint32_t clusterBits)
{
    const uint32_t clusterCount = 1u << clusterBits;
    const uint32_t width = 16, height = 8, stripLength = 2 * width;
    auto data = std::make_shared<CompressedModelData>();
    std::vector<uint8_t> strips;
    for (uint32_t row = 0; row + 1 < height; ++row) {
        if (row > 0)
            strips.push_back(kStripRestart);
        for (uint32_t x = 0; x < width; ++x) {
            strips.push_back(uint8_t(row * width + x));
            strips.push_back(uint8_t((row + 1) * width + x));
        }
    }
    const uint32_t firstLeafBytes = 4 * stripLength + 3; // strips 0..3
    const uint32_t upperNodes = 2 * clusterCount - 1;
    data->clusters.resize(clusterCount);
    data->vertices.resize(size_t(clusterCount) * width * height);
    data->indices.resize(size_t(clusterCount) * strips.size());
    data->nodes.resize(upperNodes + 2 * size_t(clusterCount));
    for (uint32_t n = 0; n < upperNodes - clusterCount; ++n) {
        Node& node = data->nodes[n];
        node.hi[0] = node.hi[1] = node.hi[2] = 255;
        node.kind = uint8_t(NodeKind::Interior);
        node.childCount = 2;
        node.first = 2 * n + 1;
    }
    for (uint32_t c = 0; c < clusterCount; ++c) {
        ClusterRecord& cluster = data->clusters[c];
        cluster = {{float(c), 0, 0},
                   {1.0f / 65535, 1.0f / 65535, 1.0f / 65535},
                   c * width * height,
                   uint32_t(c * strips.size()),
                   uint32_t(strips.size()),
                   uint16_t(width * height),
                   uint16_t((height - 1) * (stripLength - 2)),
                   upperNodes - clusterCount + c,
                   0};
        for (uint32_t v = 0; v < width * height; ++v)
            data->vertices[cluster.firstVertex + v] = {uint16_t(v % width * 4000), uint16_t(v / width * 8000),
                                                       uint16_t(v * 37), 0};
        std::memcpy(data->indices.data() + cluster.firstIndex, strips.data(), strips.size());
        Node& clusterNode = data->nodes[cluster.node];
        clusterNode = {{0, 0, 0}, {255, 255, 255}, uint8_t(NodeKind::Cluster), 2, upperNodes + 2 * c, c};
        data->nodes[upperNodes + 2 * c] = {{0, 0, 0}, {255, 255, 255},          uint8_t(NodeKind::Leaf), 0,
                                           c,         0u | firstLeafBytes << 16};
        data->nodes[upperNodes + 2 * c + 1] = {{0, 0, 0},
                                               {255, 255, 255},
                                               uint8_t(NodeKind::Leaf),
                                               0,
                                               c,
                                               (firstLeafBytes + 1) | (uint32_t(strips.size()) - firstLeafBytes - 1)
                                                                          << 16};
    }
    FileHeader& header = data->header;
    header.build = {255, 1024, 128, 16, kPositionBits, kNodeBoundsBits, 1.0f, 0};
    header.triangleCount = uint64_t(clusterCount) * data->clusters[0].triangleCount;
    header.sourceTriangleCount = header.triangleCount;
    header.vertexCount = data->vertices.size();
    header.indexBytes = data->indices.size();
    header.clusterCount = clusterCount;
    header.nodeCount = uint32_t(data->nodes.size());
    header.bvhDepth = clusterBits + 2;
    header.boundsMin[0] = header.boundsMin[1] = header.boundsMin[2] = 0.0f;
    header.boundsMax[0] = float(clusterCount);
    header.boundsMax[1] = header.boundsMax[2] = 1.0f;
    data->materials = {{{1.0f, 1.0f, 1.0f, 1.0f}}};
    header.materialCount = 1;
    return data;
}

TEST(ModelFile, LargeModelIsValid)
{
    EXPECT_NO_THROW(validateModel(makeCompressedModel(largeModel(4)), "large"));
}

TEST(ModelFile, DISABLED_Throughput)
{
    const char* bits = std::getenv("PENUMBRA_MODEL_CLUSTER_BITS");
    auto data = largeModel(bits ? uint32_t(std::atoi(bits)) : 19);
    std::string path = tempPath("model_throughput.penumbra");
    auto seconds = [](auto since) {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
    };
    auto start = std::chrono::steady_clock::now();
    writeModelFile(makeCompressedModel(data), path);
    double writeSeconds = seconds(start);
    data.reset();
    double best = 1e9;
    uint64_t size = 0;
    for (int i = 0; i < 3; ++i) {
        start = std::chrono::steady_clock::now();
        CompressedModel model = openModelFile(path);
        best = std::min(best, seconds(start));
        size = model.header.fileSize;
    }
    std::printf("model file %.0f MB: write (validate + checksum + write) %.2f s, open (map + validate) best of 3 "
                "%.2f s = %.2f GB/s\n",
                double(size) / 1e6, writeSeconds, best, double(size) / 1e9 / best);
    std::filesystem::remove(path);
}

} // namespace
} // namespace penumbra::test
