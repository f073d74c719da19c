// One cluster of the ReduceM-like representation (Lauterbach et al. 2009,
// section 5.1) and the lower levels of the shared BVH inside it: local vertex
// remap (<= 255 vertices, 8-bit indices), 16-bit quantization (quantize.cpp),
// then a full-sweep SAH tree over the triangles' DECODED boxes down to leaves of
// <= maxLeafTriangles, each leaf one contiguous strip range (strips.cpp); leaves
// are concatenated with one restart between them. Node boxes are the exact
// bounds of the decoded vertices, so the ray tracer's boxes contain what it
// intersects.
#include <algorithm>
#include <cmath>
#include <numeric>

#include "penumbra/error.h"
#include "preprocess_internal.h"

namespace penumbra::preprocess_detail {

namespace {

struct ClusterTreeBuilder {
    const PreprocessOptions& options;
    const uint32_t* local;          // 3 local indices per cluster triangle
    const uint32_t* tris;           // input triangle per cluster triangle
    uint32_t vertexCount;
    bool wantSource;
    std::vector<Box> boxes;         // decoded box per triangle
    std::vector<glm::vec3> centers; // box centers
    std::vector<uint32_t> order;
    std::vector<uint32_t> leafIndices, leafSource;
    BuiltCluster& out;

    Box rangeBox(uint32_t begin, uint32_t end) const
    {
        Box b;
        for (uint32_t i = begin; i < end; ++i)
            b.grow(boxes[order[i]]);
        return b;
    }

    // Median split along the widest centroid axis.
    uint32_t medianSplit(uint32_t begin, uint32_t end, const Box& centroids)
    {
        glm::vec3 e = centroids.max - centroids.min;
        int axis = e.x >= e.y && e.x >= e.z ? 0 : (e.y >= e.z ? 1 : 2);
        uint32_t mid = begin + (end - begin) / 2;
        std::nth_element(order.begin() + begin, order.begin() + mid, order.begin() + end, [&](uint32_t a, uint32_t b) {
            return centers[a][axis] < centers[b][axis] || (centers[a][axis] == centers[b][axis] && a < b);
        });
        return mid;
    }

    // Binned SAH over the triangles' decoded boxes; the cost counts leaves (what
    // strips and nodes cost) with a small per-triangle term. Returns the split position.
    uint32_t split(uint32_t begin, uint32_t end, uint32_t depth)
    {
        constexpr uint32_t kBins = 16;
        const uint32_t n = end - begin;
        Box centroids;
        for (uint32_t i = begin; i < end; ++i)
            centroids.grow(centers[order[i]]);
        if (!sahSplitAllowed(depth, n))
            return medianSplit(begin, end, centroids);
        const float leaf = float(options.maxLeafTriangles);
        auto leafCost = [&](uint32_t count) { return std::ceil(float(count) / leaf) + 0.01f * float(count); };
        float bestCost = INFINITY;
        int bestAxis = -1;
        uint32_t bestBin = 0;
        float scale[3];
        for (int axis = 0; axis < 3; ++axis) {
            float extent = centroids.max[axis] - centroids.min[axis];
            scale[axis] = extent > 0.0f ? float(kBins) / extent : 0.0f;
            if (scale[axis] == 0.0f)
                continue;
            Box bins[kBins];
            uint32_t counts[kBins] = {};
            for (uint32_t i = begin; i < end; ++i) {
                uint32_t t = order[i];
                uint32_t b = std::min(kBins - 1, uint32_t((centers[t][axis] - centroids.min[axis]) * scale[axis]));
                bins[b].grow(boxes[t]);
                counts[b]++;
            }
            float rightArea[kBins];
            uint32_t rightCount[kBins];
            Box acc;
            uint32_t cnt = 0;
            for (uint32_t b = kBins; b-- > 1;) {
                acc.grow(bins[b]);
                cnt += counts[b];
                rightArea[b] = acc.halfArea();
                rightCount[b] = cnt;
            }
            acc = Box();
            cnt = 0;
            for (uint32_t b = 0; b + 1 < kBins; ++b) {
                acc.grow(bins[b]);
                cnt += counts[b];
                if (cnt == 0 || rightCount[b + 1] == 0)
                    continue;
                float cost = acc.halfArea() * leafCost(cnt) + rightArea[b + 1] * leafCost(rightCount[b + 1]);
                if (cost < bestCost) {
                    bestCost = cost;
                    bestAxis = axis;
                    bestBin = b;
                }
            }
        }
        if (bestAxis < 0)
            return medianSplit(begin, end, centroids);
        auto mid = std::partition(order.begin() + begin, order.begin() + end, [&](uint32_t t) {
            return std::min(kBins - 1, uint32_t((centers[t][bestAxis] - centroids.min[bestAxis]) * scale[bestAxis])) <=
                   bestBin;
        });
        return uint32_t(mid - order.begin());
    }

    void emitLeaf(LocalNode& node, uint32_t begin, uint32_t end)
    {
        leafIndices.clear();
        leafSource.clear();
        for (uint32_t i = begin; i < end; ++i) {
            uint32_t t = order[i];
            leafIndices.insert(leafIndices.end(), local + 3 * t, local + 3 * t + 3);
            leafSource.push_back(tris[t]);
        }
        if (!out.bytes.empty())
            out.bytes.push_back(model::kStripRestart);
        node.leafStart = uint32_t(out.bytes.size());
        bool ok = appendLeafStrips(leafIndices.data(), end - begin, vertexCount, out.bytes, leafSource.data(),
                                   wantSource ? &out.source : nullptr);
        node.leafBytes = uint32_t(out.bytes.size()) - node.leafStart;
        out.leaves++;
        out.fallbackLeaves += ok ? 0 : 1;
    }

    void build(uint32_t nodeIndex, uint32_t begin, uint32_t end, uint32_t depth)
    {
        out.nodes[nodeIndex].box = rangeBox(begin, end);
        if (end - begin <= options.maxLeafTriangles) {
            LocalNode node = out.nodes[nodeIndex];
            emitLeaf(node, begin, end);
            out.nodes[nodeIndex] = node;
            return;
        }
        uint32_t mid = split(begin, end, depth);
        uint32_t first = uint32_t(out.nodes.size());
        out.nodes[nodeIndex].first = first;
        out.nodes[nodeIndex].childCount = 2;
        out.nodes.resize(first + 2);
        build(first, begin, mid, depth + 1);
        build(first + 1, mid, end, depth + 1);
    }
};

} // namespace

void buildCluster(const Mesh& mesh, const uint32_t* tris, uint32_t count, uint32_t expectedVertices, uint32_t depth,
                  const PreprocessOptions& options, bool wantSource, model::QuantizedVertex* vertexOut,
                  BuiltCluster& out)
{
    // Local vertex remap in order of first use (good for the vertex cache of the
    // strips): an open-addressing table of input index -> local index, at most
    // a quarter full (kMaxClusterVertices = 255).
    constexpr uint32_t kSlotBits = 10, kSlots = 1u << kSlotBits;
    static_assert(kSlots >= 4 * model::kMaxClusterVertices);
    thread_local std::vector<uint32_t> vertices, local, slotKey(kSlots), slotValue(kSlots);
    std::fill(slotKey.begin(), slotKey.end(), kNone); // input indices are < vertexCount <= 2^32-1
    vertices.clear();
    local.resize(size_t(count) * 3);
    for (uint32_t t = 0; t < count; ++t)
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = mesh.indices[3 * uint64_t(tris[t]) + k];
            uint32_t slot = (v * 2654435761u) >> (32 - kSlotBits);
            while (slotKey[slot] != v && slotKey[slot] != kNone)
                slot = (slot + 1) & (kSlots - 1);
            if (slotKey[slot] == kNone) {
                if (vertices.size() >= expectedVertices)
                    fail("preprocess", "internal error: cluster has more vertices than the tree stage counted");
                slotKey[slot] = v;
                slotValue[slot] = uint32_t(vertices.size());
                vertices.push_back(v);
            }
            local[3 * t + k] = slotValue[slot];
        }
    const uint32_t vertexCount = uint32_t(vertices.size());
    if (vertexCount != expectedVertices)
        fail("preprocess", "internal error: cluster vertex count differs from the tree stage's count");

    // Quantization.
    thread_local std::vector<glm::vec3> decoded;
    decoded.resize(vertexCount);
    quantizeCluster(mesh, vertices.data(), vertexCount, out.record, vertexOut, decoded.data(),
                    out.inputBox, out.maxError);
    out.record.vertexCount = uint16_t(vertexCount);
    out.record.triangleCount = uint16_t(count);

    // Local tree and strips.
    ClusterTreeBuilder builder{options, local.data(), tris, vertexCount, wantSource, {}, {}, {}, {}, {}, out};
    builder.boxes.resize(count);
    builder.centers.resize(count);
    builder.order.resize(count);
    for (uint32_t t = 0; t < count; ++t) {
        Box b;
        for (int k = 0; k < 3; ++k)
            b.grow(decoded[local[3 * t + k]]);
        builder.boxes[t] = b;
        builder.centers[t] = (b.min + b.max) * 0.5f;
        builder.order[t] = t;
    }
    out.nodes.clear();
    out.nodes.resize(1);
    out.bytes.clear();
    out.bytes.reserve(size_t(count) * 2);
    builder.build(0, 0, count, depth);
    out.record.indexBytes = uint32_t(out.bytes.size());
}

} // namespace penumbra::preprocess_detail
