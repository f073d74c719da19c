// Tests for the procedural scenes: determinism, budget accuracy, mesh validity,
// closedness and orientation of parts, thin geometry in the city, and error cases.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <unordered_map>
#include <vector>

#include <glm/geometric.hpp>

#include "penumbra/error.h"
#include "penumbra/generate.h"

using namespace penumbra;

namespace {

const char* const kScenes[] = {"city", "interior", "plant", "scan"};

Scene generate(const std::string& name, uint64_t triangles, uint64_t seed = 1)
{
    GenerateOptions options;
    options.triangles = triangles;
    options.seed = seed;
    return generateScene(name, options);
}

// Connected components over shared vertices: each generator part is one component.
struct Components {
    std::vector<uint32_t> triangleComponent;
    uint32_t count = 0;
};

Components components(const Mesh& mesh)
{
    std::vector<uint32_t> parent(mesh.vertexCount());
    std::iota(parent.begin(), parent.end(), 0u);
    auto find = [&](uint32_t v) {
        while (parent[v] != v)
            v = parent[v] = parent[parent[v]];
        return v;
    };
    for (size_t i = 0; i < mesh.indices.size(); i += 3) {
        uint32_t a = find(mesh.indices[i]);
        for (int k = 1; k < 3; ++k) {
            uint32_t b = find(mesh.indices[i + k]);
            if (a != b)
                parent[b] = a;
        }
    }
    Components result;
    std::vector<uint32_t> label(mesh.vertexCount(), ~0u);
    result.triangleComponent.resize(mesh.triangleCount());
    for (size_t t = 0; t < mesh.triangleCount(); ++t) {
        uint32_t root = find(mesh.indices[t * 3]);
        if (label[root] == ~0u)
            label[root] = result.count++;
        result.triangleComponent[t] = label[root];
    }
    return result;
}

// Per component: is every directed edge matched by its reverse exactly once?
std::vector<bool> closedComponents(const Mesh& mesh, const Components& parts)
{
    std::unordered_map<uint64_t, int> directed;
    directed.reserve(mesh.indices.size() * 2);
    for (size_t t = 0; t < mesh.triangleCount(); ++t)
        for (int k = 0; k < 3; ++k) {
            uint64_t a = mesh.indices[t * 3 + k], b = mesh.indices[t * 3 + (k + 1) % 3];
            directed[(a << 32) | b]++;
        }
    std::vector<bool> closed(parts.count, true);
    for (size_t t = 0; t < mesh.triangleCount(); ++t)
        for (int k = 0; k < 3; ++k) {
            uint64_t a = mesh.indices[t * 3 + k], b = mesh.indices[t * 3 + (k + 1) % 3];
            auto forward = directed.find((a << 32) | b);
            auto reverse = directed.find((b << 32) | a);
            if (forward->second != 1 || reverse == directed.end() || reverse->second != 1)
                closed[parts.triangleComponent[t]] = false;
        }
    return closed;
}

void expectValid(const Scene& scene, uint64_t budget)
{
    const Mesh& mesh = scene.mesh;
    ASSERT_EQ(mesh.positions.size() % 3, 0u);
    ASSERT_EQ(mesh.indices.size() % 3, 0u);
    EXPECT_NEAR(double(mesh.triangleCount()), double(budget), 0.05 * double(budget));
    for (float v : mesh.positions)
        ASSERT_TRUE(std::isfinite(v));
    const size_t vertexCount = mesh.vertexCount();
    for (uint32_t i : mesh.indices)
        ASSERT_LT(i, vertexCount);
    size_t degenerate = 0;
    for (size_t t = 0; t < mesh.triangleCount(); ++t) {
        glm::vec3 a = mesh.position(mesh.indices[t * 3]), b = mesh.position(mesh.indices[t * 3 + 1]),
                  c = mesh.position(mesh.indices[t * 3 + 2]);
        if (glm::length(glm::cross(b - a, c - a)) <= 1e-12f)
            ++degenerate;
    }
    EXPECT_LE(degenerate, mesh.triangleCount() / 1000) << "degenerate triangles";
    Bounds bounds = computeBounds(mesh);
    ASSERT_FALSE(bounds.empty());
    for (int axis = 0; axis < 3; ++axis) {
        EXPECT_GT(bounds.extent()[axis], 0.1f);
        EXPECT_LT(bounds.extent()[axis], 1e5f);
    }
    EXPECT_GE(bounds.min.y, -1.0f); // stands on the ground at y = 0, +Y up
    ASSERT_EQ(scene.cameras.size(), 1u);
    EXPECT_EQ(scene.cameras[0].projection, Projection::Perspective);
    EXPECT_GT(glm::length(scene.cameras[0].target - scene.cameras[0].position), 0.1f);
    ASSERT_EQ(scene.lights.size(), 1u);
    EXPECT_EQ(scene.lights[0].type, LightType::Directional);
    EXPECT_NEAR(glm::length(scene.lights[0].direction), 1.0f, 1e-4f);
    EXPECT_LT(scene.lights[0].direction.y, -0.2f); // sun above the horizon
    EXPECT_GT(scene.lights[0].direction.y, -0.8f); // but low enough for long shadows
}

} // namespace

TEST(Generate, NamesListAllScenes)
{
    std::vector<std::string> names = generatorNames();
    ASSERT_EQ(names.size(), 4u);
    for (const char* name : kScenes)
        EXPECT_NE(std::find(names.begin(), names.end(), name), names.end()) << name;
}

TEST(Generate, RejectsUnknownName)
{
    try {
        generate("cathedral", 10'000);
        FAIL() << "expected Error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("cathedral"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("unknown"), std::string::npos) << e.what();
    }
}

TEST(Generate, RejectsBudgetOutOfRange)
{
    for (const char* name : kScenes)
        for (uint64_t budget : {uint64_t(0), uint64_t(10), uint64_t(100'000'000'000)}) {
            try {
                generate(name, budget);
                FAIL() << name << " accepted budget " << budget;
            } catch (const Error& e) {
                EXPECT_NE(std::string(e.what()).find("budget"), std::string::npos) << e.what();
                EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
            }
        }
}

class GenerateScene : public ::testing::TestWithParam<const char*> {};

TEST_P(GenerateScene, DeterministicFromSeed)
{
    Scene a = generate(GetParam(), 20'000, 7), b = generate(GetParam(), 20'000, 7), c = generate(GetParam(), 20'000, 8);
    EXPECT_EQ(a.mesh.positions, b.mesh.positions);
    EXPECT_EQ(a.mesh.indices, b.mesh.indices);
    EXPECT_NE(a.mesh.positions, c.mesh.positions);
}

TEST_P(GenerateScene, MeetsBudgetAndIsValid)
{
    for (uint64_t budget : {1'000u, 3'333u, 25'000u, 120'000u, 400'000u}) {
        SCOPED_TRACE(budget);
        expectValid(generate(GetParam(), budget, 3), budget);
    }
}

// Every closed part (box, swept tube, lathe) encloses positive volume: faces point outward.
TEST_P(GenerateScene, ClosedPartsFaceOutward)
{
    Scene scene = generate(GetParam(), 60'000, 5);
    const Mesh& mesh = scene.mesh;
    Components parts = components(mesh);
    std::vector<bool> closed = closedComponents(mesh, parts);
    std::vector<double> volume(parts.count, 0.0);
    std::vector<glm::dvec3> anchor(parts.count, glm::dvec3(0.0));
    std::vector<bool> anchored(parts.count, false);
    for (size_t t = 0; t < mesh.triangleCount(); ++t) {
        uint32_t part = parts.triangleComponent[t];
        glm::dvec3 a = mesh.position(mesh.indices[t * 3]), b = mesh.position(mesh.indices[t * 3 + 1]),
                   c = mesh.position(mesh.indices[t * 3 + 2]);
        if (!anchored[part])
            anchor[part] = a, anchored[part] = true;
        a -= anchor[part], b -= anchor[part], c -= anchor[part];
        volume[part] += glm::dot(a, glm::cross(b, c)) / 6.0;
    }
    size_t closedCount = 0;
    for (uint32_t part = 0; part < parts.count; ++part) {
        if (!closed[part])
            continue;
        ++closedCount;
        EXPECT_GT(volume[part], 0.0) << "part " << part;
    }
    EXPECT_GT(closedCount, 0u);
}

INSTANTIATE_TEST_SUITE_P(AllScenes, GenerateScene, ::testing::ValuesIn(kScenes),
                         [](const auto& info) { return std::string(info.param); });

TEST(GenerateScan, StatueIsClosed)
{
    Scene scene = generate("scan", 150'000, 11);
    const Mesh& mesh = scene.mesh;
    Components parts = components(mesh);
    ASSERT_EQ(parts.count, 2u); // statue and ground
    std::vector<size_t> sizes(parts.count, 0);
    for (uint32_t part : parts.triangleComponent)
        ++sizes[part];
    const uint32_t statue = uint32_t(std::max_element(sizes.begin(), sizes.end()) - sizes.begin());
    EXPECT_GT(sizes[statue], mesh.triangleCount() * 9 / 10);
    std::vector<bool> closed = closedComponents(mesh, parts);
    EXPECT_TRUE(closed[statue]);
    // Euler characteristic of a sphere: V - E + F = 2.
    std::vector<bool> used(mesh.vertexCount(), false);
    for (size_t t = 0; t < mesh.triangleCount(); ++t)
        if (parts.triangleComponent[t] == statue)
            for (int k = 0; k < 3; ++k)
                used[mesh.indices[t * 3 + k]] = true;
    const int64_t v = std::count(used.begin(), used.end(), true), f = int64_t(sizes[statue]);
    EXPECT_EQ(v - f * 3 / 2 + f, 2);
}

TEST(GenerateCity, HasThinGeometry)
{
    Scene scene = generate("city", 200'000, 2);
    const Mesh& mesh = scene.mesh;
    Components parts = components(mesh);
    std::vector<Bounds> bounds(parts.count);
    for (size_t t = 0; t < mesh.triangleCount(); ++t)
        for (int k = 0; k < 3; ++k) {
            glm::vec3 p = mesh.position(mesh.indices[t * 3 + k]);
            Bounds& b = bounds[parts.triangleComponent[t]];
            b.min = glm::min(b.min, p);
            b.max = glm::max(b.max, p);
        }
    size_t thinTriangles = 0, thinParts = 0;
    for (uint32_t part = 0; part < parts.count; ++part) {
        glm::vec3 e = bounds[part].extent();
        if (std::min({e.x, e.y, e.z}) < 0.05f)
            ++thinParts;
    }
    for (uint32_t part : parts.triangleComponent) {
        glm::vec3 e = bounds[part].extent();
        if (std::min({e.x, e.y, e.z}) < 0.05f)
            ++thinTriangles;
    }
    EXPECT_GT(thinParts, 100u);
    EXPECT_GT(thinTriangles, mesh.triangleCount() / 20);
}

TEST(GeneratePlant, GrowsByModules)
{
    Bounds small = computeBounds(generate("plant", 50'000).mesh);
    Bounds large = computeBounds(generate("plant", 1'500'000).mesh);
    EXPECT_GT(large.extent().x, small.extent().x * 2.0f);
}
