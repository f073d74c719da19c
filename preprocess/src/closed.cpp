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
#include <cmath>
#include <cstring>
#include <limits>

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

// ---- clearance (crowdedComponents) -------------------------------------------------

namespace penumbra::preprocess_detail {

namespace {

using glm::dvec3;

// Squared distance between segments p1q1 and p2q2 (Ericson, Real-Time Collision Detection, 5.1.9).
double segmentSegment2(const dvec3& p1, const dvec3& q1, const dvec3& p2, const dvec3& q2)
{
    const dvec3 d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
    const double a = glm::dot(d1, d1), e = glm::dot(d2, d2), f = glm::dot(d2, r);
    double s = 0.0, t = 0.0;
    if (a <= 1e-300 && e <= 1e-300)
        return glm::dot(r, r);
    if (a <= 1e-300) {
        t = std::clamp(f / e, 0.0, 1.0);
    } else {
        const double c = glm::dot(d1, r);
        if (e <= 1e-300) {
            s = std::clamp(-c / a, 0.0, 1.0);
        } else {
            const double b = glm::dot(d1, d2), denom = a * e - b * b;
            s = denom > 0.0 ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
            t = (b * s + f) / e;
            if (t < 0.0) {
                t = 0.0;
                s = std::clamp(-c / a, 0.0, 1.0);
            } else if (t > 1.0) {
                t = 1.0;
                s = std::clamp((b - c) / a, 0.0, 1.0);
            }
        }
    }
    const dvec3 d = (p1 + d1 * s) - (p2 + d2 * t);
    return glm::dot(d, d);
}

// Squared distance from p to the triangle abc, not degenerate (Ericson 5.1.5).
double pointTriangle2(const dvec3& p, const dvec3& a, const dvec3& b, const dvec3& c)
{
    const dvec3 ab = b - a, ac = c - a, ap = p - a;
    const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
    dvec3 q;
    if (d1 <= 0.0 && d2 <= 0.0) {
        q = a;
    } else {
        const dvec3 bp = p - b;
        const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
        const dvec3 cp = p - c;
        const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
        const double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6, va = d3 * d6 - d5 * d4;
        if (d3 >= 0.0 && d4 <= d3)
            q = b;
        else if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0)
            q = a + ab * (d1 / (d1 - d3));
        else if (d6 >= 0.0 && d5 <= d6)
            q = c;
        else if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0)
            q = a + ac * (d2 / (d2 - d6));
        else if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0)
            q = b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
        else {
            const double denom = 1.0 / (va + vb + vc);
            q = a + ab * (vb * denom) + ac * (vc * denom);
        }
    }
    const dvec3 d = p - q;
    return glm::dot(d, d);
}

// Whether the triangles come closer than `distance` (exactly, in double precision): the
// smallest distance of two triangles is one between an edge of each, between a corner of
// one and the other, or zero where an edge of one crosses the other (each candidate below
// is a distance between points of both, so none is too small).
bool trianglesCloser(const dvec3* a, const dvec3* b, double distance)
{
    const double limit = distance * distance;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            if (segmentSegment2(a[i], a[(i + 1) % 3], b[j], b[(j + 1) % 3]) < limit)
                return true;
    // Corners against faces and edges through faces: only for faces with an area (a flat
    // triangle is its edges, which the loop above has measured).
    for (int side = 0; side < 2; ++side) {
        const dvec3* f = side ? b : a;
        const dvec3* o = side ? a : b;
        const dvec3 n = glm::cross(f[1] - f[0], f[2] - f[0]);
        const double n2 = glm::dot(n, n);
        const double scale = std::max({glm::dot(f[1] - f[0], f[1] - f[0]), glm::dot(f[2] - f[0], f[2] - f[0]),
                                       glm::dot(f[2] - f[1], f[2] - f[1])});
        if (!(n2 > 1e-24 * scale * scale))
            continue;
        double h[3];
        for (int k = 0; k < 3; ++k) {
            if (pointTriangle2(o[k], f[0], f[1], f[2]) < limit)
                return true;
            h[k] = glm::dot(n, o[k] - f[0]);
        }
        for (int k = 0; k < 3; ++k) {
            const double h0 = h[k], h1 = h[(k + 1) % 3];
            if ((h0 <= 0.0) == (h1 <= 0.0) || h0 == h1)
                continue;
            const dvec3 x = o[k] + (o[(k + 1) % 3] - o[k]) * (h0 / (h0 - h1));
            if (pointTriangle2(x, f[0], f[1], f[2]) < limit)
                return true;
        }
    }
    return false;
}

} // namespace

double closedClearance(const float* boundsMin, const float* boundsMax)
{
    // shadowRayOffset (runtime/src/api.cpp): max(1e-5 x |model box extent|, 4 x the largest
    // per-coordinate quantization error). The error is at most half a 16-bit step of the
    // cluster's box plus the decoder's float roundings (quantize.cpp); no cluster box is
    // wider than the model's, so half a step of the model's widest axis bounds it before
    // any cluster exists. 1% and the roundings' own bound on top.
    double extent2 = 0.0, widest = 0.0, largest = 0.0;
    for (int a = 0; a < 3; ++a) {
        const double e = double(boundsMax[a]) - double(boundsMin[a]);
        extent2 += e * e;
        widest = std::max(widest, e);
        largest = std::max({largest, std::fabs(double(boundsMin[a])), std::fabs(double(boundsMax[a]))});
    }
    const double error = 0.5 * widest / 65535.0 + 8.0 * 0x1p-24 * (largest + widest);
    return 1.01 * std::max(1e-5 * std::sqrt(extent2), 4.0 * error);
}

void meshBounds(const Mesh& mesh, float* boundsMin, float* boundsMax)
{
    for (int a = 0; a < 3; ++a) {
        boundsMin[a] = mesh.vertexCount() ? std::numeric_limits<float>::infinity() : 0.0f;
        boundsMax[a] = mesh.vertexCount() ? -std::numeric_limits<float>::infinity() : 0.0f;
    }
    const float* p = mesh.positions.data();
    for (uint64_t v = 0; v < mesh.vertexCount(); ++v)
        for (int a = 0; a < 3; ++a) {
            boundsMin[a] = std::min(boundsMin[a], p[3 * v + uint64_t(a)]);
            boundsMax[a] = std::max(boundsMax[a], p[3 * v + uint64_t(a)]);
        }
}

std::vector<uint8_t> crowdedComponents(const Mesh& mesh, const uint32_t* component, double distance, const float* cellMin,
                                       const float* cellMax, unsigned threads)
{
    const uint64_t triangleCount = mesh.triangleCount();
    std::vector<uint8_t> crowded(triangleCount, 0);
    bool anyClosed = false;
    for (uint64_t t = 0; t < triangleCount && !anyClosed; ++t)
        anyClosed = component[t] != kOpenComponent;
    if (!anyClosed)
        return crowded;
    const uint32_t* idx = mesh.indices.data();
    auto degenerate = [idx](uint64_t t) {
        return idx[3 * t] == idx[3 * t + 1] || idx[3 * t + 1] == idx[3 * t + 2] || idx[3 * t] == idx[3 * t + 2];
    };
    auto corners = [&](uint64_t t, dvec3* p) {
        for (int k = 0; k < 3; ++k)
            p[k] = dvec3(mesh.position(idx[3 * t + uint64_t(k)]));
    };
    const uint64_t chunk = 1 << 14;
    const uint64_t chunks = (triangleCount + chunk - 1) / chunk;
    auto mark = [&](uint32_t c) { std::atomic_ref<uint8_t>(crowded[c]).store(1, std::memory_order_relaxed); };
    auto isCrowded = [&](uint32_t c) { return std::atomic_ref<uint8_t>(crowded[c]).load(std::memory_order_relaxed) != 0; };

    // A component whose triangles come within `distance` of the cell's faces may have a
    // neighbour in another chunk that is not in this chunk's halo: crowded.
    if (cellMin && cellMax)
        parallelFor(threads, chunks, [&](uint64_t c) {
            for (uint64_t t = c * chunk, e = std::min(triangleCount, t + chunk); t < e; ++t) {
                if (component[t] == kOpenComponent || degenerate(t))
                    continue;
                dvec3 p[3];
                corners(t, p);
                for (int a = 0; a < 3; ++a) {
                    const double lo = std::min({p[0][a], p[1][a], p[2][a]}), hi = std::max({p[0][a], p[1][a], p[2][a]});
                    if (lo - distance <= double(cellMin[a]) || hi + distance >= double(cellMax[a]))
                        mark(component[t]);
                }
            }
        });

    // A binary BVH over the triangles' boxes (median splits of the centres on the widest
    // axis, up to 4 triangles a leaf); each node knows the one component all its triangles
    // belong to (or none: mixed or open), so that a query skips its own solid's subtrees.
    struct Node {
        float lo[3], hi[3];
        uint32_t first, count; // leaf: triangles [first, first + count) of order; else count = 0, children first, first + 1
        uint32_t only;         // the single closed component of the subtree, or kOpenComponent
    };
    std::vector<uint32_t> order;
    order.reserve(triangleCount);
    for (uint64_t t = 0; t < triangleCount; ++t)
        if (!degenerate(t))
            order.push_back(uint32_t(t));
    if (order.empty())
        return crowded;
    std::vector<float> centre(3 * triangleCount);
    parallelFor(threads, chunks, [&](uint64_t c) {
        for (uint64_t t = c * chunk, e = std::min(triangleCount, t + chunk); t < e; ++t)
            for (int a = 0; a < 3; ++a) {
                const float x = mesh.position(idx[3 * t])[a], y = mesh.position(idx[3 * t + 1])[a], z = mesh.position(idx[3 * t + 2])[a];
                centre[3 * t + uint64_t(a)] = 0.5f * (std::min({x, y, z}) + std::max({x, y, z}));
            }
    });
    std::vector<Node> nodes;
    nodes.reserve(order.size() / 2 + 2);
    nodes.push_back({});
    struct Task {
        uint32_t node, begin, end;
    };
    std::vector<Task> tasks{{0, 0, uint32_t(order.size())}};
    while (!tasks.empty()) {
        const Task task = tasks.back();
        tasks.pop_back();
        float cmin[3] = {INFINITY, INFINITY, INFINITY}, cmax[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (uint32_t i = task.begin; i < task.end; ++i)
            for (int a = 0; a < 3; ++a) {
                cmin[a] = std::min(cmin[a], centre[3 * uint64_t(order[i]) + uint64_t(a)]);
                cmax[a] = std::max(cmax[a], centre[3 * uint64_t(order[i]) + uint64_t(a)]);
            }
        int axis = 0;
        for (int a = 1; a < 3; ++a)
            if (cmax[a] - cmin[a] > cmax[axis] - cmin[axis])
                axis = a;
        if (task.end - task.begin <= 4 || !(cmax[axis] > cmin[axis])) {
            nodes[task.node].first = task.begin;
            nodes[task.node].count = task.end - task.begin;
            continue;
        }
        const uint32_t mid = task.begin + (task.end - task.begin) / 2;
        std::nth_element(order.begin() + task.begin, order.begin() + mid, order.begin() + task.end, [&](uint32_t x, uint32_t y) {
            return centre[3 * uint64_t(x) + uint64_t(axis)] < centre[3 * uint64_t(y) + uint64_t(axis)];
        });
        const uint32_t left = uint32_t(nodes.size());
        nodes[task.node].first = left;
        nodes[task.node].count = 0;
        nodes.push_back({});
        nodes.push_back({});
        tasks.push_back({left, task.begin, mid});
        tasks.push_back({left + 1, mid, task.end});
    }
    centre = {};
    // Boxes and summaries bottom-up: children always come after their parent.
    for (size_t n = nodes.size(); n-- > 0;) {
        Node& node = nodes[n];
        for (int a = 0; a < 3; ++a) {
            node.lo[a] = INFINITY;
            node.hi[a] = -INFINITY;
        }
        auto grow = [&](const float* lo, const float* hi) {
            for (int a = 0; a < 3; ++a) {
                node.lo[a] = std::min(node.lo[a], lo[a]);
                node.hi[a] = std::max(node.hi[a], hi[a]);
            }
        };
        if (node.count) {
            node.only = component[order[node.first]];
            for (uint32_t i = node.first; i < node.first + node.count; ++i) {
                const uint32_t t = order[i];
                for (int k = 0; k < 3; ++k) {
                    const float* p = &mesh.positions[3 * uint64_t(idx[3 * uint64_t(t) + uint64_t(k)])];
                    grow(p, p);
                }
                if (component[t] != node.only)
                    node.only = kOpenComponent;
            }
        } else {
            const Node& l = nodes[node.first];
            const Node& r = nodes[node.first + 1];
            grow(l.lo, l.hi);
            grow(r.lo, r.hi);
            node.only = l.only == r.only ? l.only : kOpenComponent;
        }
    }

    // The distance is symmetric, so only the triangles of closed components not yet crowded
    // ask: for the triangles u of other components (or open ones) whose boxes come within
    // `distance` of their own; the exact distance decides, and crowds both sides.
    parallelFor(threads, chunks, [&](uint64_t c) {
        std::vector<uint32_t> stack;
        for (uint64_t t = c * chunk, e = std::min(triangleCount, t + chunk); t < e; ++t) {
            const uint32_t ct = component[t];
            if (ct == kOpenComponent || isCrowded(ct))
                continue; // degenerate triangles are open
            dvec3 tri[3];
            corners(t, tri);
            double lo[3], hi[3];
            for (int a = 0; a < 3; ++a) {
                lo[a] = std::min({tri[0][a], tri[1][a], tri[2][a]}) - distance;
                hi[a] = std::max({tri[0][a], tri[1][a], tri[2][a]}) + distance;
            }
            stack.assign(1, 0);
            while (!stack.empty() && !isCrowded(ct)) {
                const Node& node = nodes[stack.back()];
                stack.pop_back();
                if (node.only == ct)
                    continue;
                bool apart = false;
                for (int a = 0; a < 3; ++a)
                    apart |= double(node.lo[a]) > hi[a] || double(node.hi[a]) < lo[a];
                if (apart)
                    continue;
                if (!node.count) {
                    stack.push_back(node.first);
                    stack.push_back(node.first + 1);
                    continue;
                }
                for (uint32_t i = node.first; i < node.first + node.count; ++i) {
                    const uint32_t u = order[i];
                    const uint32_t cu = component[u];
                    if (cu == ct)
                        continue;
                    dvec3 other[3];
                    corners(u, other);
                    bool far = false;
                    for (int a = 0; a < 3; ++a)
                        far |= std::min({other[0][a], other[1][a], other[2][a]}) > hi[a] ||
                               std::max({other[0][a], other[1][a], other[2][a]}) < lo[a];
                    if (far || !trianglesCloser(tri, other, distance))
                        continue;
                    mark(ct);
                    if (cu != kOpenComponent)
                        mark(cu);
                    break;
                }
            }
        }
    });
    return crowded;
}

} // namespace penumbra::preprocess_detail
