// Procedural benchmark scenes that stand in for the paper's models.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "penumbra/mesh.h"

namespace penumbra {

struct GenerateOptions {
    uint64_t triangles = 1'000'000;  // triangle budget; the result is within a few % of it
    uint64_t seed = 1;               // same name, budget and seed: bit-identical output
};

// Names accepted by generateScene: "city", "interior", "plant", "scan".
std::vector<std::string> generatorNames();

// Builds the named scene with a suggested camera and light. Throws Error for
// an unknown name or a budget outside the generator's range.
Scene generateScene(const std::string& name, const GenerateOptions& options);

// Writes the named scene to a model file without holding it in memory, where
// a streaming writer exists: "scan" as binary PLY, the same bytes as
// exportScene(generateScene(...)) writes, for budgets up to 8 G triangles
// (inputs larger than memory for streamed preprocessing). Returns false, and
// writes nothing, for other scenes and formats. Throws Error for a bad budget
// or a write failure (nothing is left under path).
bool writeSceneStreamed(const std::string& name, const GenerateOptions& options, const std::string& path, bool binary,
                        uint64_t* triangles = nullptr, uint64_t* vertices = nullptr);

} // namespace penumbra
