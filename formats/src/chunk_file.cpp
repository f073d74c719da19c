// Chunk files of streamed and distributed builds (chunk_file.h): written to a
// temporary name and renamed; read back with every field checked, so a
// corrupt, truncated or foreign chunk gives one line naming the file.
#include "penumbra/chunk_file.h"

#include <xxhash.h>

#include <cmath>
#include <cstring>

#include "io_internal.h"

namespace penumbra {

namespace {

using chunk::ChunkHeader;

uint64_t headerChecksum(ChunkHeader header)
{
    header.headerChecksum = 0;
    return XXH64(&header, sizeof(header), 0);
}

// Checks of the header alone against the file size; throws Error("<path>: ...").
void checkHeader(const ChunkHeader& h, uint64_t fileSize, const std::string& path)
{
    if (std::memcmp(h.magic, chunk::kMagic, sizeof(h.magic)) != 0)
        fail(path, "not a Penumbra chunk file (bad magic)");
    if (h.version != chunk::kVersion)
        fail(path, "unsupported chunk file version " + std::to_string(h.version) + " (this build reads version " +
                       std::to_string(chunk::kVersion) + "; build the chunk again)");
    if (h.headerSize != sizeof(ChunkHeader))
        fail(path, "chunk header size " + std::to_string(h.headerSize) + " is not " + std::to_string(sizeof(ChunkHeader)));
    if (headerChecksum(h) != h.headerChecksum)
        fail(path, "chunk header checksum mismatch (corrupt file)");
    if (h.fileSize > fileSize)
        fail(path, "truncated: chunk header says " + std::to_string(h.fileSize) + " bytes, file has " + std::to_string(fileSize));
    if (h.fileSize < fileSize)
        fail(path, "trailing data: chunk header says " + std::to_string(h.fileSize) + " bytes, file has " +
                       std::to_string(fileSize));
    if (h.chunkCount == 0 || h.chunkIndex >= h.chunkCount)
        fail(path, "chunk index " + std::to_string(h.chunkIndex) + " is not below the chunk count " +
                       std::to_string(h.chunkCount));
    if (h.rootDepth < 1 || h.rootDepth > model::kMaxBvhDepth)
        fail(path, "chunk root depth " + std::to_string(h.rootDepth) + " is outside 1.." + std::to_string(model::kMaxBvhDepth));
    if (h.flags & ~chunk::kFlagEmpty)
        fail(path, "unknown chunk flag bits");
    for (uint64_t r : h.reserved)
        if (r != 0)
            fail(path, "reserved chunk header field is not zero");
    if (h.chunkTriangles > h.inputTriangles || h.droppedDegenerate > h.chunkTriangles)
        fail(path, "chunk triangle counts are inconsistent");
    for (int a = 0; a < 3; ++a)
        if (std::isnan(h.cellMin[a]) || std::isnan(h.cellMax[a]) || h.cellMin[a] > h.cellMax[a])
            fail(path, "chunk cell is not a box");
    const bool empty = (h.flags & chunk::kFlagEmpty) != 0;
    if (empty) {
        if (h.modelOffset || h.modelSize || h.fileSize != sizeof(h) ||
            h.closedTriangles || h.closedClusterTriangles || h.closedClusters || h.chunkTriangles != h.droppedDegenerate)
            fail(path, "an empty chunk with a model");
        return;
    }
    if (h.modelOffset != sizeof(ChunkHeader) || h.modelSize % 64 != 0 || h.modelSize < sizeof(model::FileHeader) ||
        h.modelSize > fileSize - h.modelOffset)
        fail(path, "chunk model image at " + std::to_string(h.modelOffset) + "+" + std::to_string(h.modelSize) +
                       " does not fit the file (" + std::to_string(fileSize) + " bytes)");
    if (h.modelOffset + h.modelSize != h.fileSize)
        fail(path, "chunk model image at " + std::to_string(h.modelOffset) + "+" + std::to_string(h.modelSize) +
                       " does not end the file (" + std::to_string(h.fileSize) + " bytes)");
}

} // namespace

void writeChunkFile(const std::string& path, ChunkHeader header, const CompressedModel* model)
{
    std::memcpy(header.magic, chunk::kMagic, sizeof(header.magic));
    header.version = chunk::kVersion;
    header.headerSize = sizeof(ChunkHeader);
    AtomicFileWriter out(path);
    out.write(&header, sizeof(header)); // rewritten at the end
    if (!model) {
        header.flags |= chunk::kFlagEmpty;
        header.modelOffset = header.modelSize = 0;
        header.fileSize = sizeof(header);
    } else {
        header.flags &= ~chunk::kFlagEmpty;
        header.modelOffset = sizeof(header);
        header.modelSize = detail::writeModelImage(*model, out, path);
        header.fileSize = header.modelOffset + header.modelSize;
    }
    header.headerChecksum = headerChecksum(header);
    checkHeader(header, header.fileSize, path + ": refusing to write an invalid chunk");
    out.writeAt(0, &header, sizeof(header));
    out.commit(AtomicFileWriter::Durability::Synced);
}

chunk::ChunkHeader readChunkHeader(const std::string& path)
{
    FileReader file(path, 4096);
    ChunkHeader header;
    if (file.size() < sizeof(header)) {
        if (file.size() >= sizeof(chunk::kMagic)) {
            char magic[8];
            file.readAt(0, magic, 8);
            if (std::memcmp(magic, chunk::kMagic, 8) != 0)
                fail(path, "not a Penumbra chunk file (bad magic)");
        }
        fail(path, "truncated: file has " + std::to_string(file.size()) + " bytes, the chunk header alone needs " +
                       std::to_string(sizeof(header)));
    }
    file.readAt(0, &header, sizeof(header));
    checkHeader(header, file.size(), path);
    return header;
}

ChunkFile openChunkFile(const std::string& path)
{
    ChunkFile result;
    result.header = readChunkHeader(path);
    if (result.empty())
        return result;
    auto file = std::make_shared<detail::MappedFile>(path);
    if (file->size() != result.header.fileSize)
        fail(path, "the file changed while it was read");
    const ChunkHeader& h = result.header;
    std::span<const uint8_t> image(file->data() + h.modelOffset, size_t(h.modelSize));
    result.model = openModelMemory(image, file, path);
    if (result.model.header.bvhDepth + h.rootDepth - 1 > model::kMaxBvhDepth)
        fail(path, "the chunk's BVH (" + std::to_string(result.model.header.bvhDepth) + " levels) does not fit below depth " +
                       std::to_string(h.rootDepth) + " of a " + std::to_string(model::kMaxBvhDepth) + "-level BVH");
    result.storage = file;
    return result;
}

} // namespace penumbra
