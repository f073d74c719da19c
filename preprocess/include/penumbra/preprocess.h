// The preprocessor: turns an indexed triangle mesh into the .penumbra model
// (model_format.h): 8-bit strip clusters with 16-bit quantized vertices and ONE
// BVH whose upper levels cull clusters and whose lower levels (inside each
// cluster, down to strip-range leaves) are traversed by the ray tracer
// (Lauterbach et al. 2009, section 5.1). Algorithm and measured numbers:
// preprocess/README.md. No Vulkan.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "penumbra/mesh.h"
#include "penumbra/model_format.h"

namespace penumbra {

struct PreprocessOptions {
    uint32_t maxClusterVertices = 255;  // unique vertices per cluster, 3..model::kMaxClusterVertices
    uint32_t maxClusterTriangles = 512; // triangles per cluster, 1..model::kMaxClusterTriangles
    uint32_t maxLeafTriangles = 18;     // triangles per strip-range leaf inside a cluster (1..maxClusterTriangles); 18 keeps the
                                        // bench scenes within 8 (scan) and 10 (plant) bytes per triangle with 4-wide nodes
    uint32_t sahBins = 16;              // bins of the top-level binned SAH build, 2..256
    unsigned threads = 0;               // worker threads including the caller; 0 = hardware concurrency
    // Clusters do not mix triangles of closed components clear of other surfaces (those
    // that can be flagged) with the rest (as they do not mix materials), so that those
    // parts get model::kClusterClosed; false: purely spatial.
    bool separateClosed = false;
    // Optional. Called on the calling thread only, at most every ~0.5% of a stage,
    // with the stage name ("filter", "tree", "clusters", "layout") and its fraction done.
    std::function<void(const char* stage, double fraction)> progress;
};

// Counters and timings of one build.
struct PreprocessStats {
    double filterSeconds = 0;   // index validation, degenerate removal, centroids
    double treeSeconds = 0;     // top-level binned SAH down to clusters
    double clusterSeconds = 0;  // per cluster: remap, quantization, local tree, strips
    double layoutSeconds = 0;   // node array with 8-bit bounds, section concatenation
    double totalSeconds = 0;
    uint64_t inputTriangles = 0;
    uint64_t droppedDegenerate = 0; // triangles with a repeated vertex index
    uint64_t triangles = 0;         // stored
    uint64_t clusters = 0;
    uint64_t nodes = 0;
    uint64_t leaves = 0;
    uint64_t vertices = 0;
    uint64_t indexBytes = 0;
    uint64_t stripFallbackLeaves = 0; // leaves whose meshoptimizer strip did not reproduce the triangles (stored as 3+restart)
    uint64_t widenedBounds = 0;       // node coordinates widened by one step after the containment check
    uint32_t bvhDepth = 0;
    float maxPositionError = 0;       // model units
    uint32_t materials = 0;           // entries of the material table
    uint64_t mixedMaterialTriangles = 0; // triangles whose cluster has another material (depth budget; normally 0)
    double bytesPerTriangle = 0;      // (clusters + nodes + vertices + indices + materials) / triangles
    double closedSeconds = 0;         // the closed-component test (part of filterSeconds)
    uint64_t closedTriangles = 0;     // stored triangles of closed components (model::kClusterClosed)
    uint64_t closedClusterTriangles = 0; // triangles of clusters flagged kClusterClosed
    uint64_t closedClusters = 0;      // clusters flagged kClusterClosed
};

// Builds the compressed model. Throws Error("preprocess: <problem>") for bad
// options, an index out of range, a non-finite position, more than 2^32-1
// triangles, or a mesh with no non-degenerate triangle. Triangles with a
// repeated vertex index are dropped (counted in stats); triangles whose
// distinct vertices coincide in space are kept. The result does not depend on
// the thread count. Colours (Mesh::materials, triangleMaterials, colors):
// with at most 4096 materials and no vertex colours, clusters do not mix
// materials and each names its own in the material table (a copy of
// mesh.materials); otherwise each cluster gets the mean albedo of its
// triangles (mesh.triangleColor) as its own table entry, equal ones shared.
// Without colours the table is one white material. The header's magic, version, fileSize, sections and
// checksums are left for writeModelFile.
// decodedTriangleSource (tests): if not null, receives for every stored
// triangle, in decode order (clusters in order, forEachStripTriangle over each
// cluster's bytes), the index of the input triangle it came from.
CompressedModel buildCompressedModel(const Mesh& mesh, const PreprocessOptions& options,
                                     PreprocessStats* stats = nullptr,
                                     std::vector<uint32_t>* decodedTriangleSource = nullptr);

// The test behind model::kClusterClosed, per triangle of mesh: 1 when the
// triangle belongs to a closed, consistently oriented 2-manifold connected
// component (vertices welded by exact position, components connected through
// edges, every edge of the component used by exactly two of its triangles in
// opposite directions, no triangle with two corners at one position, positive
// enclosed volume), else 0. Triangles with a repeated vertex index get 0 (they
// are not stored). A cluster is flagged closed when all its triangles are, each
// of their components lies wholly in flagged clusters, and no other surface
// (another component or an open triangle) comes within the default shadow-ray
// offset of those components (the clearance rule, preprocess/README.md): this
// function is the topological test only. Throws Error("preprocess: ...") for
// an index out of range. threads: 0 = all cores.
std::vector<uint8_t> findClosedTriangles(const Mesh& mesh, unsigned threads = 0);

// The format's size limits (model::kMaxNodes, kMaxClusters: 32-bit node and
// cluster indices) against a model of `triangles` triangles built with
// `options`, checked before a build starts: the node count is estimated as
// 4 per maxLeafTriangles triangles (measured: 2.7 per 48 on the plant and
// scan scenes), clusters as 2 per maxClusterTriangles. Throws
// Error("<subject>: ...") naming the limit and the option that raises it. The
// layout stage checks the exact count again.
void checkModelLimits(uint64_t triangles, const PreprocessOptions& options, const std::string& subject = "preprocess");

struct SimplifiedMesh {
    Mesh mesh;                 // unused vertices removed
    float error = 0;           // meshoptimizer's error relative to the mesh extent
    float absoluteError = 0;   // error * meshopt_simplifyScale, model units
    bool sloppy = false;       // meshopt_simplifySloppy was used (the topology-preserving pass stopped short)
};

// Reduces the mesh to about ratio * triangles (0 < ratio <= 1) with
// meshopt_simplify; if that ends above 1.1x the target (it preserves topology
// and borders), meshopt_simplifySloppy is used instead. ratio >= 1 returns a
// copy with error 0. Throws Error for ratio <= 0 or a malformed mesh.
SimplifiedMesh simplifyMesh(const Mesh& mesh, float ratio);

} // namespace penumbra
