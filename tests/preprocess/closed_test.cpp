// The closed-component test behind model::kClusterClosed (format version 3):
// closed cube, sphere and torus are closed; a removed or flipped triangle, a
// T-junction or a non-manifold edge opens the whole component; a mixed scene
// marks exactly its closed parts, and the build flags exactly the clusters of
// closed triangles (never an open one). A brute-force reference (maps over
// welded positions) checks random damage of closed meshes.
#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "penumbra/error.h"
#include "penumbra/generate.h"
#include "penumbra/preprocess.h"
#include "preprocess_internal.h" // crowdedComponents

using namespace penumbra;

namespace {

// Appends a mesh (its own vertices) to scene; returns its first triangle.
size_t append(Mesh& scene, const Mesh& part)
{
    const uint32_t base = uint32_t(scene.vertexCount());
    const size_t first = scene.triangleCount();
    scene.positions.insert(scene.positions.end(), part.positions.begin(), part.positions.end());
    for (uint32_t i : part.indices)
        scene.indices.push_back(base + i);
    return first;
}

Mesh translated(Mesh mesh, float dx, float dy, float dz)
{
    for (size_t v = 0; v < mesh.vertexCount(); ++v) {
        mesh.positions[3 * v] += dx;
        mesh.positions[3 * v + 1] += dy;
        mesh.positions[3 * v + 2] += dz;
    }
    return mesh;
}

// Unit cube, 8 shared vertices, 12 outward counter-clockwise triangles.
Mesh cube()
{
    Mesh m;
    for (int i = 0; i < 8; ++i)
        m.positions.insert(m.positions.end(), {float(i & 1), float((i >> 1) & 1), float((i >> 2) & 1)});
    m.indices = {0, 2, 1, 1, 2, 3,  // z = 0 (normal -z)
                 4, 5, 6, 5, 7, 6,  // z = 1
                 0, 1, 4, 1, 5, 4,  // y = 0
                 2, 6, 3, 3, 6, 7,  // y = 1
                 0, 4, 2, 2, 4, 6,  // x = 0
                 1, 3, 5, 3, 7, 5}; // x = 1
    return m;
}

// The same cube with 4 vertices per face (24, no index shared between faces): welding by position closes it.
Mesh unweldedCube()
{
    Mesh c = cube(), m;
    for (size_t t = 0; t < c.triangleCount(); ++t)
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = c.indices[3 * t + k];
            m.positions.insert(m.positions.end(), {c.positions[3 * v], c.positions[3 * v + 1], c.positions[3 * v + 2]});
            m.indices.push_back(uint32_t(m.indices.size()));
        }
    return m;
}

// Latitude-longitude sphere with poles: closed, outward.
Mesh sphere(int rings = 12, int segments = 24)
{
    Mesh m;
    m.positions.insert(m.positions.end(), {0.0f, 1.0f, 0.0f});
    for (int r = 1; r < rings; ++r) {
        const float theta = float(M_PI) * float(r) / float(rings);
        for (int s = 0; s < segments; ++s) {
            const float phi = 2.0f * float(M_PI) * float(s) / float(segments);
            m.positions.insert(m.positions.end(),
                               {std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi)});
        }
    }
    m.positions.insert(m.positions.end(), {0.0f, -1.0f, 0.0f});
    const uint32_t south = uint32_t(m.vertexCount() - 1);
    auto ring = [&](int r, int s) { return uint32_t(1 + (r - 1) * segments + (s % segments)); };
    for (int s = 0; s < segments; ++s)
        m.indices.insert(m.indices.end(), {0u, ring(1, s + 1), ring(1, s)});
    for (int r = 1; r + 1 < rings; ++r)
        for (int s = 0; s < segments; ++s) {
            m.indices.insert(m.indices.end(), {ring(r, s), ring(r, s + 1), ring(r + 1, s)});
            m.indices.insert(m.indices.end(), {ring(r, s + 1), ring(r + 1, s + 1), ring(r + 1, s)});
        }
    for (int s = 0; s < segments; ++s)
        m.indices.insert(m.indices.end(), {south, ring(rings - 1, s), ring(rings - 1, s + 1)});
    return m;
}

Mesh torus(int major = 24, int minor = 12)
{
    Mesh m;
    for (int i = 0; i < major; ++i)
        for (int j = 0; j < minor; ++j) {
            const float u = 2.0f * float(M_PI) * float(i) / float(major), v = 2.0f * float(M_PI) * float(j) / float(minor);
            const float r = 1.0f + 0.3f * std::cos(v);
            m.positions.insert(m.positions.end(), {r * std::cos(u), 0.3f * std::sin(v), r * std::sin(u)});
        }
    auto at = [&](int i, int j) { return uint32_t((i % major) * minor + (j % minor)); };
    for (int i = 0; i < major; ++i)
        for (int j = 0; j < minor; ++j) {
            m.indices.insert(m.indices.end(), {at(i, j), at(i, j + 1), at(i + 1, j)});
            m.indices.insert(m.indices.end(), {at(i, j + 1), at(i + 1, j + 1), at(i + 1, j)});
        }
    return m;
}

// An open grid (a sheet) of n x n quads in the plane y = 0.
Mesh sheet(int n = 8)
{
    Mesh m;
    for (int z = 0; z <= n; ++z)
        for (int x = 0; x <= n; ++x)
            m.positions.insert(m.positions.end(), {float(x) / float(n), 0.0f, float(z) / float(n)});
    auto at = [&](int x, int z) { return uint32_t(z * (n + 1) + x); };
    for (int z = 0; z < n; ++z)
        for (int x = 0; x < n; ++x) {
            m.indices.insert(m.indices.end(), {at(x, z), at(x, z + 1), at(x + 1, z)});
            m.indices.insert(m.indices.end(), {at(x + 1, z), at(x, z + 1), at(x + 1, z + 1)});
        }
    return m;
}

Mesh withoutTriangle(Mesh m, size_t t)
{
    m.indices.erase(m.indices.begin() + 3 * t, m.indices.begin() + 3 * t + 3);
    return m;
}

Mesh flipped(Mesh m, size_t t)
{
    std::swap(m.indices[3 * t], m.indices[3 * t + 1]);
    return m;
}

size_t count(const std::vector<uint8_t>& flags)
{
    return size_t(std::accumulate(flags.begin(), flags.end(), uint64_t(0)));
}

// Brute force: components through edges of welded positions; open when an edge is not used exactly
// twice in opposite directions, or a triangle has two corners at one position.
std::vector<uint8_t> reference(const Mesh& mesh)
{
    using Position = std::array<float, 3>;
    std::map<Position, uint32_t> ids;
    std::vector<uint32_t> weld(mesh.vertexCount());
    for (size_t v = 0; v < mesh.vertexCount(); ++v) {
        Position p = {mesh.positions[3 * v] + 0.0f, mesh.positions[3 * v + 1] + 0.0f, mesh.positions[3 * v + 2] + 0.0f};
        weld[v] = ids.emplace(p, uint32_t(ids.size())).first->second;
    }
    const size_t n = mesh.triangleCount();
    std::vector<size_t> parent(n);
    std::iota(parent.begin(), parent.end(), size_t(0));
    auto find = [&](size_t x) {
        while (parent[x] != x)
            x = parent[x];
        return x;
    };
    std::map<std::pair<uint32_t, uint32_t>, std::vector<std::pair<size_t, bool>>> edges; // (lo, hi) -> (triangle, lo->hi)
    std::vector<uint8_t> skip(n, 0), bad(n, 0);
    for (size_t t = 0; t < n; ++t) {
        const uint32_t* i = &mesh.indices[3 * t];
        if (i[0] == i[1] || i[1] == i[2] || i[0] == i[2]) {
            skip[t] = 1;
            continue;
        }
        const uint32_t w[3] = {weld[i[0]], weld[i[1]], weld[i[2]]};
        if (w[0] == w[1] || w[1] == w[2] || w[0] == w[2])
            bad[t] = 1;
        for (int k = 0; k < 3; ++k) {
            const uint32_t a = w[k], b = w[(k + 1) % 3];
            if (a != b)
                edges[{std::min(a, b), std::max(a, b)}].push_back({t, a < b});
        }
    }
    for (auto& [edge, uses] : edges) {
        for (size_t k = 1; k < uses.size(); ++k)
            parent[find(uses[k].first)] = find(uses[0].first);
        if (uses.size() != 2 || uses[0].second == uses[1].second)
            for (auto& use : uses)
                bad[use.first] = 1;
    }
    std::vector<uint8_t> openRoot(n, 0), closed(n, 0);
    for (size_t t = 0; t < n; ++t)
        if (bad[t])
            openRoot[find(t)] = 1;
    // Outward: the component's signed volume (divergence theorem) must be positive.
    std::map<size_t, double> volume;
    for (size_t t = 0; t < n; ++t)
        if (!skip[t]) {
            const glm::dvec3 a(mesh.position(mesh.indices[3 * t])), b(mesh.position(mesh.indices[3 * t + 1])),
                c(mesh.position(mesh.indices[3 * t + 2]));
            volume[find(t)] += glm::dot(a, glm::cross(b, c)) / 6.0;
        }
    for (size_t t = 0; t < n; ++t)
        closed[t] = !skip[t] && !openRoot[find(t)] && volume[find(t)] > 0.0;
    return closed;
}

std::vector<uint8_t> closedOf(const Mesh& mesh)
{
    std::vector<uint8_t> closed = findClosedTriangles(mesh, 2);
    EXPECT_EQ(closed, reference(mesh));
    return closed;
}

bool allClosed(const Mesh& mesh)
{
    return count(closedOf(mesh)) == mesh.triangleCount();
}

bool noneClosed(const Mesh& mesh)
{
    return count(closedOf(mesh)) == 0;
}

TEST(Closed, ClosedMeshesAreClosed)
{
    EXPECT_TRUE(allClosed(cube()));
    EXPECT_TRUE(allClosed(unweldedCube()));
    EXPECT_TRUE(allClosed(sphere()));
    EXPECT_TRUE(allClosed(torus()));
    // Inward-facing (every triangle flipped) is consistently oriented, but wound inside out: open
    // (the runtime treats a flagged solid's faces seen from behind as its inside).
    Mesh inward = cube();
    for (size_t t = 0; t < inward.triangleCount(); ++t)
        inward = flipped(inward, t);
    EXPECT_TRUE(noneClosed(inward));
    // Two cubes touching at one corner are two edge-connected components, each closed.
    Mesh corner = cube();
    append(corner, translated(cube(), 1, 1, 1));
    EXPECT_TRUE(allClosed(corner));
    // -0 and +0 weld.
    Mesh signedZero = unweldedCube();
    for (float& p : signedZero.positions)
        if (p == 0.0f)
            p = (&p - signedZero.positions.data()) % 2 ? -0.0f : 0.0f;
    EXPECT_TRUE(allClosed(signedZero));
}

TEST(Closed, DamageOpensTheWholeComponent)
{
    for (const Mesh& closed : {cube(), sphere(), torus()}) {
        EXPECT_TRUE(noneClosed(withoutTriangle(closed, 0)));
        EXPECT_TRUE(noneClosed(withoutTriangle(closed, closed.triangleCount() / 2)));
        EXPECT_TRUE(noneClosed(flipped(closed, 0)));
        EXPECT_TRUE(noneClosed(flipped(closed, closed.triangleCount() - 1)));
        // A duplicated triangle: its edges are used three times.
        Mesh duplicated = closed;
        duplicated.indices.insert(duplicated.indices.end(), closed.indices.begin(), closed.indices.begin() + 3);
        EXPECT_TRUE(noneClosed(duplicated));
    }
    EXPECT_TRUE(noneClosed(sheet()));
}

TEST(Closed, TJunctionIsOpen)
{
    // The cube's top face (y = 1: 2 3 6 7) re-triangulated with a vertex m on the edge 2-3: the side face
    // y... z = 0 keeps the long edge 2-3, so the edges 2-m and m-3 are used once.
    Mesh m = cube();
    m.positions.insert(m.positions.end(), {0.5f, 1.0f, 0.0f});
    const uint32_t mid = 8;
    // Replace the y = 1 face (triangles 6 and 7: 2 6 3, 3 6 7) by 2 6 m, m 6 7, m 7 3.
    m.indices.erase(m.indices.begin() + 18, m.indices.begin() + 24);
    m.indices.insert(m.indices.end(), {2, 6, mid, mid, 6, 7, mid, 7, 3});
    ASSERT_TRUE(noneClosed(m));
    // With the side face split at m too, the surface is closed again.
    Mesh fixed = m;
    // The z = 0 face is triangles 0 and 1: 0 2 1, 1 2 3; split 1 2 3 into 1 2 m, 1 m 3.
    fixed.indices.erase(fixed.indices.begin() + 3, fixed.indices.begin() + 6);
    fixed.indices.insert(fixed.indices.end(), {1, 2, mid, 1, mid, 3});
    EXPECT_TRUE(allClosed(fixed));
}

TEST(Closed, NonManifoldEdgeIsOpen)
{
    // A fin on the cube's edge 0-1.
    Mesh fin = cube();
    fin.positions.insert(fin.positions.end(), {0.5f, -1.0f, -1.0f});
    fin.indices.insert(fin.indices.end(), {0, 1, 8});
    EXPECT_TRUE(noneClosed(fin));
    // Two cubes sharing an edge (welded by position): the edge is used four times.
    Mesh pair = cube();
    append(pair, translated(cube(), 1, 1, 0));
    EXPECT_TRUE(noneClosed(pair));
}

TEST(Closed, DegenerateTriangles)
{
    // A repeated index is not stored and does not open anything.
    Mesh m = cube();
    m.indices.insert(m.indices.end(), {0, 0, 1});
    std::vector<uint8_t> closed = closedOf(m);
    EXPECT_EQ(count(closed), 12u);
    EXPECT_EQ(closed[12], 0);
    // Distinct indices at one position: a zero-area triangle that is stored; it shares the edge 0-1
    // with the cube, so the cube opens too.
    Mesh z = cube();
    z.positions.insert(z.positions.end(), {0, 0, 0, 0, 0, 0, 1, 0, 0});
    z.indices.insert(z.indices.end(), {8, 9, 10});
    EXPECT_TRUE(noneClosed(z));
}

TEST(Closed, RandomDamageAgreesWithReference)
{
    std::mt19937 random(7);
    for (int round = 0; round < 40; ++round) {
        Mesh scene;
        append(scene, sphere(6, 10));
        append(scene, translated(torus(10, 6), 3, 0, 0));
        append(scene, translated(cube(), -3, 0, 0));
        append(scene, translated(unweldedCube(), -3, 1, 0)); // shares the face y = 1 of the cube: non-manifold
        const int damage = int(random() % 4);
        for (int d = 0; d < damage; ++d) {
            const size_t t = random() % scene.triangleCount();
            switch (random() % 3) {
            case 0: scene = withoutTriangle(scene, t); break;
            case 1: scene = flipped(scene, t); break;
            default: scene.indices.insert(scene.indices.end(), scene.indices.begin() + 3 * t, scene.indices.begin() + 3 * t + 3);
            }
        }
        closedOf(scene);
    }
}

// A scene of closed and open parts: exactly the closed parts' triangles are closed, the build
// flags exactly the clusters of closed triangles and keeps them apart from open ones.
TEST(Closed, MixedSceneFlagsOnlyClosedClusters)
{
    Mesh scene;
    std::vector<uint8_t> expected;
    std::vector<uint32_t> part; // per triangle: its part (each closed part is one component)
    auto add = [&](const Mesh& mesh, bool closed) {
        append(scene, mesh);
        expected.insert(expected.end(), mesh.triangleCount(), closed ? 1 : 0);
        part.insert(part.end(), mesh.triangleCount(), part.empty() ? 0u : part.back() + 1u);
    };
    for (int i = 0; i < 6; ++i) {
        add(translated(sphere(), float(3 * i), 0, 0), true);
        add(translated(sheet(12), float(3 * i), -1.5f, 0), false); // under each sphere, close to it
        add(translated(withoutTriangle(torus(), size_t(i)), float(3 * i), 2.0f, 0), false);
        add(translated(torus(), float(3 * i), 3.0f, 0), true);
        add(translated(cube(), float(3 * i), 4.0f, 0), true);
    }
    ASSERT_EQ(closedOf(scene), expected);

    for (bool separate : {true, false}) {
        PreprocessOptions options;
        options.threads = 2;
        options.separateClosed = separate;
        options.maxClusterTriangles = 256;
        PreprocessStats stats;
        std::vector<uint32_t> source;
        CompressedModel model = buildCompressedModel(scene, options, &stats, &source);
        ASSERT_EQ(source.size(), scene.triangleCount());
        EXPECT_EQ(stats.closedTriangles, count(expected));
        // A cluster is flagged when all its triangles are closed and each of their parts lies
        // wholly in such clusters (closedClusterFlags), found here by repeating the rule until
        // nothing changes.
        std::vector<uint8_t> expectedFlag(model.clusters.size(), 1);
        for (bool changed = true; changed;) {
            changed = false;
            std::vector<uint8_t> partOpen(part.back() + 1, 0);
            size_t k = 0;
            for (size_t c = 0; c < model.clusters.size(); ++c) {
                for (uint32_t i = 0; i < model.clusters[c].triangleCount; ++i) {
                    if (!expected[source[k + i]] && expectedFlag[c]) {
                        expectedFlag[c] = 0;
                        changed = true;
                    }
                    if (!expectedFlag[c])
                        partOpen[part[source[k + i]]] = 1;
                }
                k += model.clusters[c].triangleCount;
            }
            k = 0;
            for (size_t c = 0; c < model.clusters.size(); ++c) {
                for (uint32_t i = 0; i < model.clusters[c].triangleCount; ++i)
                    if (partOpen[part[source[k + i]]] && expectedFlag[c]) {
                        expectedFlag[c] = 0;
                        changed = true;
                    }
                k += model.clusters[c].triangleCount;
            }
        }
        size_t k = 0, clusterIndex = 0;
        uint64_t flaggedTriangles = 0, closedClusters = 0;
        for (const model::ClusterRecord& c : model.clusters) {
            EXPECT_EQ((c.flags & model::kClusterClosed) != 0, expectedFlag[clusterIndex++] != 0)
                << "cluster of " << c.triangleCount << " triangles";
            EXPECT_EQ(c.flags & ~uint32_t(model::kClusterClosed), 0u);
            flaggedTriangles += (c.flags & model::kClusterClosed) ? c.triangleCount : 0;
            closedClusters += (c.flags & model::kClusterClosed) ? 1 : 0;
            k += c.triangleCount;
        }
        EXPECT_EQ(stats.closedClusterTriangles, flaggedTriangles);
        EXPECT_EQ(stats.closedClusters, closedClusters);
        if (separate) {
            EXPECT_EQ(flaggedTriangles, count(expected)) << "clusters mix closed and open triangles";
        } else {
            EXPECT_LE(flaggedTriangles, count(expected));
        }
    }
}

// The procedural scenes: every part is built closed except the ground or floor grids and
// the parts the generators leave open; the shares are printed (README) and bounded loosely.
// No flagged cluster holds an open triangle.
TEST(Closed, ProceduralScenes)
{
    for (const char* name : {"city", "interior", "plant", "scan"}) {
        GenerateOptions generate;
        generate.triangles = 60'000;
        const Mesh mesh = generateScene(name, generate).mesh;
        PreprocessOptions options;
        options.threads = 2;
        options.separateClosed = true; // default builds mix closed parts with the ground and lose most flags
        PreprocessStats stats;
        std::vector<uint32_t> source;
        CompressedModel model = buildCompressedModel(mesh, options, &stats, &source);
        const std::vector<uint8_t> closed = findClosedTriangles(mesh, 2);
        EXPECT_EQ(stats.closedTriangles, count(closed)) << name;
        // Never a flagged cluster with an open triangle.
        size_t k = 0;
        for (const model::ClusterRecord& c : model.clusters) {
            if (c.flags & model::kClusterClosed) {
                for (uint32_t i = 0; i < c.triangleCount; ++i)
                    ASSERT_TRUE(closed[source[k + i]]) << name;
            }
            k += c.triangleCount;
        }
        const double share = double(stats.closedClusterTriangles) / double(stats.triangles);
        std::printf("[ closed ] %-8s %zu triangles: %.1f%% in closed components, %.1f%% in closed clusters (%llu of %llu)\n",
                    name, mesh.triangleCount(), 100.0 * double(stats.closedTriangles) / double(stats.triangles), 100.0 * share,
                    (unsigned long long)stats.closedClusters, (unsigned long long)stats.clusters);
        // Every closed part of these scenes touches another surface (buildings and furniture
        // stand on floors, beams and pipes meet, the statue crosses its ground): none is flagged
        // (crowdedComponents; PartsNearOtherSurfacesAreNotFlagged).
        EXPECT_GT(double(stats.closedTriangles) / double(stats.triangles), 0.5) << name;
        EXPECT_EQ(stats.closedClusters, 0u) << name;
    }
}

// A closed part that another surface (a part, closed or open) comes within the
// runtime's default shadow-ray offset of is not flagged (crowdedComponents): a
// ray from that surface could start inside it. Parts touching, crossing, and
// facing each other across 0.9 x the offset (face to face, edge to edge, a
// sheet over a cube) lose their flags; free parts and parts 10 x the offset
// apart keep them.
TEST(Closed, PartsNearOtherSurfacesAreNotFlagged)
{
    struct Part {
        std::string name;
        bool flagged;
    };
    auto makeScene = [](float gap, std::vector<uint32_t>& part, std::vector<Part>& parts) {
        Mesh scene;
        part.clear();
        parts.clear();
        auto add = [&](const Mesh& mesh, const std::string& name, bool flagged) {
            append(scene, mesh);
            part.insert(part.end(), mesh.triangleCount(), uint32_t(parts.size()));
            parts.push_back({name, flagged});
        };
        Mesh ground = sheet(4);
        for (size_t v = 0; v < ground.vertexCount(); ++v) {
            ground.positions[3 * v] = ground.positions[3 * v] * 20.0f - 10.0f;
            ground.positions[3 * v + 2] = ground.positions[3 * v + 2] * 20.0f - 10.0f;
        }
        add(ground, "ground", false);
        add(translated(cube(), -8, 0, -8), "cube on the ground", false);
        add(translated(cube(), -6, -0.5f, -8), "cube through the ground", false);
        add(translated(cube(), -4, 2, -8), "free cube", true);
        add(translated(cube(), -2, 2, -8), "cube touching the next", false);
        add(translated(cube(), -1, 2, -8), "cube touching the previous", false);
        add(translated(cube(), 0, 2, -8), "cube 0.9 offsets from the next, face to face", false);
        add(translated(cube(), 1 + 0.9f * gap, 2, -8), "cube 0.9 offsets from the previous, face to face", false);
        add(translated(cube(), 0, 2, -5), "cube 10 offsets from the next, face to face", true);
        add(translated(cube(), 1 + 10.0f * gap, 2, -5), "cube 10 offsets from the previous, face to face", true);
        const float d = 0.9f * gap / std::sqrt(2.0f), e = 10.0f * gap / std::sqrt(2.0f);
        add(translated(cube(), 3, 2, -8), "cube 0.9 offsets from the next, edge to edge", false);
        add(translated(cube(), 4 + d, 3 + d, -8), "cube 0.9 offsets from the previous, edge to edge", false);
        add(translated(cube(), 3, 2, -5), "cube 10 offsets from the next, edge to edge", true);
        add(translated(cube(), 4 + e, 3 + e, -5), "cube 10 offsets from the previous, edge to edge", true);
        add(translated(cube(), 6, 2, -8), "cube 0.9 offsets under a sheet", false);
        add(translated(sheet(2), 6, 3 + 0.9f * gap, -8), "sheet", false);
        add(translated(cube(), 6, 2, -5), "cube 10 offsets under a sheet", true);
        add(translated(sheet(2), 6, 3 + 10.0f * gap, -5), "sheet", false);
        return scene;
    };
    PreprocessOptions options;
    options.threads = 2;
    options.separateClosed = true;
    options.maxClusterTriangles = 64;
    std::vector<uint32_t> part;
    std::vector<Part> parts;
    // The runtime's offset (shadowRayOffset: max(1e-5 x |box extent|, 4 x max position error))
    // of the scene, which the gaps hardly change.
    auto offsetOf = [](const CompressedModel& model) {
        const glm::vec3 extent(model.header.boundsMax[0] - model.header.boundsMin[0], model.header.boundsMax[1] - model.header.boundsMin[1],
                               model.header.boundsMax[2] - model.header.boundsMin[2]);
        return std::max(1e-5f * glm::length(extent), 4.0f * model.header.maxPositionError);
    };
    const float offset = offsetOf(buildCompressedModel(makeScene(1e-3f, part, parts), options));
    const Mesh scene = makeScene(offset, part, parts);
    std::vector<uint32_t> source;
    const CompressedModel model = buildCompressedModel(scene, options, nullptr, &source);
    ASSERT_LT(0.9f * offset, offsetOf(model));
    std::printf("[ closed ] offset %g\n", offset);
    std::vector<int> flagged(parts.size(), -1); // -1 none seen, 0 / 1; 2: mixed
    size_t k = 0;
    for (const model::ClusterRecord& c : model.clusters)
        for (uint32_t i = 0; i < c.triangleCount; ++i, ++k) {
            int& f = flagged[part[source[k]]];
            const int now = (c.flags & model::kClusterClosed) ? 1 : 0;
            f = f == -1 ? now : f == now ? f : 2;
        }
    for (size_t p = 0; p < parts.size(); ++p)
        EXPECT_EQ(flagged[p], parts[p].flagged ? 1 : 0) << parts[p].name;
}

// crowdedComponents itself, as a streamed chunk calls it: a part within the distance of
// its cell's faces is crowded (a neighbour beyond may be in no halo), a part farther in is
// not; infinite faces crowd nothing; a neighbour (here an open sheet, as a halo is) crowds.
TEST(Closed, CellFacesCrowdPartsNearThem)
{
    Mesh scene;
    append(scene, cube());                          // x 0..1
    append(scene, translated(cube(), 3, 0, 0));     // x 3..4
    append(scene, translated(sheet(2), 3, 1.05f, 0)); // 0.05 over the second cube
    const std::vector<uint32_t> component = preprocess_detail::closedComponents(scene, 2);
    ASSERT_NE(component[0], preprocess_detail::kOpenComponent);
    ASSERT_NE(component[12], preprocess_detail::kOpenComponent);
    auto crowded = [&](double distance, const float* lo, const float* hi) {
        const std::vector<uint8_t> c = preprocess_detail::crowdedComponents(scene, component.data(), distance, lo, hi, 2);
        return std::array<int, 2>{c[component[0]], c[component[12]]};
    };
    const float inf = std::numeric_limits<float>::infinity();
    const float lo[3] = {-inf, -inf, -inf}, hi[3] = {5.0f, inf, inf}, near[3] = {-0.02f, -inf, -inf};
    EXPECT_EQ(crowded(0.01, nullptr, nullptr), (std::array<int, 2>{0, 0}));
    EXPECT_EQ(crowded(0.06, nullptr, nullptr), (std::array<int, 2>{0, 1})) << "the sheet 0.05 over the second cube";
    EXPECT_EQ(crowded(0.03, lo, hi), (std::array<int, 2>{0, 0})) << "infinite faces and x = 5, 1 from the second cube";
    EXPECT_EQ(crowded(0.03, near, hi), (std::array<int, 2>{1, 0})) << "the first cube 0.02 from the cell's face x = -0.02";
    EXPECT_EQ(crowded(0.01, near, hi), (std::array<int, 2>{0, 0}));
}

TEST(Closed, Errors)
{
    Mesh m = cube();
    m.indices[5] = 99;
    EXPECT_THROW(findClosedTriangles(m), Error);
}

} // namespace
