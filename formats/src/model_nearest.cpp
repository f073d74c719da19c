// The distance from a point to a compressed model's nearest triangle: the
// BVH walked nearest box first, every box at least as far as the best
// triangle so far skipped, the leaves' triangles decoded as the GPU decodes
// them.
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include <glm/geometric.hpp>

#include "penumbra/model_format.h"

namespace penumbra {
namespace {

float boxDistance2(glm::vec3 p, glm::vec3 lo, glm::vec3 hi)
{
    const glm::vec3 d = glm::max(glm::max(lo - p, p - hi), glm::vec3(0.0f));
    return glm::dot(d, d);
}

// The point of triangle abc nearest to p (Ericson, Real-Time Collision
// Detection, 5.1.5: the Voronoi regions of the vertices, the edges and the face).
glm::vec3 closestOnTriangle(glm::vec3 p, glm::vec3 a, glm::vec3 b, glm::vec3 c)
{
    const glm::vec3 ab = b - a, ac = c - a, ap = p - a;
    const float d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
    if (d1 <= 0.0f && d2 <= 0.0f)
        return a;
    const glm::vec3 bp = p - b;
    const float d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
    if (d3 >= 0.0f && d4 <= d3)
        return b;
    const float vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0f && d1 >= 0.0f && d3 <= 0.0f)
        return a + ab * (d1 / (d1 - d3));
    const glm::vec3 cp = p - c;
    const float d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
    if (d6 >= 0.0f && d5 <= d6)
        return c;
    const float vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0f && d2 >= 0.0f && d6 <= 0.0f)
        return a + ac * (d2 / (d2 - d6));
    const float va = d3 * d6 - d5 * d4;
    if (va <= 0.0f && d4 - d3 >= 0.0f && d5 - d6 >= 0.0f)
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    const float denominator = va + vb + vc;
    if (!(denominator > 0.0f)) // degenerate (zero-area) triangle: its vertices and edges answered above
        return a;
    return a + ab * (vb / denominator) + ac * (vc / denominator);
}

} // namespace

float nearestTriangleDistance(const CompressedModel& model, glm::vec3 point)
{
    float best2 = std::numeric_limits<float>::infinity();
    if (model.nodes.empty())
        return best2;
    struct Entry {
        float distance2;
        uint32_t node;
    };
    std::vector<Entry> stack;
    stack.push_back({boxDistance2(point, glm::vec3(model.header.boundsMin[0], model.header.boundsMin[1], model.header.boundsMin[2]),
                                  glm::vec3(model.header.boundsMax[0], model.header.boundsMax[1], model.header.boundsMax[2])),
                     0});
    while (!stack.empty()) {
        const Entry entry = stack.back();
        stack.pop_back();
        if (entry.distance2 >= best2)
            continue;
        const model::Node& node = model.nodes[entry.node];
        Entry inner[model::kNodeChildren];
        uint32_t innerCount = 0;
        const uint32_t children = model::childCount(node);
        for (uint32_t c = 0; c < children; ++c) {
            glm::vec3 lo, hi;
            decodeChildBox(node, c, lo, hi);
            const float d2 = boxDistance2(point, lo, hi);
            if (d2 >= best2)
                continue;
            switch (model::childKind(node, c)) {
            case model::ChildKind::Interior:
            case model::ChildKind::Cluster: // a cluster's root node
                inner[innerCount++] = {d2, node.child[c]};
                break;
            case model::ChildKind::Leaf: {
                const model::ClusterRecord& cluster = model.clusters[node.cluster];
                const uint8_t* begin = model.indices.data() + cluster.firstIndex + (node.child[c] & 0xFFFFu);
                const model::QuantizedVertex* vertices = model.vertices.data() + cluster.firstVertex;
                forEachStripTriangle(begin, begin + (node.child[c] >> 16), [&](uint32_t a, uint32_t b, uint32_t v) {
                    const glm::vec3 q = closestOnTriangle(point, decodePosition(cluster, vertices[a]), decodePosition(cluster, vertices[b]),
                                                          decodePosition(cluster, vertices[v]));
                    best2 = std::min(best2, glm::dot(q - point, q - point));
                });
                break;
            }
            case model::ChildKind::Empty:
                break;
            }
        }
        // Pushed farthest first: the nearest child is taken next.
        for (uint32_t i = 1; i < innerCount; ++i)
            for (uint32_t j = i; j > 0 && inner[j - 1].distance2 < inner[j].distance2; --j)
                std::swap(inner[j - 1], inner[j]);
        stack.insert(stack.end(), inner, inner + innerCount);
    }
    return std::sqrt(best2);
}

} // namespace penumbra
