// Shared pieces of the preprocessor (preprocess.cpp, cluster_bvh.cpp,
// cluster_tree.cpp, quantize.cpp, strips.cpp, node_layout.cpp). Not installed.
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <vector>

#include <glm/common.hpp>
#include <glm/vec3.hpp>

#include "penumbra/parallel.h"
#include "penumbra/preprocess.h"

namespace penumbra::preprocess_detail {

// Axis-aligned box; empty when min > max.
struct Box {
    glm::vec3 min{std::numeric_limits<float>::max()};
    glm::vec3 max{-std::numeric_limits<float>::max()};
    void grow(const glm::vec3& p)
    {
        min = glm::min(min, p);
        max = glm::max(max, p);
    }
    void grow(const Box& b)
    {
        min = glm::min(min, b.min);
        max = glm::max(max, b.max);
    }
    bool empty() const { return min.x > max.x; }
    float halfArea() const
    {
        if (empty())
            return 0.0f;
        glm::vec3 e = max - min;
        return e.x * e.y + e.y * e.z + e.z * e.x;
    }
};

// ceil(log2(n)) for n >= 1.
inline uint32_t ceilLog2(uint64_t n)
{
    uint32_t r = 0;
    while ((uint64_t(1) << r) < n)
        ++r;
    return r;
}

// Levels of the binary trees the nodes are collapsed from: 4-wide nodes that
// take two binary levels each (layoutNodes' fallback) stay within
// kMaxBvhDepth, counting a level lost at each side of a cluster's root.
inline constexpr uint32_t kMaxBinaryDepth = 2 * model::kMaxBvhDepth - 8;

// True when a node at `depth` (root = 1) holding n triangles may take an
// unbalanced (SAH) split and still finish within kMaxBinaryDepth: after it, object
// median splits need ceil(log2(n)) more levels plus the Cluster->Leaf level.
inline bool sahSplitAllowed(uint32_t depth, uint64_t n)
{
    return depth + ceilLog2(n) + 2 <= kMaxBinaryDepth;
}

// ---- top-level tree (cluster_bvh.cpp) ------------------------------------------

struct TriangleRef {
    float centroid[3]; // sum of the three vertices (3x the centroid)
    uint32_t triangle; // input triangle index
};
static_assert(sizeof(TriangleRef) == 16);

struct TopNode {
    uint32_t begin, end;   // triangle range in the reference array
    uint32_t child[2];     // node indices (larger than this node's)
    uint32_t childCount;   // 0 for a cluster
    uint32_t cluster;      // cluster index, or kNone
    uint32_t depth;        // root = 1
};

struct ClusterRange {
    uint32_t begin, end; // triangle range in the reference array
    uint32_t node;       // TopNode
    uint32_t depth;      // depth of the Cluster node
    uint32_t vertices;   // unique vertices of its triangles
};

inline constexpr uint32_t kNone = 0xFFFFFFFFu;

struct TopTree {
    std::vector<TopNode> nodes; // node 0 is the root
    std::vector<ClusterRange> clusters; // in depth-first, first-child-first order (the order of the file)
};

// Top-down binned SAH over centroids until a node has <= maxClusterTriangles
// triangles using <= maxClusterVertices vertices. Reorders refs. Clusters come
// out in the depth-first order in which layoutNodes numbers them.
// meanExtent: the average triangle bounding-box extent per axis.
// materials (per input triangle, or null): a node that fits a cluster but
// mixes materials is split by material until every cluster has one (unless
// the depth budget forbids it: then the cluster takes its first triangle's).
// rootDepth: the binary depth of the tree's root (root = 1; a chunk of a streamed
// build hangs below the chunks' top nodes: BuildExtras), so that the depth budget
// (kMaxBinaryDepth) holds for the whole.
TopTree buildTopTree(const Mesh& mesh, std::vector<TriangleRef>& refs, const glm::vec3& meanExtent,
                     const PreprocessOptions& options, unsigned threads, const std::function<void(double)>& progress,
                     const uint32_t* materials = nullptr, uint32_t rootDepth = 1);

// At most this many materials are kept apart by the clusters; with more (or
// with vertex colours) each cluster gets the mean colour of its triangles.
inline constexpr size_t kMaxSplitMaterials = 4096;

// ---- one cluster (cluster_tree.cpp, quantize.cpp, strips.cpp) ------------------

struct LocalNode {
    Box box;             // exact bounds of the decoded vertices below
    uint32_t first = 0;  // first child (local index) when not a leaf
    uint32_t childCount = 0;
    uint32_t leafStart = 0, leafBytes = 0; // leaf: strip bytes relative to the cluster
};

struct BuiltCluster {
    model::ClusterRecord record{}; // boxMin, step, counts (firstVertex/firstIndex/node set by the driver)
    std::vector<uint8_t> bytes;
    std::vector<LocalNode> nodes; // local tree; node 0 = the cluster's root (a leaf if it has childCount 0)
    std::vector<uint32_t> source; // input triangle per decoded triangle (only when requested)
    Box inputBox;                 // bounds of the input positions
    float maxError = 0;
    uint32_t leaves = 0, fallbackLeaves = 0;
};

// Builds one cluster from input triangles tris[0..count) whose Cluster node is
// at `depth`, using exactly vertexCount unique vertices (ClusterRange::vertices):
// its quantized vertices go to vertexOut[0..vertexCount), straight into the
// model's vertex section.
void buildCluster(const Mesh& mesh, const uint32_t* tris, uint32_t count, uint32_t vertexCount, uint32_t depth,
                  const PreprocessOptions& options, bool wantSource, model::QuantizedVertex* vertexOut,
                  BuiltCluster& out);

// Quantizes vertices (input indices) to 16 bits within their bounds; fills
// record.boxMin/step, out[count], decoded[count] (decodePosition of each),
// the input box and the largest per-coordinate error.
void quantizeCluster(const Mesh& mesh, const uint32_t* vertices, uint32_t count, model::ClusterRecord& record,
                     model::QuantizedVertex* out, glm::vec3* decoded, Box& inputBox, float& maxError);

// Appends the strip bytes of `count` triangles (local indices, 3 per triangle)
// to out: meshoptimizer vertex-cache order and stripification with restarts,
// verified to decode to exactly these triangles (else one 3-index strip per
// triangle). No leading or trailing restart. If source is not null, appends to
// sourceOut the entry of source[] for every decoded triangle in decode order.
// Returns false when the fallback was used.
bool appendLeafStrips(const uint32_t* localIndices, uint32_t count, uint32_t vertexCount, std::vector<uint8_t>& out,
                      const uint32_t* source, std::vector<uint32_t>* sourceOut);

// ---- closed components (closed.cpp) ------------------------------------------------

// Per triangle of mesh: 1 when it belongs to a closed, consistently oriented
// 2-manifold (model::kClusterClosed): vertices welded by exact position,
// components connected through edges, every edge of the component used by
// exactly two of its triangles in opposite directions, no triangle with two
// corners at one position. Triangles with a repeated vertex index are ignored
// (not stored) and get 0. openSeed (optional, one per triangle): a nonzero entry
// makes that triangle's whole component open (streaming builds: a triangle that
// a chunk boundary cuts, or a neighbour from another chunk). Indices must be in range.
std::vector<uint8_t> closedTriangles(const Mesh& mesh, unsigned threads, const uint8_t* openSeed = nullptr);

// The same test, per triangle its closed component's id (below
// mesh.triangleCount(): one of its triangles' indices), or kOpenComponent.
inline constexpr uint32_t kOpenComponent = 0xFFFFFFFFu;
std::vector<uint32_t> closedComponents(const Mesh& mesh, unsigned threads, const uint8_t* openSeed = nullptr);

// The clearance a closed component needs to be flagged: an upper bound of the
// runtime's default shadow-ray offset (shadowRayOffset, runtime/src/api.cpp:
// max(1e-5 x |box extent|, 4 x header.maxPositionError)) for a model whose
// vertices lie in this box, known before any cluster is quantized: half a
// 16-bit step of the box's widest axis bounds every cluster's error. The same
// box (the input's vertices) gives the same bound to in-core, streamed and
// chunk builds.
double closedClearance(const float* boundsMin, const float* boundsMax);

// The box of all of mesh's vertices (referenced or not, as a streamed build's
// scan sees them); an empty mesh gives zeros.
void meshBounds(const Mesh& mesh, float* boundsMin, float* boundsMax);

// Per closed component id (component[t], closedComponents' ids; the result has
// one entry per triangle of mesh): 1 when a triangle of another component or
// an open triangle of mesh comes closer than `distance` to one of its
// triangles (exact triangle-triangle distance, double precision), or, with a
// chunk's cell (cellMin/cellMax, infinite faces allowed; else nullptr), when
// one of its triangles comes within `distance` of a cell face: a neighbour
// there may be another chunk's and not in the halo. A shadow ray starts
// `distance` off its receiver along the normal, so it can start inside a
// closed solid only where that solid comes that close to another surface;
// such a solid must not be flagged (casting back faces only, a ray from inside
// it would see no caster). Same-component triangles are not tested against
// each other (a solid's own folds closer than `distance` are not caught).
// A binary BVH over the triangles' boxes whose nodes name the one component
// under them (a query skips its own solid); only triangles of closed
// components not yet crowded query (the distance is symmetric), in parallel.
// Memory: 12 B per triangle (box centres, freed after the build) plus about
// 18 B per triangle of nodes and order, below the tree stage's peak.
std::vector<uint8_t> crowdedComponents(const Mesh& mesh, const uint32_t* component, double distance, const float* cellMin,
                                       const float* cellMax, unsigned threads);

// model::kClusterClosed per cluster (`clusters`: ranges of `triangles`, which
// index `component`, closedComponents' ids below componentLimit): a cluster is
// flagged when all its triangles are closed and every component of them lies
// wholly in flagged clusters. So a closed component is flagged everywhere or
// nowhere: the runtime may treat "flagged" as "this whole solid is closed"
// (afsm draws no flagged triangle seen from behind, and casts only the
// light-back-facing ones); a component split between a flagged cluster and
// one mixed with open triangles would be neither.
std::vector<uint8_t> closedClusterFlags(const uint32_t* component, const uint32_t* triangles, const ClusterRange* clusters,
                                        size_t clusterCount, uint64_t componentLimit, unsigned threads);

// ---- node array (node_layout.cpp) ------------------------------------------------

struct Layout {
    std::vector<model::Node> nodes;
    std::vector<uint32_t> clusterOrder; // final cluster index -> built cluster index
    std::vector<uint32_t> clusterNode;  // final cluster index -> its root node
    uint32_t depth = 0;
    uint64_t widened = 0;
    uint64_t leaves = 0;
    std::vector<uint32_t> subtreeNode, subtreeDepth; // layoutSubtrees: per subtree, its root's node and depth
};

// Collapses the binary trees into the 4-wide node array (node 0 the root,
// children after their node, depth first) and encodes every child box in 8
// bits on its node's grid, verified to contain the exact box. topBoxes:
// exact box per TopNode. The root's own box is the header's (not stored).
// maxDepth: the levels the layout may use (kMaxBvhDepth, less the levels
// above a chunk's root in a streamed build): the area-first collapse, or
// where it is deeper, the level-by-level one.
Layout layoutNodes(const TopTree& tree, const std::vector<Box>& topBoxes, const std::vector<BuiltCluster>& clusters,
                   uint32_t maxDepth = model::kMaxBvhDepth);

// The merge of a streamed build: a binary tree whose leaves (TopNode::cluster
// = subtree index, 0..k-1) are the roots of subtrees laid out already (the
// chunks' node arrays), collapsed level by level like layoutNodes' fallback.
// Returns the nodes above the subtrees, with one placeholder node per subtree
// root (Layout::subtreeNode, at Layout::subtreeDepth, root = 1) for the caller
// to fill; the subtree roots are Interior children. A leaf at binary level l
// (root 0) gets depth ceil(l / 2) + 1 (subtreeRootDepth). Needs >= 2 leaves.
Layout layoutSubtrees(const TopTree& tree, const std::vector<Box>& topBoxes);

// The depth (root = 1) of the subtree roots under layoutSubtrees over a
// balanced binary tree of n leaves: ceil(ceil(log2 n) / 2) + 1.
inline uint32_t subtreeRootDepth(uint64_t n)
{
    return (ceilLog2(std::max<uint64_t>(n, 1)) + 1) / 2 + 1;
}

// What a streamed build adds to buildCompressedModel (buildModel).
struct BuildExtras {
    // Depth (root = 1) of the model's root node in the final 4-wide BVH: the
    // binary build starts at binary depth 2 x (rootDepth - 1) + 1 and the
    // layout keeps kMaxBvhDepth - (rootDepth - 1) levels; header.bvhDepth
    // counts from the model's root.
    uint32_t rootDepth = 1;
    const uint32_t* component = nullptr; // per input triangle: closedComponents computed outside (streaming: with neighbours and seeds)
    const uint8_t* crowded = nullptr;    // with component: crowdedComponents computed outside (streaming: halo and cell)
};
CompressedModel buildModel(const Mesh& mesh, const PreprocessOptions& options, PreprocessStats* stats,
                           std::vector<uint32_t>* decodedTriangleSource, const BuildExtras& extras);

} // namespace penumbra::preprocess_detail
