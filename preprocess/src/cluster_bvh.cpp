// Top-level BVH over the whole mesh, down to clusters: a top-down binned SAH
// build over triangle centroids (Wald 2007, "On fast Construction of SAH-based
// Bounding Volume Hierarchies"), stopping at the first node that fits a cluster
// (<= maxClusterTriangles triangles on <= maxClusterVertices unique vertices) -
// the cluster level of the single BVH of Lauterbach et al. 2009, section 5.1.
// Only centroids are binned (16 bytes per triangle: no per-triangle boxes), so
// the SAH sees centroid boxes; exact boxes come later from decoded vertices.
// Large nodes near the root are split on the calling thread with parallel
// binning; the subtrees below are built in parallel, each into its own arrays,
// and merged in a fixed order (the result does not depend on the thread count).
// Nodes of up to 4 clusters' worth are split by "filling" (fillNode), sorting
// the centroids once per such region. When the depth budget requires it
// (sahSplitAllowed) or SAH finds no split (identical centroids), the split is
// an object median along the widest axis. Needs SSE (x86-64 baseline).
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>

#include <immintrin.h>

#include "preprocess_internal.h"

namespace penumbra::preprocess_detail {

namespace {

struct CentroidBox {
    float min[3] = {INFINITY, INFINITY, INFINITY};
    float max[3] = {-INFINITY, -INFINITY, -INFINITY};
    void grow(const float* c)
    {
        for (int a = 0; a < 3; ++a) {
            min[a] = std::min(min[a], c[a]);
            max[a] = std::max(max[a], c[a]);
        }
    }
    void grow(const CentroidBox& b)
    {
        for (int a = 0; a < 3; ++a) {
            min[a] = std::min(min[a], b.min[a]);
            max[a] = std::max(max[a], b.max[a]);
        }
    }
    // Half area of the box grown by the typical triangle size (centroid boxes of
    // thin or flat parts have ~zero area, which would make SAH shave them off).
    float halfArea(const float* inflate) const
    {
        if (min[0] > max[0])
            return 0.0f;
        float ex = max[0] - min[0] + inflate[0], ey = max[1] - min[1] + inflate[1], ez = max[2] - min[2] + inflate[2];
        return ex * ey + ey * ez + ez * ex;
    }
};

constexpr uint32_t kMaxBins = 256;
constexpr uint32_t kMaterialRegion = 16; // clusters' worth of triangles below which materials are split apart

// Bin boxes as 4-lane min/max (the 4th lane holds the triangle index bits of a
// TriangleRef and is ignored), so growing a bin is two SIMD instructions.
struct Bins {
    uint32_t count[3][kMaxBins];
    __m128 min[3][kMaxBins];
    __m128 max[3][kMaxBins];
    CentroidBox box(int axis, uint32_t k) const
    {
        CentroidBox b;
        alignas(16) float lo[4], hi[4];
        _mm_store_ps(lo, min[axis][k]);
        _mm_store_ps(hi, max[axis][k]);
        for (int a = 0; a < 3; ++a) {
            b.min[a] = lo[a];
            b.max[a] = hi[a];
        }
        return b;
    }
};

struct Binner {
    float origin[3];
    float scale[3]; // bins / extent, 0 for a flat axis
    uint32_t bins;
    uint32_t bin(const float* c, int axis) const
    {
        int b = int((c[axis] - origin[axis]) * scale[axis]);
        return uint32_t(std::clamp(b, 0, int(bins) - 1));
    }
};

CentroidBox centroidBounds(const TriangleRef* refs, uint32_t n, unsigned threads)
{
    if (threads <= 1 || n < 65536) {
        CentroidBox box;
        for (uint32_t i = 0; i < n; ++i)
            box.grow(refs[i].centroid);
        return box;
    }
    std::vector<CentroidBox> parts(threads);
    parallelFor(threads, threads, [&](uint64_t t) {
        uint64_t b = n * t / threads, e = n * (t + 1) / threads;
        for (uint64_t i = b; i < e; ++i)
            parts[t].grow(refs[i].centroid);
    });
    CentroidBox box;
    for (auto& p : parts)
        box.grow(p);
    return box;
}

void binRange(const TriangleRef* refs, uint64_t b, uint64_t e, const Binner& binner, Bins& bins)
{
    const __m128 empty = _mm_set1_ps(INFINITY), emptyMax = _mm_set1_ps(-INFINITY);
    for (int a = 0; a < 3; ++a)
        for (uint32_t k = 0; k < binner.bins; ++k) {
            bins.count[a][k] = 0;
            bins.min[a][k] = empty;
            bins.max[a][k] = emptyMax;
        }
    for (uint64_t i = b; i < e; ++i) {
        const float* c = refs[i].centroid;
        const __m128 v = _mm_loadu_ps(c);
        for (int a = 0; a < 3; ++a) {
            uint32_t k = binner.bin(c, a);
            bins.count[a][k]++;
            bins.min[a][k] = _mm_min_ps(bins.min[a][k], v);
            bins.max[a][k] = _mm_max_ps(bins.max[a][k], v);
        }
    }
}

// Returns the split position (0 < mid < n) and reorders refs[0..n).
uint32_t splitRange(TriangleRef* refs, uint32_t n, uint32_t depth, uint32_t sahBins, const float* inflate,
                    unsigned threads)
{
    CentroidBox cb = centroidBounds(refs, n, threads);
    if (sahSplitAllowed(depth, n)) {
        Binner binner;
        binner.bins = sahBins;
        bool anyAxis = false;
        for (int a = 0; a < 3; ++a) {
            float extent = cb.max[a] - cb.min[a];
            binner.origin[a] = cb.min[a];
            binner.scale[a] = extent > 0.0f ? float(sahBins) / extent : 0.0f;
            anyAxis |= extent > 0.0f;
        }
        if (anyAxis) {
            // Bin (in parallel chunks for large nodes), then sweep every axis.
            Bins total;
            if (threads <= 1 || n < 65536) {
                binRange(refs, 0, n, binner, total);
            } else {
                std::vector<Bins> parts(threads);
                parallelFor(threads, threads, [&](uint64_t t) {
                    binRange(refs, n * t / threads, n * (t + 1) / threads, binner, parts[t]);
                });
                total = parts[0];
                for (unsigned t = 1; t < threads; ++t)
                    for (int a = 0; a < 3; ++a)
                        for (uint32_t k = 0; k < sahBins; ++k) {
                            total.count[a][k] += parts[t].count[a][k];
                            total.min[a][k] = _mm_min_ps(total.min[a][k], parts[t].min[a][k]);
                            total.max[a][k] = _mm_max_ps(total.max[a][k], parts[t].max[a][k]);
                        }
            }
            float bestCost = INFINITY;
            int bestAxis = -1;
            uint32_t bestBin = 0;
            for (int a = 0; a < 3; ++a) {
                if (binner.scale[a] == 0.0f)
                    continue;
                float rightArea[kMaxBins];
                uint32_t rightCount[kMaxBins];
                CentroidBox acc;
                uint32_t cnt = 0;
                for (uint32_t k = sahBins; k-- > 1;) {
                    acc.grow(total.box(a, k));
                    cnt += total.count[a][k];
                    rightArea[k] = acc.halfArea(inflate);
                    rightCount[k] = cnt;
                }
                acc = CentroidBox();
                cnt = 0;
                for (uint32_t k = 0; k + 1 < sahBins; ++k) {
                    acc.grow(total.box(a, k));
                    cnt += total.count[a][k];
                    if (cnt == 0 || rightCount[k + 1] == 0)
                        continue;
                    float cost = acc.halfArea(inflate) * float(cnt) + rightArea[k + 1] * float(rightCount[k + 1]);
                    if (cost < bestCost) {
                        bestCost = cost;
                        bestAxis = a;
                        bestBin = k;
                    }
                }
            }
            if (bestAxis >= 0) {
                TriangleRef* mid = std::partition(refs, refs + n, [&](const TriangleRef& r) {
                    return binner.bin(r.centroid, bestAxis) <= bestBin;
                });
                uint32_t m = uint32_t(mid - refs);
                if (m > 0 && m < n)
                    return m;
            }
        }
    }
    // Object median along the widest centroid axis.
    int axis = 0;
    for (int a = 1; a < 3; ++a)
        if (cb.max[a] - cb.min[a] > cb.max[axis] - cb.min[axis])
            axis = a;
    uint32_t m = n / 2;
    std::nth_element(refs, refs + m, refs + n, [axis](const TriangleRef& x, const TriangleRef& y) {
        return x.centroid[axis] < y.centroid[axis];
    });
    return m;
}

struct Builder {
    const Mesh& mesh;
    TriangleRef* refs;
    const PreprocessOptions& options;
    const float* inflate;
    const uint32_t* materials; // per input triangle; null: clusters may mix them (one material, or colours per cluster)
    // Unique-vertex counting without sorting: stamp[v] == epoch marks v as seen.
    // One array per thread, allocated once (4 bytes per mesh vertex).
    std::vector<uint32_t>& stamp = threadStamp();
    uint32_t& epoch = threadEpoch();
    static std::vector<uint32_t>& threadStamp()
    {
        thread_local std::vector<uint32_t> s;
        return s;
    }
    static uint32_t& threadEpoch()
    {
        thread_local uint32_t e = 0;
        return e;
    }

    void newEpoch()
    {
        if (stamp.size() != mesh.vertexCount()) {
            stamp.assign(mesh.vertexCount(), 0u);
            epoch = 0;
        }
        if (++epoch == 0) {
            std::fill(stamp.begin(), stamp.end(), 0u);
            epoch = 1;
        }
    }

    // Number of triangles, walking base[order[i]] (or base[i] without an order)
    // from either end, that fit a cluster; *vertexCount receives their unique vertices.
    uint32_t fittingRun(const TriangleRef* base, const uint32_t* order, uint32_t n, bool fromEnd,
                        uint32_t* vertexCount = nullptr)
    {
        newEpoch();
        const uint32_t* indices = mesh.indices.data();
        uint32_t vertices = 0, run = 0;
        for (; run < n && run < options.maxClusterTriangles; ++run) {
            uint32_t position = fromEnd ? n - 1 - run : run;
            if (order)
                position = order[position];
            const uint32_t* tri = indices + 3 * uint64_t(base[position].triangle);
            uint32_t added = (stamp[tri[0]] != epoch) + (stamp[tri[1]] != epoch) + (stamp[tri[2]] != epoch);
            if (vertices + added > options.maxClusterVertices)
                break;
            vertices += added;
            stamp[tri[0]] = stamp[tri[1]] = stamp[tri[2]] = epoch;
        }
        if (vertexCount)
            *vertexCount = vertices;
        return run;
    }

    // True when refs[begin, end) fits one cluster; then *vertexCount is its number of unique vertices.
    bool fitsCluster(uint32_t begin, uint32_t end, uint32_t* vertexCount)
    {
        uint32_t n = end - begin;
        if (n > options.maxClusterTriangles)
            return false;
        return fittingRun(refs + begin, nullptr, n, false, vertexCount) == n;
    }

    // Makes nodes[index] a cluster if it fits one (a subtree of one-material
    // clusters if it fits one but mixes materials); returns whether it did.
    bool tryCluster(TopTree& tree, uint32_t index)
    {
        const TopNode node = tree.nodes[index];
        uint32_t vertices = 0;
        if (!fitsCluster(node.begin, node.end, &vertices))
            return false;
        if (materials && mixesMaterials(node.begin, node.end) && sahSplitAllowed(node.depth, node.end - node.begin)) {
            splitByMaterial(tree, index);
            return true;
        }
        tree.nodes[index].cluster = uint32_t(tree.clusters.size());
        tree.clusters.push_back({node.begin, node.end, index, node.depth, vertices});
        return true;
    }

    // Materials are separated in regions of at most kMaterialRegion clusters' worth, so that the
    // clusters below fill up with one material (splitting only at cluster size leaves many small
    // clusters: +1.4 B/tri on a city whose 18 k parts have one of 8 materials each, against -0.4 this way).
    bool splitsByMaterial(const TopNode& node) const
    {
        const uint32_t n = node.end - node.begin;
        return materials && n <= kMaterialRegion * options.maxClusterTriangles && sahSplitAllowed(node.depth, n) &&
               mixesMaterials(node.begin, node.end);
    }

    bool mixesMaterials(uint32_t begin, uint32_t end) const
    {
        for (uint32_t i = begin + 1; i < end; ++i)
            if (materials[refs[i].triangle] != materials[refs[begin].triangle])
                return true;
        return false;
    }

    // Splits a node that fits a cluster but mixes materials: its triangles
    // ordered by material (stably, so each keeps the spatial order), cut at
    // the material boundary nearest the middle; both halves fit a cluster
    // too and are split again until each holds one material. Children are
    // built depth first, so clusters keep the file's order.
    void splitByMaterial(TopTree& tree, uint32_t index)
    {
        const uint32_t first = splitByMaterialOnce(tree, index);
        tryCluster(tree, first);
        tryCluster(tree, first + 1);
    }

    // Orders a node's triangles by material and makes the two children either side of the
    // material boundary nearest the middle; returns the first child.
    uint32_t splitByMaterialOnce(TopTree& tree, uint32_t index)
    {
        const TopNode node = tree.nodes[index];
        std::stable_sort(refs + node.begin, refs + node.end, [this](const TriangleRef& a, const TriangleRef& b) {
            return materials[a.triangle] < materials[b.triangle];
        });
        uint32_t cut = 0;
        uint64_t bestDistance = ~uint64_t(0);
        for (uint32_t i = node.begin + 1; i < node.end; ++i) {
            if (materials[refs[i].triangle] == materials[refs[i - 1].triangle])
                continue;
            uint64_t distance = uint64_t(std::abs(int64_t(2 * uint64_t(i)) - int64_t(uint64_t(node.begin) + node.end)));
            if (distance < bestDistance) {
                bestDistance = distance;
                cut = i;
            }
        }
        return addChildren(tree, index, cut);
    }

    // Appends the two children [begin, mid) and [mid, end) of nodes[index]; returns the first.
    static uint32_t addChildren(TopTree& tree, uint32_t index, uint32_t mid)
    {
        const TopNode node = tree.nodes[index];
        uint32_t first = uint32_t(tree.nodes.size());
        tree.nodes[index].child[0] = first;
        tree.nodes[index].child[1] = first + 1;
        tree.nodes[index].childCount = 2;
        tree.nodes.push_back({node.begin, mid, {0, 0}, 0, kNone, node.depth + 1});
        tree.nodes.push_back({mid, node.end, {0, 0}, 0, kNone, node.depth + 1});
        return first;
    }

    // State of one fill region (a node of <= 4 clusters' worth): the region's
    // triangles copied once (ids index `region`) and their ids sorted by centroid
    // along each axis. A split keeps every axis order sorted by a stable
    // partition, so each region is sorted once instead of once per split.
    struct FillRegion {
        std::vector<TriangleRef> region;
        std::vector<uint32_t> order[3];
        std::vector<uint8_t> left; // per id: in the left child of the current split
        std::vector<uint32_t> buffer;
    };

    // Splits a node a few clusters big so that one side is as full a cluster as
    // possible (halving would leave two half-empty clusters and duplicate the
    // vertices along the cut): along each axis in centroid order, the longest
    // fitting run from either end; the longest wins. Then builds both children
    // the same way. offset: the node's first entry in the region's orders.
    // refs[begin, end) always equals the region's triangles in the order of the
    // last split axis, so ranges stay contiguous.
    void fillNode(TopTree& tree, uint32_t index, FillRegion& fill, uint32_t offset)
    {
        if (tryCluster(tree, index))
            return;
        const TopNode node = tree.nodes[index];
        const uint32_t n = node.end - node.begin;
        uint32_t best = 0;
        int bestAxis = -1;
        bool bestFromEnd = false;
        if (sahSplitAllowed(node.depth, n))
            for (int a = 0; a < 3; ++a)
                for (bool fromEnd : {false, true}) {
                    uint32_t run = fittingRun(fill.region.data(), fill.order[a].data() + offset, n, fromEnd);
                    if (run > best && run < n) {
                        best = run;
                        bestAxis = a;
                        bestFromEnd = fromEnd;
                    }
                }
        if (bestAxis < 0) {
            // No fill split (or no depth budget for one): SAH / median on refs, then the generic build.
            const uint32_t mid = node.begin + splitRange(refs + node.begin, n, node.depth, options.sahBins, inflate, 1);
            const uint32_t first = addChildren(tree, index, mid);
            build(tree, first);
            build(tree, first + 1);
            return;
        }
        const uint32_t split = bestFromEnd ? n - best : best;
        const uint32_t* axisOrder = fill.order[bestAxis].data() + offset;
        for (uint32_t i = 0; i < n; ++i)
            fill.left[axisOrder[i]] = i < split;
        for (int a = 0; a < 3; ++a) {
            if (a == bestAxis)
                continue;
            uint32_t* order = fill.order[a].data() + offset;
            uint32_t l = 0, r = split;
            for (uint32_t i = 0; i < n; ++i)
                fill.buffer[fill.left[order[i]] ? l++ : r++] = order[i];
            std::copy(fill.buffer.begin(), fill.buffer.begin() + n, order);
        }
        for (uint32_t i = 0; i < n; ++i)
            refs[node.begin + i] = fill.region[axisOrder[i]];
        const uint32_t first = addChildren(tree, index, node.begin + split);
        fillNode(tree, first, fill, offset);
        fillNode(tree, first + 1, fill, offset + split);
    }

    void buildFillRegion(TopTree& tree, uint32_t index)
    {
        const TopNode node = tree.nodes[index];
        const uint32_t n = node.end - node.begin;
        FillRegion fill;
        fill.region.assign(refs + node.begin, refs + node.end);
        fill.left.resize(n);
        fill.buffer.resize(n);
        std::vector<uint64_t> keys(n);
        for (int a = 0; a < 3; ++a) {
            // Sort keys: the centroid coordinate as an order-preserving integer, then the id.
            for (uint32_t i = 0; i < n; ++i) {
                uint32_t bits;
                std::memcpy(&bits, &fill.region[i].centroid[a], 4);
                bits ^= (bits & 0x80000000u) ? 0xFFFFFFFFu : 0x80000000u;
                keys[i] = uint64_t(bits) << 32 | i;
            }
            std::sort(keys.begin(), keys.end());
            fill.order[a].resize(n);
            for (uint32_t i = 0; i < n; ++i)
                fill.order[a][i] = uint32_t(keys[i]);
        }
        fillNode(tree, index, fill, 0);
    }

    // Builds below nodes[root] (already holding begin/end/depth) into tree,
    // depth first (clusters are appended in depth-first, first-child-first order).
    void build(TopTree& tree, uint32_t root)
    {
        std::vector<uint32_t> stack{root};
        while (!stack.empty()) {
            uint32_t index = stack.back();
            stack.pop_back();
            const TopNode node = tree.nodes[index];
            const uint32_t n = node.end - node.begin;
            if (splitsByMaterial(node)) {
                const uint32_t first = splitByMaterialOnce(tree, index);
                stack.push_back(first + 1);
                stack.push_back(first);
                continue;
            }
            if (n <= 4 * options.maxClusterTriangles && sahSplitAllowed(node.depth, n)) {
                buildFillRegion(tree, index);
                continue;
            }
            if (tryCluster(tree, index))
                continue;
            const uint32_t mid = node.begin + splitRange(refs + node.begin, n, node.depth, options.sahBins, inflate, 1);
            const uint32_t first = addChildren(tree, index, mid);
            stack.push_back(first + 1);
            stack.push_back(first);
        }
    }
};

} // namespace

TopTree buildTopTree(const Mesh& mesh, std::vector<TriangleRef>& refs, const glm::vec3& meanExtent,
                     const PreprocessOptions& options, unsigned threads, const std::function<void(double)>& progress,
                     const uint32_t* materials, uint32_t rootDepth)
{
    // Centroids are stored as vertex sums (3x), so the triangle size is scaled likewise.
    const float inflate[3] = {3.0f * meanExtent.x, 3.0f * meanExtent.y, 3.0f * meanExtent.z};
    const uint32_t total = uint32_t(refs.size());
    TopTree tree;
    tree.nodes.push_back({0, total, {0, 0}, 0, kNone, rootDepth});

    // Split big nodes here (parallel binning) until the pieces make enough tasks.
    const uint32_t taskSize = std::max<uint32_t>(
        std::max<uint32_t>(4096, options.maxClusterTriangles), threads > 1 ? total / (threads * 16) : total);
    std::vector<uint32_t> pending{0}, tasks;
    while (!pending.empty()) {
        uint32_t index = pending.back();
        pending.pop_back();
        TopNode node = tree.nodes[index];
        // A node that the builder would split by material is a task too (thread-count independence).
        if (node.end - node.begin <= taskSize || Builder{mesh, refs.data(), options, inflate, materials}.splitsByMaterial(node)) {
            tasks.push_back(index);
            continue;
        }
        uint32_t mid = node.begin + splitRange(refs.data() + node.begin, node.end - node.begin, node.depth,
                                               options.sahBins, inflate, threads);
        uint32_t first = uint32_t(tree.nodes.size());
        tree.nodes[index].child[0] = first;
        tree.nodes[index].child[1] = first + 1;
        tree.nodes[index].childCount = 2;
        tree.nodes.push_back({node.begin, mid, {0, 0}, 0, kNone, node.depth + 1});
        tree.nodes.push_back({mid, node.end, {0, 0}, 0, kNone, node.depth + 1});
        pending.push_back(first + 1);
        pending.push_back(first);
    }

    // Subtrees in parallel, biggest first, each into its own tree (root = local node 0).
    std::vector<uint32_t> order(tasks.size());
    for (uint32_t i = 0; i < order.size(); ++i)
        order[i] = i;
    std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
        const TopNode &x = tree.nodes[tasks[a]], &y = tree.nodes[tasks[b]];
        return x.end - x.begin > y.end - y.begin;
    });
    std::vector<TopTree> subtrees(tasks.size());
    std::atomic<uint64_t> trianglesDone{0};
    parallelFor(
        threads, tasks.size(),
        [&](uint64_t k) {
            uint32_t t = order[k];
            Builder builder{mesh, refs.data(), options, inflate, materials};
            subtrees[t].nodes.push_back(tree.nodes[tasks[t]]);
            builder.build(subtrees[t], 0);
            trianglesDone += tree.nodes[tasks[t]].end - tree.nodes[tasks[t]].begin;
        },
        [&](uint64_t) {
            if (progress)
                progress(double(trianglesDone.load()) / double(std::max<uint32_t>(total, 1)));
        });

    // Worker threads' stamp arrays died with them; release the caller's.
    std::vector<uint32_t>().swap(Builder::threadStamp());

    // Merge in task order: local node 0 is the pending node, local i > 0 is appended.
    for (size_t t = 0; t < tasks.size(); ++t) {
        TopTree& sub = subtrees[t];
        const uint32_t base = uint32_t(tree.nodes.size()) - 1;
        const uint32_t clusterBase = uint32_t(tree.clusters.size());
        auto map = [&](uint32_t local) { return local == 0 ? tasks[t] : base + local; };
        for (uint32_t i = 0; i < sub.nodes.size(); ++i) {
            TopNode node = sub.nodes[i];
            for (uint32_t c = 0; c < node.childCount; ++c)
                node.child[c] = map(node.child[c]);
            if (node.cluster != kNone)
                node.cluster += clusterBase;
            if (i == 0)
                tree.nodes[tasks[t]] = node;
            else
                tree.nodes.push_back(node);
        }
        for (ClusterRange range : sub.clusters) {
            range.node = map(range.node);
            tree.clusters.push_back(range);
        }
        sub = TopTree();
    }
    return tree;
}

} // namespace penumbra::preprocess_detail
