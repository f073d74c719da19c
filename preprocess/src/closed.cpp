// Closed components (model::kClusterClosed, formats/README.md "Cluster
// flags"): which triangles belong to a closed, consistently oriented
// 2-manifold. Vertices are welded by exact position (-0 = +0); components are
// connected through shared edges; a component is closed when every undirected
// edge of it is used by exactly two of its triangles, in opposite directions,
// and none of its triangles has two corners at one position. Shadow methods
// that cast only the light-back-facing triangles of closed clusters rely on
// this being conservative, so every doubt makes a component open.
//
// Memory (per triangle T, per vertex V): the weld (4 B/V plus a 2-slot-per-
// vertex table, 8 B/V, freed before the rest), triangles per welded vertex in
// CSR form (12 B/T + 8 B/V), a union-find parent (4 B/T) and two flag bytes:
// about 27 B/T on a mesh of 0.5 V/T, below the tree stage's peak. Everything is
// parallel: the corner lists are filled with atomic cursors (their order does
// not matter), the union-find links with compare-and-swap (the partition it
// ends with does not depend on the order of the links).
#include <algorithm>
#include <atomic>
#include <cstring>

#include <glm/geometric.hpp>

#include "penumbra/error.h"
#include "preprocess_internal.h"

namespace penumbra::preprocess_detail {

namespace {

constexpr uint32_t kEmpty = 0xFFFFFFFFu;

uint32_t positionKey(float f)
{
    uint32_t bits;
    std::memcpy(&bits, &f, 4);
    return bits == 0x80000000u ? 0u : bits;
}

// weld[v] = the smallest vertex index at v's exact position.
std::vector<uint32_t> weldVertices(const Mesh& mesh)
{
    const uint64_t count = mesh.vertexCount();
    const float* p = mesh.positions.data();
    uint64_t tableSize = 16;
    while (tableSize < count * 2)
        tableSize <<= 1;
    std::vector<uint32_t> table(tableSize, kEmpty);
    std::vector<uint32_t> weld(count);
    for (uint64_t v = 0; v < count; ++v) {
        const uint32_t kx = positionKey(p[3 * v]), ky = positionKey(p[3 * v + 1]), kz = positionKey(p[3 * v + 2]);
        uint64_t h = (uint64_t(kx) * 0x9E3779B97F4A7C15ull) ^ (uint64_t(ky) * 0xC2B2AE3D27D4EB4Full) ^
                     (uint64_t(kz) * 0x165667B19E3779F9ull);
        h ^= h >> 29;
        for (uint64_t slot = h & (tableSize - 1);; slot = (slot + 1) & (tableSize - 1)) {
            const uint32_t w = table[slot];
            if (w == kEmpty) {
                table[slot] = uint32_t(v);
                weld[v] = uint32_t(v);
                break;
            }
            if (positionKey(p[3 * uint64_t(w)]) == kx && positionKey(p[3 * uint64_t(w) + 1]) == ky &&
                positionKey(p[3 * uint64_t(w) + 2]) == kz) {
                weld[v] = w;
                break;
            }
        }
    }
    return weld;
}

uint32_t find(std::vector<uint32_t>& parent, uint32_t x)
{
    for (;;) {
        std::atomic_ref<uint32_t> px(parent[x]);
        uint32_t p = px.load(std::memory_order_relaxed);
        if (p == x)
            return x;
        std::atomic_ref<uint32_t> pp(parent[p]);
        uint32_t g = pp.load(std::memory_order_relaxed);
        if (g != p)
            px.compare_exchange_weak(p, g, std::memory_order_relaxed); // path halving; a failed CAS is harmless
        x = g;
    }
}

// Links the sets of a and b: the larger root under the smaller, by CAS.
void unite(std::vector<uint32_t>& parent, uint32_t a, uint32_t b)
{
    for (;;) {
        a = find(parent, a);
        b = find(parent, b);
        if (a == b)
            return;
        if (a < b)
            std::swap(a, b);
        uint32_t expected = a;
        if (std::atomic_ref<uint32_t>(parent[a]).compare_exchange_strong(expected, b, std::memory_order_relaxed))
            return;
    }
}

} // namespace

namespace {

// One corner of a triangle in the list of its welded vertex a: the triangle and
// the welded vertex after a in its winding (its directed edge a -> next).
struct Corner {
    uint32_t triangle;
    uint32_t next;
};

template <typename Offset>
std::vector<uint32_t> componentsWithOffsets(const Mesh& mesh, unsigned threads, const uint8_t* openSeed)
{
    const uint64_t triangleCount = mesh.triangleCount();
    const uint64_t vertexCount = mesh.vertexCount();
    const uint32_t* idx = mesh.indices.data();
    std::vector<uint32_t> component(triangleCount, kOpenComponent);
    const uint64_t chunk = 1 << 16;
    const uint64_t triangleChunks = (triangleCount + chunk - 1) / chunk;
    auto isDegenerate = [idx](uint64_t t) {
        return idx[3 * t] == idx[3 * t + 1] || idx[3 * t + 1] == idx[3 * t + 2] || idx[3 * t] == idx[3 * t + 2];
    };

    // Corners per welded vertex in CSR form.
    std::vector<uint32_t> weld = weldVertices(mesh);
    std::vector<Offset> offsets(vertexCount + 1, 0);
    parallelFor(threads, triangleChunks, [&](uint64_t c) {
        for (uint64_t t = c * chunk, e = std::min(triangleCount, t + chunk); t < e; ++t) {
            if (isDegenerate(t))
                continue;
            for (int k = 0; k < 3; ++k)
                std::atomic_ref<Offset>(offsets[weld[idx[3 * t + k]] + 1]).fetch_add(1, std::memory_order_relaxed);
        }
    });
    for (uint64_t v = 0; v < vertexCount; ++v)
        offsets[v + 1] += offsets[v];
    std::vector<Corner> corners(offsets[vertexCount]);
    {
        std::vector<Offset> cursor(offsets.begin(), offsets.end() - 1);
        parallelFor(threads, triangleChunks, [&](uint64_t c) {
            for (uint64_t t = c * chunk, e = std::min(triangleCount, t + chunk); t < e; ++t) {
                if (isDegenerate(t))
                    continue;
                const uint32_t w[3] = {weld[idx[3 * t]], weld[idx[3 * t + 1]], weld[idx[3 * t + 2]]};
                for (int k = 0; k < 3; ++k) {
                    const Offset at = std::atomic_ref<Offset>(cursor[w[k]]).fetch_add(1, std::memory_order_relaxed);
                    corners[at] = {uint32_t(t), w[(k + 1) % 3]};
                }
            }
        });
    }

    // The undirected edge {a, b} of t (t runs a -> b) is good when exactly one corner runs a -> b
    // (t's own) and exactly one b -> a; then t joins that triangle's component. Every triangle on a
    // bad edge is itself bad, so components need no links through bad edges: all their sides are open.
    std::vector<uint32_t> parent(triangleCount);
    for (uint64_t t = 0; t < triangleCount; ++t)
        parent[t] = uint32_t(t);
    std::vector<uint8_t> bad(triangleCount, 0);
    parallelFor(threads, triangleChunks, [&](uint64_t c) {
        for (uint64_t t = c * chunk, e = std::min(triangleCount, t + chunk); t < e; ++t) {
            if (isDegenerate(t))
                continue;
            const uint32_t w[3] = {weld[idx[3 * t]], weld[idx[3 * t + 1]], weld[idx[3 * t + 2]]};
            bool open = (openSeed && openSeed[t]) || w[0] == w[1] || w[1] == w[2] || w[0] == w[2];
            for (int k = 0; k < 3 && !open; ++k) {
                const uint32_t a = w[k], b = w[(k + 1) % 3];
                uint32_t forward = 0, backward = 0, partner = 0;
                for (Offset i = offsets[a]; i < offsets[a + 1]; ++i)
                    forward += corners[i].next == b;
                for (Offset i = offsets[b]; i < offsets[b + 1]; ++i)
                    if (corners[i].next == a) {
                        ++backward;
                        partner = corners[i].triangle;
                    }
                open = forward != 1 || backward != 1;
                if (!open)
                    unite(parent, uint32_t(t), partner);
            }
            bad[t] = open;
        }
    });
    corners = {};
    offsets = {};
    weld = {};

    // A component is open when any of its triangles is.
    std::vector<uint8_t> openRoot(triangleCount, 0);
    parallelFor(threads, triangleChunks, [&](uint64_t c) {
        for (uint64_t t = c * chunk, e = std::min(triangleCount, t + chunk); t < e; ++t)
            if (bad[t])
                std::atomic_ref<uint8_t>(openRoot[find(parent, uint32_t(t))]).store(1, std::memory_order_relaxed);
    });
    parallelFor(threads, triangleChunks, [&](uint64_t c) {
        for (uint64_t t = c * chunk, e = std::min(triangleCount, t + chunk); t < e; ++t)
            if (!isDegenerate(t)) {
                const uint32_t root = find(parent, uint32_t(t));
                if (!openRoot[root])
                    component[t] = root;
            }
    });
    // Orientation: a closed component must enclose positive volume (its triangles wound
    // counter-clockwise seen from outside); one wound inside out, or flat (a two-sided sheet,
    // zero volume), is open. Signed volume relative to the root triangle's first corner (small
    // numbers), summed in triangle order (the same sum whatever the thread count).
    openRoot = {};
    bad = {};
    std::vector<double> volume(triangleCount, 0.0);
    std::vector<double> scale(triangleCount, 0.0);
    for (uint64_t t = 0; t < triangleCount; ++t) {
        const uint32_t root = component[t];
        if (root == kOpenComponent)
            continue;
        const glm::dvec3 o(mesh.position(idx[3 * uint64_t(root)]));
        const glm::dvec3 a = glm::dvec3(mesh.position(idx[3 * t])) - o, b = glm::dvec3(mesh.position(idx[3 * t + 1])) - o,
                         d = glm::dvec3(mesh.position(idx[3 * t + 2])) - o;
        volume[root] += glm::dot(a, glm::cross(b, d));
        scale[root] = std::max({scale[root], glm::length(a), glm::length(b), glm::length(d)});
    }
    for (uint64_t t = 0; t < triangleCount; ++t) {
        const uint32_t root = component[t];
        if (root != kOpenComponent && !(volume[root] > 1e-9 * scale[root] * scale[root] * scale[root]))
            component[t] = kOpenComponent;
    }
    return component;
}

} // namespace

std::vector<uint32_t> closedComponents(const Mesh& mesh, unsigned threads, const uint8_t* openSeed)
{
    if (mesh.triangleCount() > 0xFFFFFFFEull || mesh.vertexCount() > 0xFFFFFFFEull)
        fail("preprocess", "internal error: too many triangles for the closed-component test");
    if (mesh.triangleCount() == 0)
        return {};
    // 32-bit list offsets while the 3 corners per triangle fit them (half the memory traffic).
    if (3 * uint64_t(mesh.triangleCount()) < 0xFFFFFFFFull)
        return componentsWithOffsets<uint32_t>(mesh, threads, openSeed);
    return componentsWithOffsets<uint64_t>(mesh, threads, openSeed);
}

std::vector<uint8_t> closedTriangles(const Mesh& mesh, unsigned threads, const uint8_t* openSeed)
{
    const std::vector<uint32_t> component = closedComponents(mesh, threads, openSeed);
    std::vector<uint8_t> closed(component.size());
    for (size_t t = 0; t < component.size(); ++t)
        closed[t] = component[t] != kOpenComponent;
    return closed;
}

std::vector<uint8_t> closedClusterFlags(const uint32_t* component, const uint32_t* triangles, const ClusterRange* clusters,
                                        size_t clusterCount, uint64_t componentLimit, unsigned threads)
{
    // ok[c]: every triangle of cluster c is closed (the first pass), then: and no component of
    // them has a triangle in a cluster that is not ok. A cluster that loses its flag can cost
    // other components theirs (they share it), so the passes go on until nothing changes:
    // each pass only clears flags, so at most as many passes as clusters, in practice 2-3.
    std::vector<uint8_t> ok(clusterCount, 1);
    parallelFor(threads, clusterCount, [&](uint64_t c) {
        for (uint32_t i = clusters[c].begin; i < clusters[c].end; ++i)
            if (component[triangles[i]] == kOpenComponent) {
                ok[c] = 0;
                break;
            }
    });
    std::vector<uint8_t> openComponent(componentLimit, 0);
    for (bool changed = true; changed;) {
        parallelFor(threads, clusterCount, [&](uint64_t c) {
            if (ok[c])
                return;
            for (uint32_t i = clusters[c].begin; i < clusters[c].end; ++i) {
                const uint32_t k = component[triangles[i]];
                if (k != kOpenComponent)
                    std::atomic_ref<uint8_t>(openComponent[k]).store(1, std::memory_order_relaxed);
            }
        });
        std::atomic<bool> cleared{false};
        parallelFor(threads, clusterCount, [&](uint64_t c) {
            if (!ok[c])
                return;
            for (uint32_t i = clusters[c].begin; i < clusters[c].end; ++i)
                if (std::atomic_ref<uint8_t>(openComponent[component[triangles[i]]]).load(std::memory_order_relaxed)) {
                    ok[c] = 0;
                    cleared.store(true, std::memory_order_relaxed);
                    break;
                }
        });
        changed = cleared.load();
    }
    return ok;
}

} // namespace penumbra::preprocess_detail
