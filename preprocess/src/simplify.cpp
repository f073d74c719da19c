// Mesh simplification for the reduced-detail variants: meshoptimizer's
// edge-collapse simplifier with quadric error metrics (Garland & Heckbert 1997,
// meshopt_simplify), falling back to its topology-ignoring vertex clustering
// (meshopt_simplifySloppy) when the first stops short of the target because it
// preserves topology and borders. Unused vertices are removed afterwards.
#include <cmath>
#include <string>

#include <meshoptimizer.h>

#include "penumbra/error.h"
#include "penumbra/preprocess.h"

namespace penumbra {

SimplifiedMesh simplifyMesh(const Mesh& mesh, float ratio)
{
    if (!(ratio > 0.0f))
        fail("simplify", "ratio must be > 0 (got " + std::to_string(ratio) + ")");
    if (mesh.positions.size() % 3 != 0 || mesh.indices.size() % 3 != 0)
        fail("simplify", "mesh arrays are not multiples of 3");
    const size_t vertexCount = mesh.vertexCount();
    for (uint32_t index : mesh.indices)
        if (index >= vertexCount)
            fail("simplify", "vertex index out of range");
    SimplifiedMesh result;
    if (ratio >= 1.0f || mesh.indices.empty()) {
        result.mesh = mesh;
        return result;
    }

    const size_t indexCount = mesh.indices.size();
    const size_t target = std::max<size_t>(1, size_t(double(mesh.triangleCount()) * ratio)) * 3;
    std::vector<uint32_t> simplified(indexCount);
    float error = 0.0f;
    // target_error 1.0 (the whole extent): stop at the triangle target, not at an error bound.
    size_t count = meshopt_simplify(simplified.data(), mesh.indices.data(), indexCount, mesh.positions.data(),
                                    vertexCount, sizeof(float) * 3, target, 1.0f, 0, &error);
    if (double(count) > 1.1 * double(target)) {
        float sloppyError = 0.0f;
        size_t sloppyCount = meshopt_simplifySloppy(simplified.data(), mesh.indices.data(), indexCount,
                                                    mesh.positions.data(), vertexCount, sizeof(float) * 3, target,
                                                    1.0f, &sloppyError);
        count = sloppyCount;
        error = sloppyError;
        result.sloppy = true;
    }
    simplified.resize(count);

    // Colours: vertex colours stay with their vertices; a simplified triangle takes the material of
    // the last input triangle that used its first vertex (materials are not kept apart by the simplifier).
    std::vector<uint32_t> vertexMaterial;
    if (!mesh.triangleMaterials.empty()) {
        vertexMaterial.assign(vertexCount, 0);
        for (size_t t = 0; t < mesh.triangleMaterials.size(); ++t)
            for (int k = 0; k < 3; ++k)
                vertexMaterial[mesh.indices[3 * t + k]] = mesh.triangleMaterials[t];
        result.mesh.triangleMaterials.resize(count / 3);
        for (size_t t = 0; t < count / 3; ++t)
            result.mesh.triangleMaterials[t] = vertexMaterial[simplified[3 * t]];
    }
    result.mesh.materials = mesh.materials;

    // Compact: keep used vertices in first-use order.
    std::vector<uint32_t> remap(vertexCount, 0xFFFFFFFFu);
    uint32_t next = 0;
    result.mesh.indices.resize(count);
    for (size_t i = 0; i < count; ++i) {
        uint32_t v = simplified[i];
        if (remap[v] == 0xFFFFFFFFu) {
            remap[v] = next++;
            result.mesh.positions.insert(result.mesh.positions.end(), mesh.positions.begin() + 3 * size_t(v),
                                         mesh.positions.begin() + 3 * size_t(v) + 3);
            if (!mesh.colors.empty())
                result.mesh.colors.insert(result.mesh.colors.end(), mesh.colors.begin() + 3 * size_t(v),
                                          mesh.colors.begin() + 3 * size_t(v) + 3);
        }
        result.mesh.indices[i] = remap[v];
    }
    result.error = error;
    result.absoluteError = error * meshopt_simplifyScale(mesh.positions.data(), vertexCount, sizeof(float) * 3);
    return result;
}

} // namespace penumbra
