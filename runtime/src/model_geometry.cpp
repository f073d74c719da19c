#include "model_geometry.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <thread>

#include <glm/geometric.hpp>

#include "config.h"
#include "penumbra/parallel.h"
#include "surface.h"

namespace penumbra {

// A node's leaf slots' smallest triangle altitudes (model_geometry.h), over
// the triangles the thin-triangle pass can take for slivers: those at least
// PENUMBRA_THIN_ASPECT times longer than high in model space (its
// thinInModelSpace), with a margin so that rounding on the device cannot find
// one that was left out here.
void nodeLeafAltitudes(const CompressedModel& model, uint32_t n, float out[model::kNodeChildren], float longestEdges[model::kNodeChildren])
{
    const model::Node& node = model.nodes[n];
    for (uint32_t slot = 0; slot < model::kNodeChildren; ++slot) {
        out[slot] = 0.0f;
        if (longestEdges)
            longestEdges[slot] = 0.0f;
        if (model::childKind(node, slot) != model::ChildKind::Leaf)
            continue;
        const model::ClusterRecord& cluster = model.clusters[node.cluster];
        const uint8_t* strips = model.indices.data() + cluster.firstIndex + (node.child[slot] & 0xFFFF);
        const model::QuantizedVertex* vertices = model.vertices.data() + cluster.firstVertex;
        float smallest = std::numeric_limits<float>::max(), longestEdge = 0.0f;
        forEachStripTriangle(strips, strips + (node.child[slot] >> 16), [&](uint32_t a, uint32_t b, uint32_t c) {
            glm::vec3 p0 = decodePosition(cluster, vertices[a]), p1 = decodePosition(cluster, vertices[b]),
                      p2 = decodePosition(cluster, vertices[c]);
            float longest = std::max({glm::length(p1 - p0), glm::length(p2 - p1), glm::length(p0 - p2)});
            float twiceArea = glm::length(glm::cross(p1 - p0, p2 - p0));
            float altitude = longest > 0.0f ? twiceArea / longest : 0.0f;
            if (longest < 0.999f * float(PENUMBRA_THIN_ASPECT) * altitude)
                return; // wide in model space: a sliver in no light's view (thinInModelSpace)
            smallest = std::min(smallest, altitude);
            longestEdge = std::max(longestEdge, longest);
        });
        out[slot] = smallest;
        if (longestEdges)
            longestEdges[slot] = longestEdge * (1.0f + 1e-5f); // rounded up: the skip must stay conservative
    }
}

namespace {

// Smallest altitude (twice the area over the longest edge) of each leaf's
// decoded triangles, at 8 x node + slot, and the longest edge of any of
// them at 8 x node + 4 + slot: a triangle can be a sliver in a light's view
// only if it is thin in model space or seen edge-on, and long enough. 0 for
// the slots that are not leaves.
std::vector<float> leafMinimumAltitudes(const CompressedModel& model)
{
    std::vector<float> altitudes(model.nodes.size() * 2 * model::kNodeChildren, 0.0f);
    auto work = [&](size_t begin, size_t end) {
        for (size_t n = begin; n < end; ++n)
            nodeLeafAltitudes(model, uint32_t(n), altitudes.data() + n * 2 * model::kNodeChildren,
                              altitudes.data() + n * 2 * model::kNodeChildren + model::kNodeChildren);
    };
    const unsigned threads = std::max(1u, std::thread::hardware_concurrency());
    const size_t nodes = model.nodes.size(), per = (nodes + threads - 1) / threads;
    parallelFor(threads, per ? (nodes + per - 1) / per : 0,
                [&](uint64_t t) { work(size_t(t) * per, std::min(nodes, size_t(t + 1) * per)); });
    return altitudes;
}

// One cluster's strips as a triangle list (RasterIndices::Triangles): every
// triangle with area in index terms, in strip order, its vertices in the
// order Vulkan's strip topology gives them (triangle i of a strip is
// i, i+1, i+2, an odd one i, i+2, i+1), so the images are the same bit for
// bit. Triangles with a repeated index are left out: they cover no sample.
} // namespace

void appendTriangles(const uint8_t* strips, uint32_t bytes, std::vector<uint8_t>& out)
{
    const uint8_t* p = strips;
    const uint8_t* end = strips + bytes;
    while (p < end) {
        const uint8_t* stripEnd = p;
        while (stripEnd < end && *stripEnd != model::kStripRestart)
            ++stripEnd;
        for (const uint8_t* q = p; q + 2 < stripEnd; ++q) {
            if (q[0] == q[1] || q[1] == q[2] || q[0] == q[2])
                continue;
            const bool odd = (q - p) & 1;
            out.push_back(q[0]);
            out.push_back(odd ? q[2] : q[1]);
            out.push_back(odd ? q[1] : q[2]);
        }
        p = stripEnd + 1;
    }
}

namespace {

constexpr VkDeviceSize kChunkBytes = 1ull << 30; // per buffer, also capped by maxMemoryAllocationSize

// GpuGeometry::texels over the first buffer of each kind; complete when each kind has one.
void createTexelViews(vk::Device& device, GpuGeometry& geometry)
{
    const VkDeviceSize maxTexels = device.properties.limits.maxTexelBufferElements;
    GpuGeometry::TexelViews& t = geometry.texels;
    // Paged: the node records live in the pool (PagedBvh), found through the node table.
    const vk::Buffer& nodes = geometry.paged() ? geometry.pool : geometry.nodeChunks[0];
    t.nodes = vk::createTexelView(device, nodes, VK_FORMAT_R32G32B32A32_UINT, 16);
    t.nodeTable = vk::createTexelView(device, geometry.paged() ? geometry.nodeTable : nodes, VK_FORMAT_R32_UINT, 4);
    t.clusters = vk::createTexelView(device, geometry.clusters, VK_FORMAT_R32G32B32A32_UINT, 16);
    VkFormatProperties vertexFormat{};
    vkGetPhysicalDeviceFormatProperties(device.physical, VK_FORMAT_R16G16B16_UINT, &vertexFormat);
    geometry.vertexTexelsSplit = !(vertexFormat.bufferFeatures & VK_FORMAT_FEATURE_UNIFORM_TEXEL_BUFFER_BIT);
    t.vertices = geometry.vertexTexelsSplit ? vk::createTexelView(device, geometry.chunks[0].vertices, VK_FORMAT_R16_UINT, 2)
                                            : vk::createTexelView(device, geometry.chunks[0].vertices, VK_FORMAT_R16G16B16_UINT, 6);
    t.strips = vk::createTexelView(device, geometry.chunks[0].indices, VK_FORMAT_R32G32B32A32_UINT, 16);
    geometry.texelsComplete = (geometry.paged() ? geometry.nodeTable.size / 4 <= maxTexels : geometry.nodeChunks.size() == 1) &&
                              geometry.chunks.size() == 1 && nodes.size / 16 <= maxTexels && geometry.clusters.size / 16 <= maxTexels &&
                              geometry.chunks[0].vertices.size / (geometry.vertexTexelsSplit ? 2 : 6) <= maxTexels && geometry.chunks[0].indices.size / 16 <= maxTexels;
    // Paged nodes are read through texels only (the tracer and the thin-triangle pass).
    if (geometry.paged() && !geometry.texelsComplete)
        fail("--geometry-budget", "the pool (" + std::to_string(geometry.pool.size >> 20) + " MiB), the node table (" +
                                      std::to_string(geometry.nodeTable.size / 4) + " nodes) or the cluster table exceed this device's " +
                                      std::to_string(maxTexels) + " texel-buffer elements: use a smaller budget or page");
}

VkDeviceSize chunkLimit(const vk::Device& device)
{
    VkDeviceSize limit = std::min<VkDeviceSize>(kChunkBytes, device.maxAllocationSize);
    return device.maxModelBufferBytes ? std::min(limit, device.maxModelBufferBytes) : limit;
}

} // namespace

bool leafAltitudesFit(const vk::Device& device, const CompressedModel& model)
{
    return model.nodes.size() * 2 * model::kNodeChildren * sizeof(float) <= chunkLimit(device);
}

GpuGeometry uploadCompressed(vk::Device& device, const CompressedModel& model, const PagedBvh* paged)
{
    const uint64_t poolBytes = paged ? paged->poolBytes : 0;
    const RasterIndices rasterIndices = device.rasterIndices == RasterIndices::Triangles ? RasterIndices::Triangles : RasterIndices::Strips;
    const auto& h = model.header;
    if (model.clusters.empty())
        fail("model", "has no clusters");
    GpuGeometry geometry;
    geometry.encoding = GeometryEncoding::Compressed;
    geometry.rasterIndices = rasterIndices;
    geometry.triangles = h.triangleCount;
    geometry.vertexCount = model.vertices.size();
    geometry.bounds.min = {h.boundsMin[0], h.boundsMin[1], h.boundsMin[2]};
    geometry.bounds.max = {h.boundsMax[0], h.boundsMax[1], h.boundsMax[2]};
    geometry.maxPositionError = h.maxPositionError;
    geometry.nodeCount = uint32_t(model.nodes.size());
    try {
        // Chunks of consecutive clusters whose vertices and strips (and raster indices) each fit one allocation.
        const VkDeviceSize limit = chunkLimit(device);
        auto rasterBound = [&](const model::ClusterRecord& c) -> VkDeviceSize {
            return rasterIndices == RasterIndices::Triangles ? 3 * VkDeviceSize(c.triangleCount) : 0;
        };
        std::vector<VkDrawIndexedIndirectCommand>& commands = geometry.commands;
        commands.resize(model.clusters.size());
        std::vector<uint8_t> raster;
        uint32_t first = 0;
        if (poolBytes) {
            // Paged: one pool, no cluster resident (GeometryPages uploads them), empty draws.
            if (poolBytes > limit)
                fail("model", "geometry pool of " + std::to_string(poolBytes >> 20) + " MiB exceeds this device's largest buffer (" +
                                  std::to_string(limit >> 20) + " MiB)");
            geometry.pool = vk::createBuffer(device, poolBytes,
                                             VK_BUFFER_USAGE_VERTEX_BUFFER_BIT | VK_BUFFER_USAGE_INDEX_BUFFER_BIT |
                                                 VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                             vk::MemoryUse::DeviceLocal, vk::Addressable::Yes);
            if (!paged->topRecords.empty()) {
                vk::Buffer staging = vk::createBuffer(device, paged->topRecords.size(), VK_BUFFER_USAGE_TRANSFER_SRC_BIT, vk::MemoryUse::Upload);
                std::memcpy(staging.mapped, paged->topRecords.data(), paged->topRecords.size());
                try {
                    vk::immediateSubmit(device, [&](VkCommandBuffer cmd) {
                        VkBufferCopy region{0, paged->topRecordsByte, paged->topRecords.size()};
                        vkCmdCopyBuffer(cmd, staging.buffer, geometry.pool.buffer, 1, &region);
                    }, "the top nodes' upload");
                } catch (...) {
                    if (!device.hung)
                        vk::destroyBuffer(device, staging);
                    throw;
                }
                vk::destroyBuffer(device, staging);
            }
            geometry.nodeTable = vk::createBufferWithData(device, paged->nodeTable.data(), paged->nodeTable.size() * sizeof(uint32_t),
                                                          VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                                          vk::Addressable::Yes); // afsm_bin.comp reads it by address
            GpuGeometry::Chunk chunk;
            chunk.clusterCount = uint32_t(model.clusters.size());
            chunk.vertices = chunk.indices = geometry.pool;
            geometry.chunks.push_back(chunk);
            for (auto& command : commands)
                command = {0, 1, 0, 0, 0};
            for (uint32_t i = 0; i < commands.size(); ++i)
                commands[i].firstInstance = i;
            first = uint32_t(model.clusters.size());
        }
        while (first < model.clusters.size()) {
            const model::ClusterRecord& start = model.clusters[first];
            uint32_t end = first;
            VkDeviceSize rasterTotal = 0;
            while (end < model.clusters.size()) {
                const model::ClusterRecord& c = model.clusters[end];
                VkDeviceSize vertexBytes = (VkDeviceSize(c.firstVertex) + c.vertexCount - start.firstVertex) * sizeof(model::QuantizedVertex);
                VkDeviceSize indexBytes = VkDeviceSize(c.firstIndex) + c.indexBytes - start.firstIndex;
                if (end > first && (vertexBytes > limit || indexBytes > limit || rasterTotal + rasterBound(c) > limit))
                    break;
                rasterTotal += rasterBound(c);
                ++end;
            }
            const model::ClusterRecord& last = model.clusters[end - 1];
            uint64_t vertexCount = uint64_t(last.firstVertex) + last.vertexCount - start.firstVertex;
            uint64_t indexBytes = uint64_t(last.firstIndex) + last.indexBytes - start.firstIndex;
            GpuGeometry::Chunk chunk;
            chunk.firstCluster = first;
            chunk.clusterCount = end - first;
            chunk.vertexBase = start.firstVertex;
            chunk.indexBase = start.firstIndex;
            chunk.vertices = vk::createBufferWithData(device, model.vertices.data() + start.firstVertex,
                                                      vertexCount * sizeof(model::QuantizedVertex),
                                                      VK_BUFFER_USAGE_VERTEX_BUFFER_BIT | VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT,
                                                      vk::Addressable::Yes);
            geometry.chunks.push_back(chunk); // owned from here on, even if the next upload throws
            // Padded to whole 16-byte texels for the tracer's RGBA32UI view.
            geometry.chunks.back().indices =
                vk::createBufferWithData(device, model.indices.data() + start.firstIndex, indexBytes,
                                         VK_BUFFER_USAGE_INDEX_BUFFER_BIT | VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT, vk::Addressable::Yes,
                                         (indexBytes + 15) & ~VkDeviceSize(15));
            raster.clear();
            for (uint32_t i = first; i < end; ++i) {
                const model::ClusterRecord& c = model.clusters[i];
                // Chunk-relative: below the chunk limit (<= 1 GiB), so 32 bits hold them.
                const int32_t vertexOffset = int32_t(c.firstVertex - start.firstVertex);
                if (rasterIndices == RasterIndices::Strips) {
                    commands[i] = {c.indexBytes, 1, uint32_t(c.firstIndex - start.firstIndex), vertexOffset, i};
                    continue;
                }
                const size_t at = raster.size();
                appendTriangles(model.indices.data() + c.firstIndex, c.indexBytes, raster);
                commands[i] = {uint32_t(raster.size() - at), 1, uint32_t(at), vertexOffset, i};
            }
            if (rasterIndices != RasterIndices::Strips) {
                raster.resize(std::max<size_t>(raster.size(), 4), 0); // a buffer is never empty
                geometry.chunks.back().rasterIndices =
                    vk::createBufferWithData(device, raster.data(), raster.size(), VK_BUFFER_USAGE_INDEX_BUFFER_BIT);
                geometry.rasterIndexBytes += raster.size();
            }
            first = end;
        }
        if (poolBytes) {
            std::vector<model::ClusterRecord> records(model.clusters.begin(), model.clusters.end());
            for (model::ClusterRecord& record : records)
                record.firstVertex |= kNotResident;
            geometry.clusters = vk::createBufferWithData(device, records.data(), records.size() * sizeof(model::ClusterRecord),
                                                         VK_BUFFER_USAGE_VERTEX_BUFFER_BIT | VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT |
                                                             VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                                         vk::Addressable::Yes);
        } else {
            geometry.clusters = vk::createBufferWithData(device, model.clusters.data(), model.clusters.size_bytes(),
                                                         VK_BUFFER_USAGE_VERTEX_BUFFER_BIT | VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT,
                                                         vk::Addressable::Yes);
        }
        // BVH nodes in power-of-two chunks below the limit, so a shader finds node i in chunk i >> shift
        // (paged: in the pool, through the node table).
        while (geometry.nodeChunkShift < 31 && (VkDeviceSize(sizeof(model::Node)) << (geometry.nodeChunkShift + 1)) <= limit)
            ++geometry.nodeChunkShift;
        const size_t nodesPerChunk = size_t(1) << geometry.nodeChunkShift;
        for (size_t node = 0; !poolBytes && node < model.nodes.size(); node += nodesPerChunk) {
            size_t count = std::min(nodesPerChunk, model.nodes.size() - node);
            geometry.nodeChunks.push_back(vk::createBufferWithData(device, model.nodes.data() + node, count * sizeof(model::Node),
                                                                   VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT,
                                                                   vk::Addressable::Yes));
        }
        createTexelViews(device, geometry);
        geometry.indirect = vk::createBufferWithData(device, commands.data(), commands.size() * sizeof(VkDrawIndexedIndirectCommand),
                                                     VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT | (poolBytes ? VK_BUFFER_USAGE_TRANSFER_DST_BIT : 0));
        // Each cluster's material colour, packed for the G-buffer (8 bits per channel, linear).
        std::vector<uint32_t> albedo(model.clusters.size());
        for (size_t c = 0; c < model.clusters.size(); ++c) {
            const float* rgb = model.materials[model.clusters[c].material].baseColor;
            uint32_t packed = 0;
            for (int k = 0; k < 3; ++k)
                packed |= uint32_t(std::lround(std::clamp(rgb[k], 0.0f, 1.0f) * 255.0f)) << (8 * k);
            albedo[c] = packed;
            geometry.coloured |= packed != kWhiteAlbedo;
        }
        geometry.albedo = vk::createBufferWithData(device, albedo.data(), albedo.size() * sizeof(uint32_t),
                                                   VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::Addressable::Yes);
        geometry.pagedAltitudes = poolBytes && leafAltitudesFit(device, model);
        if (!poolBytes && leafAltitudesFit(device, model)) {
            std::vector<float> altitudes = leafMinimumAltitudes(model);
            geometry.leafAltitudes = vk::createBufferWithData(device, altitudes.data(), altitudes.size() * sizeof(float),
                                                              VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::Addressable::Yes);
        }
    } catch (...) {
        destroyGeometry(device, geometry);
        throw;
    }
    geometry.deviceBytes = (poolBytes ? poolBytes + geometry.nodeTable.size : model.vertices.size_bytes() + model.indices.size_bytes() + model.nodes.size_bytes()) +
                           model.clusters.size_bytes() + model.clusters.size() * sizeof(VkDrawIndexedIndirectCommand) +
                           geometry.albedo.size +
                           geometry.leafAltitudes.size + geometry.rasterIndexBytes;
    return geometry;
}

GpuGeometry uploadReference(vk::Device& device, const Mesh& mesh)
{
    if (mesh.triangleCount() == 0)
        fail("model", "has no triangles");
    const VkDeviceSize limit = chunkLimit(device);
    VkDeviceSize vertexBytes = mesh.positions.size() * sizeof(float), indexBytes = mesh.indices.size() * sizeof(uint32_t);
    if (vertexBytes > limit || indexBytes > limit)
        fail("model", "too large for the uncompressed reference path (one buffer each, at most " + std::to_string(limit >> 20) + " MiB)");
    GpuGeometry geometry;
    geometry.encoding = GeometryEncoding::UncompressedReference;
    geometry.triangles = mesh.triangleCount();
    geometry.vertexCount = mesh.vertexCount();
    geometry.bounds = computeBounds(mesh);
    try {
        GpuGeometry::Chunk chunk;
        chunk.indexCount = mesh.indices.size();
        chunk.vertices = vk::createBufferWithData(device, mesh.positions.data(), vertexBytes, VK_BUFFER_USAGE_VERTEX_BUFFER_BIT);
        geometry.chunks.push_back(chunk);
        geometry.chunks.back().indices = vk::createBufferWithData(device, mesh.indices.data(), indexBytes, VK_BUFFER_USAGE_INDEX_BUFFER_BIT);
    } catch (...) {
        destroyGeometry(device, geometry);
        throw;
    }
    geometry.deviceBytes = vertexBytes + indexBytes;
    return geometry;
}

void destroyGeometry(vk::Device& device, GpuGeometry& geometry)
{
    for (VkBufferView view : {geometry.texels.nodes, geometry.texels.clusters, geometry.texels.vertices, geometry.texels.strips,
                              geometry.texels.nodeTable})
        if (view)
            vkDestroyBufferView(device.device, view, nullptr);
    if (geometry.paged()) {
        vk::destroyBuffer(device, geometry.pool);
        vk::destroyBuffer(device, geometry.nodeTable);
        geometry.chunks.clear(); // their vertices and indices name the pool
    }
    for (GpuGeometry::Chunk& chunk : geometry.chunks) {
        vk::destroyBuffer(device, chunk.vertices);
        vk::destroyBuffer(device, chunk.indices);
        vk::destroyBuffer(device, chunk.rasterIndices);
    }
    for (vk::Buffer& nodes : geometry.nodeChunks)
        vk::destroyBuffer(device, nodes);
    vk::destroyBuffer(device, geometry.clusters);
    vk::destroyBuffer(device, geometry.indirect);
    vk::destroyBuffer(device, geometry.albedo);
    vk::destroyBuffer(device, geometry.leafAltitudes);
    geometry = {};
}

GeometryInputState geometryInputState(GeometryEncoding encoding, RasterIndices rasterIndices)
{
    GeometryInputState state;
    if (encoding == GeometryEncoding::UncompressedReference) {
        state.bindings[0] = {0, 3 * sizeof(float), VK_VERTEX_INPUT_RATE_VERTEX};
        state.attributes[0] = {0, 0, VK_FORMAT_R32G32B32_SFLOAT, 0};
        state.bindingCount = state.attributeCount = 1;
        state.topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST;
        state.primitiveRestart = VK_FALSE;
        return state;
    }
    state.bindings[0] = {0, sizeof(model::QuantizedVertex), VK_VERTEX_INPUT_RATE_VERTEX};
    state.bindings[1] = {1, sizeof(model::ClusterRecord), VK_VERTEX_INPUT_RATE_INSTANCE};
    // A 6-byte QuantizedVertex as R16G16_UINT (x, y) + R16_UINT (z): formats every device fetches.
    state.attributes[0] = {0, 0, VK_FORMAT_R16G16_UINT, 0};
    state.attributes[1] = {1, 1, VK_FORMAT_R32G32B32_SFLOAT, offsetof(model::ClusterRecord, boxMin)};
    state.attributes[2] = {2, 1, VK_FORMAT_R32G32B32_SFLOAT, offsetof(model::ClusterRecord, step)};
    state.attributes[3] = {3, 0, VK_FORMAT_R16_UINT, offsetof(model::QuantizedVertex, z)};
    state.bindingCount = 2;
    state.attributeCount = 4;
    if (rasterIndices == RasterIndices::Triangles) {
        state.topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST;
        state.primitiveRestart = VK_FALSE;
    }
    return state;
}

void bindChunk(VkCommandBuffer cmd, const GpuGeometry& geometry, const GpuGeometry::Chunk& chunk)
{
    VkBuffer buffers[2] = {chunk.vertices.buffer, geometry.clusters.buffer};
    VkDeviceSize offsets[2] = {0, 0};
    vkCmdBindVertexBuffers(cmd, 0, 2, buffers, offsets);
    vkCmdBindIndexBuffer(cmd, chunk.rasterIndices.buffer ? chunk.rasterIndices.buffer : chunk.indices.buffer, 0, VK_INDEX_TYPE_UINT8_EXT);
}

void drawGeometry(VkCommandBuffer cmd, const GpuGeometry& geometry, const std::function<void(uint64_t vertexBase)>& beforeChunk)
{
    VkDeviceSize zero = 0;
    for (const GpuGeometry::Chunk& chunk : geometry.chunks) {
        if (beforeChunk)
            beforeChunk(chunk.vertexBase);
        if (geometry.encoding == GeometryEncoding::UncompressedReference) {
            vkCmdBindVertexBuffers(cmd, 0, 1, &chunk.vertices.buffer, &zero);
            vkCmdBindIndexBuffer(cmd, chunk.indices.buffer, 0, VK_INDEX_TYPE_UINT32);
            vkCmdDrawIndexed(cmd, uint32_t(chunk.indexCount), 1, 0, 0, 0);
            continue;
        }
        bindChunk(cmd, geometry, chunk);
        vkCmdDrawIndexedIndirect(cmd, geometry.indirect.buffer, VkDeviceSize(chunk.firstCluster) * sizeof(VkDrawIndexedIndirectCommand),
                                 chunk.clusterCount, sizeof(VkDrawIndexedIndirectCommand));
    }
}

} // namespace penumbra
