// Model import and export: OBJ, PLY (ASCII and binary), STL (ASCII and binary),
// glTF 2.0 (.gltf/.glb, including KHR_draco_mesh_compression) and Draco .drc.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "penumbra/mesh.h"

namespace penumbra {

enum class ModelFormat { Obj, Ply, Stl, Gltf, Glb, Draco };

// Format from the file extension (case-insensitive). Throws Error naming the
// path when the extension is unknown.
ModelFormat formatFromPath(const std::string& path);

// Reads a triangle model. Polygons are triangulated; the mesh is flattened
// into one indexed triangle list in world space (glTF node transforms are
// applied). glTF cameras and KHR_lights_punctual lights are returned in the
// scene. Throws Error("<path>: <problem>") on a missing, truncated, malformed
// or non-triangle file; never crashes on hostile input.
Scene importScene(const std::string& path);

// importScene on bytes in memory. name gives the format (by its extension) and
// is the subject of messages; glTF external buffers are resolved relative to
// its directory.
Scene importSceneMemory(std::span<const uint8_t> bytes, const std::string& name);

struct ExportOptions {
    bool binary = true;   // PLY/STL: binary or ASCII
    bool draco = false;   // GLB/glTF: compress with KHR_draco_mesh_compression
    int dracoPositionBits = 14;   // Draco (GLB/glTF/.drc): position quantization bits, 1..30
    int dracoSpeed = 5;           // Draco: 0 (smallest, slowest) .. 10 (fastest)
};

// Writes the scene's mesh (and, for glTF, its cameras and lights) to path,
// in the format its extension names. Writes to a temporary name in the same
// directory and renames, so a failed or interrupted write never leaves a
// file that looks valid. Throws Error on failure.
void exportScene(const Scene& scene, const std::string& path, const ExportOptions& options = {});

} // namespace penumbra
