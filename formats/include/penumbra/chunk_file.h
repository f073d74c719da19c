// Chunk files: one spatial chunk of a streamed or distributed build
// (penumbra preprocess --memory-limit / --chunk I/N), joined into the
// .penumbra file by penumbra merge (preprocess/README.md, "Streamed builds").
//
// Layout: a 256-byte ChunkHeader, then (unless the chunk is empty) a complete
// .penumbra model image of the chunk (the current format version, validated
// like a file, its BVH root at depth rootDepth of the merged BVH). Version 4
// nodes decode without their parents, so the merge copies them with their
// indices rebased and lays out new nodes only above the chunks' roots.
// Little-endian, sections 64-byte aligned, checksummed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "penumbra/model_format.h"

namespace penumbra {

namespace chunk {

inline constexpr char kMagic[8] = {'P', 'E', 'N', 'B', 'C', 'H', 'N', 'K'};
inline constexpr uint32_t kVersion = 2; // 1: model format 3 and a box per node
inline constexpr uint32_t kFlagEmpty = 1u << 0; // no triangles: no model

struct ChunkHeader {
    char magic[8];                  // kMagic
    uint32_t version;               // kVersion
    uint32_t headerSize;            // sizeof(ChunkHeader)
    uint64_t fileSize;              // total bytes, a multiple of 64
    uint64_t fingerprint;           // equal for all chunks of one build: input, options, chunk count, partition
    uint32_t chunkIndex;            // 0..chunkCount-1
    uint32_t chunkCount;            // >= 1
    uint32_t rootDepth;             // depth of the chunk's root node in the merged 4-wide BVH (root = 1), 1..kMaxBvhDepth
    uint32_t flags;                 // kFlagEmpty; other bits 0
    uint64_t inputTriangles;        // triangles of the whole input (all chunks)
    uint64_t chunkTriangles;        // input triangles assigned to this chunk (degenerate ones included)
    uint64_t droppedDegenerate;     // of those, not stored (a repeated vertex index or, streamed, position)
    uint64_t closedTriangles;       // stored triangles of closed components (conservative across chunks)
    uint64_t closedClusterTriangles;// triangles of clusters flagged kClusterClosed
    uint64_t closedClusters;
    float cellMin[3];               // the chunk's region (centroids inside it); may be infinite
    float cellMax[3];
    uint64_t modelOffset;           // the .penumbra image: right after this header (0 when empty)
    uint64_t modelSize;             // a multiple of 64; the file ends with the image
    uint64_t reserved[14];          // 0
    uint64_t headerChecksum;        // XXH64 of this struct with headerChecksum = 0
};
static_assert(sizeof(ChunkHeader) == 256);
static_assert(offsetof(ChunkHeader, chunkIndex) == 32 && offsetof(ChunkHeader, inputTriangles) == 48 &&
                  offsetof(ChunkHeader, cellMin) == 96 && offsetof(ChunkHeader, modelOffset) == 120 &&
                  offsetof(ChunkHeader, reserved) == 136 && offsetof(ChunkHeader, headerChecksum) == 248,
              "ChunkHeader layout is documented in formats/README.md");

} // namespace chunk

// A chunk file read and validated: the header and the model (its spans point
// into the mapping). An empty chunk has no model.
struct ChunkFile {
    chunk::ChunkHeader header{};
    CompressedModel model;           // empty when header.flags & kFlagEmpty
    std::shared_ptr<const void> storage;
    bool empty() const { return (header.flags & chunk::kFlagEmpty) != 0; }
};

// Writes a chunk file: header (magic, version, sizes, offsets and checksum
// filled in here) and the model image (validated as writeModelFile does; null
// for an empty chunk); to a temporary name, fsynced, then renamed. Throws
// Error("<path>: ...").
void writeChunkFile(const std::string& path, chunk::ChunkHeader header, const CompressedModel* model);

// Reads only the header (checked: magic, version, size, checksum, fields).
// Throws Error("<path>: <problem>") in one line.
chunk::ChunkHeader readChunkHeader(const std::string& path);

// Maps a chunk file and validates all of it: header and model
// (openModelMemory). Throws Error("<path>: <problem>").
ChunkFile openChunkFile(const std::string& path);

} // namespace penumbra
