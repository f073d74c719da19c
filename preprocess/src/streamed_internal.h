// Shared pieces of the streamed build (streamed.cpp, merge.cpp). Not installed.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "penumbra/chunk_file.h"
#include "penumbra/streamed.h"
#include "preprocess_internal.h"

namespace penumbra::streamed_detail {

using preprocess_detail::Box;

// A cell of the spatial partition: triangles whose centroid c has lo <= c < hi
// on every axis (bounds may be infinite).
struct Cell {
    float lo[3] = {-INFINITY, -INFINITY, -INFINITY};
    float hi[3] = {INFINITY, INFINITY, INFINITY};
    // The box strictly inside the open cell (touching a face does not count).
    bool strictlyInside(const float* min, const float* max) const
    {
        for (int a = 0; a < 3; ++a)
            if (!(min[a] > lo[a] && max[a] < hi[a]))
                return false;
        return true;
    }
    // The box meets the closed cell.
    bool overlaps(const float* min, const float* max) const
    {
        for (int a = 0; a < 3; ++a)
            if (max[a] < lo[a] || min[a] > hi[a])
                return false;
        return true;
    }
};

// A k-d partition into leaves (chunks) numbered in depth-first order.
struct Plan {
    struct Node {
        int axis = -1;       // -1: a leaf
        float split = 0;     // left: < split
        uint32_t child[2] = {0, 0};
        uint32_t leaf = 0;   // leaf number
    };
    std::vector<Node> nodes; // node 0: the root
    std::vector<Cell> cells; // per leaf
    uint32_t leaves() const { return uint32_t(cells.size()); }
    uint32_t locate(const float* p) const
    {
        uint32_t n = 0;
        while (nodes[n].axis >= 0)
            n = nodes[n].child[p[nodes[n].axis] < nodes[n].split ? 0 : 1];
        return nodes[n].leaf;
    }
    // Leaves whose closed cell the box meets.
    template <typename Fn> void overlapping(const float* min, const float* max, Fn&& fn) const
    {
        uint32_t stack[128];
        size_t top = 0;
        stack[top++] = 0;
        while (top > 0) {
            const Node& node = nodes[stack[--top]];
            if (node.axis < 0) {
                fn(node.leaf);
                continue;
            }
            if (min[node.axis] <= node.split && top < 128)
                stack[top++] = node.child[0];
            if (max[node.axis] >= node.split && top < 128)
                stack[top++] = node.child[1];
        }
    }
    uint64_t hash() const;
};

// Splits points (3 floats each; reordered) into at most `count` leaves of about
// equal numbers of points within `cell`: at each node the widest axis of the
// points, cut at the quantile floor(k/2)/k (the left part gets floor(k/2)
// leaves). Points that cannot be told apart make fewer leaves.
Plan makePlan(std::vector<float>& points, uint32_t count, const Cell& cell);

using preprocess_detail::subtreeRootDepth;

// The merge (merge.cpp): chunk files -> a .penumbra file, or (intoChunk set) a
// chunk file whose model's root sits at intoChunk->rootDepth (a chunk too large
// for memory, built in parts). Chunks may be given in any order.
struct MergeResult {
    uint64_t triangles = 0, clusters = 0, nodes = 0, fileBytes = 0;
    uint32_t bvhDepth = 0;
    float maxPositionError = 0;
    uint64_t closedTriangles = 0, closedClusterTriangles = 0, closedClusters = 0;
};
MergeResult mergeChunks(const std::vector<std::string>& chunks, const std::string& output, const chunk::ChunkHeader* intoChunk,
                        const std::function<void(double)>& progress);

} // namespace penumbra::streamed_detail
