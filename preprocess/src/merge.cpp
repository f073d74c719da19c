// The merge of a streamed or distributed build (streamed.h): chunk files ->
// one .penumbra file (or, for a chunk built in parts, one chunk file).
//   check     every chunk file's header (same build, every index once), then
//             each non-empty chunk whole (openChunkFile: the model as a reader
//             checks a file, the node boxes), one at a time
//   top tree  a balanced binary tree over the non-empty chunks in index order
//             (the partition numbers its cells depth first, so neighbours in
//             space are neighbours here; each chunk was built with its root at
//             the depth this tree gives it, so the depth budget holds)
//   write     sections in file order, each streamed from the chunk files with
//             pread and checked against the chunk's checksums as it is read:
//             clusters rebased (vertex, strip, node and material offsets), the
//             top nodes and the chunk roots, then every chunk's other nodes with
//             their 8-bit boxes encoded again under their new parents from the
//             chunks' exact boxes, vertices and strips copied; the header last.
// Memory: one chunk at a time (its mapping while it is checked, a box per node
// while its nodes are written) plus buffers.
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
    float rootBox[6] = {};
    // Output placement.
    uint32_t slot = 0;              // output index of the root
    uint32_t slotDepth = 0;         // its depth (output root = 1)
    uint64_t nodeBase = 0;          // output index of the chunk's node 1
    uint64_t clusterBase = 0, vertexBase = 0, indexBase = 0;
    uint32_t materialBase = 0;
    float rootDecoded[6] = {};
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
    std::memcpy(part.rootBox, file.boxes.data(), sizeof(part.rootBox));
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

// A node of the top tree: over parts[first, first + count).
struct TopNode {
    uint32_t first = 0, count = 0;
    uint32_t child[2] = {0, 0};
    float box[6];
};

uint32_t buildTop(std::vector<TopNode>& top, const std::vector<Part>& parts, uint32_t first, uint32_t count)
{
    const uint32_t index = uint32_t(top.size());
    top.emplace_back();
    top[index].first = first;
    top[index].count = count;
    float box[6] = {INFINITY, INFINITY, INFINITY, -INFINITY, -INFINITY, -INFINITY};
    for (uint32_t p = first; p < first + count; ++p)
        for (int a = 0; a < 3; ++a) {
            box[a] = std::min(box[a], parts[p].rootBox[a]);
            box[3 + a] = std::max(box[3 + a], parts[p].rootBox[3 + a]);
        }
    std::memcpy(top[index].box, box, sizeof(box));
    if (count > 1) {
        const uint32_t left = count / 2;
        const uint32_t l = buildTop(top, parts, first, left);
        const uint32_t r = buildTop(top, parts, first + left, count - left);
        top[index].child[0] = l;
        top[index].child[1] = r;
    }
    return index;
}

Box boxOf(const float* b)
{
    Box box;
    box.min = {b[0], b[1], b[2]};
    box.max = {b[3], b[4], b[5]};
    return box;
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

    // The top tree and its layout: depth first, each node's children stored consecutively after it.
    std::vector<TopNode> top;
    buildTop(top, parts, 0, uint32_t(parts.size()));
    std::vector<Node> topNodes(1);
    std::vector<float> topExact(6, 0.0f);
    struct Item {
        uint32_t top, index, depth;
        float parent[6];
    };
    const uint32_t baseDepth = into ? into->rootDepth : 1; // depth of the output's root in the final BVH
    std::vector<Item> stack{{0, 0, 1, {}}};
    for (int a = 0; a < 3; ++a) {
        stack[0].parent[a] = header.boundsMin[a];
        stack[0].parent[3 + a] = header.boundsMax[a];
    }
    uint32_t depth = 0;
    while (!stack.empty()) {
        const Item item = stack.back();
        stack.pop_back();
        const TopNode& t = top[item.top];
        const bool slot = t.count == 1;
        Part* part = slot ? &parts[t.first] : nullptr;
        const float* exact = slot ? part->rootBox : t.box;
        Node node = slot ? part->root : Node{};
        glm::vec3 decodedMin, decodedMax;
        if (item.index == 0) {
            for (int a = 0; a < 3; ++a) {
                node.lo[a] = 0;
                node.hi[a] = 255;
            }
            decodedMin = {header.boundsMin[0], header.boundsMin[1], header.boundsMin[2]};
            decodedMax = {header.boundsMax[0], header.boundsMax[1], header.boundsMax[2]};
        } else {
            uint64_t widened = 0;
            preprocess_detail::encodeBounds(node, {item.parent[0], item.parent[1], item.parent[2]},
                                            {item.parent[3], item.parent[4], item.parent[5]}, boxOf(exact), decodedMin,
                                            decodedMax, widened);
        }
        std::memcpy(&topExact[6 * size_t(item.index)], exact, 24);
        if (slot) {
            part->slot = item.index;
            part->slotDepth = item.depth;
            for (int a = 0; a < 3; ++a) {
                part->rootDecoded[a] = decodedMin[a];
                part->rootDecoded[3 + a] = decodedMax[a];
            }
            if (item.depth + baseDepth - 1 > part->header.rootDepth)
                fail(part->path, "the merged tree puts this chunk's root at depth " + std::to_string(item.depth + baseDepth - 1) +
                                     ", below the depth " + std::to_string(part->header.rootDepth) + " it was built for");
            depth = std::max(depth, item.depth + part->model.bvhDepth - 1);
            topNodes[item.index] = node; // children remapped when the chunk blocks are placed
            continue;
        }
        depth = std::max(depth, item.depth);
        node.kind = uint8_t(NodeKind::Interior);
        node.childCount = 2;
        node.first = uint32_t(topNodes.size());
        topNodes.resize(topNodes.size() + 2);
        topExact.resize(6 * topNodes.size());
        topNodes[item.index] = node;
        for (int c = 1; c >= 0; --c) {
            Item child{t.child[c], node.first + uint32_t(c), item.depth + 1, {}};
            for (int a = 0; a < 3; ++a) {
                child.parent[a] = decodedMin[a];
                child.parent[3 + a] = decodedMax[a];
            }
            stack.push_back(child);
        }
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
    auto remapNode = [](const Part& part, uint32_t n) { return n == 0 ? uint64_t(part.slot) : part.nodeBase + n - 1; };
    for (Part& part : parts) {
        Node& slot = topNodes[part.slot];
        slot.first = uint32_t(remapNode(part, slot.first));
        if (slot.kind == uint8_t(NodeKind::Cluster))
            slot.second += uint32_t(part.clusterBase);
    }

    // ---- write ----
    AtomicFileWriter out(output);
    chunk::ChunkHeader chunkHeader{};
    if (into) {
        chunkHeader = *into;
        out.write(&chunkHeader, sizeof(chunkHeader)); // rewritten at the end
    }
    Output image{out, out.written()};
    out.write(&header, sizeof(header)); // rewritten at the end
    std::unique_ptr<TemporaryFile> boxes;
    if (into)
        boxes = std::make_unique<TemporaryFile>(std::filesystem::path(output).parent_path().string().empty()
                                                    ? std::string(".")
                                                    : std::filesystem::path(output).parent_path().string(),
                                                "the node boxes of " + output);
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
                c.node = uint32_t(remapNode(part, c.node));
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
    if (boxes)
        boxes->append(topExact.data(), topExact.size() * sizeof(float));
    for (const Part& part : parts) {
        FileReader file(part.path, 4096);
        SectionReader reader(file, part.nodes, "section Nodes");
        const uint64_t count = part.model.nodeCount;
        // The decoded box of every node's parent, filled as the parents are written.
        std::vector<float> parentBox(6 * size_t(count), 0.0f);
        std::vector<float> exact;
        uint64_t n = 0;
        auto setChildren = [&](const Node& node, const glm::vec3& min, const glm::vec3& max) {
            if (node.kind == uint8_t(NodeKind::Leaf))
                return;
            for (uint32_t c = node.first; c < node.first + node.childCount; ++c)
                for (int a = 0; a < 3; ++a) {
                    parentBox[6 * size_t(c) + size_t(a)] = min[a];
                    parentBox[6 * size_t(c) + 3 + size_t(a)] = max[a];
                }
        };
        for (std::span<const uint8_t> bytes = reader.next(kBlock); !bytes.empty(); bytes = reader.next(kBlock)) {
            std::vector<Node> block(bytes.size() / sizeof(Node));
            std::memcpy(block.data(), bytes.data(), bytes.size());
            exact.resize(6 * block.size());
            file.readAt(part.header.boxesOffset + n * 24, exact.data(), exact.size() * sizeof(float));
            std::vector<Node> written;
            written.reserve(block.size());
            for (size_t k = 0; k < block.size(); ++k, ++n) {
                Node node = block[k];
                if (n == 0) {
                    setChildren(node, {part.rootDecoded[0], part.rootDecoded[1], part.rootDecoded[2]},
                                {part.rootDecoded[3], part.rootDecoded[4], part.rootDecoded[5]});
                    continue; // the root is the slot in the top nodes
                }
                const float* parent = &parentBox[6 * size_t(n)];
                glm::vec3 decodedMin, decodedMax;
                uint64_t widened = 0;
                preprocess_detail::encodeBounds(node, {parent[0], parent[1], parent[2]}, {parent[3], parent[4], parent[5]},
                                                boxOf(&exact[6 * k]), decodedMin, decodedMax, widened);
                setChildren(node, decodedMin, decodedMax);
                switch (NodeKind(node.kind)) {
                case NodeKind::Leaf:
                    node.first += uint32_t(part.clusterBase);
                    break;
                case NodeKind::Cluster:
                    node.second += uint32_t(part.clusterBase);
                    node.first = uint32_t(remapNode(part, node.first));
                    break;
                default:
                    node.first = uint32_t(remapNode(part, node.first));
                }
                written.push_back(node);
            }
            image.write(written.data(), written.size() * sizeof(Node));
            if (boxes)
                boxes->append(exact.data() + (written.size() < block.size() ? 6 : 0), written.size() * 24);
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
        // The boxes after the image, then the chunk header.
        boxes->flush();
        chunkHeader.modelOffset = image.imageBase;
        chunkHeader.modelSize = header.fileSize;
        chunkHeader.boxesOffset = out.written();
        chunkHeader.boxesSize = boxes->size();
        XXH64_state_t* state = XXH64_createState();
        XXH64_reset(state, 0);
        std::vector<uint8_t> block(kBlock);
        for (uint64_t at = 0; at < boxes->size(); at += kBlock) {
            const size_t n = size_t(std::min<uint64_t>(kBlock, boxes->size() - at));
            boxes->readAt(at, block.data(), n);
            out.write(block.data(), n);
            XXH64_update(state, block.data(), n);
        }
        chunkHeader.boxesChecksum = XXH64_digest(state);
        XXH64_freeState(state);
        static constexpr char kZeros[64] = {};
        out.write(kZeros, size_t((64 - out.written() % 64) % 64));
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
