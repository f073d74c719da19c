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
#include <stdexcept>
#include <string>
#include <vector>

#include <glm/common.hpp>
#include <glm/vector_relational.hpp>

#include "penumbra/error.h"
#include "penumbra/model_format.h"
#include "test_helpers.h"

namespace penumbra::test {
namespace {

using namespace model;

// ---------------------------------------------------------------------------
// A tiny hand-made builder: each cluster is its positions plus its leaves,
// each leaf a list of strips (local indices). Nodes are numbered depth first
// (pre-order), as the preprocessor lays them out: node 0 is the root above
// the clusters and names the clusters' root nodes in Cluster slots (more than
// four clusters get Interior nodes above them, the clusters split in four
// parts a level); a cluster's root holds its leaves as Leaf slots or, when the
// cluster lists groups, one Interior node per group holding those leaves.
// Every node's child boxes lie on a grid of its own, rounded outward and
// checked with decodeChildBox, as preprocess/src/node_layout.cpp does.

struct TestLeaf {
    std::vector<std::vector<uint8_t>> strips;
};
struct TestCluster {
    std::vector<glm::vec3> positions;
    std::vector<TestLeaf> leaves;
    std::vector<std::vector<uint32_t>> groups; // leaf indices per Interior node; empty: the leaves are the root's slots
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

// One child slot of a node under construction.
struct Slot {
    ChildKind kind;
    uint32_t child; // node index, or start | count << 16 for a leaf
    Box box;        // exact box of the child's geometry
};

// The smallest grid exponent whose 255 steps from origin reach max.
uint8_t gridExponent(float origin, float max)
{
    uint32_t exponent = 1;
    while (exponent < 254 && !(origin + 255.0f * nodeStep(uint8_t(exponent)) >= max))
        ++exponent;
    return uint8_t(exponent);
}

// Child c's box on the node's grid: floor/ceil, then widened by a step while
// the decoder misses the exact box.
void encodeChildBox(Node& node, uint32_t c, const Box& exact)
{
    for (int a = 0; a < 3; ++a) {
        const float step = nodeStep(node.exponent[a]);
        node.lo[a][c] = uint8_t(std::clamp(std::floor((exact.min[a] - node.origin[a]) / step), 0.0f, 255.0f));
        node.hi[a][c] = uint8_t(std::clamp(std::ceil((exact.max[a] - node.origin[a]) / step), 0.0f, 255.0f));
        node.hi[a][c] = std::max(node.hi[a][c], node.lo[a][c]);
    }
    for (bool changed = true; changed;) {
        glm::vec3 min, max;
        decodeChildBox(node, c, min, max);
        changed = false;
        for (int a = 0; a < 3; ++a) {
            if (min[a] > exact.min[a] && node.lo[a][c] > 0)
                node.lo[a][c]--, changed = true;
            if (max[a] < exact.max[a] && node.hi[a][c] < 255)
                node.hi[a][c]++, changed = true;
        }
    }
    glm::vec3 min, max;
    decodeChildBox(node, c, min, max);
    if (glm::any(glm::greaterThan(min, exact.min)) || glm::any(glm::lessThan(max, exact.max)))
        throw std::runtime_error("test builder: a child box escapes its node's grid");
}

// A node of `cluster` (kNoCluster above the clusters) over 1..4 slots, its grid over their boxes.
Node gridNode(uint32_t cluster, const std::vector<Slot>& slots)
{
    if (slots.empty() || slots.size() > kNodeChildren)
        throw std::runtime_error("test builder: a node has 1..4 children");
    Node node{};
    node.cluster = cluster;
    Box all;
    for (const Slot& slot : slots)
        all.add(slot.box);
    for (int a = 0; a < 3; ++a) {
        node.origin[a] = all.min[a];
        node.exponent[a] = gridExponent(all.min[a], all.max[a]);
    }
    for (uint32_t c = 0; c < slots.size(); ++c) {
        node.kinds |= uint8_t(uint32_t(slots[c].kind) << (2 * c));
        node.child[c] = slots[c].child;
        encodeChildBox(node, c, slots[c].box);
    }
    return node;
}

Box unionOf(const std::vector<Slot>& slots)
{
    Box box;
    for (const Slot& slot : slots)
        box.add(slot.box);
    return box;
}

// Builds the node array over clusters whose leaves (Leaf slots) and groups are
// given; sets every record's node, the header's nodeCount and bvhDepth.
class TreeBuilder {
public:
    TreeBuilder(CompressedModelData& data, const std::vector<std::vector<Slot>>& leaves,
                const std::vector<std::vector<std::vector<uint32_t>>>& groups)
        : data_(data), leaves_(leaves), groups_(groups)
    {
        data_.nodes.clear();
        top(0, uint32_t(leaves_.size()), 1);
        data_.header.nodeCount = uint32_t(data_.nodes.size());
        data_.header.bvhDepth = depth_;
    }

private:
    uint32_t allocate(uint32_t level)
    {
        depth_ = std::max(depth_, level);
        data_.nodes.emplace_back();
        return uint32_t(data_.nodes.size() - 1);
    }

    // A node above the clusters [first, first + count).
    Slot top(uint32_t first, uint32_t count, uint32_t level)
    {
        const uint32_t index = allocate(level);
        std::vector<Slot> slots;
        const uint32_t parts = std::min(count, kNodeChildren);
        for (uint32_t p = 0, begin = first; p < parts; ++p) {
            const uint32_t size = count / parts + (p < count % parts ? 1 : 0);
            slots.push_back(size == 1 ? cluster(begin, level + 1) : top(begin, size, level + 1));
            begin += size;
        }
        data_.nodes[index] = gridNode(kNoCluster, slots);
        return {ChildKind::Interior, index, unionOf(slots)};
    }

    // Cluster c's root node and the Interior nodes of its groups.
    Slot cluster(uint32_t c, uint32_t level)
    {
        const uint32_t index = allocate(level);
        data_.clusters[c].node = index;
        std::vector<Slot> slots;
        if (groups_[c].empty())
            slots = leaves_[c];
        for (const std::vector<uint32_t>& group : groups_[c]) {
            const uint32_t node = allocate(level + 1);
            std::vector<Slot> groupSlots;
            for (uint32_t leaf : group)
                groupSlots.push_back(leaves_[c][leaf]);
            data_.nodes[node] = gridNode(c, groupSlots);
            slots.push_back({ChildKind::Interior, node, unionOf(groupSlots)});
        }
        data_.nodes[index] = gridNode(c, slots);
        return {ChildKind::Cluster, index, unionOf(slots)};
    }

    CompressedModelData& data_;
    const std::vector<std::vector<Slot>>& leaves_;
    const std::vector<std::vector<std::vector<uint32_t>>>& groups_;
    uint32_t depth_ = 0;
};

std::shared_ptr<CompressedModelData> buildModel(const std::vector<TestCluster>& input)
{
    auto data = std::make_shared<CompressedModelData>();
    FileHeader& header = data->header;
    header.build = {255, 1024, 8, 16, kPositionBits, kNodeBoundsBits, 1.0f, 0};

    const uint32_t clusterCount = uint32_t(input.size());
    std::vector<std::vector<Slot>> leaves(clusterCount);
    std::vector<std::vector<std::vector<uint32_t>>> groups(clusterCount);
    Box rootBox;
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
        record.firstVertex = data->vertices.size();
        record.firstIndex = data->indices.size();
        record.vertexCount = uint16_t(in.positions.size());
        for (const glm::vec3& p : in.positions) {
            QuantizedVertex q{};
            uint16_t* out[3] = {&q.x, &q.y, &q.z};
            for (int axis = 0; axis < 3; ++axis)
                *out[axis] = record.step[axis] > 0.0f
                                 ? uint16_t(std::lround((p[axis] - record.boxMin[axis]) / record.step[axis]))
                                 : 0;
            data->vertices.push_back(q);
        }
        uint32_t clusterTriangles = 0;
        for (const TestLeaf& leaf : in.leaves) {
            if (data->indices.size() > record.firstIndex)
                data->indices.push_back(kStripRestart);
            const uint32_t start = uint32_t(data->indices.size() - record.firstIndex);
            for (size_t s = 0; s < leaf.strips.size(); ++s) {
                if (s > 0)
                    data->indices.push_back(kStripRestart);
                data->indices.insert(data->indices.end(), leaf.strips[s].begin(), leaf.strips[s].end());
            }
            const uint32_t end = uint32_t(data->indices.size() - record.firstIndex);
            const uint8_t* bytes = data->indices.data() + record.firstIndex;
            Box leafBox;
            forEachStripTriangle(bytes + start, bytes + end, [&](uint32_t a, uint32_t b, uint32_t cc) {
                ++clusterTriangles;
                for (uint32_t v : {a, b, cc})
                    leafBox.add(decodePosition(record, data->vertices[record.firstVertex + v]));
            });
            leaves[c].push_back({ChildKind::Leaf, start | (end - start) << 16, leafBox});
            rootBox.add(leafBox);
        }
        record.indexBytes = uint32_t(data->indices.size() - record.firstIndex);
        record.triangleCount = uint16_t(clusterTriangles);
        triangles += clusterTriangles;
        data->clusters.push_back(record);
        groups[c] = in.groups;
    }
    TreeBuilder(*data, leaves, groups);
    for (int axis = 0; axis < 3; ++axis) {
        header.boundsMin[axis] = rootBox.min[axis];
        header.boundsMax[axis] = rootBox.max[axis];
    }
    header.triangleCount = triangles;
    header.sourceTriangleCount = triangles;
    header.vertexCount = data->vertices.size();
    header.indexBytes = data->indices.size();
    header.clusterCount = clusterCount;
    data->materials = {{{1.0f, 1.0f, 1.0f, 1.0f}}};
    header.materialCount = 1;
    return data;
}

// One cluster: a unit quad as the strip 0 1 2 3 (2 triangles), one leaf.
// Nodes: 0 root [Cluster 1]; 1 cluster 0's root [Leaf 0..4].
std::shared_ptr<CompressedModelData> quadModel()
{
    TestCluster quad;
    quad.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
    quad.leaves = {TestLeaf{{{0, 1, 2, 3}}}};
    return buildModel({quad});
}

TestCluster cubeCluster()
{
    TestCluster cube;
    for (int i = 0; i < 8; ++i)
        cube.positions.push_back({float(i & 1), float((i >> 1) & 1), float((i >> 2) & 1)});
    cube.leaves = {TestLeaf{{{0, 2, 1, 3}, {4, 5, 6, 7}, {0, 1, 4, 5}}},
                   TestLeaf{{{2, 6, 3, 7}, {0, 4, 2, 6}, {1, 3, 5, 7}}}};
    return cube;
}

TestCluster sideQuadCluster()
{
    TestCluster quad;
    quad.positions = {{2, 0, 0}, {3, 0, 0}, {2, 1, 0.5f}, {3, 1, 0.5f}};
    quad.leaves = {TestLeaf{{{0, 1, 2, 3}}}};
    return quad;
}

// Two clusters: a cube (6 faces as 4-index strips, 12 triangles, two leaves
// of 3 faces) and a quad beside it.
// Nodes: 0 root [Cluster 1, Cluster 2]; 1 cluster 0's root [Leaf 0..14, Leaf 15..29];
// 2 cluster 1's root [Leaf 0..4].
std::shared_ptr<CompressedModelData> cubeModel()
{
    return buildModel({cubeCluster(), sideQuadCluster()});
}

// The cube model with an Interior level inside the cube's cluster.
// Nodes: 0 root [Cluster 1, Cluster 4]; 1 cluster 0's root [Interior 2, Interior 3];
// 2 [Leaf 0..14]; 3 [Leaf 15..29]; 4 cluster 1's root [Leaf 0..4].
std::shared_ptr<CompressedModelData> nestedModel()
{
    TestCluster cube = cubeCluster();
    cube.groups = {{0}, {1}};
    return buildModel({cube, sideQuadCluster()});
}

// Six clusters (quads in a row): Interior nodes above the clusters' root nodes.
// Nodes: 0 root [Interior 1, Interior 4, Cluster 7, Cluster 8]; 1 [Cluster 2, Cluster 3];
// 4 [Cluster 5, Cluster 6]; clusters 0..5 at nodes 2, 3, 5, 6, 7, 8.
std::shared_ptr<CompressedModelData> rowModel()
{
    std::vector<TestCluster> quads;
    for (int i = 0; i < 6; ++i) {
        TestCluster quad;
        const float x = 1.5f * float(i);
        quad.positions = {{x, 0, 0}, {x + 1, 0, 0}, {x, 1, 0.25f * float(i)}, {x + 1, 1, 0}};
        quad.leaves = {TestLeaf{{{0, 1, 2, 3}}}};
        quads.push_back(quad);
    }
    return buildModel(quads);
}

// Sets child slot c of a node (its box unchanged).
void setSlot(Node& node, uint32_t c, ChildKind kind, uint32_t child)
{
    node.kinds = uint8_t((node.kinds & ~(3u << (2 * c))) | uint32_t(kind) << (2 * c));
    node.child[c] = child;
}

// Empties child slot c of a node (kind, box and reference 0).
void clearSlot(Node& node, uint32_t c)
{
    setSlot(node, c, ChildKind::Empty, 0);
    for (int a = 0; a < 3; ++a)
        node.lo[a][c] = node.hi[a][c] = 0;
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
    for (auto make : {quadModel, cubeModel, nestedModel, rowModel})
        EXPECT_EQ(errorOf([&] { validateModel(view(make()), "m"); }), "");
    EXPECT_EQ(cubeModel()->header.triangleCount, 14u);
    // The layouts the tests below name nodes and slots of.
    auto kinds = [](const Node& node) {
        std::string text;
        for (uint32_t c = 0; c < kNodeChildren; ++c)
            text += "EICL"[uint32_t(childKind(node, c))];
        return text;
    };
    auto cube = cubeModel();
    ASSERT_EQ(cube->nodes.size(), 3u);
    EXPECT_EQ(cube->header.bvhDepth, 2u);
    EXPECT_EQ(kinds(cube->nodes[0]) + kinds(cube->nodes[1]) + kinds(cube->nodes[2]), "CCEE" "LLEE" "LEEE");
    EXPECT_EQ(cube->nodes[0].cluster, kNoCluster);
    EXPECT_EQ(cube->nodes[1].cluster, 0u);
    EXPECT_EQ(cube->nodes[2].cluster, 1u);
    EXPECT_EQ(cube->nodes[0].child[0], 1u);
    EXPECT_EQ(cube->nodes[0].child[1], 2u);
    EXPECT_EQ(cube->nodes[1].child[0], 0u | 14u << 16);
    EXPECT_EQ(cube->nodes[1].child[1], 15u | 14u << 16);
    EXPECT_EQ(cube->nodes[2].child[0], 0u | 4u << 16);
    auto nested = nestedModel();
    ASSERT_EQ(nested->nodes.size(), 5u);
    EXPECT_EQ(nested->header.bvhDepth, 3u);
    EXPECT_EQ(kinds(nested->nodes[1]) + kinds(nested->nodes[2]) + kinds(nested->nodes[3]), "IIEE" "LEEE" "LEEE");
    EXPECT_EQ(nested->nodes[0].child[1], 4u);
    EXPECT_EQ(nested->nodes[3].cluster, 0u);
    auto row = rowModel();
    ASSERT_EQ(row->nodes.size(), 9u);
    EXPECT_EQ(row->header.bvhDepth, 3u);
    EXPECT_EQ(kinds(row->nodes[0]) + kinds(row->nodes[1]), "IICC" "CCEE");
    EXPECT_EQ(row->clusters[5].node, 8u);
}

// Every child box decodes to a box that holds its subtree's triangles, with
// at most a step of slack on each side (the grid is the node's own).
TEST(ModelFile, BuilderBoxesHoldTheirGeometry)
{
    for (auto make : {quadModel, cubeModel, nestedModel, rowModel}) {
        auto data = make();
        const CompressedModel model = view(data);
        // Exact box of the geometry below slot c of node n (recursive; the models are tiny).
        std::function<Box(uint32_t, uint32_t)> exact = [&](uint32_t n, uint32_t c) {
            const Node& node = model.nodes[n];
            Box box;
            if (childKind(node, c) == ChildKind::Leaf) {
                const ClusterRecord& cluster = model.clusters[node.cluster];
                const uint8_t* strips = model.indices.data() + cluster.firstIndex + (node.child[c] & 0xFFFF);
                forEachStripTriangle(strips, strips + (node.child[c] >> 16), [&](uint32_t a, uint32_t b, uint32_t d) {
                    for (uint32_t v : {a, b, d})
                        box.add(decodePosition(cluster, model.vertices[cluster.firstVertex + v]));
                });
                return box;
            }
            for (uint32_t k = 0; k < childCount(model.nodes[node.child[c]]); ++k)
                box.add(exact(node.child[c], k));
            return box;
        };
        for (uint32_t n = 0; n < model.nodes.size(); ++n) {
            const Node& node = model.nodes[n];
            for (uint32_t c = 0; c < childCount(node); ++c) {
                const Box geometry = exact(n, c);
                glm::vec3 min, max;
                decodeChildBox(node, c, min, max);
                for (int a = 0; a < 3; ++a) {
                    const float step = nodeStep(node.exponent[a]);
                    EXPECT_LE(min[a], geometry.min[a]) << "node " << n << " child " << c;
                    EXPECT_GE(max[a], geometry.max[a]) << "node " << n << " child " << c;
                    EXPECT_GT(min[a] + step, geometry.min[a]) << "node " << n << " child " << c;
                    EXPECT_LT(max[a] - step, geometry.max[a]) << "node " << n << " child " << c;
                }
            }
        }
    }
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

// Files of earlier versions (the seed corpus's cube as version 2 and as
// version 3 wrote it, kept as they were written) are refused with one line
// that says what to do.
TEST(ModelFileBad, OlderVersionFilesSayToPreprocessAgain)
{
    for (const char* version : {"2", "3"}) {
        const std::string path = (std::filesystem::path(__FILE__).parent_path() / "data" /
                                  (std::string("cube_version") + version + ".penumbra"))
                                     .string();
        ASSERT_TRUE(std::filesystem::exists(path)) << path;
        const std::string message = errorOf([&] { openModelFile(path); });
        EXPECT_EQ(message, path + ": unsupported version " + version +
                               " (this build reads version 4; run penumbra preprocess on the source model again)");
    }
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
    const SectionEntry& vertices = sectionOf(header, SectionType::Vertices);
    bad[vertices.offset + vertices.size] = 1; // 96 bytes of vertices -> 32 bytes of padding follow
    EXPECT_ERROR_CONTAINS(openError("model_padding.penumbra", bad),
                          "nonzero padding byte at offset " + std::to_string(vertices.offset + vertices.size));
    // Nodes are 64 bytes: no padding follows them, the vertices begin at once.
    EXPECT_EQ(nodes.size, 3u * 64u);
    EXPECT_EQ(nodes.offset + nodes.size, vertices.offset);
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
                          "unsupported version 7 (this build reads version 4; run penumbra preprocess on the source model again)");
    // A version-4 file with its version field set to 3 (header checksum repaired or not): the version is read first.
    EXPECT_EQ(withHeader([](FileHeader& h) { h.version = 3; }),
              tempPath("model_header.penumbra") +
                  ": unsupported version 3 (this build reads version 4; run penumbra preprocess on the source model again)");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.version = 3; }, false), "unsupported version 3 (this build reads version 4");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.version = 2; }),
                          "model_header.penumbra: unsupported version 2 (this build reads version 4; run penumbra preprocess on the source model again)");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.version = 1; }), "unsupported version 1 (this build reads version 4");
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
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.bvhDepth = 33; }), "header bvhDepth 33 is outside 1..32");
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.bvhDepth = 0; }), "header bvhDepth 0 is outside 1..32");
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
    EXPECT_ERROR_CONTAINS(withHeader([&](FileHeader& h) { entry(h, SectionType::Vertices).elementSize = 8; }),
                          "section Vertices: element size 8, expected 6");
    // Counts pointing outside the file.
    EXPECT_ERROR_CONTAINS(withHeader([](FileHeader& h) { h.vertexCount = uint64_t(1) << 62; }),
                          "section Vertices: 72 bytes, but the header's count 4611686018427387904 needs");
    EXPECT_ERROR_CONTAINS(withHeader([&](FileHeader& h) {
                              h.vertexCount = 1000;
                              entry(h, SectionType::Vertices).size = 6000;
                          }),
                          "section Vertices: 6000 bytes at offset");
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
    root.child[0] = 1000;
    std::memcpy(bad.data() + nodes.offset, &root, sizeof(root));
    fixChecksums(bad);
    EXPECT_ERROR_CONTAINS(openError("model_hostile.penumbra", bad), "node 0: child 0: node 1000 out of range (3 nodes)");
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
        "cluster 1: node 99 out of range (3 nodes)");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[1].node = 1; },
        "cluster 1: node 1 is not this cluster's root node");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.clusters[1].node = 0; },
        "cluster 1: node 0 is not this cluster's root node");
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
    // Cube model (BuilderMakesValidModels): 0 root [Cluster 1, Cluster 2]; 1 cluster 0's root
    // [Leaf 0..14, Leaf 15..29]; 2 cluster 1's root [Leaf 0..4].
    // The grid: exponents 1..254, finite origin, 255 steps from it finite.
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[1].exponent[1] = 0; },
        "node 1: grid exponent 0 outside 1..254 on axis 1");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[2].exponent[2] = 255; },
        "node 2: grid exponent 255 outside 1..254 on axis 2");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[0].origin[2] = NAN; }, "node 0: non-finite grid origin");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[1].origin[0] = -INFINITY; }, "node 1: non-finite grid origin");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[1].exponent[0] = 254; }, "node 1: grid overflows on axis 0");
    expectInvalid(
        cubeModel,
        [](CompressedModelData& d) {
            d.nodes[2].origin[1] = 3.0e38f;
            d.nodes[2].exponent[1] = 127 + 120; // 255 x 2^120 = 3.4e38: finite alone, not added to the origin
        },
        "node 2: grid overflows on axis 1");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[2].reserved = 1; }, "node 2: reserved word is not zero");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[0].cluster = 7; }, "node 0: cluster 7 out of range (2 clusters)");

    // Slots: at least one child, the non-empty ones first, empty ones all zero, lo <= hi.
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { clearSlot(d.nodes[2], 0); }, "node 2: no children");
    expectInvalid(
        cubeModel,
        [](CompressedModelData& d) {
            Node& node = d.nodes[1];
            setSlot(node, 2, ChildKind::Leaf, node.child[1]);
            for (int a = 0; a < 3; ++a)
                node.lo[a][2] = node.lo[a][1], node.hi[a][2] = node.hi[a][1];
            clearSlot(node, 1);
        },
        "node 1: child 2: follows an empty slot");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[2].hi[1][3] = 1; }, "node 2: child 3: empty slot with a box");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[0].lo[0][2] = 4; }, "node 0: child 2: empty slot with a box");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[2].child[1] = 4; }, "node 2: child 1: empty slot with a reference");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[1].lo[1][0] = 200, d.nodes[1].hi[1][0] = 100; },
        "node 1: child 0: box lo 200 > hi 100 on axis 1");

    // Kinds by part of the tree: no leaves above the clusters, no Cluster slots inside one.
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { setSlot(d.nodes[0], 1, ChildKind::Leaf, 0u | 4u << 16); },
        "node 0: child 1: a leaf in a node above the clusters");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { setSlot(d.nodes[1], 1, ChildKind::Cluster, 2); },
        "node 1: child 1: a cluster inside cluster 0");

    // References: after the node, in range, one parent each.
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[0].child[1] = 0; }, "node 0: child 1: node 0 is not after its parent");
    expectInvalid(
        nestedModel, [](CompressedModelData& d) { setSlot(d.nodes[2], 0, ChildKind::Interior, 1); },
        "node 2: child 0: node 1 is not after its parent");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[0].child[1] = 3; }, "node 0: child 1: node 3 out of range (3 nodes)");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[0].child[1] = 0xFFFFFFFFu; },
        "node 0: child 1: node 4294967295 out of range (3 nodes)");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { setSlot(d.nodes[1], 1, ChildKind::Interior, 2); },
        "node 2 is referenced by two parents (nodes 0 and 1)");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[0].child[1] = 1; }, "node 1 is referenced by two parents (nodes 0 and 0)");

    // A Cluster slot names a cluster's root node; an Interior slot a node of its own part of the tree.
    expectInvalid(
        nestedModel, [](CompressedModelData& d) { d.nodes[0].child[0] = 2; },
        "node 0: child 0: node 2 is not the root node of the cluster it names");
    expectInvalid(
        rowModel, [](CompressedModelData& d) { setSlot(d.nodes[0], 0, ChildKind::Cluster, 1); },
        "node 0: child 0: node 1 is not the root node of the cluster it names");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { setSlot(d.nodes[0], 1, ChildKind::Interior, 2); },
        "node 0: child 1: interior node 2 lies in another part of the tree (cluster 1)");
    expectInvalid(
        nestedModel, [](CompressedModelData& d) { d.nodes[3].cluster = 1; },
        "node 1: child 1: interior node 3 lies in another part of the tree (cluster 1)");
    expectInvalid(
        nestedModel,
        [](CompressedModelData& d) {
            d.nodes.push_back(d.nodes[3]);
            d.nodes[5].cluster = kNoCluster;
            d.nodes[1].child[1] = 5;
            d.header.nodeCount = 6;
        },
        "node 1: child 1: interior node 5 lies in another part of the tree (cluster none)");

    // The root lies above the clusters: a one-cluster model whose cluster's root is node 0.
    expectInvalid(
        quadModel,
        [](CompressedModelData& d) {
            d.nodes = {d.nodes[1]};
            d.clusters[0].node = 0;
            d.header.nodeCount = 1;
            d.header.bvhDepth = 1;
        },
        "node 0: the root lies in cluster 0 (it must be above the clusters)");

    // Every node reachable: a cluster's root, an Interior node of a cluster, one above the clusters.
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { clearSlot(d.nodes[0], 1); }, "cluster 1 (node 2) is not reachable from the root");
    expectInvalid(
        nestedModel, [](CompressedModelData& d) { clearSlot(d.nodes[1], 1); }, "node 3: not referenced by any parent (unreachable)");
    expectInvalid(
        rowModel,
        [](CompressedModelData& d) {
            // The root names cluster 2's root (node 5) instead of node 4 [Cluster 5, Cluster 6]; node 4 keeps node 6.
            setSlot(d.nodes[0], 1, ChildKind::Cluster, 5);
            Node& node = d.nodes[4];
            setSlot(node, 0, ChildKind::Cluster, 6);
            for (int a = 0; a < 3; ++a)
                node.lo[a][0] = node.lo[a][1], node.hi[a][0] = node.hi[a][1];
            clearSlot(node, 1);
        },
        "node 4: not referenced by any parent (unreachable)");
}

TEST(ModelValidate, Leaves)
{
    // Cube cluster: strips 0 2 1 3 | 4 5 6 7 | 0 1 4 5 || 2 6 3 7 | 0 4 2 6 | 1 3 5 7 (| = restart);
    // node 1's child 0 covers bytes 0..14, child 1 bytes 15..29.
    auto data = cubeModel();
    ASSERT_EQ(data->nodes[1].child[0], 0u | 14u << 16);
    ASSERT_EQ(data->nodes[1].child[1], 15u | 14u << 16);
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[1].child[1] = 15u | 20u << 16; },
        "node 1: child 1: leaf range 15..35 lies outside the 29 strip bytes of cluster 0");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[1].child[1] = 16u | 13u << 16; },
        "node 1: child 1: leaf range 16..29 does not begin at a strip start");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[1].child[0] = 0u | 13u << 16; },
        "node 1: child 0: leaf range 0..13 does not end at a strip end");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[1].child[0] = 0u; }, "node 1: child 0: leaf range 0..0 is empty");
    // Child 0 covering everything overlaps child 1 (slots are checked in order).
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[1].child[0] = 0u | 29u << 16; },
        "node 1: child 1: leaf range 15..29 overlaps another leaf of cluster 0");
    // The same across nodes: the nested model's leaves lie in nodes 2 and 3.
    expectInvalid(
        nestedModel, [](CompressedModelData& d) { d.nodes[3].child[0] = 0u | 14u << 16; },
        "node 3: child 0: leaf range 0..14 overlaps another leaf of cluster 0");
    // Child 0 covering only its first strip: the leaves hold 2 + 6 of 12 triangles.
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[1].child[0] = 0u | 4u << 16; },
        "cluster 0: its leaves hold 8 triangles, the cluster 12");
    // A leaf of the quad cluster's bytes in the cube cluster's node: ranges are the node's cluster's.
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.nodes[2].child[0] = 0u | 14u << 16; },
        "node 2: child 0: leaf range 0..14 lies outside the 4 strip bytes of cluster 1");
    // A strip of degenerate triangles only.
    expectInvalid(
        quadModel,
        [](CompressedModelData& d) {
            d.indices = {0, 1, 2, 3, kStripRestart, 1, 1, 2};
            d.header.indexBytes = 8;
            d.clusters[0].indexBytes = 8;
            setSlot(d.nodes[1], 1, ChildKind::Leaf, 5u | 3u << 16);
            for (int a = 0; a < 3; ++a)
                d.nodes[1].lo[a][1] = d.nodes[1].lo[a][0], d.nodes[1].hi[a][1] = d.nodes[1].hi[a][0];
        },
        "node 1: child 1: leaf range 5..8 holds no triangles");
}

// A chain of nodes above one cluster: `depth` levels, the quad's cluster root
// the last; each node has one child.
std::shared_ptr<CompressedModelData> chainModel(uint32_t depth)
{
    auto data = quadModel(); // nodes: 0 root [Cluster 1], 1 cluster 0's root [Leaf]
    std::vector<Node> nodes;
    const Node root = data->nodes[0], clusterRoot = data->nodes[1];
    for (uint32_t i = 0; i + 2 < depth; ++i) {
        Node n = root;
        setSlot(n, 0, ChildKind::Interior, i + 1);
        nodes.push_back(n);
    }
    Node last = root;
    last.child[0] = uint32_t(nodes.size() + 1);
    nodes.push_back(last);
    nodes.push_back(clusterRoot);
    data->nodes = nodes;
    data->clusters[0].node = uint32_t(nodes.size() - 1);
    data->header.nodeCount = uint32_t(nodes.size());
    data->header.bvhDepth = std::min(depth, kMaxBvhDepth);
    return data;
}

TEST(ModelValidate, Depth)
{
    EXPECT_NO_THROW(validateModel(view(chainModel(2)), "m"));
    EXPECT_NO_THROW(validateModel(view(chainModel(kMaxBvhDepth)), "m"));
    EXPECT_ERROR_CONTAINS(errorOf([] { validateModel(view(chainModel(33)), "m"); }), "m: BVH deeper than 32 levels");
    EXPECT_ERROR_CONTAINS(errorOf([] { validateModel(view(chainModel(1000)), "m"); }), "m: BVH deeper than 32 levels");
    expectInvalid(
        cubeModel, [](CompressedModelData& d) { d.header.bvhDepth = 3; }, "header says the BVH has 3 levels but it has 2");
    expectInvalid(
        nestedModel, [](CompressedModelData& d) { d.header.bvhDepth = 2; }, "header says the BVH has 2 levels but it has 3");
    // The file round trip of the deepest legal BVH.
    CompressedModel model = openModelFile(writeModel("model_deep.penumbra", chainModel(kMaxBvhDepth)));
    EXPECT_EQ(model.header.bvhDepth, 32u);
}

// A caterpillar of `levels` levels: path node k (level k + 1) holds an
// Interior slot for path node k + 1 first and three clusters' roots after it,
// the last path node four clusters' roots. A depth-first traversal then keeps
// three pending entries per level, the most a 4-wide tree can: 3 x (levels -
// 2) + 4 at once (readers may use fixed stacks of 3 x depth + 1 entries).
std::shared_ptr<CompressedModelData> caterpillarModel(uint32_t levels)
{
    const uint32_t pathNodes = levels - 1, clusterCount = 3 * (pathNodes - 1) + 4;
    std::vector<TestCluster> quads;
    for (uint32_t i = 0; i < clusterCount; ++i) {
        TestCluster quad;
        const float x = float(i);
        quad.positions = {{x, 0, 0}, {x + 1, 0, 0}, {x, 1, 0}, {x + 1, 1, 0}};
        quad.leaves = {TestLeaf{{{0, 1, 2, 3}}}};
        quads.push_back(quad);
    }
    auto data = buildModel(quads); // a balanced tree above the clusters, replaced below
    std::vector<Node> nodes(pathNodes + clusterCount);
    std::vector<Box> clusterBoxes;
    for (uint32_t c = 0; c < clusterCount; ++c) {
        ClusterRecord& record = data->clusters[c];
        nodes[pathNodes + c] = data->nodes[record.node];
        record.node = pathNodes + c;
        glm::vec3 min, max;
        decodeChildBox(nodes[pathNodes + c], 0, min, max); // holds the quad
        Box box;
        box.add(min);
        box.add(max);
        clusterBoxes.push_back(box);
    }
    Box below;
    for (uint32_t k = pathNodes; k-- > 0;) {
        std::vector<Slot> slots;
        if (k + 1 < pathNodes)
            slots.push_back({ChildKind::Interior, k + 1, below});
        const uint32_t first = 3 * k, count = k + 1 < pathNodes ? 3 : 4;
        for (uint32_t c = first; c < first + count; ++c)
            slots.push_back({ChildKind::Cluster, pathNodes + c, clusterBoxes[c]});
        nodes[k] = gridNode(kNoCluster, slots);
        below = unionOf(slots);
    }
    data->nodes = nodes;
    data->header.nodeCount = uint32_t(nodes.size());
    data->header.bvhDepth = std::min(levels, kMaxBvhDepth);
    return data;
}

TEST(ModelValidate, WideDeepTreeFitsTheTraversalStack)
{
    auto data = caterpillarModel(kMaxBvhDepth);
    EXPECT_EQ(data->clusters.size(), 94u);
    EXPECT_EQ(errorOf([&] { validateModel(view(data), "m"); }), "");
    EXPECT_ERROR_CONTAINS(errorOf([] { validateModel(view(caterpillarModel(kMaxBvhDepth + 1)), "m"); }),
                          "m: BVH deeper than 32 levels");
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
// then copy tmp/fuzz_seed_<name>.penumbra to tests/fuzz/corpus/<name>.penumbra).
// Leaf slots in a cluster's root (quad, cube), Interior nodes inside a cluster
// (nested) and above the clusters (row).
TEST(ModelFile, DISABLED_WriteFuzzSeeds)
{
    writeModelFile(view(quadModel()), tempPath("fuzz_seed_quad.penumbra"));
    auto cube = cubeModel();
    cube->clusters[0].flags = kClusterClosed; // the cube is closed: a seed with the flag set
    writeModelFile(view(cube), tempPath("fuzz_seed_cube.penumbra"));
    writeModelFile(view(nestedModel()), tempPath("fuzz_seed_nested.penumbra"));
    writeModelFile(view(rowModel()), tempPath("fuzz_seed_row.penumbra"));
}

} // namespace
} // namespace penumbra::test

namespace penumbra::test {
namespace {

// A large synthetic model (2^k clusters of 128 vertices and 210 triangles in
// 7 strips, 2 leaves each, a 4-wide tree above the clusters' root nodes) to
// time writing and opening. PENUMBRA_MODEL_CLUSTER_BITS sets k (default 19:
// ~740 MB).
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
    const uint32_t leafRanges[2] = {0u | firstLeafBytes << 16,
                                    (firstLeafBytes + 1) | (uint32_t(strips.size()) - firstLeafBytes - 1) << 16};
    std::vector<QuantizedVertex> pattern(width * height);
    for (uint32_t v = 0; v < width * height; ++v)
        pattern[v] = {uint16_t(v % width * 4000), uint16_t(v / width * 8000), uint16_t(v * 37)};
    // Each leaf's quantized box, the same in every cluster (decoding is monotonic in q).
    std::array<std::array<QuantizedVertex, 2>, 2> leafBoxes;
    for (int leaf = 0; leaf < 2; ++leaf) {
        QuantizedVertex lo{0xFFFF, 0xFFFF, 0xFFFF}, hi{0, 0, 0};
        const uint8_t* begin = strips.data() + (leafRanges[leaf] & 0xFFFF);
        forEachStripTriangle(begin, begin + (leafRanges[leaf] >> 16), [&](uint32_t a, uint32_t b, uint32_t c) {
            for (uint32_t v : {a, b, c}) {
                lo = {std::min(lo.x, pattern[v].x), std::min(lo.y, pattern[v].y), std::min(lo.z, pattern[v].z)};
                hi = {std::max(hi.x, pattern[v].x), std::max(hi.y, pattern[v].y), std::max(hi.z, pattern[v].z)};
            }
        });
        leafBoxes[leaf] = {lo, hi};
    }
    data->clusters.resize(clusterCount);
    data->vertices.resize(size_t(clusterCount) * width * height);
    data->indices.resize(size_t(clusterCount) * strips.size());
    std::vector<std::vector<Slot>> leaves(clusterCount);
    const std::vector<std::vector<std::vector<uint32_t>>> groups(clusterCount);
    for (uint32_t c = 0; c < clusterCount; ++c) {
        ClusterRecord& cluster = data->clusters[c];
        cluster = {{float(c), 0, 0},
                   {1.0f / 65535, 1.0f / 65535, 1.0f / 65535},
                   uint64_t(c) * width * height,
                   uint64_t(c) * strips.size(),
                   uint32_t(strips.size()),
                   uint16_t(width * height),
                   uint16_t((height - 1) * (stripLength - 2)),
                   0, // node: set by TreeBuilder
                   0};
        std::memcpy(data->vertices.data() + cluster.firstVertex, pattern.data(), pattern.size() * sizeof(QuantizedVertex));
        std::memcpy(data->indices.data() + cluster.firstIndex, strips.data(), strips.size());
        for (int leaf = 0; leaf < 2; ++leaf) {
            Box box;
            box.add(decodePosition(cluster, leafBoxes[leaf][0]));
            box.add(decodePosition(cluster, leafBoxes[leaf][1]));
            leaves[c].push_back({ChildKind::Leaf, leafRanges[leaf], box});
        }
    }
    TreeBuilder(*data, leaves, groups);
    FileHeader& header = data->header;
    header.build = {255, 1024, 128, 16, kPositionBits, kNodeBoundsBits, 1.0f, 0};
    header.triangleCount = uint64_t(clusterCount) * data->clusters[0].triangleCount;
    header.sourceTriangleCount = header.triangleCount;
    header.vertexCount = data->vertices.size();
    header.indexBytes = data->indices.size();
    header.clusterCount = clusterCount;
    header.boundsMin[0] = header.boundsMin[1] = header.boundsMin[2] = 0.0f;
    header.boundsMax[0] = float(clusterCount);
    header.boundsMax[1] = header.boundsMax[2] = 1.0f;
    data->materials = {{{1.0f, 1.0f, 1.0f, 1.0f}}};
    header.materialCount = 1;
    return data;
}

TEST(ModelFile, LargeModelIsValid)
{
    auto data = largeModel(5);
    EXPECT_EQ(errorOf([&] { validateModel(makeCompressedModel(data), "large"); }), "");
    EXPECT_EQ(data->header.bvhDepth, 4u); // the root, 4 nodes of 8 clusters, 16 of 2, the clusters' roots
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
