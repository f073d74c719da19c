// The model on the GPU, uploaded once, drawn straight from its compressed form:
// 8-bit triangle strips with primitive restart, R16G16B16A16_UINT vertices
// dequantized in the vertex shader with the cluster box taken per instance
// from the ClusterRecord array, one indirect draw per cluster. Buffers are
// split into chunks below the device's allocation limit. The compressed
// buffers (and the BVH nodes) are also readable by shaders through their
// device addresses (the ray tracer).
#pragma once

#include <functional>
#include <vector>

#include "penumbra/mesh.h"
#include "penumbra/model_format.h"
#include "resources.h"

namespace penumbra {

enum class GeometryEncoding {
    Compressed,             // the only path of the renderer
    UncompressedReference,  // indexed float triangle list: benchmarks compare against it
};


// Paged geometry: bit 63 of a cluster's firstVertex in the DEVICE copy of its
// ClusterRecord marks it not resident (the file's records never set it: a
// model holds fewer than 2^63 vertices). Shaders learn residency from the
// node table (kNodeAbsent) instead, which is reached before any record; the
// bit keeps an evicted record from naming another page's vertices.
inline constexpr uint64_t kNotResident = uint64_t(1) << 63;

// Paged geometry's BVH (geometry_pages.h): each node has a record of
// kNodeRecordBytes in the pool (the model::Node, then the four leaf slots'
// smallest altitudes as floats, 0 where unknown) and a word in the node
// table: the record's first texel (16 bytes) in the pool, or, for a node of a
// cluster that is not resident, the cluster | kNodeAbsent.
inline constexpr uint32_t kNodeRecordBytes = 80;
inline constexpr uint32_t kNodeAbsent = 0x80000000u;
struct PagedBvh {
    uint64_t poolBytes = 0;          // page slots, then the top records (a multiple of 48)
    uint64_t topRecordsByte = 0;     // where the records of the nodes above the clusters start
    std::vector<uint8_t> topRecords; // those records, in node order
    std::vector<uint32_t> nodeTable; // the node table with no cluster resident
};

// A node's leaf slots' smallest decoded-triangle altitudes (model units; 0
// for slots that are not leaves), and when `longest` is given their longest
// edges, both over the triangles long and narrow in model space (a leaf with
// none: the float maximum and 0): the thin-triangle pass skips leaves that
// cannot hold a sliver (no long and narrow triangle; every one wide, or every
// one short, at the light's texel size).
void nodeLeafAltitudes(const CompressedModel& model, uint32_t node, float out[model::kNodeChildren],
                       float longest[model::kNodeChildren] = nullptr);
// Whether the altitudes and longest edges of every node fit one buffer of this device (else the thin-triangle
// pass skips no leaf).
bool leafAltitudesFit(const vk::Device& device, const CompressedModel& model);

struct GpuGeometry {
    struct Chunk {
        vk::Buffer vertices;      // QuantizedVertex[] (or float3[] for the reference)
        vk::Buffer indices;       // uint8 strips (or uint32 triangle list for the reference)
        vk::Buffer rasterIndices; // RasterIndices::Triangles: uint8 triangle lists the raster passes draw (else empty: `indices`)
        uint32_t firstCluster = 0;
        uint32_t clusterCount = 0;
        uint64_t vertexBase = 0;  // global index of the chunk's first vertex
        uint64_t indexBase = 0;   // byte offset in Indices of the chunk's first strip byte
        uint64_t indexCount = 0;  // reference path: indices to draw
    };
    GeometryEncoding encoding = GeometryEncoding::Compressed;
    std::vector<Chunk> chunks;
    vk::Buffer clusters;          // ClusterRecord[] as per-instance vertex data (reference: one identity record)
    vk::Buffer indirect;          // VkDrawIndexedIndirectCommand per cluster
    std::vector<VkDrawIndexedIndirectCommand> commands; // the same on the host (compressed only)
    RasterIndices rasterIndices = RasterIndices::Strips; // Strips or Triangles (device.rasterIndices)
    uint64_t rasterIndexBytes = 0;                       // bytes of the chunks' rasterIndices
    vk::Buffer albedo;            // uint per cluster: its material's linear RGB, 8 bits each (gbuffer.vert); compressed only
    bool coloured = false;        // some cluster's albedo is not white (else the camera writes no albedo target)
    // The BVH (model::Node[]) for the ray tracer, in chunks of 2^nodeChunkShift
    // nodes (node i is in nodeChunks[i >> nodeChunkShift]); compressed only.
    std::vector<vk::Buffer> nodeChunks;
    // float per child slot (4 x node + slot): a leaf's smallest triangle
    // altitude (model units), 0 for other slots. The thin-triangle pass skips
    // leaves with no sliver. Empty when the array would not fit one buffer
    // (then no leaf is skipped).
    vk::Buffer leafAltitudes; // per node: its 4 slots' smallest altitudes, then their longest edges (nodeLeafAltitudes)
    uint32_t nodeChunkShift = 0;
    uint32_t nodeCount = 0;
    // The ray tracer's view of the model through uniform texel buffers: on
    // lavapipe a texel fetch is a branch-free gather, every other buffer load
    // not provably uniform a loop over the lanes (2.5-4x slower, measured).
    // nodes and clusters: RGBA32UI (a Node and a ClusterRecord are four
    // texels each); vertices: R16G16B16_UINT (one QuantizedVertex a texel)
    // where the device takes that format in a texel buffer, else R16_UINT
    // (three texels a vertex, vertexTexelsSplit);
    // strips: RGBA32UI (16 strip bytes a texel, the buffer padded to 16).
    // Made when the nodes, the vertices and the strips each lie in one buffer
    // within the device's texel-buffer limit (texelsComplete); the views
    // exist anyway, over the first buffers, so that descriptors are valid.
    struct TexelViews {
        VkBufferView nodes = VK_NULL_HANDLE, clusters = VK_NULL_HANDLE, vertices = VK_NULL_HANDLE, strips = VK_NULL_HANDLE;
        VkBufferView nodeTable = VK_NULL_HANDLE; // R32UI over GpuGeometry::nodeTable (paged); else over the nodes, unread
    } texels;
    bool texelsComplete = false;
    bool vertexTexelsSplit = false; // vertices as R16_UINT texels (3 a vertex)
    float maxPositionError = 0;   // header.maxPositionError, model units
    uint64_t triangles = 0;
    uint64_t vertexCount = 0;
    Bounds bounds;                // compressed: the header's (root node) bounds
    uint64_t deviceBytes = 0;     // bytes of all model buffers
    // Paged geometry (RendererOptions::geometryBudgetBytes, geometry_pages.h):
    // the vertices, strips and raster indices of every cluster live in one
    // pool of fixed-size pages (`pool`, the only chunk's vertices and indices
    // both name it, not owned twice); `clusters` and `indirect` are the
    // device copies GeometryPages rewrites on every upload and eviction (a
    // cluster that is not resident has bit 63 of its firstVertex set and an
    // empty draw). Empty in core.
    // The pool also holds every resident node's record (PagedBvh), found
    // through `nodeTable` (one uint per node; texels.nodeTable): no node
    // chunks, no leafAltitudes buffer then; texels.nodes views the pool.
    vk::Buffer pool;
    vk::Buffer nodeTable;
    bool pagedAltitudes = false; // the pool's node records carry altitudes (else the thin pass skips no leaf)
    bool paged() const { return pool.buffer != VK_NULL_HANDLE; }
};

// Raster passes draw device.rasterIndices (Strips or Triangles, RendererOptions).
// paged: paged geometry, a pool of paged->poolBytes (a multiple of 48, so that both the
// vertices' and the strips' texel views tile it) and no cluster resident yet.
GpuGeometry uploadCompressed(vk::Device& device, const CompressedModel& model, const PagedBvh* paged = nullptr);
// One cluster's strips as a triangle list (RasterIndices::Triangles), appended to out.
void appendTriangles(const uint8_t* strips, uint32_t bytes, std::vector<uint8_t>& out);
GpuGeometry uploadReference(vk::Device& device, const Mesh& mesh);
void destroyGeometry(vk::Device& device, GpuGeometry& geometry);

// Pipeline state of the encoding (vertex bindings/attributes, topology, restart);
// rasterIndices: the compressed model's (device.rasterIndices).
struct GeometryInputState {
    VkVertexInputBindingDescription bindings[2];
    VkVertexInputAttributeDescription attributes[4];
    uint32_t bindingCount = 0, attributeCount = 0;
    VkPrimitiveTopology topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_STRIP;
    VkBool32 primitiveRestart = VK_TRUE;
};
GeometryInputState geometryInputState(GeometryEncoding encoding, RasterIndices rasterIndices);
// Binds the chunk's vertices (and the cluster records) and the index buffer the raster passes draw.
void bindChunk(VkCommandBuffer cmd, const GpuGeometry& geometry, const GpuGeometry::Chunk& chunk);

// Records the draws of the whole model (its per-cluster indirect commands); beforeChunk (optional) runs before each
// chunk's draws with the chunk's global vertex base (e.g. to push constants).
void drawGeometry(VkCommandBuffer cmd, const GpuGeometry& geometry, const std::function<void(uint64_t vertexBase)>& beforeChunk = {});

} // namespace penumbra
