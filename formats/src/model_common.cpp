// Pieces of the .penumbra model shared by the writer, reader, preprocessor,
// runtime and tests: owning views, the scalar position decoder, node boxes.
#include <glm/common.hpp>

#include "penumbra/model_format.h"

// The decoder must match the vertex shader bit for bit: no fused multiply-add.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC optimize("fp-contract=off")
#endif
#if defined(__clang__)
#pragma clang fp contract(off)
#endif

namespace penumbra {

CompressedModel makeCompressedModel(std::shared_ptr<CompressedModelData> data)
{
    CompressedModel model;
    model.header = data->header;
    model.clusters = data->clusters;
    model.nodes = data->nodes;
    model.vertices = data->vertices;
    model.indices = data->indices;
    model.storage = std::move(data);
    return model;
}

glm::vec3 decodePosition(const model::ClusterRecord& cluster, const model::QuantizedVertex& vertex)
{
    volatile float x = float(vertex.x) * cluster.step[0];
    volatile float y = float(vertex.y) * cluster.step[1];
    volatile float z = float(vertex.z) * cluster.step[2];
    return {cluster.boxMin[0] + x, cluster.boxMin[1] + y, cluster.boxMin[2] + z};
}

void decodeChildBounds(const model::Node& child, const glm::vec3& parentMin, const glm::vec3& parentMax, glm::vec3& min,
                       glm::vec3& max)
{
    const glm::vec3 extent = (parentMax - parentMin) * (1.0f / 255.0f);
    for (int axis = 0; axis < 3; ++axis) {
        min[axis] = parentMin[axis] + float(child.lo[axis]) * extent[axis];
        max[axis] = parentMin[axis] + float(child.hi[axis]) * extent[axis];
    }
    // hi = 255 must reach the parent's max exactly despite rounding.
    for (int axis = 0; axis < 3; ++axis)
        if (child.hi[axis] == 255)
            max[axis] = parentMax[axis];
}

} // namespace penumbra
