// The merge of a streamed or distributed build (streamed.h): chunk files ->
// one .penumbra file (or, for a chunk built in parts, one chunk file).
//   check     every chunk file's header (same build, every index once), then
//             each non-empty chunk whole (openChunkFile: the model as a reader
//             checks a file), one at a time
//   top tree  a balanced binary tree over the non-empty chunks in index order
//             (the partition numbers its cells depth first, so neighbours in
//             space are neighbours here), collapsed into 4-wide nodes by the
//             layout stage's collapse (layoutSubtrees) with the chunks' roots
//             as opaque children; each chunk was built with its root at the
//             depth this gives it (subtreeRootDepth), so the depth budget holds
//   write     sections in file order, each streamed from the chunk files with
//             pread and checked against the chunk's checksums as it is read:
//             clusters rebased (vertex, strip, node and material offsets), the
//             top nodes with the chunks' roots in their places, then every
//             chunk's other nodes, vertices and strips. A version-4 node's child
//             boxes lie on a grid of its own, so the chunks' nodes are copied
//             with only their node and cluster indices rebased. The header last.
// Memory: one chunk at a time (its mapping while it is checked) plus buffers.
#include <xxhash.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <map>

#include "penumbra/error.h"
#include "penumbra/file_io.h"
#include "streamed_internal.h"

namespace penumbra::streamed_detail {

namespace {

using namespace model;

struct Section {
    uint64_t offset = 0; // in the chunk file
    uint64_t size = 0;
    uint64_t checksum = 0;
};

// What the merge keeps of a checked chunk.
struct Part {
    std::string path;
    chunk::ChunkHeader header{};
    FileHeader model{};
    Section clusters, nodes, vertices, indices;
    std::vector<MaterialRecord> materials;
    std::vector<CameraRecord> cameras;
    std::vector<LightRecord> lights;
    Node root{};
    // Output placement.
    uint32_t slot = 0;              // output index of the root
    uint32_t slotDepth = 0;         // its depth (output root = 1)
    uint64_t nodeBase = 0;          // output index of the chunk's node 1
    uint64_t clusterBase = 0, vertexBase = 0, indexBase = 0;
    uint32_t materialBase = 0;

    uint32_t node(uint32_t n) const { return n == 0 ? slot : uint32_t(nodeBase + n - 1); }
    // A node of this chunk with its node and cluster indices rebased (leaf ranges are
    // relative to their cluster's strips: unchanged).
    Node rebased(Node node) const
    {
        if (node.cluster != kNoCluster)
            node.cluster += uint32_t(clusterBase);
        for (uint32_t c = 0; c < kNodeChildren; ++c) {
            const ChildKind kind = childKind(node, c);
            if (kind == ChildKind::Interior || kind == ChildKind::Cluster)
                node.child[c] = this->node(node.child[c]);
        }
        return node;
    }
};

const SectionEntry* findSection(const FileHeader& header, SectionType type)
{
    for (const SectionEntry& entry : header.sections)
        if (entry.type == uint32_t(type))
            return &entry;
    return nullptr;
}

Part checkPart(const std::string& path, const chunk::ChunkHeader& header)
{
    Part part;
    part.path = path;
    part.header = header;
    ChunkFile file = openChunkFile(path);
    const CompressedModel& m = file.model;
    part.model = m.header;
    auto section = [&](SectionType type) {
        const SectionEntry* entry = findSection(m.header, type);
        Section s;
        if (entry) {
            s.offset = header.modelOffset + entry->offset;
            s.size = entry->size;
            s.checksum = entry->checksum;
        }
        return s;
    };
    part.clusters = section(SectionType::Clusters);
    part.nodes = section(SectionType::Nodes);
    part.vertices = section(SectionType::Vertices);
    part.indices = section(SectionType::Indices);
    part.materials.assign(m.materials.begin(), m.materials.end());
    part.cameras.assign(m.cameras.begin(), m.cameras.end());
    part.lights.assign(m.lights.begin(), m.lights.end());
    part.root = m.nodes[0];
    return part;
}

// Reads a section of a chunk file in blocks, checking its checksum at the end.
class SectionReader {
  public:
    SectionReader(FileReader& file, const Section& section, const std::string& name)
        : file_(file), section_(section), name_(name)
    {
        state_ = XXH64_createState();
        XXH64_reset(state_, 0);
    }
    ~SectionReader() { XXH64_freeState(state_); }
    // Up to `bytes` bytes more (a multiple of the element size the caller wants); empty at the end.
    std::span<const uint8_t> next(size_t bytes)
    {
        const uint64_t left = section_.size - done_;
        const size_t n = size_t(std::min<uint64_t>(left, bytes));
        buffer_.resize(n);
        if (n > 0) {
            file_.readAt(section_.offset + done_, buffer_.data(), n);
            XXH64_update(state_, buffer_.data(), n);
        }
        done_ += n;
        if (done_ == section_.size && !checked_) {
            checked_ = true;
            if (XXH64_digest(state_) != section_.checksum)
                fail(file_.path(), "checksum mismatch in " + name_ + " (the file changed during the merge?)");
        }
        return buffer_;
    }

  private:
    FileReader& file_;
    Section section_;
    std::string name_;
    XXH64_state_t* state_;
    std::vector<uint8_t> buffer_;
    uint64_t done_ = 0;
    bool checked_ = false;
};

// The output: a writer and a running checksum of the current section.
struct Output {
    AtomicFileWriter& out;
    uint64_t imageBase;
    XXH64_state_t* state = XXH64_createState();
    ~Output() { XXH64_freeState(state); }
    SectionEntry begin(SectionType type, uint32_t elementSize)
    {
        static constexpr char kZeros[64] = {};
        const uint64_t at = out.written() - imageBase;
        out.write(kZeros, size_t((64 - at % 64) % 64));
        SectionEntry entry{};
        entry.type = uint32_t(type);
        entry.elementSize = elementSize;
        entry.offset = out.written() - imageBase;
        XXH64_reset(state, 0);
        return entry;
    }
    void write(const void* data, size_t size)
    {
        out.write(data, size);
        XXH64_update(state, data, size);
    }
    void end(SectionEntry& entry)
    {
        entry.size = out.written() - imageBase - entry.offset;
        entry.checksum = XXH64_digest(state);
    }
};

// A balanced binary tree over parts[first, first + count) (leaves: TopNode::cluster = part
// index) for layoutSubtrees; returns its node.
uint32_t buildTop(preprocess_detail::TopTree& tree, std::vector<Box>& boxes, const std::vector<Part>& parts, uint32_t first,
                  uint32_t count)
{
    using preprocess_detail::kNone;
    const uint32_t index = uint32_t(tree.nodes.size());
    tree.nodes.push_back({0, 0, {0, 0}, 0, count == 1 ? first : kNone, 0});
    boxes.emplace_back();
    if (count == 1) {
        const FileHeader& h = parts[first].model;
        boxes[index].min = {h.boundsMin[0], h.boundsMin[1], h.boundsMin[2]};
        boxes[index].max = {h.boundsMax[0], h.boundsMax[1], h.boundsMax[2]};
        return index;
    }
    const uint32_t left = count / 2;
    const uint32_t l = buildTop(tree, boxes, parts, first, left);
    const uint32_t r = buildTop(tree, boxes, parts, first + left, count - left);
    tree.nodes[index].child[0] = l;
    tree.nodes[index].child[1] = r;
    tree.nodes[index].childCount = 2;
    boxes[index] = boxes[l];
    boxes[index].grow(boxes[r]);
    return index;
}

} // namespace

MergeResult mergeChunks(const std::vector<std::string>& paths, const std::string& output, const chunk::ChunkHeader* into,
                        const std::function<void(double)>& progress)
{
    if (paths.empty())
        fail(output, "no chunk files to merge");
    // ---- check: headers first (cheap), then each chunk whole ----
    std::vector<chunk::ChunkHeader> headers;
    headers.reserve(paths.size());
    for (const std::string& path : paths)
        headers.push_back(readChunkHeader(path));
    const chunk::ChunkHeader& first = headers[0];
    std::vector<int64_t> byIndex(first.chunkCount, -1);
    for (size_t i = 0; i < paths.size(); ++i) {
        const chunk::ChunkHeader& h = headers[i];
        if (h.fingerprint != first.fingerprint || h.chunkCount != first.chunkCount || h.inputTriangles != first.inputTriangles)
            fail(paths[i], "belongs to another build than " + paths[0] + " (its input, options or chunk count differ: chunk " +
                               std::to_string(h.chunkIndex) + " of " + std::to_string(h.chunkCount) + ", against " +
                               std::to_string(first.chunkCount) + ")");
        if (byIndex[h.chunkIndex] >= 0)
            fail(paths[i], "chunk " + std::to_string(h.chunkIndex) + " of " + std::to_string(h.chunkCount) + " again (also " +
                               paths[size_t(byIndex[h.chunkIndex])] + ")");
        byIndex[h.chunkIndex] = int64_t(i);
    }
    for (uint32_t c = 0; c < first.chunkCount; ++c)
        if (byIndex[c] < 0)
            fail(output, "chunk " + std::to_string(c) + " of " + std::to_string(first.chunkCount) +
                             " is missing (no chunk file given holds it; the " + std::to_string(paths.size()) +
                             " given include " + paths[0] + ")");
    std::vector<Part> parts;
    uint64_t droppedDegenerate = 0;
    for (uint32_t c = 0; c < first.chunkCount; ++c) {
        const size_t i = size_t(byIndex[c]);
        droppedDegenerate += headers[i].droppedDegenerate;
        if (headers[i].flags & chunk::kFlagEmpty)
            continue;
        parts.push_back(checkPart(paths[i], headers[i]));
        if (progress)
            progress(0.1 * double(c + 1) / double(first.chunkCount));
    }
    if (parts.empty())
        fail(output, "no triangles: every chunk is empty");
    const Part& reference = parts[0];
    for (const Part& part : parts)
        if (std::memcmp(&part.model.build, &reference.model.build, sizeof(BuildParameters)) != 0)
            fail(part.path, "built with other build parameters than " + reference.path);

    // ---- placement ----
    MergeResult result;
    FileHeader header{};
    uint64_t clusters = 0, vertices = 0, indexBytes = 0;
    bool sharedMaterials = true;
    for (const Part& part : parts)
        sharedMaterials &= part.materials.size() == reference.materials.size() &&
                           std::memcmp(part.materials.data(), reference.materials.data(),
                                       part.materials.size() * sizeof(MaterialRecord)) == 0;
    uint64_t materials = sharedMaterials ? reference.materials.size() : 0;
    for (Part& part : parts) {
        part.clusterBase = clusters;
        part.vertexBase = vertices;
        part.indexBase = indexBytes;
        part.materialBase = sharedMaterials ? 0 : uint32_t(materials);
        clusters += part.model.clusterCount;
        vertices += part.model.vertexCount;
        indexBytes += part.model.indexBytes;
        if (!sharedMaterials)
            materials += part.materials.size();
        result.triangles += part.model.triangleCount;
        result.maxPositionError = std::max(result.maxPositionError, part.model.maxPositionError);
        result.closedTriangles += part.header.closedTriangles;
        result.closedClusterTriangles += part.header.closedClusterTriangles;
        result.closedClusters += part.header.closedClusters;
        for (int a = 0; a < 3; ++a) {
            header.boundsMin[a] = &part == &parts[0] ? part.model.boundsMin[a] : std::min(header.boundsMin[a], part.model.boundsMin[a]);
            header.boundsMax[a] = &part == &parts[0] ? part.model.boundsMax[a] : std::max(header.boundsMax[a], part.model.boundsMax[a]);
        }
    }
    if (clusters > kMaxClusters)
        fail(output, std::to_string(clusters) + " clusters, more than the format's " + std::to_string(kMaxClusters));
    if (materials > kMaxMaterials)
        fail(output, std::to_string(materials) + " cluster colours in the chunks' material tables, more than the format's " +
                         std::to_string(kMaxMaterials) + " entries (a model with vertex colours this large needs fewer chunks)");

    // The top nodes: the layout stage's collapse over the chunks' roots (one chunk: its root is the root).
    const uint32_t baseDepth = into ? into->rootDepth : 1; // depth of the output's root in the final BVH
    std::vector<Node> topNodes(1);
    uint32_t depth = 1;
    if (parts.size() == 1) {
        parts[0].slot = 0;
        parts[0].slotDepth = 1;
    } else {
        preprocess_detail::TopTree tree;
        std::vector<Box> boxes;
        buildTop(tree, boxes, parts, 0, uint32_t(parts.size()));
        preprocess_detail::Layout layout = preprocess_detail::layoutSubtrees(tree, boxes);
        topNodes = std::move(layout.nodes);
        depth = layout.depth;
        for (size_t p = 0; p < parts.size(); ++p) {
            parts[p].slot = layout.subtreeNode[p];
            parts[p].slotDepth = layout.subtreeDepth[p];
        }
    }
    for (const Part& part : parts) {
        if (part.slotDepth + baseDepth - 1 > part.header.rootDepth)
            fail(part.path, "the merged tree puts this chunk's root at depth " + std::to_string(part.slotDepth + baseDepth - 1) +
                                ", below the depth " + std::to_string(part.header.rootDepth) + " it was built for");
        depth = std::max(depth, part.slotDepth + part.model.bvhDepth - 1);
    }
    uint64_t nodes = topNodes.size();
    for (Part& part : parts) {
        part.nodeBase = nodes;
        nodes += part.model.nodeCount - 1;
    }
    if (nodes > kMaxNodes)
        fail(output, std::to_string(nodes) + " BVH nodes, more than the format's " + std::to_string(kMaxNodes) +
                         " (32-bit node indices)");
    if (depth + baseDepth - 1 > kMaxBvhDepth)
        fail(output, "internal error: merged BVH depth " + std::to_string(depth + baseDepth - 1));
    for (const Part& part : parts)
        topNodes[part.slot] = part.rebased(part.root);

    // ---- write ----
    AtomicFileWriter out(output);
    chunk::ChunkHeader chunkHeader{};
    if (into) {
        chunkHeader = *into;
        out.write(&chunkHeader, sizeof(chunkHeader)); // rewritten at the end
    }
    Output image{out, out.written()};
    out.write(&header, sizeof(header)); // rewritten at the end
    const uint64_t totalBytes = std::max<uint64_t>(1, clusters * sizeof(ClusterRecord) + nodes * sizeof(Node) +
                                                          vertices * sizeof(QuantizedVertex) + indexBytes);
    uint64_t doneBytes = 0;
    auto advance = [&](uint64_t bytes) {
        doneBytes += bytes;
        if (progress)
            progress(0.1 + 0.9 * double(doneBytes) / double(totalBytes));
    };
    constexpr size_t kBlock = size_t(1) << 20;
    std::vector<SectionEntry> entries;

    SectionEntry entry = image.begin(SectionType::Clusters, sizeof(ClusterRecord));
    for (const Part& part : parts) {
        FileReader file(part.path, 4096);
        SectionReader reader(file, part.clusters, "section Clusters");
        for (std::span<const uint8_t> bytes = reader.next(kBlock); !bytes.empty(); bytes = reader.next(kBlock)) {
            std::vector<ClusterRecord> records(bytes.size() / sizeof(ClusterRecord));
            std::memcpy(records.data(), bytes.data(), bytes.size());
            for (ClusterRecord& c : records) {
                c.firstVertex += part.vertexBase;
                c.firstIndex += part.indexBase;
                c.node = part.node(c.node);
                c.material += part.materialBase;
            }
            image.write(records.data(), records.size() * sizeof(ClusterRecord));
            advance(bytes.size());
        }
    }
    image.end(entry);
    entries.push_back(entry);

    entry = image.begin(SectionType::Nodes, sizeof(Node));
    image.write(topNodes.data(), topNodes.size() * sizeof(Node));
    for (const Part& part : parts) {
        FileReader file(part.path, 4096);
        SectionReader reader(file, part.nodes, "section Nodes");
        bool root = true; // node 0 is in topNodes
        for (std::span<const uint8_t> bytes = reader.next(kBlock); !bytes.empty(); bytes = reader.next(kBlock)) {
            std::vector<Node> block(bytes.size() / sizeof(Node));
            std::memcpy(block.data(), bytes.data(), bytes.size());
            const size_t skip = root ? 1 : 0;
            root = false;
            for (size_t k = skip; k < block.size(); ++k)
                block[k] = part.rebased(block[k]);
            image.write(block.data() + skip, (block.size() - skip) * sizeof(Node));
            advance(bytes.size());
        }
    }
    image.end(entry);
    entries.push_back(entry);

    for (SectionType type : {SectionType::Vertices, SectionType::Indices}) {
        entry = image.begin(type, type == SectionType::Vertices ? sizeof(QuantizedVertex) : 1);
        for (const Part& part : parts) {
            FileReader file(part.path, 4096);
            SectionReader reader(file, type == SectionType::Vertices ? part.vertices : part.indices,
                                 type == SectionType::Vertices ? "section Vertices" : "section Indices");
            for (std::span<const uint8_t> bytes = reader.next(kBlock); !bytes.empty(); bytes = reader.next(kBlock)) {
                image.write(bytes.data(), bytes.size());
                advance(bytes.size());
            }
        }
        image.end(entry);
        entries.push_back(entry);
    }
    entry = image.begin(SectionType::Materials, sizeof(MaterialRecord));
    if (sharedMaterials)
        image.write(reference.materials.data(), reference.materials.size() * sizeof(MaterialRecord));
    else
        for (const Part& part : parts)
            image.write(part.materials.data(), part.materials.size() * sizeof(MaterialRecord));
    image.end(entry);
    entries.push_back(entry);
    const Part* scene = &reference;
    if (!reference.cameras.empty()) {
        entry = image.begin(SectionType::Cameras, sizeof(CameraRecord));
        image.write(scene->cameras.data(), scene->cameras.size() * sizeof(CameraRecord));
        image.end(entry);
        entries.push_back(entry);
    }
    if (!reference.lights.empty()) {
        entry = image.begin(SectionType::Lights, sizeof(LightRecord));
        image.write(scene->lights.data(), scene->lights.size() * sizeof(LightRecord));
        image.end(entry);
        entries.push_back(entry);
    }
    {
        static constexpr char kZeros[64] = {};
        const uint64_t at = out.written() - image.imageBase;
        out.write(kZeros, size_t((64 - at % 64) % 64));
    }

    std::memcpy(header.magic, kMagic, sizeof(kMagic));
    header.version = kVersion;
    header.headerSize = sizeof(FileHeader);
    header.fileSize = out.written() - image.imageBase;
    header.triangleCount = result.triangles;
    header.sourceTriangleCount = reference.model.sourceTriangleCount;
    header.vertexCount = vertices;
    header.indexBytes = indexBytes;
    header.clusterCount = uint32_t(clusters);
    header.nodeCount = uint32_t(nodes);
    header.bvhDepth = depth;
    header.materialCount = uint32_t(materials);
    header.maxPositionError = result.maxPositionError;
    header.simplifyError = 0.0f;
    header.build = reference.model.build;
    for (size_t i = 0; i < entries.size(); ++i)
        header.sections[i] = entries[i];
    header.cameraCount = uint32_t(scene->cameras.size());
    header.lightCount = uint32_t(scene->lights.size());
    header.headerChecksum = 0;
    header.headerChecksum = XXH64(&header, sizeof(header), 0);
    out.writeAt(image.imageBase, &header, sizeof(header));
    if (into) {
        chunkHeader.modelOffset = image.imageBase;
        chunkHeader.modelSize = header.fileSize;
        chunkHeader.fileSize = out.written();
        chunkHeader.flags &= ~chunk::kFlagEmpty;
        chunkHeader.droppedDegenerate = droppedDegenerate;
        chunkHeader.closedTriangles = result.closedTriangles;
        chunkHeader.closedClusterTriangles = result.closedClusterTriangles;
        chunkHeader.closedClusters = result.closedClusters;
        std::memcpy(chunkHeader.magic, chunk::kMagic, sizeof(chunk::kMagic));
        chunkHeader.version = chunk::kVersion;
        chunkHeader.headerSize = sizeof(chunk::ChunkHeader);
        chunkHeader.headerChecksum = 0;
        chunkHeader.headerChecksum = XXH64(&chunkHeader, sizeof(chunkHeader), 0);
        out.writeAt(0, &chunkHeader, sizeof(chunkHeader));
    }
    out.commit(AtomicFileWriter::Durability::Synced);
    result.clusters = clusters;
    result.nodes = nodes;
    result.bvhDepth = depth;
    result.fileBytes = std::filesystem::file_size(output);
    return result;
}

} // namespace penumbra::streamed_detail
