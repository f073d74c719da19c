// A model file read in passes, for builds that do not hold the model in
// memory (penumbra preprocess --memory-limit / --chunk): PLY (ASCII and
// binary), OBJ, STL (ASCII and binary), glTF and GLB. Nothing is mapped; files
// are read through fixed buffers, and vertices that later passes need at
// random are kept in a vertex store: the input itself for binary PLY (fixed-
// size vertex records are addressable), else a temporary file of floats.
//
// The triangles, vertices, materials and colours a stream delivers are
// exactly those importScene() returns for the same file (tests compare them
// on every test and fuzz seed file), in the same order, with the same errors
// for malformed input (the message may differ in detail). Exceptions:
//   * glTF/GLB primitives are read one at a time (each accessor range with
//     pread), so memory grows with the largest primitive, not the file. A
//     KHR_draco_mesh_compression primitive is decoded whole (Draco needs its
//     whole buffer): memory grows with the largest Draco primitive;
//   * .drc files are one Draco mesh: refused (Error "...: a Draco file is one
//     compressed mesh and cannot be streamed; preprocess it without
//     --memory-limit or convert it, e.g. to PLY").
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "penumbra/mesh.h"

namespace penumbra {

struct ModelStreamOptions {
    std::string tempDirectory;                 // vertex store when the input cannot serve; "" = the input's folder
    size_t bufferBytes = size_t(4) << 20;      // each read buffer
};

// A batch of triangles in file order.
struct StreamTriangles {
    size_t count = 0;
    const uint64_t* vertices = nullptr;  // 3 vertex ids per triangle (indexed formats), or null
    const float* corners = nullptr;      // 9 floats per triangle (STL: no shared vertices), or null
    const uint32_t* materials = nullptr; // 1 per triangle (index into materials()), or null (no materials)
};

class ModelStream {
  public:
    virtual ~ModelStream() = default;

    // The first pass: checks the whole file, fills the vertex store and calls
    // onVertices for every vertex position (STL: every corner) in file order,
    // in batches (positions: 3 floats each). Must be called once, first.
    virtual void scan(const std::function<void(const float* positions, size_t count)>& onVertices) = 0;
    // Every triangle, in file order, in batches; any number of times after scan.
    virtual void triangles(const std::function<void(const StreamTriangles&)>& onTriangles) = 0;
    // Vertices [first, first + count) of the vertex store (after scan): 3 floats
    // each into positions, and into colors when the model has vertex colours
    // and colors is not null. Indexed formats only.
    virtual void readVertices(uint64_t first, uint64_t count, float* positions, float* colors) = 0;

    // Known after scan.
    bool indexed() const { return indexed_; }          // triangles name vertices (else corners)
    uint64_t vertexCount() const { return vertexCount_; }
    uint64_t triangleCount() const { return triangleCount_; }
    bool vertexColors() const { return vertexColors_; }
    const std::vector<Material>& materials() const { return materials_; } // as Mesh::materials
    const std::vector<Camera>& cameras() const { return cameras_; }
    const std::vector<Light>& lights() const { return lights_; }
    const std::string& path() const { return path_; }

  protected:
    std::string path_;
    bool indexed_ = true;
    uint64_t vertexCount_ = 0, triangleCount_ = 0;
    bool vertexColors_ = false;
    std::vector<Material> materials_;
    std::vector<Camera> cameras_;
    std::vector<Light> lights_;
};

// Opens path for streaming (the format from the extension, as importScene).
// Throws Error("<path>: <problem>") for a missing file or an unknown or
// unstreamable format; format errors come from scan().
std::unique_ptr<ModelStream> openModelStream(const std::string& path, const ModelStreamOptions& options = {});

// Reads a whole stream into a Scene (tests: it must equal importScene).
Scene readModelStream(ModelStream& stream);

} // namespace penumbra
