// The .penumbra model file: strip-compressed clusters with quantized vertices
// ("ReduceM-like", Lauterbach et al. 2009, section 5.1) plus ONE BVH that the
// rasterizer (culling) and the ray tracer share. Field-by-field documentation:
// formats/README.md. All integers little-endian; every section 64-byte aligned
// so it can be memory-mapped and uploaded without conversion.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "penumbra/mesh.h"

namespace penumbra {

namespace model {

inline constexpr char kMagic[8] = {'P', 'E', 'N', 'U', 'M', 'B', 'R', 'A'};
inline constexpr uint32_t kVersion = 4;
inline constexpr uint32_t kSectionAlignment = 64;      // bytes; offsets and the file size are multiples
inline constexpr uint8_t kStripRestart = 0xFF;         // primitive-restart value of the 8-bit strip indices
inline constexpr uint32_t kMaxClusterVertices = 255;   // local indices 0..254; 255 is the restart
inline constexpr uint32_t kMaxClusterTriangles = 1024; // hard limit of the format
inline constexpr uint32_t kMaxLeafIndexBytes = 65535;  // a leaf's strip range fits 16 bits
inline constexpr uint32_t kPositionBits = 16;          // quantized coordinate width
inline constexpr uint32_t kNodeBoundsBits = 8;         // child boxes on their node's grid
inline constexpr uint32_t kNodeChildren = 4;           // children per node (a 4-wide BVH)
inline constexpr uint32_t kMaxBvhDepth = 32;           // node levels; readers may use fixed traversal stacks (3 x depth + 1 entries)
inline constexpr uint32_t kNoCluster = 0xFFFFFFFFu;    // Node::cluster of the nodes above the clusters
inline constexpr uint32_t kMaxMaterials = 1u << 24;    // MaterialRecord elements
inline constexpr uint32_t kMaxCameras = 256;           // CameraRecord elements
inline constexpr uint32_t kMaxLights = 256;            // LightRecord elements
// Nodes name their children and clusters, and clusters their root node, by
// 32-bit index: the format's only size limits. With the default options a
// model has about 0.013 nodes and 0.004 clusters per triangle, so 2^32 - 1
// nodes hold some 300 G triangles; preprocess checks a conservative estimate
// (2 nodes per maxLeafTriangles triangles) before it builds. Vertex and strip
// offsets and every byte count are 64-bit.
inline constexpr uint64_t kMaxNodes = 0xFFFFFFFFull;
inline constexpr uint64_t kMaxClusters = 0xFFFFFFFFull;

enum class SectionType : uint32_t {
    Clusters = 1, // ClusterRecord[clusterCount]
    Nodes = 2,    // Node[nodeCount]; node 0 is the root
    Vertices = 3, // QuantizedVertex[vertexCount]
    Indices = 4,  // uint8_t[indexBytes]: per cluster, strips of local indices separated by kStripRestart
    Materials = 5,// MaterialRecord[materialCount]; required, >= 1 entry
    Cameras = 6,  // CameraRecord[cameraCount]; present exactly when cameraCount > 0
    Lights = 7,   // LightRecord[lightCount]; present exactly when lightCount > 0
};
inline constexpr uint32_t kSectionTypes = 7;   // types 1..7
inline constexpr uint32_t kSectionSlots = 8;   // entries of the section table; unused ones are all zero

// One entry of the section table.
struct SectionEntry {
    uint32_t type;        // SectionType
    uint32_t elementSize; // bytes per element (1 for Indices)
    uint64_t offset;      // from the start of the file; multiple of kSectionAlignment
    uint64_t size;        // bytes of payload (elementSize * element count); padding after it is zero
    uint64_t checksum;    // XXH64 (seed 0) of the payload bytes
};
static_assert(sizeof(SectionEntry) == 32);

// Parameters the data depends on; a reader rejects values outside the format limits.
struct BuildParameters {
    uint32_t maxClusterVertices;  // <= kMaxClusterVertices
    uint32_t maxClusterTriangles; // <= kMaxClusterTriangles
    uint32_t maxLeafTriangles;    // triangles per strip-range leaf inside a cluster
    uint32_t sahBins;             // bins of the binned SAH build
    uint32_t positionBits;        // == kPositionBits
    uint32_t nodeBoundsBits;      // == kNodeBoundsBits
    float simplifyTarget;         // requested triangle ratio (1 = not simplified)
    uint32_t reserved;            // 0
};
static_assert(sizeof(BuildParameters) == 32);

struct FileHeader {
    char magic[8];                 // kMagic
    uint32_t version;              // kVersion
    uint32_t headerSize;           // sizeof(FileHeader)
    uint64_t fileSize;             // total bytes, multiple of kSectionAlignment
    uint64_t triangleCount;        // triangles stored (sum over clusters)
    uint64_t sourceTriangleCount;  // triangles of the input before simplification
    uint64_t vertexCount;          // QuantizedVertex elements
    uint64_t indexBytes;           // Indices section payload bytes
    uint32_t clusterCount;         // ClusterRecord elements (1..kMaxClusters: nodes name clusters in 32 bits)
    uint32_t nodeCount;            // Node elements (1..kMaxNodes: nodes name nodes in 32 bits)
    uint32_t bvhDepth;             // levels from the root (1 = root only); <= kMaxBvhDepth
    uint32_t materialCount;        // MaterialRecord elements, 1..kMaxMaterials
    float boundsMin[3];            // root node box, model units
    float boundsMax[3];
    float maxPositionError;        // largest |decoded - input| coordinate over all vertices, model units
    float simplifyError;           // meshoptimizer's relative error of the simplification (0 if none)
    BuildParameters build;
    SectionEntry sections[kSectionSlots]; // one per present SectionType, in any order; unused entries all zero
    uint32_t cameraCount;          // CameraRecord elements, 0..kMaxCameras
    uint32_t lightCount;           // LightRecord elements, 0..kMaxLights
    uint64_t reserved1[5];         // 0
    uint64_t headerChecksum;       // XXH64 of this struct with headerChecksum = 0
};
static_assert(sizeof(FileHeader) == 448);

// Bits of ClusterRecord::flags.
enum ClusterFlags : uint32_t {
    // Every triangle of the cluster belongs to a closed, consistently oriented
    // 2-manifold connected component of the input: with vertices welded by
    // exact position, every undirected edge of the component is used by exactly
    // two of its triangles, in opposite directions (components connected by
    // edges), and it encloses positive volume. Conservative: the preprocessor
    // never sets it on a cluster that has one triangle of an open component,
    // sets it in all clusters of such a component or in none, and only where
    // no other surface comes within the default shadow-ray offset of the
    // component (formats/README.md, "Cluster flags"). A shadow method may then
    // cast only the light-back-facing triangles of such clusters. The claim is
    // about the input positions; decoded positions differ from them by at most
    // the header's maxPositionError.
    kClusterClosed = 1u << 0,
};
inline constexpr uint32_t kClusterFlagsMask = kClusterClosed; // every other bit is zero

// A cluster: up to 255 vertices and its triangles as 8-bit strips.
// Decoded position = boxMin + float(q) * step, evaluated without fused multiply-add.
// 64 bytes (since version 3), with 64-bit vertex and strip offsets (a file may
// hold more than 2^32 vertices or 4 GiB of strips) and flags.
struct ClusterRecord {
    float boxMin[3];        // 0: quantization origin (the cluster's bounds minimum)
    float step[3];          // 12: model units per quantization step, per axis (>= 0)
    uint64_t firstVertex;   // 24: first QuantizedVertex of this cluster (index into Vertices)
    uint64_t firstIndex;    // 32: byte offset of this cluster's strips in Indices
    uint32_t indexBytes;    // 40: bytes of strips (restarts included); first and last byte are not restarts
    uint16_t vertexCount;   // 44: 3..maxClusterVertices
    uint16_t triangleCount; // 46: 1..maxClusterTriangles
    uint32_t node;          // 48: index of this cluster's root Node (named by one Cluster slot)
    uint32_t material;      // 52: index into Materials: every triangle of the cluster has this material
    uint32_t flags;         // 56: ClusterFlags; bits outside kClusterFlagsMask are zero
    uint32_t reserved;      // 60: 0
};
static_assert(sizeof(ClusterRecord) == 64, "ClusterRecord is 64 bytes (a multiple of 8; shaders read it as 4 x 16)");
static_assert(offsetof(ClusterRecord, boxMin) == 0 && offsetof(ClusterRecord, step) == 12 &&
                  offsetof(ClusterRecord, firstVertex) == 24 && offsetof(ClusterRecord, firstIndex) == 32 &&
                  offsetof(ClusterRecord, indexBytes) == 40 && offsetof(ClusterRecord, vertexCount) == 44 &&
                  offsetof(ClusterRecord, triangleCount) == 46 && offsetof(ClusterRecord, node) == 48 &&
                  offsetof(ClusterRecord, material) == 52 && offsetof(ClusterRecord, flags) == 56,
              "ClusterRecord layout is read by shaders/bvh_traversal.glsli (loadCluster)");

// A material: the linear base colour of the clusters that name it.
struct MaterialRecord {
    float baseColor[4];    // linear RGBA, each in [0, 1]
};
static_assert(sizeof(MaterialRecord) == 16);

// A camera of the source scene (penumbra::Camera).
struct CameraRecord {
    float position[3];
    float target[3];       // != position
    float up[3];           // nonzero, not parallel to target - position
    uint32_t projection;   // 0 perspective, 1 orthographic
    float yfovDegrees;     // (0, 180)
    float orthoHeight;     // > 0
    float nearPlane;       // >= 0 (0: derived from the bounds)
    float farPlane;        // 0 (derived) or > nearPlane
    uint32_t reserved[2];  // 0
};
static_assert(sizeof(CameraRecord) == 64);

// A light of the source scene (penumbra::Light).
struct LightRecord {
    uint32_t type;             // LightType: 0 point, 1 spot, 2 directional, 3 rectangle, 4 disk, 5 sphere
    float position[3];
    float direction[3];        // nonzero
    float up[3];
    float color[3];            // >= 0
    float intensity;           // >= 0
    float range;               // >= 0 (0: infinite)
    float innerConeDegrees;    // spot: 0 <= inner <= outer
    float outerConeDegrees;    // spot: (0, 90)
    float width, height;       // rectangle: > 0
    float radius;              // disk, sphere: > 0
};
static_assert(sizeof(LightRecord) == 80);

// A vertex: 6 bytes, no padding (version 4; version 3 padded to 8). The
// rasterizer reads it as R16G16_UINT + R16_UINT attributes (formats every
// device supports), the ray tracer as one R16G16B16_UINT texel where the
// device can, else three R16_UINT texels.
struct QuantizedVertex {
    uint16_t x, y, z; // position in the cluster box, 0..65535
};
static_assert(sizeof(QuantizedVertex) == 6);

// What a node's child slot holds (2 bits per slot in Node::kinds).
enum class ChildKind : uint8_t {
    Empty = 0,    // no child (only after the node's last child)
    Interior = 1, // a node of the same part of the tree: child[c] is its index
    Cluster = 2,  // in a node above the clusters: a cluster's root node, child[c] is its index
    Leaf = 3,     // in a node of a cluster: a strip range of that cluster, child[c] = start | count << 16
                  // (bytes, relative to the cluster's firstIndex)
};

// BVH node: a 4-wide node in the spirit of compressed wide BVHs (Ylitie,
// Karras, Laine 2017). The children's boxes lie on a grid of the node's own,
// 8 bits per coordinate: lo = origin + lo * 2^(exponent - 127) per axis, hi
// likewise (the power-of-two step makes the product exact, so decoding has one
// rounding; boxes are rounded outward and checked with the decoder at build),
// so a node decodes without its parent. The root is node 0 and its own box is
// the header's bounds. Nodes above the clusters (cluster = kNoCluster) hold
// Interior and Cluster children; a cluster's root node and the nodes below it
// (cluster = its index) hold Interior and Leaf children. Children have larger
// indices than their node, each node but the root is the child of exactly one
// slot, each cluster's root is named by one Cluster slot and by its record.
// 64 bytes: shaders read it as four 16-byte words.
struct Node {
    float origin[3];     // 0: the grid's origin (model units)
    uint8_t exponent[3]; // 12: per axis, the grid step is 2^(exponent - 127); 1..254
    uint8_t kinds;       // 15: ChildKind of child c in bits 2c..2c+1; the non-empty children first, at least one
    uint8_t lo[3][4];    // 16: [axis][child] box minimum on the grid (0 for empty children)
    uint8_t hi[3][4];    // 28: [axis][child] box maximum, >= lo (0 for empty children)
    uint32_t cluster;    // 40: the cluster whose subtree this node is in (its root included), or kNoCluster
    uint32_t reserved;   // 44: 0
    uint32_t child[4];   // 48: per ChildKind (0 for empty children)
};
static_assert(sizeof(Node) == 64);
static_assert(offsetof(Node, exponent) == 12 && offsetof(Node, kinds) == 15 && offsetof(Node, lo) == 16 &&
              offsetof(Node, hi) == 28 && offsetof(Node, cluster) == 40 && offsetof(Node, child) == 48);

inline ChildKind childKind(const Node& node, uint32_t c) { return ChildKind((node.kinds >> (2 * c)) & 3u); }
// Children of the node (the non-empty slots).
inline uint32_t childCount(const Node& node)
{
    uint32_t n = 0;
    while (n < kNodeChildren && childKind(node, n) != ChildKind::Empty)
        ++n;
    return n;
}

} // namespace model

// A model in memory, either built by the preprocessor (owning vectors) or
// mapped from a file. The spans stay valid as long as the object lives.
struct CompressedModel {
    model::FileHeader header{};
    std::span<const model::ClusterRecord> clusters;
    std::span<const model::Node> nodes;
    std::span<const model::QuantizedVertex> vertices;
    std::span<const uint8_t> indices;
    std::span<const model::MaterialRecord> materials;
    std::span<const model::CameraRecord> cameras; // may be empty
    std::span<const model::LightRecord> lights;   // may be empty
    std::shared_ptr<const void> storage; // keeps the vectors or the mapping alive

    uint64_t triangleCount() const { return header.triangleCount; }
};

// Owning storage filled by the preprocessor; view() makes a CompressedModel
// sharing it (header fields are the caller's to fill before view()).
struct CompressedModelData {
    model::FileHeader header{};
    std::vector<model::ClusterRecord> clusters;
    std::vector<model::Node> nodes;
    std::vector<model::QuantizedVertex> vertices;
    std::vector<uint8_t> indices;
    std::vector<model::MaterialRecord> materials;
    std::vector<model::CameraRecord> cameras;
    std::vector<model::LightRecord> lights;
};
CompressedModel makeCompressedModel(std::shared_ptr<CompressedModelData> data);

// The cameras and lights stored with a model (and their records), and a copy
// of a model that stores the given ones instead (the rest shared, not copied).
model::CameraRecord cameraRecord(const Camera& camera);
model::LightRecord lightRecord(const Light& light);
Camera cameraFromRecord(const model::CameraRecord& record);
Light lightFromRecord(const model::LightRecord& record);
std::vector<Camera> modelCameras(const CompressedModel& model);
std::vector<Light> modelLights(const CompressedModel& model);
// Cameras and lights that the format would reject (a degenerate node transform,
// a spot cone of 90 degrees) are left out, with one warning each naming subject.
CompressedModel withScene(const CompressedModel& model, const std::vector<Camera>& cameras, const std::vector<Light>& lights,
                          const std::string& subject = "scene");
// The checks of one camera or light record (validateModel applies them to
// every record). Throw Error("<subject>: <problem>").
void validateCameraRecord(const model::CameraRecord& record, const std::string& subject);
void validateLightRecord(const model::LightRecord& record, const std::string& subject);

// Decoded position of a cluster's local vertex (exactly the GPU's arithmetic).
glm::vec3 decodePosition(const model::ClusterRecord& cluster, const model::QuantizedVertex& vertex);

// The grid step of a node's axis: 2^(exponent - 127) (exponent 1..254).
float nodeStep(uint8_t exponent);

// Decoded box of child c of node (exactly the GPU's arithmetic).
void decodeChildBox(const model::Node& node, uint32_t c, glm::vec3& min, glm::vec3& max);

// The distance from point to the model's nearest triangle, as the GPU decodes
// the triangles (infinity for a model without nodes). A walk of the BVH that
// decodes only the leaves nearer than the best triangle so far: 2-60
// microseconds for a light among the geometry of the suite's 1-2 M-triangle models.
float nearestTriangleDistance(const CompressedModel& model, glm::vec3 point);

// Calls fn(a, b, c) with the local vertex indices of every triangle of the
// strip bytes [begin, end) (restart-separated strips, alternating winding
// undone so every triangle has its original orientation). Degenerate
// triangles (repeated index) are skipped.
template <typename Fn> void forEachStripTriangle(const uint8_t* begin, const uint8_t* end, Fn&& fn);

// Writes a model file: header, section table, 64-byte aligned sections with
// checksums; to a temporary name, then renamed. Throws Error.
void writeModelFile(const CompressedModel& model, const std::string& path);

// Maps and fully validates a model file (header, section table, checksums,
// every count, offset, index and child reference). Throws Error("<path>: <problem>").
CompressedModel openModelFile(const std::string& path);

// Validates the bytes of a whole model file held in memory (what
// openModelFile does after mapping): header, section table, checksums, zero
// padding, then validateModel. bytes.data() must be 8-byte aligned (mmap and
// malloc results are). The returned spans point into bytes; keepAlive becomes
// CompressedModel::storage and must own them. Throws Error("<subject>: <problem>").
CompressedModel openModelMemory(std::span<const uint8_t> bytes, std::shared_ptr<const void> keepAlive,
                                const std::string& subject);

// Validates an in-memory model the same way (used by the reader and tests).
// subject names the source in error messages. Checks the header's counts
// against the spans, the build parameters against the format limits, every
// cluster (ranges, strips, quantization), every node (kinds, child links form
// a tree with children after parents, leaf ranges) and the BVH depth; O(size).
void validateModel(const CompressedModel& model, const std::string& subject);

// ---------------------------------------------------------------------------

template <typename Fn> void forEachStripTriangle(const uint8_t* begin, const uint8_t* end, Fn&& fn)
{
    const uint8_t* p = begin;
    while (p < end) {
        const uint8_t* stripEnd = p;
        while (stripEnd < end && *stripEnd != model::kStripRestart)
            ++stripEnd;
        for (const uint8_t* q = p; q + 2 < stripEnd; ++q) {
            uint32_t a = q[0], b = q[1], c = q[2];
            if ((q - p) & 1)
                std::swap(a, b);
            if (a != b && b != c && a != c)
                fn(a, b, c);
        }
        p = stripEnd + 1;
    }
}

} // namespace penumbra
