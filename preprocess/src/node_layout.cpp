// The node array of the single BVH (Lauterbach et al. 2009, section 5.1; 8-bit
// hierarchical bounds as in compressed BVHs, Mahovsky 2005): top-level nodes,
// Cluster nodes and the cluster-internal nodes down to strip-range leaves in
// one array, root first, the children of a node stored consecutively after it
// in depth-first order. Each box is stored as 8-bit lo/hi relative to its
// parent's DECODED box (decodeChildBounds), rounded outward and then checked
// with the decoder itself: a coordinate whose decoded value misses the exact
// box (float rounding) is widened by one step until it contains it.
#include <algorithm>
#include <cmath>
#include <string>

#include "penumbra/error.h"
#include "preprocess_internal.h"

namespace penumbra::preprocess_detail {

namespace {

// Encodes exact into node.lo/hi relative to the parent box; returns the decoded box.
void encodeBounds(model::Node& node, const glm::vec3& parentMin, const glm::vec3& parentMax, const Box& exact,
                  glm::vec3& decodedMin, glm::vec3& decodedMax, uint64_t& widened)
{
    const glm::vec3 step = (parentMax - parentMin) * (1.0f / 255.0f);
    for (int a = 0; a < 3; ++a) {
        if (!(step[a] > 0.0f)) {
            node.lo[a] = 0;
            node.hi[a] = 255;
            continue;
        }
        float lo = std::floor((exact.min[a] - parentMin[a]) / step[a]);
        float hi = std::ceil((exact.max[a] - parentMin[a]) / step[a]);
        node.lo[a] = uint8_t(std::clamp(lo, 0.0f, 255.0f));
        node.hi[a] = uint8_t(std::clamp(hi, 0.0f, 255.0f));
        if (node.hi[a] < node.lo[a])
            node.hi[a] = node.lo[a];
    }
    for (;;) {
        decodeChildBounds(node, parentMin, parentMax, decodedMin, decodedMax);
        bool changed = false;
        for (int a = 0; a < 3; ++a) {
            if (decodedMin[a] > exact.min[a] && node.lo[a] > 0) {
                node.lo[a]--;
                changed = true;
            }
            if (decodedMax[a] < exact.max[a] && node.hi[a] < 255) {
                node.hi[a]++;
                changed = true;
            }
        }
        if (!changed)
            break;
        widened++;
    }
    for (int a = 0; a < 3; ++a)
        if (!(decodedMin[a] <= exact.min[a] && decodedMax[a] >= exact.max[a]))
            fail("preprocess", "internal error: a node box escapes its parent's decoded box");
}

struct Item {
    uint32_t index;   // final node
    uint32_t source;  // TopNode, or local node of `cluster`
    uint32_t cluster; // built cluster, kNone for a TopNode
    bool leafOnly;    // the Leaf child of a single-leaf cluster
    uint32_t level;
    glm::vec3 parentMin, parentMax;
};

} // namespace

Layout layoutNodes(const TopTree& tree, const std::vector<Box>& topBoxes, const std::vector<BuiltCluster>& clusters,
                   const glm::vec3& rootMin, const glm::vec3& rootMax)
{
    Layout layout;
    size_t total = tree.nodes.size();
    for (const BuiltCluster& c : clusters)
        total += c.nodes.size() - 1 + (c.nodes[0].childCount == 0 ? 1 : 0);
    if (total > model::kMaxNodes)
        fail("preprocess", "the BVH needs " + std::to_string(total) + " nodes, more than the format's limit of " +
                               std::to_string(model::kMaxNodes) + " (32-bit node indices); use larger leaves (--leaf-triangles)");
    layout.nodes.reserve(total);
    layout.nodes.resize(1);
    std::vector<uint32_t> finalCluster(clusters.size(), kNone);

    std::vector<Item> stack{{0, 0, kNone, false, 1, rootMin, rootMax}};
    while (!stack.empty()) {
        const Item item = stack.back();
        stack.pop_back();
        model::Node node{};
        glm::vec3 dmin, dmax;
        const bool local = item.cluster != kNone;
        const LocalNode* ln = local ? &clusters[item.cluster].nodes[item.source] : nullptr;
        const Box& exact = local ? ln->box : topBoxes[item.source];
        if (item.index == 0) {
            for (int a = 0; a < 3; ++a) {
                node.lo[a] = 0;
                node.hi[a] = 255;
            }
            dmin = rootMin;
            dmax = rootMax;
        } else {
            encodeBounds(node, item.parentMin, item.parentMax, exact, dmin, dmax, layout.widened);
        }
        layout.depth = std::max(layout.depth, item.level);

        // Children: (source, cluster, leafOnly) triples.
        Item children[2];
        uint32_t childCount = 0;
        auto child = [&](uint32_t source, uint32_t cluster, bool leafOnly) {
            children[childCount++] = {0, source, cluster, leafOnly, item.level + 1, dmin, dmax};
        };
        if (!local) {
            const TopNode& top = tree.nodes[item.source];
            if (top.cluster == kNone) {
                node.kind = uint8_t(model::NodeKind::Interior);
                for (uint32_t c = 0; c < top.childCount; ++c)
                    child(top.child[c], kNone, false);
            } else {
                const uint32_t index = uint32_t(layout.clusterOrder.size());
                finalCluster[top.cluster] = index;
                layout.clusterOrder.push_back(top.cluster);
                layout.clusterNode.push_back(item.index);
                node.kind = uint8_t(model::NodeKind::Cluster);
                node.second = index;
                const LocalNode& root = clusters[top.cluster].nodes[0];
                if (root.childCount == 0) {
                    child(0, top.cluster, true);
                } else {
                    for (uint32_t c = 0; c < root.childCount; ++c)
                        child(root.first + c, top.cluster, false);
                }
            }
        } else if (ln->childCount == 0 || item.leafOnly) {
            node.kind = uint8_t(model::NodeKind::Leaf);
            node.first = finalCluster[item.cluster];
            node.second = ln->leafStart | (ln->leafBytes << 16);
            layout.leaves++;
        } else {
            node.kind = uint8_t(model::NodeKind::Interior);
            for (uint32_t c = 0; c < ln->childCount; ++c)
                child(ln->first + c, item.cluster, false);
        }
        if (childCount > 0) {
            node.first = uint32_t(layout.nodes.size());
            node.childCount = uint8_t(childCount);
            layout.nodes.resize(layout.nodes.size() + childCount);
            for (uint32_t c = childCount; c-- > 0;) {
                children[c].index = node.first + c;
                stack.push_back(children[c]);
            }
        }
        layout.nodes[item.index] = node;
    }
    if (layout.depth > model::kMaxBvhDepth)
        fail("preprocess", "internal error: BVH depth " + std::to_string(layout.depth) + " exceeds the format limit");
    return layout;
}

} // namespace penumbra::preprocess_detail
