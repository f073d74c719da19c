// Streamed (out-of-core) and distributed preprocessing: models larger than
// memory (issue 19). The input is read in passes through model_stream.h,
// never held whole; triangles are partitioned spatially into chunks on disk,
// each chunk is built in memory with the in-core builder (clusters, strips,
// quantization, its part of the BVH) and written as a chunk file
// (chunk_file.h), and the chunks' roots are merged under one top BVH into the
// .penumbra file. Algorithm, memory model and measurements:
// preprocess/README.md, "Streamed builds".
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "penumbra/preprocess.h"

namespace penumbra {

struct StreamedOptions {
    PreprocessOptions build;         // the in-core builder's options (progress is ignored)
    uint64_t memoryLimit = 0;        // bytes the build may use beyond the process's baseline (0: 1 GiB)
    std::string tempDirectory;       // chunk temporaries and chunk files ("": the output's folder)
    uint32_t chunks = 0;             // preprocessStreamed: chunks of the partition (0: from the memory limit); a chunk
                                     // larger than the limit allows is still built in parts
    uint64_t chunkTriangles = 0;     // tests: triangles one chunk may have (0: chunkCapacity(memoryLimit))
    // Called on the calling thread with a stage ("scan", "partition", "chunk 3/8", "merge") and its fraction done.
    std::function<void(const std::string& stage, double fraction)> progress;
};

struct StreamedStats {
    uint64_t inputTriangles = 0;      // triangles of the input
    uint64_t triangles = 0;           // stored
    uint64_t vertices = 0;            // of the input (indexed formats)
    uint32_t chunks = 0;              // chunk files built (after any splits of chunks too large for memory)
    uint64_t largestChunk = 0;        // triangles of the largest chunk built in one piece
    uint64_t chunkCapacity = 0;       // triangles one chunk may have within the memory limit
    uint64_t temporaryBytes = 0;      // largest disk use of temporaries at once (chunk records, vertex store, chunk files)
    uint64_t closedTriangles = 0;     // stored triangles of closed components (cut components count as open)
    uint64_t closedClusterTriangles = 0;
    double vertexCacheHitRate = 0;    // of the partition pass's vertex reads
    double scanSeconds = 0, partitionSeconds = 0, buildSeconds = 0, mergeSeconds = 0, totalSeconds = 0;
    uint64_t fileBytes = 0;           // the output's size
    float maxPositionError = 0;
    uint32_t bvhDepth = 0;
    uint64_t clusters = 0, nodes = 0;
};

// Triangles one chunk may hold when the build may use memoryLimit bytes
// (the in-core builder's measured peak per triangle, the chunk's records and
// the closed-component test), at least 1024.
uint64_t chunkCapacity(uint64_t memoryLimit, const PreprocessOptions& options);

// input -> output (.penumbra) within options.memoryLimit: scan, partition, build
// each chunk, merge. Temporaries are unnamed or removed; the output appears
// only when complete (temporary name, fsync, rename). Throws Error naming the
// file and the problem: unreadable or unstreamable input, a model beyond the
// format's limits (checked after the scan, before any chunk is built), disk full.
StreamedStats preprocessStreamed(const std::string& input, const std::string& output, const StreamedOptions& options);

// Chunk `index` of `count` of input -> a chunk file (penumbra preprocess --chunk I/N).
// Every process of one build must be given the same input, count and build
// options: they compute the same partition from the same scan. A chunk too large
// for options.memoryLimit is split and merged inside its file.
StreamedStats preprocessChunk(const std::string& input, const std::string& chunkPath, uint32_t index, uint32_t count,
                              const StreamedOptions& options);

// Chunk files of one build (every index 0..count-1 exactly once, in any order)
// -> output (.penumbra). Corrupt, missing, duplicate or mismatched chunks give
// Error("<chunk file>: <problem>") before the output is started. Memory: the
// largest chunk file (each is validated whole) plus buffers.
StreamedStats mergeChunkFiles(const std::vector<std::string>& chunks, const std::string& output,
                              const StreamedOptions& options);

} // namespace penumbra
