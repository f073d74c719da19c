// The node array of the single BVH (Lauterbach et al. 2009, section 5.1) as a
// 4-wide BVH with compressed child boxes (Ylitie, Karras, Laine 2017): the
// binary top tree over the clusters and each cluster's binary tree down to
// strip-range leaves are collapsed into nodes of up to four children, root
// first, children after their node in depth-first order. A node's children
// are its binary children with the largest-area interior ones replaced by
// theirs while four slots allow it (a cluster's root is never merged into
// the nodes above it: it stays a node of its own, named by a Cluster slot).
// Each node quantizes its children's boxes to 8 bits on a grid of its own
// (origin, power-of-two step per axis), rounded outward and then checked with
// the decoder itself (decodeChildBox): a coordinate whose decoded value misses
// the exact box is widened by one step until it holds it.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "penumbra/error.h"
#include "preprocess_internal.h"

namespace penumbra::preprocess_detail {

namespace {

// A node of the binary trees: a TopNode (cluster == kNone) or a cluster's LocalNode.
struct BinaryRef {
    uint32_t source;
    uint32_t cluster; // built cluster, kNone for a TopNode
};

struct Trees {
    const TopTree& tree;
    const std::vector<Box>& topBoxes;
    const std::vector<BuiltCluster>& clusters;
    // layoutSubtrees: a TopNode leaf names a subtree laid out elsewhere (its
    // root an Interior child here, never expanded, never descended into).
    bool subtrees = false;

    const Box& box(BinaryRef r) const { return r.cluster == kNone ? topBoxes[r.source] : clusters[r.cluster].nodes[r.source].box; }
    bool subtree(BinaryRef r) const { return subtrees && r.cluster == kNone && tree.nodes[r.source].cluster != kNone; }
    model::ChildKind kind(BinaryRef r) const
    {
        if (r.cluster == kNone)
            return tree.nodes[r.source].cluster == kNone || subtrees ? model::ChildKind::Interior : model::ChildKind::Cluster;
        return clusters[r.cluster].nodes[r.source].childCount == 0 ? model::ChildKind::Leaf : model::ChildKind::Interior;
    }
    // An Interior child whose binary children may take its slot.
    bool expandable(BinaryRef r) const { return kind(r) == model::ChildKind::Interior && !subtree(r); }
    uint32_t childCount(BinaryRef r) const
    {
        return r.cluster == kNone ? tree.nodes[r.source].childCount : clusters[r.cluster].nodes[r.source].childCount;
    }
    BinaryRef child(BinaryRef r, uint32_t c) const
    {
        if (r.cluster == kNone)
            return {tree.nodes[r.source].child[c], kNone};
        return {clusters[r.cluster].nodes[r.source].first + c, r.cluster};
    }
};

float area(const Box& b)
{
    const glm::vec3 e = glm::max(b.max - b.min, glm::vec3(0.0f));
    return e.x * e.y + e.y * e.z + e.z * e.x;
}

// The exponent of the smallest power-of-two step whose 255 steps from origin reach max.
uint8_t gridExponent(float origin, float max)
{
    const float extent = max - origin;
    int exponent = 1;
    if (extent > 0.0f) {
        int e = 0;
        std::frexp(extent / 255.0f, &e); // extent / 255 = m * 2^e, 0.5 <= m < 1: step 2^e suffices
        exponent = std::clamp(e + 127, 1, 254);
    }
    while (exponent < 254 && !(origin + 255.0f * nodeStep(uint8_t(exponent)) >= max))
        ++exponent;
    return uint8_t(exponent);
}

// The node's grid on axis a over [min, max]: the origin at min and the step of
// gridExponent. The format requires origin + 255 steps to be finite: where
// that overflows (boxes beyond about 1e38), the origin moves down to
// FLT_MAX - 255 steps, which still lies below min. Only a box wider than 255
// x 2^120 (about 3.39e38) has no grid: the model is refused.
void setGrid(model::Node& node, int a, float min, float max)
{
    for (uint32_t exponent = gridExponent(min, max);; ++exponent) {
        const float reach = 255.0f * nodeStep(uint8_t(exponent)); // inf from exponent 248 on
        if (!std::isfinite(reach)) {
            char text[160];
            std::snprintf(text, sizeof(text),
                          "the model spans %.3g units on axis %d, more than a node's grid holds (255 x 2^120 = %.3g)",
                          double(max) - double(min), a, double(255.0f * nodeStep(247)));
            fail("preprocess", text);
        }
        const float origin = std::isfinite(min + reach) ? min : std::numeric_limits<float>::max() - reach;
        if (origin <= min && origin + reach >= max) {
            node.origin[a] = origin;
            node.exponent[a] = uint8_t(exponent);
            return;
        }
    }
}

// Child c's box on the node's grid, rounded outward and checked with the decoder.
void encodeChildBox(model::Node& node, uint32_t c, const Box& exact, uint64_t& widened)
{
    for (int a = 0; a < 3; ++a) {
        const float step = nodeStep(node.exponent[a]);
        const float lo = std::floor((exact.min[a] - node.origin[a]) / step);
        const float hi = std::ceil((exact.max[a] - node.origin[a]) / step);
        node.lo[a][c] = uint8_t(std::clamp(lo, 0.0f, 255.0f));
        node.hi[a][c] = uint8_t(std::clamp(hi, 0.0f, 255.0f));
        if (node.hi[a][c] < node.lo[a][c])
            node.hi[a][c] = node.lo[a][c];
    }
    for (;;) {
        glm::vec3 min, max;
        decodeChildBox(node, c, min, max);
        bool changed = false;
        for (int a = 0; a < 3; ++a) {
            if (min[a] > exact.min[a] && node.lo[a][c] > 0) {
                node.lo[a][c]--;
                changed = true;
            }
            if (max[a] < exact.max[a] && node.hi[a][c] < 255) {
                node.hi[a][c]++;
                changed = true;
            }
        }
        if (!changed) {
            for (int a = 0; a < 3; ++a)
                if (!(min[a] <= exact.min[a] && max[a] >= exact.max[a]))
                    fail("preprocess", "internal error: a child box escapes its node's grid");
            return;
        }
        widened++;
    }
}

struct Pending {
    uint32_t index;   // final node
    BinaryRef owner;  // the binary node it stands for (a cluster's root: its TopNode)
    uint32_t depth;   // root = 1
};

// Lays out the wide nodes; byLevel: expand every interior child once (depth <=
// half the binary depth plus the cluster boundaries) instead of by area.
Layout layout(const Trees& t, bool byLevel)
{
    Layout out;
    out.nodes.resize(1);
    if (t.subtrees) {
        uint32_t count = 0;
        for (const TopNode& n : t.tree.nodes)
            count += n.cluster != kNone ? 1 : 0;
        out.subtreeNode.assign(count, kNone);
        out.subtreeDepth.assign(count, 0);
    }
    std::vector<Pending> stack{{0, {0, kNone}, 1}};
    while (!stack.empty()) {
        const Pending item = stack.back();
        stack.pop_back();
        out.depth = std::max(out.depth, item.depth);
        model::Node node{};
        node.cluster = model::kNoCluster;

        // The binary children this node starts from.
        std::array<BinaryRef, 4> children{};
        uint32_t count = 0;
        const bool clusterRoot = item.index != 0 && t.kind(item.owner) == model::ChildKind::Cluster;
        if (item.index == 0 && t.kind(item.owner) == model::ChildKind::Cluster) {
            children[count++] = item.owner; // a one-cluster model: the root holds the cluster's root
        } else if (clusterRoot) {
            const uint32_t built = t.tree.nodes[item.owner.source].cluster;
            node.cluster = uint32_t(out.clusterOrder.size());
            out.clusterOrder.push_back(built);
            out.clusterNode.push_back(item.index);
            const BinaryRef root{0, built};
            if (t.childCount(root) == 0)
                children[count++] = root; // a single-leaf cluster
            else
                for (uint32_t c = 0; c < t.childCount(root); ++c)
                    children[count++] = t.child(root, c);
        } else {
            if (item.owner.cluster != kNone)
                node.cluster = uint32_t(out.clusterOrder.size() - 1); // the cluster being laid out
            for (uint32_t c = 0; c < t.childCount(item.owner); ++c)
                children[count++] = t.child(item.owner, c);
        }

        // Interior children are replaced by their children while four slots allow it.
        if (byLevel) {
            std::array<BinaryRef, 4> expanded{};
            uint32_t n = 0;
            for (uint32_t c = 0; c < count; ++c) {
                const BinaryRef r = children[c];
                if (t.expandable(r) && n + t.childCount(r) + (count - c - 1) <= 4)
                    for (uint32_t k = 0; k < t.childCount(r); ++k)
                        expanded[n++] = t.child(r, k);
                else
                    expanded[n++] = r;
            }
            children = expanded;
            count = n;
        } else {
            for (;;) {
                int best = -1;
                float bestArea = -1.0f;
                for (uint32_t c = 0; c < count; ++c) {
                    const BinaryRef r = children[c];
                    if (!t.expandable(r) || count - 1 + t.childCount(r) > 4)
                        continue;
                    const float a = area(t.box(r));
                    if (a > bestArea) {
                        best = int(c);
                        bestArea = a;
                    }
                }
                if (best < 0)
                    break;
                const BinaryRef r = children[size_t(best)];
                const uint32_t k = t.childCount(r);
                for (uint32_t c = count; c-- > uint32_t(best) + 1;)
                    children[c + k - 1] = children[c];
                for (uint32_t c = 0; c < k; ++c)
                    children[size_t(best) + c] = t.child(r, c);
                count += k - 1;
            }
        }

        // The node's grid over the union of its children's boxes.
        Box box = t.box(children[0]);
        for (uint32_t c = 1; c < count; ++c)
            box.grow(t.box(children[c]));
        for (int a = 0; a < 3; ++a)
            setGrid(node, a, box.min[a], box.max[a]);
        for (uint32_t c = 0; c < count; ++c) {
            const BinaryRef r = children[c];
            const model::ChildKind kind = t.kind(r);
            node.kinds |= uint8_t(uint32_t(kind) << (2 * c));
            encodeChildBox(node, c, t.box(r), out.widened);
            if (kind == model::ChildKind::Leaf) {
                const LocalNode& leaf = t.clusters[r.cluster].nodes[r.source];
                node.child[c] = leaf.leafStart | (leaf.leafBytes << 16);
                out.leaves++;
            }
        }
        // Child nodes get their indices now, in order; depth first, first child next.
        for (uint32_t c = 0; c < count; ++c)
            if (t.kind(children[c]) != model::ChildKind::Leaf) {
                if (out.nodes.size() >= model::kMaxNodes) // the exact count (checkModelLimits estimated it)
                    fail("preprocess", "the BVH needs more than " + std::to_string(model::kMaxNodes) +
                                           " nodes, the format's limit (32-bit node indices); use larger --leaf-triangles");
                node.child[c] = uint32_t(out.nodes.size());
                out.nodes.emplace_back();
                if (t.subtree(children[c])) { // its root's place: the caller fills it
                    const uint32_t sub = t.tree.nodes[children[c].source].cluster;
                    out.subtreeNode[sub] = node.child[c];
                    out.subtreeDepth[sub] = item.depth + 1;
                    out.depth = std::max(out.depth, item.depth + 1);
                }
            }
        for (uint32_t c = count; c-- > 0;)
            if (t.kind(children[c]) != model::ChildKind::Leaf && !t.subtree(children[c]))
                stack.push_back({node.child[c], children[c], item.depth + 1});
        out.nodes[item.index] = node;
    }
    return out;
}

} // namespace

Layout layoutNodes(const TopTree& tree, const std::vector<Box>& topBoxes, const std::vector<BuiltCluster>& clusters,
                   uint32_t maxDepth)
{
    const Trees trees{tree, topBoxes, clusters};
    Layout result = layout(trees, false);
    if (result.depth > maxDepth)
        result = layout(trees, true);
    if (result.depth > maxDepth)
        fail("preprocess", "internal error: BVH depth " + std::to_string(result.depth) + " exceeds the " +
                               std::to_string(maxDepth) + " levels left to it (format limit " +
                               std::to_string(model::kMaxBvhDepth) + ")");
    return result;
}

Layout layoutSubtrees(const TopTree& tree, const std::vector<Box>& topBoxes)
{
    if (tree.nodes.size() < 3 || tree.nodes[0].childCount == 0)
        fail("preprocess", "internal error: a top tree over fewer than two subtrees");
    const std::vector<BuiltCluster> none;
    Trees trees{tree, topBoxes, none};
    trees.subtrees = true;
    return layout(trees, true);
}

} // namespace penumbra::preprocess_detail
