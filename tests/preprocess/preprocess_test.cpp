// Tests for the preprocessor: a scalar CPU decoder of the built model compared
// with the input (every triangle exactly once, winding kept, positions within
// the reported error), the BVH invariants the rasterizer and ray tracer rely on,
// degenerate and error cases, thread-count independence, and simplifyMesh.
#include <gtest/gtest-spi.h>
#include <gtest/gtest.h>

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/gtc/type_ptr.hpp>

#include "penumbra/error.h"
#include "penumbra/generate.h"
#include "penumbra/preprocess.h"

using namespace penumbra;

namespace {

Mesh generate(const std::string& name, uint64_t triangles)
{
    GenerateOptions options;
    options.triangles = triangles;
    return generateScene(name, options).mesh;
}

bool degenerate(const Mesh& mesh, size_t t)
{
    uint32_t a = mesh.indices[3 * t], b = mesh.indices[3 * t + 1], c = mesh.indices[3 * t + 2];
    return a == b || b == c || a == c;
}

// Decodes every triangle and compares it with the input triangle it came from.
void checkRoundTrip(const Mesh& mesh, const CompressedModel& model, const std::vector<uint32_t>& source)
{
    const model::FileHeader& h = model.header;
    ASSERT_EQ(source.size(), h.triangleCount);
    const float tolerance = h.maxPositionError;
    float maxStep = 0.0f, maxCoordinate = 0.0f;
    std::vector<uint8_t> seen(mesh.triangleCount(), 0);
    size_t k = 0;
    uint64_t triangles = 0, vertices = 0, bytes = 0;
    float measured = 0.0f;
    for (const model::ClusterRecord& c : model.clusters) {
        ASSERT_EQ(c.firstVertex, vertices);
        ASSERT_EQ(c.firstIndex, bytes);
        vertices += c.vertexCount;
        bytes += c.indexBytes;
        for (int a = 0; a < 3; ++a) {
            maxStep = std::max(maxStep, c.step[a]);
            maxCoordinate = std::max({maxCoordinate, std::fabs(c.boxMin[a]), std::fabs(c.boxMin[a] + 65535.0f * c.step[a])});
        }
        const model::QuantizedVertex* v = model.vertices.data() + c.firstVertex;
        const uint8_t* s = model.indices.data() + c.firstIndex;
        uint32_t count = 0;
        forEachStripTriangle(s, s + c.indexBytes, [&](uint32_t a, uint32_t b, uint32_t d) {
            ASSERT_LT(a, c.vertexCount);
            ASSERT_LT(b, c.vertexCount);
            ASSERT_LT(d, c.vertexCount);
            ASSERT_LT(k, source.size());
            uint32_t t = source[k++];
            ASSERT_LT(t, mesh.triangleCount());
            ASSERT_FALSE(degenerate(mesh, t));
            ASSERT_EQ(seen[t], 0) << "triangle " << t << " stored twice";
            seen[t] = 1;
            count++;
            glm::vec3 decoded[3] = {decodePosition(c, v[a]), decodePosition(c, v[b]), decodePosition(c, v[d])};
            glm::vec3 input[3];
            for (int i = 0; i < 3; ++i)
                input[i] = mesh.position(mesh.indices[3 * size_t(t) + i]);
            // Some rotation (never a reflection) must match within the reported error.
            float best = INFINITY;
            for (int r = 0; r < 3; ++r) {
                float e = 0.0f;
                for (int i = 0; i < 3; ++i) {
                    glm::vec3 d3 = glm::abs(decoded[i] - input[(i + r) % 3]);
                    e = std::max({e, d3.x, d3.y, d3.z});
                }
                best = std::min(best, e);
            }
            measured = std::max(measured, best);
            ASSERT_LE(best, tolerance) << "triangle " << t;
        });
        ASSERT_EQ(count, c.triangleCount);
        triangles += count;
    }
    EXPECT_EQ(triangles, h.triangleCount);
    EXPECT_EQ(vertices, h.vertexCount);
    EXPECT_EQ(bytes, h.indexBytes);
    EXPECT_EQ(k, source.size());
    for (size_t t = 0; t < mesh.triangleCount(); ++t)
        if (!degenerate(mesh, t)) {
            ASSERT_EQ(seen[t], 1) << "triangle " << t << " missing";
        }
    // Half a step of the largest cluster plus one float rounding of the largest coordinate.
    EXPECT_LE(tolerance, 0.5f * maxStep + 2.0f * maxCoordinate * 1.2e-7f);
    EXPECT_GE(tolerance, measured);
}

// Every structural invariant of the node array (format version 4: 4-wide
// nodes, child boxes on each node's own grid) and the clusters. Walks the tree
// from the root; each slot's decoded box must hold every triangle below it
// and lie within two grid steps of their exact box on each side.
class BvhChecker {
public:
    BvhChecker(const CompressedModel& model, const PreprocessOptions& options)
        : model_(model), options_(options), nodeVisits_(model.nodes.size(), 0), clusterVisits_(model.clusters.size(), 0),
          byteCovered_(model.indices.size(), 0)
    {
    }

    void run()
    {
        const model::FileHeader& h = model_.header;
        Box all;
        ASSERT_NO_FATAL_FAILURE(visit(0, 1, model::kNoCluster, all));
        // The root's own box is the header's.
        for (int a = 0; a < 3; ++a) {
            EXPECT_LE(h.boundsMin[a], all.min[a]);
            EXPECT_GE(h.boundsMax[a], all.max[a]);
        }
        for (uint32_t i = 0; i < h.nodeCount; ++i)
            ASSERT_EQ(nodeVisits_[i], 1u) << "node " << i << " unreachable";
        for (uint32_t i = 0; i < h.clusterCount; ++i)
            ASSERT_EQ(clusterVisits_[i], 1u) << "cluster " << i << " unreachable";
        for (uint64_t i = 0; i < h.indexBytes; ++i)
            if (model_.indices[i] != model::kStripRestart) {
                ASSERT_EQ(byteCovered_[i], 1) << "index byte " << i << " in no leaf";
            }
        EXPECT_EQ(leafTriangles_, h.triangleCount);
        EXPECT_EQ(interiorSlots_ + clusterSlots_ + 1, h.nodeCount); // one slot names each node but the root
        EXPECT_EQ(maxDepth_, h.bvhDepth);
        EXPECT_LE(h.bvhDepth, model::kMaxBvhDepth);
    }

private:
    struct Box {
        glm::vec3 min{INFINITY}, max{-INFINITY};
        void add(const glm::vec3& p)
        {
            min = glm::min(min, p);
            max = glm::max(max, p);
        }
        void add(const Box& b)
        {
            min = glm::min(min, b.min);
            max = glm::max(max, b.max);
        }
    };

    // Node n, reached at `depth` from a slot of part `cluster` (kNoCluster: above the clusters);
    // grows `exact` by its triangles.
    void visit(uint32_t n, uint32_t depth, uint32_t parentCluster, Box& exact)
    {
        ASSERT_LT(n, model_.nodes.size());
        ASSERT_EQ(nodeVisits_[n]++, 0u) << "node " << n << " referenced twice";
        ASSERT_LE(depth, model::kMaxBvhDepth);
        maxDepth_ = std::max(maxDepth_, depth);
        const model::Node& node = model_.nodes[n];
        EXPECT_EQ(node.reserved, 0u);
        if (n == 0) {
            ASSERT_EQ(node.cluster, model::kNoCluster) << "the root lies above the clusters";
        } else if (parentCluster == model::kNoCluster && node.cluster != model::kNoCluster) {
            // A cluster's root, named by a Cluster slot (checked by the caller) and by its record.
            ASSERT_LT(node.cluster, model_.clusters.size());
            ASSERT_EQ(model_.clusters[node.cluster].node, n);
            ASSERT_EQ(clusterVisits_[node.cluster]++, 0u);
        } else {
            ASSERT_EQ(node.cluster, parentCluster) << "node " << n << " changes part below an Interior slot";
        }
        const uint32_t children = model::childCount(node);
        ASSERT_GE(children, 1u);
        for (int a = 0; a < 3; ++a) {
            ASSERT_GE(node.exponent[a], 1);
            ASSERT_LE(node.exponent[a], 254);
            ASSERT_TRUE(std::isfinite(node.origin[a] + 255.0f * nodeStep(node.exponent[a]))) << "node " << n << ": grid overflows";
        }
        Box nodeExact;
        for (uint32_t c = 0; c < model::kNodeChildren; ++c) {
            const model::ChildKind kind = model::childKind(node, c);
            if (c >= children) {
                ASSERT_EQ(kind, model::ChildKind::Empty) << "node " << n << ": a child after an empty slot";
                ASSERT_EQ(node.child[c], 0u);
                for (int a = 0; a < 3; ++a)
                    ASSERT_TRUE(node.lo[a][c] == 0 && node.hi[a][c] == 0);
                continue;
            }
            glm::vec3 min, max;
            decodeChildBox(node, c, min, max);
            Box slot;
            if (kind == model::ChildKind::Leaf) {
                ASSERT_NE(node.cluster, model::kNoCluster) << "node " << n << ": a leaf above the clusters";
                ++leafSlots_;
                ASSERT_NO_FATAL_FAILURE(leaf(node, node.child[c], slot));
            } else {
                ASSERT_GT(node.child[c], n) << "children must follow their node";
                ASSERT_LT(node.child[c], model_.nodes.size());
                if (kind == model::ChildKind::Cluster) {
                    ASSERT_EQ(node.cluster, model::kNoCluster) << "node " << n << ": a cluster inside a cluster";
                    ASSERT_NE(model_.nodes[node.child[c]].cluster, model::kNoCluster);
                    ++clusterSlots_;
                } else {
                    ++interiorSlots_;
                }
                ASSERT_NO_FATAL_FAILURE(visit(node.child[c], depth + 1, node.cluster, slot));
                if (kind == model::ChildKind::Interior) {
                    ASSERT_EQ(model_.nodes[node.child[c]].cluster, node.cluster);
                }
            }
            for (int a = 0; a < 3; ++a) {
                ASSERT_LE(node.lo[a][c], node.hi[a][c]);
                // Conservative: the decoded box holds the child's triangles ...
                ASSERT_LE(min[a], slot.min[a]) << "node " << n << " child " << c << ": geometry outside its box";
                ASSERT_GE(max[a], slot.max[a]) << "node " << n << " child " << c << ": geometry outside its box";
                // ... and tight: within two steps of them (floor/ceil plus a widening).
                const float step = nodeStep(node.exponent[a]);
                const float slack = 2.0f * step + 1e-6f * std::max(std::fabs(slot.min[a]), std::fabs(slot.max[a]));
                EXPECT_GE(min[a], slot.min[a] - slack) << "node " << n << " child " << c << " axis " << a << ": box too loose";
                EXPECT_LE(max[a], slot.max[a] + slack) << "node " << n << " child " << c << " axis " << a << ": box too loose";
            }
            nodeExact.add(slot);
        }
        // The grid spans the children with 8 bits: no coarser than twice the smallest power of two that does.
        for (int a = 0; a < 3; ++a) {
            ASSERT_LE(node.origin[a], nodeExact.min[a]);
            const float extent = nodeExact.max[a] - node.origin[a];
            const float ulp = 1.2e-7f * std::max(std::fabs(node.origin[a]), std::fabs(nodeExact.max[a]));
            if (node.exponent[a] > 1) {
                EXPECT_LE(255.0f * nodeStep(node.exponent[a]), 4.0f * std::max(extent, ulp))
                    << "node " << n << " axis " << a << ": grid coarser than needed";
            }
        }
        exact.add(nodeExact);
    }

    // A leaf slot of `node`: a range of whole strips of its cluster, its triangles into `box`.
    void leaf(const model::Node& node, uint32_t reference, Box& box)
    {
        const model::ClusterRecord& c = model_.clusters[node.cluster];
        const uint32_t start = reference & 0xFFFF, count = reference >> 16;
        ASSERT_GT(count, 0u);
        ASSERT_LE(start + count, c.indexBytes);
        const uint8_t* s = model_.indices.data() + c.firstIndex;
        ASSERT_TRUE(start == 0 || s[start - 1] == model::kStripRestart);
        ASSERT_TRUE(start + count == c.indexBytes || s[start + count] == model::kStripRestart);
        for (uint32_t i = start; i < start + count; ++i)
            ASSERT_EQ(byteCovered_[c.firstIndex + i]++, 0) << "byte in two leaves";
        uint32_t triangles = 0;
        forEachStripTriangle(s + start, s + start + count, [&](uint32_t a, uint32_t b, uint32_t d) {
            ++triangles;
            for (uint32_t i : {a, b, d})
                box.add(decodePosition(c, model_.vertices[c.firstVertex + i]));
        });
        ASSERT_GE(triangles, 1u);
        ASSERT_LE(triangles, options_.maxLeafTriangles);
        leafTriangles_ += triangles;
    }

    const CompressedModel& model_;
    const PreprocessOptions& options_;
    std::vector<uint32_t> nodeVisits_, clusterVisits_;
    std::vector<uint8_t> byteCovered_;
    uint32_t maxDepth_ = 0;
    uint64_t leafTriangles_ = 0, leafSlots_ = 0, interiorSlots_ = 0, clusterSlots_ = 0;
};

void checkBvh(const CompressedModel& model, const PreprocessOptions& options)
{
    const model::FileHeader& h = model.header;
    ASSERT_EQ(h.nodeCount, model.nodes.size());
    ASSERT_EQ(h.clusterCount, model.clusters.size());
    ASSERT_GE(h.nodeCount, 2u); // the root above the clusters and at least one cluster's root
    for (const model::ClusterRecord& c : model.clusters) {
        ASSERT_GE(c.vertexCount, 3);
        ASSERT_LE(c.vertexCount, options.maxClusterVertices);
        ASSERT_GE(c.triangleCount, 1);
        ASSERT_LE(c.triangleCount, options.maxClusterTriangles);
        ASSERT_GT(c.indexBytes, 0u);
        const uint8_t* s = model.indices.data() + c.firstIndex;
        ASSERT_NE(s[0], model::kStripRestart);
        ASSERT_NE(s[c.indexBytes - 1], model::kStripRestart);
        for (uint32_t i = 1; i < c.indexBytes; ++i)
            ASSERT_FALSE(s[i] == model::kStripRestart && s[i - 1] == model::kStripRestart);
    }
    BvhChecker checker(model, options);
    ASSERT_NO_FATAL_FAILURE(checker.run());
}

void checkHeader(const CompressedModel& model, const Mesh& mesh, const PreprocessOptions& options)
{
    const model::FileHeader& h = model.header;
    EXPECT_EQ(h.sourceTriangleCount, mesh.triangleCount());
    EXPECT_EQ(h.build.maxClusterVertices, options.maxClusterVertices);
    EXPECT_EQ(h.build.maxClusterTriangles, options.maxClusterTriangles);
    EXPECT_EQ(h.build.maxLeafTriangles, options.maxLeafTriangles);
    EXPECT_EQ(h.build.sahBins, options.sahBins);
    EXPECT_EQ(h.build.positionBits, model::kPositionBits);
    EXPECT_EQ(h.build.nodeBoundsBits, model::kNodeBoundsBits);
    EXPECT_EQ(h.build.simplifyTarget, 1.0f);
    EXPECT_EQ(h.simplifyError, 0.0f);
    EXPECT_EQ(h.vertexCount, model.vertices.size());
    EXPECT_EQ(h.indexBytes, model.indices.size());
}

void checkAll(const Mesh& mesh, const PreprocessOptions& options = {})
{
    std::vector<uint32_t> source;
    PreprocessStats stats;
    CompressedModel model = buildCompressedModel(mesh, options, &stats, &source);
    checkHeader(model, mesh, options);
    checkRoundTrip(mesh, model, source);
    checkBvh(model, options);
    try {
        validateModel(model, "built model"); // the reader's validation (formats/)
    } catch (const Error& e) {
        ADD_FAILURE() << e.what();
    }
    EXPECT_EQ(stats.triangles, model.header.triangleCount);
    EXPECT_EQ(stats.maxPositionError, model.header.maxPositionError);
}

} // namespace

TEST(Preprocess, RoundTripScan) { checkAll(generate("scan", 150'000)); }
TEST(Preprocess, RoundTripPlant) { checkAll(generate("plant", 150'000)); }
TEST(Preprocess, RoundTripCity) { checkAll(generate("city", 60'000)); }
TEST(Preprocess, RoundTripInterior) { checkAll(generate("interior", 40'000)); }

TEST(Preprocess, SmallLimits)
{
    PreprocessOptions options;
    options.maxClusterVertices = 16;
    options.maxClusterTriangles = 20;
    options.maxLeafTriangles = 3;
    options.sahBins = 4;
    checkAll(generate("plant", 20'000), options);
    options.maxLeafTriangles = 1;
    checkAll(generate("scan", 10'000), options);
}

TEST(Preprocess, LargeLimits)
{
    PreprocessOptions options;
    options.maxClusterTriangles = model::kMaxClusterTriangles;
    options.maxLeafTriangles = model::kMaxClusterTriangles;
    options.sahBins = 256;
    checkAll(generate("city", 30'000), options);
}

// The node checks above can fail: a leaf box that misses its triangles, a
// box far looser than its grid allows, and a child node before its parent
// are each reported.
TEST(Preprocess, BvhCheckFindsBadNodes)
{
    const PreprocessOptions options;
    const CompressedModel built = buildCompressedModel(generate("plant", 20'000), options);
    ASSERT_NO_FATAL_FAILURE(checkBvh(built, options));
    auto failuresOf = [&](auto&& mutate) {
        auto data = std::make_shared<CompressedModelData>();
        data->header = built.header;
        data->clusters.assign(built.clusters.begin(), built.clusters.end());
        data->nodes.assign(built.nodes.begin(), built.nodes.end());
        data->vertices.assign(built.vertices.begin(), built.vertices.end());
        data->indices.assign(built.indices.begin(), built.indices.end());
        data->materials.assign(built.materials.begin(), built.materials.end());
        mutate(data->nodes);
        const CompressedModel model = makeCompressedModel(data);
        testing::TestPartResultArray results;
        {
            testing::ScopedFakeTestPartResultReporter reporter(testing::ScopedFakeTestPartResultReporter::INTERCEPT_ONLY_CURRENT_THREAD,
                                                               &results);
            checkBvh(model, options);
        }
        std::string messages;
        for (int i = 0; i < results.size(); ++i)
            messages += std::string(results.GetTestPartResult(i).message()) + "\n";
        return messages;
    };
    // Finds a slot of the given kind with an axis whose box spans at least `span` grid steps.
    auto findSlot = [](std::vector<model::Node>& nodes, model::ChildKind kind, int span, uint32_t& c, int& axis) -> model::Node& {
        for (model::Node& node : nodes)
            for (c = 0; c < model::childCount(node); ++c)
                for (axis = 0; axis < 3; ++axis)
                    if (model::childKind(node, c) == kind && node.hi[axis][c] - node.lo[axis][c] >= span && node.lo[axis][c] >= 8)
                        return node;
        throw std::runtime_error("no such slot");
    };
    EXPECT_NE(failuresOf([&](std::vector<model::Node>& nodes) {
                  uint32_t c;
                  int a;
                  model::Node& node = findSlot(nodes, model::ChildKind::Leaf, 8, c, a);
                  node.hi[a][c] = node.lo[a][c];
              }).find("geometry outside its box"),
              std::string::npos);
    EXPECT_NE(failuresOf([&](std::vector<model::Node>& nodes) {
                  uint32_t c;
                  int a;
                  model::Node& node = findSlot(nodes, model::ChildKind::Interior, 8, c, a);
                  node.lo[a][c] = 0;
              }).find("box too loose"),
              std::string::npos);
    EXPECT_NE(failuresOf([&](std::vector<model::Node>& nodes) {
                  nodes[0].child[0] = 0;
              }).find("children must follow their node"),
              std::string::npos);
}

TEST(Preprocess, SingleTriangle)
{
    Mesh mesh;
    mesh.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    mesh.indices = {0, 1, 2};
    checkAll(mesh);
}

TEST(Preprocess, ThreadCountIndependent)
{
    Mesh mesh = generate("plant", 100'000);
    PreprocessOptions one, two;
    one.threads = 1;
    two.threads = 3;
    CompressedModel a = buildCompressedModel(mesh, one), b = buildCompressedModel(mesh, two);
    ASSERT_EQ(a.nodes.size(), b.nodes.size());
    ASSERT_EQ(a.clusters.size(), b.clusters.size());
    ASSERT_EQ(a.vertices.size(), b.vertices.size());
    ASSERT_EQ(a.indices.size(), b.indices.size());
    EXPECT_EQ(0, std::memcmp(a.nodes.data(), b.nodes.data(), a.nodes.size_bytes()));
    EXPECT_EQ(0, std::memcmp(a.clusters.data(), b.clusters.data(), a.clusters.size_bytes()));
    EXPECT_EQ(0, std::memcmp(a.vertices.data(), b.vertices.data(), a.vertices.size_bytes()));
    EXPECT_EQ(0, std::memcmp(a.indices.data(), b.indices.data(), a.indices.size_bytes()));
}

// Materials: clusters do not mix them, each names its own, and they survive
// the file (write, map, decode). Interleaved materials on a city.
TEST(Preprocess, MaterialsSurviveInClustersThatDoNotMixThem)
{
    Mesh mesh = generate("city", 60'000);
    mesh.materials = {{glm::vec4(1, 0, 0, 1), "a"}, {glm::vec4(0, 1, 0, 1), "b"}, {glm::vec4(0.2f, 0.4f, 1, 0.5f), "c"}};
    mesh.triangleMaterials.resize(mesh.triangleCount());
    for (size_t t = 0; t < mesh.triangleCount(); ++t) // in runs of 1..3 triangles, most clusters would mix them
        mesh.triangleMaterials[t] = uint32_t((t / (1 + t % 3)) % 3);
    std::vector<uint32_t> source;
    PreprocessStats stats, plainStats;
    CompressedModel model = buildCompressedModel(mesh, {}, &stats, &source);
    checkAll(mesh);
    EXPECT_EQ(stats.mixedMaterialTriangles, 0u);
    EXPECT_EQ(stats.materials, 3u);
    ASSERT_EQ(model.materials.size(), 3u);
    for (size_t m = 0; m < 3; ++m)
        for (int k = 0; k < 4; ++k)
            EXPECT_EQ(model.materials[m].baseColor[k], mesh.materials[m].baseColor[k]);
    size_t k = 0;
    for (const model::ClusterRecord& c : model.clusters) {
        const uint8_t* strips = model.indices.data() + c.firstIndex;
        forEachStripTriangle(strips, strips + c.indexBytes, [&](uint32_t, uint32_t, uint32_t) {
            EXPECT_EQ(mesh.triangleMaterials[source[k++]], c.material);
        });
    }
    // As without materials, the result does not depend on the thread count.
    PreprocessOptions one, three;
    one.threads = 1;
    three.threads = 3;
    CompressedModel a = buildCompressedModel(mesh, one), b = buildCompressedModel(mesh, three);
    ASSERT_EQ(a.clusters.size(), b.clusters.size());
    ASSERT_EQ(a.nodes.size(), b.nodes.size());
    EXPECT_EQ(0, std::memcmp(a.clusters.data(), b.clusters.data(), a.clusters.size_bytes()));
    EXPECT_EQ(0, std::memcmp(a.nodes.data(), b.nodes.data(), a.nodes.size_bytes()));
    // Through a file and back to a mesh.
    const std::string path = std::string(PENUMBRA_TEST_TMP) + "/materials.penumbra";
    writeModelFile(model, path);
    CompressedModel read = openModelFile(path);
    ASSERT_EQ(read.materials.size(), 3u);
    EXPECT_EQ(std::memcmp(read.materials.data(), model.materials.data(), model.materials.size_bytes()), 0);
    EXPECT_EQ(std::memcmp(read.clusters.data(), model.clusters.data(), model.clusters.size_bytes()), 0);
    // The cost: more clusters than without materials.
    Mesh plain = mesh;
    plain.materials.clear();
    plain.triangleMaterials.clear();
    CompressedModel plainModel = buildCompressedModel(plain, {}, &plainStats);
    EXPECT_EQ(plainModel.materials.size(), 1u);
    EXPECT_GT(model.clusters.size(), plainModel.clusters.size());
    std::printf("materials: %zu clusters %.3f B/tri, without: %zu clusters %.3f B/tri\n", model.clusters.size(),
                stats.bytesPerTriangle, plainModel.clusters.size(), plainStats.bytesPerTriangle);
}

// Vertex colours: each cluster gets the mean colour of its triangles.
TEST(Preprocess, VertexColoursBecomeAColourPerCluster)
{
    Mesh mesh = generate("scan", 20'000);
    mesh.colors.resize(mesh.positions.size());
    for (size_t v = 0; v < mesh.vertexCount(); ++v) {
        mesh.colors[3 * v] = mesh.position(v).x > 0.0f ? 1.0f : 0.0f;
        mesh.colors[3 * v + 1] = 0.5f;
        mesh.colors[3 * v + 2] = 0.25f;
    }
    std::vector<uint32_t> source;
    CompressedModel model = buildCompressedModel(mesh, {}, nullptr, &source);
    validateModel(model, "coloured");
    ASSERT_GE(model.materials.size(), 2u);
    size_t k = 0;
    for (const model::ClusterRecord& c : model.clusters) {
        const uint8_t* strips = model.indices.data() + c.firstIndex;
        double sum = 0.0;
        uint32_t n = 0;
        forEachStripTriangle(strips, strips + c.indexBytes, [&](uint32_t, uint32_t, uint32_t) {
            sum += mesh.triangleColor(source[k++]).r;
            ++n;
        });
        EXPECT_NEAR(model.materials[c.material].baseColor[0], sum / n, 1e-5);
        EXPECT_EQ(model.materials[c.material].baseColor[1], 0.5f);
        EXPECT_EQ(model.materials[c.material].baseColor[2], 0.25f);
    }
}

// Degenerate triangles are dropped and counted; coincident but distinct vertices are kept.
TEST(Preprocess, DegenerateTriangles)
{
    Mesh mesh = generate("scan", 5'000);
    const uint64_t original = mesh.triangleCount();
    const uint32_t v = uint32_t(mesh.vertexCount());
    mesh.indices.insert(mesh.indices.end(), {0, 0, 1, 2, 3, 3, 4, 5, 4, 7, 7, 7});
    // Three new vertices at one point: a zero-area triangle that is NOT index-degenerate.
    mesh.positions.insert(mesh.positions.end(), {1, 2, 3, 1, 2, 3, 1, 2, 3});
    mesh.indices.insert(mesh.indices.end(), {v, v + 1, v + 2});
    PreprocessStats stats;
    std::vector<uint32_t> source;
    CompressedModel model = buildCompressedModel(mesh, {}, &stats, &source);
    EXPECT_EQ(stats.droppedDegenerate, 4u);
    EXPECT_EQ(model.header.triangleCount, original + 1);
    EXPECT_EQ(model.header.sourceTriangleCount, original + 5);
    checkRoundTrip(mesh, model, source);
    checkBvh(model, {});
}

// Many triangles with one centroid: SAH cannot split, the median fallback must.
TEST(Preprocess, IdenticalCentroids)
{
    Mesh mesh;
    for (uint32_t i = 0; i < 3000; ++i) {
        uint32_t base = uint32_t(mesh.vertexCount());
        float s = 1.0f + float(i % 7);
        mesh.positions.insert(mesh.positions.end(), {-s, -s, 0, s, -s, 0, 0, 2 * s, 0});
        mesh.indices.insert(mesh.indices.end(), {base, base + 1, base + 2});
    }
    checkAll(mesh);
}

// Exponentially spaced triangles make SAH peel one at a time; the depth budget must hold.
TEST(Preprocess, DepthLimit)
{
    Mesh mesh;
    float x = 1.0f;
    for (uint32_t i = 0; i < 20000; ++i) {
        uint32_t base = uint32_t(mesh.vertexCount());
        mesh.positions.insert(mesh.positions.end(), {x, 0, 0, x + 1e-3f, 0, 0, x, 1e-3f, 0});
        mesh.indices.insert(mesh.indices.end(), {base, base + 1, base + 2});
        x *= 1.003f;
    }
    PreprocessOptions options;
    options.maxClusterTriangles = 4;
    options.maxLeafTriangles = 1;
    checkAll(mesh, options);
    // Deep trees inside the clusters as well: the largest clusters, one triangle per leaf.
    options.maxClusterTriangles = model::kMaxClusterTriangles;
    checkAll(mesh, options);
}

// Coordinates near the top of the float range. A node's grid must stay finite
// 255 steps from its origin (the format's rule), so a node at 1e38..3e38 needs
// an origin below its box; a model wider than any grid (255 x 2^120 units,
// about 3.39e38, on one axis) is refused with one line.
TEST(Preprocess, HugeCoordinates)
{
    Mesh mesh;
    mesh.positions = {1e38f, 0, 0, 1e38f, 1, 0, 1e38f, 0, 1, 3e38f, 0, 0, 3e38f, 1, 0, 3e38f, 0, 1};
    mesh.indices = {0, 1, 2, 3, 4, 5};
    checkAll(mesh);
    for (size_t i = 0; i < mesh.positions.size(); i += 3)
        mesh.positions[i] = -mesh.positions[i];
    std::swap(mesh.indices[1], mesh.indices[2]);
    std::swap(mesh.indices[4], mesh.indices[5]);
    checkAll(mesh);
    for (size_t i = 0; i < mesh.positions.size(); i += 3)
        mesh.positions[i] = mesh.positions[i] < -2e38f ? -1.7e38f : 1.7e38f;
    std::string message;
    try {
        buildCompressedModel(mesh, {});
    } catch (const Error& e) {
        message = e.what();
    }
    EXPECT_EQ(message, "preprocess: the model spans 3.4e+38 units on axis 0, more than a node's grid holds (255 x 2^120 = 3.39e+38)");
}

TEST(Preprocess, Errors)
{
    EXPECT_THROW(buildCompressedModel(Mesh{}, {}), Error);
    Mesh allDegenerate;
    allDegenerate.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    allDegenerate.indices = {0, 0, 1, 2, 2, 2};
    EXPECT_THROW(buildCompressedModel(allDegenerate, {}), Error);
    Mesh outOfRange;
    outOfRange.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    outOfRange.indices = {0, 1, 3};
    EXPECT_THROW(buildCompressedModel(outOfRange, {}), Error);
    Mesh nonFinite = allDegenerate;
    nonFinite.indices = {0, 1, 2};
    nonFinite.positions[4] = NAN;
    EXPECT_THROW(buildCompressedModel(nonFinite, {}), Error);
    Mesh ok = nonFinite;
    ok.positions[4] = 0.0f;
    EXPECT_NO_THROW(buildCompressedModel(ok, {}));
    PreprocessOptions bad;
    bad.maxClusterVertices = 256;
    EXPECT_THROW(buildCompressedModel(ok, bad), Error);
    bad = {};
    bad.maxClusterTriangles = model::kMaxClusterTriangles + 1;
    EXPECT_THROW(buildCompressedModel(ok, bad), Error);
    bad = {};
    bad.maxLeafTriangles = 0;
    EXPECT_THROW(buildCompressedModel(ok, bad), Error);
    bad = {};
    bad.sahBins = 1;
    EXPECT_THROW(buildCompressedModel(ok, bad), Error);
    // Colours: sizes, indices and values.
    auto message = [](const Mesh& mesh) {
        try {
            buildCompressedModel(mesh, {});
        } catch (const Error& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    Mesh colors = ok;
    colors.colors = {1, 1, 1, 0, 0, 0};
    EXPECT_EQ(message(colors), "preprocess: vertex colours do not match the vertices");
    colors.colors = {1, 1, 1, 0, 0, 0, 0.5f, NAN, 0};
    EXPECT_EQ(message(colors), "preprocess: vertex colour component outside [0, 1]");
    Mesh materials = ok;
    materials.materials = {{glm::vec4(1.5f), ""}};
    EXPECT_EQ(message(materials), "preprocess: material base colour component outside [0, 1]");
    materials.materials = {{glm::vec4(1.0f), ""}};
    materials.triangleMaterials = {1};
    EXPECT_EQ(message(materials), "preprocess: triangle material index out of range");
    materials.triangleMaterials = {0, 0};
    EXPECT_EQ(message(materials), "preprocess: triangle materials do not match the triangles");
}

// Format version 3: 64-bit offsets, so 5 G triangles fit; the 32-bit node indices are the
// limit, checked from the triangle count before any work.
TEST(Preprocess, FormatLimitsCheckedBeforeTheBuild)
{
    EXPECT_NO_THROW(checkModelLimits(5'000'000'000ull, {}));
    EXPECT_NO_THROW(checkModelLimits(30'000'000'000ull, {}));
    std::string message;
    try {
        checkModelLimits(40'000'000'000ull, {}, "big.ply");
    } catch (const Error& e) {
        message = e.what();
    }
    EXPECT_EQ(message, "big.ply: 40000000000 triangles may need about 4444444447 BVH nodes (2 per 18 triangles), more "
                       "than the format's 4294967295 (32-bit node indices); use --leaf-triangles 19 or more");
    PreprocessOptions bigLeaves;
    bigLeaves.maxLeafTriangles = 19;
    EXPECT_NO_THROW(checkModelLimits(40'000'000'000ull, bigLeaves));
    EXPECT_THROW(checkModelLimits(10'000'000'000'000ull, bigLeaves), Error);
}

// The distance from a point to a triangle, by its own route: the plane when the
// projection falls inside, else the nearest of the three edges.
double pointTriangleDistance(glm::dvec3 p, glm::dvec3 a, glm::dvec3 b, glm::dvec3 c)
{
    auto segment = [&](glm::dvec3 u, glm::dvec3 v) {
        const glm::dvec3 e = v - u;
        const double len2 = glm::dot(e, e);
        const double t = len2 > 0.0 ? std::clamp(glm::dot(p - u, e) / len2, 0.0, 1.0) : 0.0;
        return glm::length(p - (u + t * e));
    };
    double best = std::min({segment(a, b), segment(b, c), segment(c, a)});
    const glm::dvec3 n = glm::cross(b - a, c - a);
    const double n2 = glm::dot(n, n);
    if (n2 > 0.0) {
        const glm::dvec3 q = p - n * (glm::dot(p - a, n) / n2);
        const bool inside = glm::dot(glm::cross(b - a, q - a), n) >= 0.0 && glm::dot(glm::cross(c - b, q - b), n) >= 0.0 &&
                            glm::dot(glm::cross(a - c, q - c), n) >= 0.0;
        if (inside)
            best = std::min(best, glm::length(p - q));
    }
    return best;
}

// nearestTriangleDistance (the shadow maps' near planes of lights among the
// geometry) against every decoded triangle, from points inside and around the model.
TEST(Preprocess, NearestTriangleDistanceIsTheBruteForceOne)
{
    for (const char* name : {"plant", "city"}) {
        const CompressedModel model = buildCompressedModel(generate(name, 30'000), PreprocessOptions{});
        std::vector<glm::dvec3> triangles;
        for (const model::ClusterRecord& cluster : model.clusters) {
            const uint8_t* begin = model.indices.data() + cluster.firstIndex;
            forEachStripTriangle(begin, begin + cluster.indexBytes, [&](uint32_t a, uint32_t b, uint32_t c) {
                for (uint32_t v : {a, b, c})
                    triangles.push_back(glm::dvec3(decodePosition(cluster, model.vertices[cluster.firstVertex + v])));
            });
        }
        ASSERT_EQ(triangles.size(), 3 * model.triangleCount()) << name;
        const glm::vec3 lo(model.header.boundsMin[0], model.header.boundsMin[1], model.header.boundsMin[2]);
        const glm::vec3 hi(model.header.boundsMax[0], model.header.boundsMax[1], model.header.boundsMax[2]);
        uint32_t seed = 12345;
        auto next = [&] {
            seed = seed * 1664525u + 1013904223u;
            return float(seed >> 8) / float(1u << 24);
        };
        for (int i = 0; i < 40; ++i) {
            // Inside the box, and (every fourth) up to half its size beyond it.
            const float spread = i % 4 == 3 ? 2.0f : 1.0f;
            const glm::vec3 t(next(), next(), next());
            const glm::vec3 point = (lo + hi) * 0.5f + (t - 0.5f) * (hi - lo) * spread;
            double expected = std::numeric_limits<double>::infinity();
            for (size_t k = 0; k < triangles.size(); k += 3)
                expected = std::min(expected, pointTriangleDistance(glm::dvec3(point), triangles[k], triangles[k + 1], triangles[k + 2]));
            const float found = nearestTriangleDistance(model, point);
            EXPECT_NEAR(found, expected, 1e-5 * glm::length(hi - lo) + 1e-6 * expected) << name << " point " << i;
        }
        // On a triangle: the distance is 0 (to rounding).
        const glm::vec3 onTriangle = glm::vec3((triangles[0] + triangles[1] + triangles[2]) / 3.0);
        EXPECT_LE(nearestTriangleDistance(model, onTriangle), 1e-5f * glm::length(hi - lo)) << name;
    }
}

TEST(Preprocess, ProgressIsReported)
{
    Mesh mesh = generate("city", 20'000);
    PreprocessOptions options;
    std::vector<std::string> stages;
    double lastFraction = 0.0;
    options.progress = [&](const char* stage, double fraction) {
        if (stages.empty() || stages.back() != stage)
            stages.push_back(stage);
        EXPECT_GE(fraction, 0.0);
        EXPECT_LE(fraction, 1.0);
        lastFraction = fraction;
    };
    buildCompressedModel(mesh, options);
    EXPECT_EQ(stages, (std::vector<std::string>{"filter", "tree", "clusters", "layout"}));
    EXPECT_EQ(lastFraction, 1.0);
}

TEST(Simplify, ReachesTarget)
{
    Mesh mesh = generate("scan", 100'000);
    for (float ratio : {0.5f, 0.25f, 0.01f}) {
        SimplifiedMesh s = simplifyMesh(mesh, ratio);
        double target = double(mesh.triangleCount()) * ratio;
        double got = double(s.mesh.triangleCount());
        EXPECT_TRUE(s.sloppy || std::fabs(got - target) <= 0.1 * target)
            << "ratio " << ratio << ": " << got << " triangles for a target of " << target;
        EXPECT_LE(got, 1.1 * target) << "ratio " << ratio;
        EXPECT_GT(got, 0.0);
        EXPECT_TRUE(std::isfinite(s.error));
        EXPECT_TRUE(std::isfinite(s.absoluteError));
        EXPECT_GE(s.absoluteError, 0.0f);
        for (uint32_t i : s.mesh.indices)
            ASSERT_LT(i, s.mesh.vertexCount());
        // No unused vertices.
        std::vector<uint8_t> used(s.mesh.vertexCount(), 0);
        for (uint32_t i : s.mesh.indices)
            used[i] = 1;
        EXPECT_EQ(std::count(used.begin(), used.end(), 1), int64_t(s.mesh.vertexCount()));
        // The simplified mesh preprocesses like any other.
        if (ratio == 0.25f)
            checkAll(s.mesh);
    }
    SimplifiedMesh same = simplifyMesh(mesh, 1.0f);
    EXPECT_EQ(same.mesh.indices, mesh.indices);
    EXPECT_EQ(same.error, 0.0f);
    EXPECT_THROW(simplifyMesh(mesh, 0.0f), Error);
}

// Size and speed measurement (not run by default):
//   PENUMBRA_MEASURE="scan:1000000 plant:12000000" ./preprocess_tests
//       --gtest_also_run_disabled_tests --gtest_filter=*DISABLED_Measure
TEST(Preprocess, DISABLED_Measure)
{
    const char* spec = std::getenv("PENUMBRA_MEASURE");
    std::string list = spec ? spec : "scan:1000000 plant:1000000";
    PreprocessOptions options;
    if (const char* t = std::getenv("PENUMBRA_THREADS"))
        options.threads = unsigned(std::atoi(t));
    if (const char* l = std::getenv("PENUMBRA_LEAF"))
        options.maxLeafTriangles = uint32_t(std::atoi(l));
    if (const char* c = std::getenv("PENUMBRA_CLUSTER_TRIANGLES"))
        options.maxClusterTriangles = uint32_t(std::atoi(c));
    size_t pos = 0;
    while (pos < list.size()) {
        size_t end = list.find(' ', pos);
        if (end == std::string::npos)
            end = list.size();
        std::string item = list.substr(pos, end - pos);
        pos = end + 1;
        if (item.empty())
            continue;
        std::string name = item.substr(0, item.find(':'));
        uint64_t count = std::stoull(item.substr(item.find(':') + 1));
        auto t0 = std::chrono::steady_clock::now();
        Mesh mesh = generate(name, count);
        auto t1 = std::chrono::steady_clock::now();
        PreprocessStats s;
        CompressedModel model = buildCompressedModel(mesh, options, &s);
        auto t2 = std::chrono::steady_clock::now();
        double gen = std::chrono::duration<double>(t1 - t0).count();
        double build = std::chrono::duration<double>(t2 - t1).count();
        double tri = double(s.triangles);
        rusage usage{};
        getrusage(RUSAGE_SELF, &usage);
        double meshBytes = double(mesh.positions.size() * 4 + mesh.indices.size() * 4);
        std::printf("%s %llu tris (%.2f MB mesh, %.2f verts/tri): generate %.2fs, build %.2fs = %.2f Mtri/s build, "
                    "%.2f Mtri/s end to end; stages filter %.2f tree %.2f clusters %.2f layout %.2f\n",
                    name.c_str(), (unsigned long long)s.triangles, meshBytes / 1e6,
                    double(mesh.vertexCount()) / double(mesh.triangleCount()), gen, build, tri / build / 1e6,
                    tri / (gen + build) / 1e6, s.filterSeconds, s.treeSeconds, s.clusterSeconds, s.layoutSeconds);
        std::printf("  bytes/tri: clusters %.3f nodes %.3f vertices %.3f indices %.3f total %.3f | clusters %llu "
                    "(%.1f tri, %.1f verts avg) leaves %llu (%.1f tri avg) nodes %llu depth %u fallback leaves %llu "
                    "widened %llu maxError %g\n",
                    double(sizeof(model::ClusterRecord)) * double(s.clusters) / tri,
                    double(sizeof(model::Node)) * double(s.nodes) / tri, double(sizeof(model::QuantizedVertex)) * double(s.vertices) / tri,
                    double(s.indexBytes) / tri, s.bytesPerTriangle, (unsigned long long)s.clusters,
                    tri / double(s.clusters), double(s.vertices) / double(s.clusters), (unsigned long long)s.leaves,
                    tri / double(s.leaves), (unsigned long long)s.nodes, s.bvhDepth,
                    (unsigned long long)s.stripFallbackLeaves, (unsigned long long)s.widenedBounds,
                    double(s.maxPositionError));
        std::printf("  peak RSS so far %.1f MB (%.2fx the mesh)\n", double(usage.ru_maxrss) / 1024.0,
                    double(usage.ru_maxrss) * 1024.0 / meshBytes);
        std::fflush(stdout);
    }
}

// The cost of materials on the generated bench scenes: every connected part
// (an object of the generator: a building, a pipe, a column) gets one of 8
// materials, so neighbouring parts usually differ. Prints bytes per triangle
// and clusters without and with materials.
// PENUMBRA_MEASURE="city:250000 ..." picks the scenes (default: the four at 250 k).
TEST(Preprocess, DISABLED_MeasureMaterials)
{
    const char* spec = std::getenv("PENUMBRA_MEASURE");
    std::string list = spec ? spec : "city:250000 interior:250000 plant:250000 scan:250000";
    size_t pos = 0;
    while (pos < list.size()) {
        size_t end = list.find(' ', pos);
        if (end == std::string::npos)
            end = list.size();
        std::string item = list.substr(pos, end - pos);
        pos = end + 1;
        if (item.empty())
            continue;
        Mesh mesh = generate(item.substr(0, item.find(':')), std::stoull(item.substr(item.find(':') + 1)));
        // Connected parts by union-find over the triangles' vertices.
        std::vector<uint32_t> parent(mesh.vertexCount());
        for (uint32_t v = 0; v < parent.size(); ++v)
            parent[v] = v;
        auto find = [&](uint32_t v) {
            while (parent[v] != v)
                v = parent[v] = parent[parent[v]];
            return v;
        };
        for (size_t i = 0; i < mesh.indices.size(); i += 3)
            for (int k = 1; k < 3; ++k)
                parent[find(mesh.indices[i + k])] = find(mesh.indices[i]);
        for (int m = 0; m < 8; ++m)
            mesh.materials.push_back({glm::vec4(float(m & 1), float(m >> 1 & 1), float(m >> 2 & 1), 1.0f), ""});
        mesh.triangleMaterials.resize(mesh.triangleCount());
        std::vector<uint8_t> partSeen(mesh.vertexCount(), 0);
        size_t parts = 0;
        for (size_t t = 0; t < mesh.triangleCount(); ++t) {
            uint32_t root = find(mesh.indices[3 * t]);
            parts += partSeen[root] ? 0 : 1;
            partSeen[root] = 1;
            mesh.triangleMaterials[t] = (root * 2654435761u) >> 29;
        }
        Mesh plain = mesh;
        plain.materials.clear();
        plain.triangleMaterials.clear();
        PreprocessStats with, without;
        buildCompressedModel(plain, {}, &without);
        buildCompressedModel(mesh, {}, &with);
        std::printf("%s: %zu parts, 8 materials | without: %llu clusters, %.3f B/tri | with: %llu clusters, %.3f B/tri "
                    "(+%.3f), %llu mixed triangles\n",
                    item.c_str(), parts, (unsigned long long)without.clusters, without.bytesPerTriangle,
                    (unsigned long long)with.clusters, with.bytesPerTriangle, with.bytesPerTriangle - without.bytesPerTriangle,
                    (unsigned long long)with.mixedMaterialTriangles);
    }
}
