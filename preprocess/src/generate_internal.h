// Shared pieces of the procedural generators (generate.cpp, city.cpp, interior.cpp,
// plant.cpp, scan.cpp). Not installed.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include <glm/vec2.hpp>

#include "mesh_builder.h"
#include "penumbra/generate.h"

namespace penumbra::detail {

// splitmix64: tiny, fast, identical on every platform (unlike std:: distributions).
struct Rng {
    uint64_t state;
    explicit Rng(uint64_t seed) : state(seed) {}
    uint64_t next()
    {
        uint64_t z = (state += 0x9e3779b97f4a7c15ull);
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
        return z ^ (z >> 31);
    }
    float uniform() { return float(next() >> 40) * (1.0f / 16777216.0f); } // [0, 1)
    float uniform(float lo, float hi) { return lo + (hi - lo) * uniform(); }
    uint32_t below(uint32_t n) { return uint32_t(((next() >> 32) * n) >> 32); } // [0, n)
    bool chance(float p) { return uniform() < p; }
};

// Independent seed for sub-stream 'salt' of 'seed'.
inline uint64_t mixSeed(uint64_t seed, uint64_t salt)
{
    Rng rng(seed ^ (salt * 0xd1b54a32d192ed03ull + 0x632be59bd9b4e019ull));
    rng.next();
    return rng.next();
}

// Cell of the index-th unit when units are laid out in square rings around (0, 0).
glm::ivec2 spiralCell(uint64_t index);
// Ring radius that holds the first 'count' units (0 for count <= 1).
int spiralRadius(uint64_t count);

using UnitBuild = std::function<void(MeshBuilder&, uint64_t unit)>;
using FinishBuild = std::function<void(MeshBuilder&, uint64_t unitCount)>;

// Builds a mesh of up to maxUnits independent units (unit k built by buildUnit(b, k))
// followed by finish (typically a ground grid that takes up the remaining budget).
// Units are counted first, in order, until the budget is spent (the last one may be
// truncated); then storage is allocated exactly and units are emitted in parallel at
// fixed offsets, so the result does not depend on the thread count.
Mesh buildUnits(const std::string& subject, uint64_t triangleBudget, uint64_t maxUnits, const UnitBuild& buildUnit,
                const FinishBuild& finish);

Scene generateCity(const GenerateOptions& options);
Scene generateInterior(const GenerateOptions& options);
Scene generatePlant(const GenerateOptions& options);
Scene generateScan(const GenerateOptions& options);
// The scan as binary PLY written row by row (exportPly's bytes), never held in memory.
void writeScanPly(const GenerateOptions& options, const std::string& path, uint64_t& triangles, uint64_t& vertices);
uint64_t scanStreamingLimit();

} // namespace penumbra::detail
