// Reader-side checks of the .penumbra model file (formats/README.md, section
// ".penumbra model file"): header, section table, checksums, zero padding and
// every structural invariant of clusters, strips and the BVH, so that a
// hostile file is rejected with a one-line error before any of its data is
// used. Everything is O(file size) with a fixed number of allocations; this
// file needs only the C++ library and libxxhash (the fuzzer compiles it alone).
#include <xxhash.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "penumbra/error.h"
#include "penumbra/model_format.h"

namespace penumbra {
namespace {

using namespace model;

constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();

std::string str(uint64_t value)
{
    return std::to_string(value);
}

// a + b as text, also when the sum does not fit 64 bits.
std::string sumText(uint64_t a, uint64_t b)
{
    if (a <= std::numeric_limits<uint64_t>::max() - b)
        return std::to_string(a + b);
    return std::to_string(a) + "+" + std::to_string(b);
}

std::string hex(uint64_t value)
{
    char text[24];
    std::snprintf(text, sizeof(text), "%llx", static_cast<unsigned long long>(value));
    return text;
}

std::string strf(float value)
{
    char text[32];
    std::snprintf(text, sizeof(text), "%g", double(value));
    return text;
}

const char* sectionName(uint32_t type)
{
    switch (SectionType(type)) {
    case SectionType::Clusters:
        return "Clusters";
    case SectionType::Nodes:
        return "Nodes";
    case SectionType::Vertices:
        return "Vertices";
    case SectionType::Indices:
        return "Indices";
    case SectionType::Materials:
        return "Materials";
    case SectionType::Cameras:
        return "Cameras";
    case SectionType::Lights:
        return "Lights";
    }
    return "unknown";
}

uint32_t elementSizeOf(uint32_t type)
{
    switch (SectionType(type)) {
    case SectionType::Clusters:
        return sizeof(ClusterRecord);
    case SectionType::Nodes:
        return sizeof(Node);
    case SectionType::Vertices:
        return sizeof(QuantizedVertex);
    case SectionType::Indices:
        return 1;
    case SectionType::Materials:
        return sizeof(MaterialRecord);
    case SectionType::Cameras:
        return sizeof(CameraRecord);
    case SectionType::Lights:
        return sizeof(LightRecord);
    }
    return 0;
}

// Element count the header declares for a section type.
uint64_t declaredCount(const FileHeader& header, uint32_t type)
{
    switch (SectionType(type)) {
    case SectionType::Clusters:
        return header.clusterCount;
    case SectionType::Nodes:
        return header.nodeCount;
    case SectionType::Vertices:
        return header.vertexCount;
    case SectionType::Indices:
        return header.indexBytes;
    case SectionType::Materials:
        return header.materialCount;
    case SectionType::Cameras:
        return header.cameraCount;
    case SectionType::Lights:
        return header.lightCount;
    }
    return 0;
}

void validateBuildParameters(const BuildParameters& build, const std::string& subject)
{
    if (build.maxClusterVertices < 3 || build.maxClusterVertices > kMaxClusterVertices)
        fail(subject, "build parameter maxClusterVertices " + str(build.maxClusterVertices) + " is outside 3.." +
                          str(kMaxClusterVertices));
    if (build.maxClusterTriangles < 1 || build.maxClusterTriangles > kMaxClusterTriangles)
        fail(subject, "build parameter maxClusterTriangles " + str(build.maxClusterTriangles) + " is outside 1.." +
                          str(kMaxClusterTriangles));
    if (build.maxLeafTriangles < 1 || build.maxLeafTriangles > build.maxClusterTriangles)
        fail(subject, "build parameter maxLeafTriangles " + str(build.maxLeafTriangles) +
                          " is outside 1..maxClusterTriangles (" + str(build.maxClusterTriangles) + ")");
    if (build.positionBits != kPositionBits)
        fail(subject, "build parameter positionBits " + str(build.positionBits) + " is not " + str(kPositionBits) +
                          " (the only value this version supports)");
    if (build.nodeBoundsBits != kNodeBoundsBits)
        fail(subject, "build parameter nodeBoundsBits " + str(build.nodeBoundsBits) + " is not " +
                          str(kNodeBoundsBits) + " (the only value this version supports)");
    if (!(build.simplifyTarget > 0.0f && build.simplifyTarget <= 1.0f))
        fail(subject, "build parameter simplifyTarget " + strf(build.simplifyTarget) + " is outside (0, 1]");
    if (build.reserved != 0)
        fail(subject, "reserved build parameter is not zero");
}

// Header fields that do not depend on the sections (shared by the file
// reader and validateModel).
void validateHeaderFields(const FileHeader& header, const std::string& subject)
{
    validateBuildParameters(header.build, subject);
    if (header.clusterCount == 0)
        fail(subject, "no clusters");
    if (header.nodeCount == 0)
        fail(subject, "no BVH nodes");
    if (header.bvhDepth < 1 || header.bvhDepth > kMaxBvhDepth)
        fail(subject, "header bvhDepth " + str(header.bvhDepth) + " is outside 1.." + str(kMaxBvhDepth));
    for (int axis = 0; axis < 3; ++axis) {
        if (!std::isfinite(header.boundsMin[axis]) || !std::isfinite(header.boundsMax[axis]))
            fail(subject, "non-finite model bounds");
        if (header.boundsMin[axis] > header.boundsMax[axis])
            fail(subject, "model bounds min " + strf(header.boundsMin[axis]) + " > max " +
                              strf(header.boundsMax[axis]) + " on axis " + str(uint64_t(axis)));
    }
    if (!(header.maxPositionError >= 0.0f) || !std::isfinite(header.maxPositionError))
        fail(subject, "maxPositionError " + strf(header.maxPositionError) + " is not a finite value >= 0");
    if (!(header.simplifyError >= 0.0f) || !std::isfinite(header.simplifyError))
        fail(subject, "simplifyError " + strf(header.simplifyError) + " is not a finite value >= 0");
    if (header.materialCount < 1 || header.materialCount > kMaxMaterials)
        fail(subject, "header materialCount " + str(header.materialCount) + " is outside 1.." + str(kMaxMaterials));
    if (header.cameraCount > kMaxCameras)
        fail(subject, "header cameraCount " + str(header.cameraCount) + " is above " + str(kMaxCameras));
    if (header.lightCount > kMaxLights)
        fail(subject, "header lightCount " + str(header.lightCount) + " is above " + str(kMaxLights));
    bool reservedZero = true;
    for (uint64_t reserved : header.reserved1)
        reservedZero &= reserved == 0;
    if (!reservedZero)
        fail(subject, "reserved header field is not zero");
}

// Sets bits [begin, end) (begin < end); returns false if any was already set.
bool claimRange(std::vector<uint64_t>& bits, uint32_t begin, uint32_t end)
{
    const uint32_t firstWord = begin >> 6, lastWord = (end - 1) >> 6;
    for (uint32_t word = firstWord; word <= lastWord; ++word) {
        uint64_t mask = ~uint64_t(0);
        if (word == firstWord)
            mask &= ~uint64_t(0) << (begin & 63);
        if (word == lastWord)
            mask &= ~uint64_t(0) >> (63 - ((end - 1) & 63));
        if (bits[word] & mask)
            return false;
        bits[word] |= mask;
    }
    return true;
}

uint32_t countStripTriangles(const uint8_t* begin, const uint8_t* end)
{
    uint32_t count = 0;
    forEachStripTriangle(begin, end, [&count](uint32_t, uint32_t, uint32_t) { ++count; });
    return count;
}

void validateClusters(const CompressedModel& model, const std::string& subject, uint32_t& maxIndexBytes)
{
    const BuildParameters& build = model.header.build;
    const uint64_t vertexCount = model.vertices.size();
    const uint64_t indexBytes = model.indices.size();
    const uint8_t* indices = model.indices.data();
    auto failCluster = [&subject](size_t c, const std::string& problem) {
        fail(subject, "cluster " + str(uint64_t(c)) + ": " + problem);
    };
    uint64_t triangleSum = 0;
    maxIndexBytes = 0;
    for (size_t c = 0; c < model.clusters.size(); ++c) {
        const ClusterRecord& cluster = model.clusters[c];
        if (cluster.vertexCount < 3 || cluster.vertexCount > build.maxClusterVertices)
            failCluster(c, "vertex count " + str(cluster.vertexCount) + " is outside 3..maxClusterVertices (" +
                               str(build.maxClusterVertices) + ")");
        if (cluster.triangleCount < 1 || cluster.triangleCount > build.maxClusterTriangles)
            failCluster(c, "triangle count " + str(cluster.triangleCount) + " is outside 1..maxClusterTriangles (" +
                               str(build.maxClusterTriangles) + ")");
        // 64-bit offsets: compare without forming firstVertex + vertexCount, which may wrap.
        if (cluster.firstVertex > vertexCount || cluster.vertexCount > vertexCount - cluster.firstVertex)
            failCluster(c, "vertices " + str(cluster.firstVertex) + ".." + sumText(cluster.firstVertex, cluster.vertexCount) +
                               " run past the " + str(vertexCount) + " vertices");
        if (cluster.indexBytes < 3)
            failCluster(c, "strip bytes " + str(cluster.indexBytes) + " < 3");
        if (cluster.firstIndex > indexBytes || cluster.indexBytes > indexBytes - cluster.firstIndex)
            failCluster(c, "strip bytes " + str(cluster.firstIndex) + ".." + sumText(cluster.firstIndex, cluster.indexBytes) +
                               " run past the " + str(indexBytes) + " index bytes");
        if (cluster.flags & ~kClusterFlagsMask)
            failCluster(c, "unknown flag bits 0x" + hex(cluster.flags & ~kClusterFlagsMask));
        if (cluster.reserved != 0)
            failCluster(c, "reserved field is not zero");
        for (int axis = 0; axis < 3; ++axis) {
            const float boxMin = cluster.boxMin[axis], step = cluster.step[axis];
            if (!std::isfinite(boxMin))
                failCluster(c, "non-finite boxMin " + strf(boxMin) + " on axis " + str(uint64_t(axis)));
            if (!std::isfinite(step) || !(step >= 0.0f))
                failCluster(c,
                            "step " + strf(step) + " on axis " + str(uint64_t(axis)) + " is not a finite value >= 0");
            if (!std::isfinite(boxMin + 65535.0f * step))
                failCluster(c, "quantization range overflows on axis " + str(uint64_t(axis)));
        }
        if (cluster.material >= model.materials.size())
            failCluster(c, "material " + str(cluster.material) + " out of range (" + str(uint64_t(model.materials.size())) +
                               " materials)");
        if (cluster.node >= model.nodes.size())
            failCluster(c, "node " + str(cluster.node) + " out of range (" + str(uint64_t(model.nodes.size())) +
                               " nodes)");
        if (model.nodes[cluster.node].cluster != c)
            failCluster(c, "node " + str(cluster.node) + " is not this cluster's root node");

        // Strips: local indices < vertexCount separated by single restarts.
        const uint8_t* strip = indices + cluster.firstIndex;
        const uint32_t size = cluster.indexBytes;
        if (strip[0] == kStripRestart || strip[size - 1] == kStripRestart)
            failCluster(c, "strips begin or end with a restart");
        const uint8_t localVertexCount = uint8_t(cluster.vertexCount); // <= 255 checked above
        bool bad = false;
        for (uint32_t i = 0; i < size; ++i) {
            const uint8_t byte = strip[i];
            bad |= byte == kStripRestart ? strip[i - 1] == kStripRestart : byte >= localVertexCount;
        }
        if (bad) {
            for (uint32_t i = 0; i < size; ++i) {
                if (strip[i] == kStripRestart && strip[i - 1] == kStripRestart)
                    failCluster(c, "two consecutive restarts at strip byte " + str(i));
                if (strip[i] != kStripRestart && strip[i] >= cluster.vertexCount)
                    failCluster(c, "strip index " + str(strip[i]) + " >= vertex count " + str(cluster.vertexCount) +
                                       " (strip byte " + str(i) + ")");
            }
        }
        const uint32_t triangles = countStripTriangles(strip, strip + size);
        if (triangles != cluster.triangleCount)
            failCluster(c,
                        "strips hold " + str(triangles) + " triangles, the record says " + str(cluster.triangleCount));
        triangleSum += cluster.triangleCount;
        maxIndexBytes = std::max(maxIndexBytes, cluster.indexBytes);
    }
    if (triangleSum != model.header.triangleCount)
        fail(subject,
             "header says " + str(model.header.triangleCount) + " triangles but the clusters hold " + str(triangleSum));
}

// Per node: grid, child kinds and boxes, child links (after the node, in
// range, exactly one slot each), clusters' roots named once and by their
// records. Together these make the nodes a tree rooted at 0.
void validateNodeLinks(const CompressedModel& model, const std::string& subject)
{
    const size_t nodeCount = model.nodes.size();
    auto failNode = [&subject](size_t n, const std::string& problem) {
        fail(subject, "node " + str(uint64_t(n)) + ": " + problem);
    };
    std::vector<uint32_t> parent(nodeCount, kNone);
    for (size_t n = 0; n < nodeCount; ++n) {
        const Node& node = model.nodes[n];
        if (!std::isfinite(node.origin[0]) || !std::isfinite(node.origin[1]) || !std::isfinite(node.origin[2]))
            failNode(n, "non-finite grid origin");
        for (int axis = 0; axis < 3; ++axis) {
            if (node.exponent[axis] < 1 || node.exponent[axis] > 254)
                failNode(n, "grid exponent " + str(node.exponent[axis]) + " outside 1..254 on axis " + str(uint64_t(axis)));
            if (!std::isfinite(node.origin[axis] + 255.0f * nodeStep(node.exponent[axis])))
                failNode(n, "grid overflows on axis " + str(uint64_t(axis)));
        }
        if (node.reserved != 0)
            failNode(n, "reserved word is not zero");
        const bool top = node.cluster == kNoCluster;
        if (!top && node.cluster >= model.clusters.size())
            failNode(n, "cluster " + str(node.cluster) + " out of range (" + str(uint64_t(model.clusters.size())) + " clusters)");
        const uint32_t children = childCount(node);
        if (children == 0)
            failNode(n, "no children");
        for (uint32_t c = 0; c < kNodeChildren; ++c) {
            const ChildKind kind = childKind(node, c);
            const std::string slot = "child " + str(c) + ": ";
            if (c >= children) {
                if (kind != ChildKind::Empty)
                    failNode(n, slot + "follows an empty slot");
                for (int axis = 0; axis < 3; ++axis)
                    if (node.lo[axis][c] != 0 || node.hi[axis][c] != 0)
                        failNode(n, slot + "empty slot with a box");
                if (node.child[c] != 0)
                    failNode(n, slot + "empty slot with a reference");
                continue;
            }
            for (int axis = 0; axis < 3; ++axis)
                if (node.lo[axis][c] > node.hi[axis][c])
                    failNode(n, slot + "box lo " + str(node.lo[axis][c]) + " > hi " + str(node.hi[axis][c]) + " on axis " +
                                    str(uint64_t(axis)));
            if (kind == ChildKind::Leaf) {
                if (top)
                    failNode(n, slot + "a leaf in a node above the clusters");
                continue; // ranges: validateTree
            }
            if (kind == ChildKind::Cluster && !top)
                failNode(n, slot + "a cluster inside cluster " + str(node.cluster));
            const uint32_t child = node.child[c];
            if (child <= n)
                failNode(n, slot + "node " + str(child) + " is not after its parent");
            if (child >= nodeCount)
                failNode(n, slot + "node " + str(child) + " out of range (" + str(uint64_t(nodeCount)) + " nodes)");
            if (parent[child] != kNone)
                fail(subject, "node " + str(child) + " is referenced by two parents (nodes " + str(parent[child]) + " and " +
                                  str(uint64_t(n)) + ")");
            parent[child] = uint32_t(n);
            const uint32_t childCluster = model.nodes[child].cluster;
            if (kind == ChildKind::Cluster) {
                if (childCluster == kNoCluster || childCluster >= model.clusters.size() || model.clusters[childCluster].node != child)
                    failNode(n, slot + "node " + str(child) + " is not the root node of the cluster it names");
            } else if (childCluster != node.cluster) {
                failNode(n, slot + "interior node " + str(child) + " lies in another part of the tree (cluster " +
                                (childCluster == kNoCluster ? std::string("none") : str(childCluster)) + ")");
            }
        }
    }
    if (model.nodes[0].cluster != kNoCluster)
        failNode(0, "the root lies in cluster " + str(model.nodes[0].cluster) + " (it must be above the clusters)");
    for (size_t n = 1; n < nodeCount; ++n) {
        if (parent[n] != kNone)
            continue;
        const Node& node = model.nodes[n];
        if (node.cluster != kNoCluster && model.clusters[node.cluster].node == n)
            fail(subject, "cluster " + str(node.cluster) + " (node " + str(uint64_t(n)) + ") is not reachable from the root");
        failNode(n, "not referenced by any parent (unreachable)");
    }
}

// Depth-first traversal from the root: every leaf lies in the subtree of its
// cluster's root and covers whole strips, the leaves of a cluster cover its
// strips once, and the depth is as declared.
void validateTree(const CompressedModel& model, const std::string& subject, uint32_t maxIndexBytes)
{
    struct Entry {
        uint32_t node;
        uint32_t depth;
    };
    // A tree of depth <= kMaxBvhDepth with 4 children a node never holds more
    // than 3 x depth + 1 pending entries.
    std::array<Entry, 3 * kMaxBvhDepth + 4> stack;
    size_t top = 0;
    stack[top++] = {0, 1};
    std::vector<uint32_t> leafTriangles(model.clusters.size(), 0);
    std::vector<uint64_t> covered(maxIndexBytes / 64 + 1, 0); // strip bytes of the current cluster owned by a leaf
    auto failNode = [&subject](size_t n, const std::string& problem) {
        fail(subject, "node " + str(uint64_t(n)) + ": " + problem);
    };
    uint32_t depth = 0, currentCluster = kNone;
    while (top > 0) {
        const Entry entry = stack[--top];
        const Node& node = model.nodes[entry.node];
        if (entry.depth > kMaxBvhDepth)
            fail(subject, "BVH deeper than " + str(kMaxBvhDepth) + " levels");
        depth = std::max(depth, entry.depth);
        const uint32_t cluster = node.cluster;
        if (cluster != kNoCluster && cluster != currentCluster) {
            // A cluster's subtree is traversed contiguously (its root first), so one bitmap serves all clusters.
            if (model.clusters[cluster].node != entry.node)
                failNode(entry.node, "reached inside cluster " + str(cluster) + " before its root");
            currentCluster = cluster;
            std::fill_n(covered.begin(), model.clusters[cluster].indexBytes / 64 + 1, 0);
        }
        const uint32_t children = childCount(node);
        for (uint32_t c = 0; c < children; ++c) {
            if (childKind(node, c) != ChildKind::Leaf)
                continue;
            const ClusterRecord& record = model.clusters[cluster];
            const uint32_t start = node.child[c] & 0xFFFF, count = node.child[c] >> 16;
            const uint32_t end = start + count;
            auto range = [&] { return "child " + str(c) + ": leaf range " + str(start) + ".." + str(end); }; // text only on failure
            if (count == 0)
                failNode(entry.node, range() + " is empty");
            if (end > record.indexBytes)
                failNode(entry.node, range() + " lies outside the " + str(record.indexBytes) + " strip bytes of cluster " + str(cluster));
            const uint8_t* strip = model.indices.data() + record.firstIndex;
            if (start > 0 && strip[start - 1] != kStripRestart)
                failNode(entry.node, range() + " does not begin at a strip start");
            if (end < record.indexBytes && strip[end] != kStripRestart)
                failNode(entry.node, range() + " does not end at a strip end");
            if (!claimRange(covered, start, end))
                failNode(entry.node, range() + " overlaps another leaf of cluster " + str(cluster));
            const uint32_t triangles = countStripTriangles(strip + start, strip + end);
            if (triangles == 0)
                failNode(entry.node, range() + " holds no triangles");
            leafTriangles[cluster] += triangles;
        }
        for (uint32_t c = children; c-- > 0;) {
            if (childKind(node, c) == ChildKind::Leaf)
                continue;
            if (top == stack.size())
                fail(subject, "BVH deeper than " + str(kMaxBvhDepth) + " levels");
            stack[top++] = {node.child[c], entry.depth + 1};
        }
    }
    if (depth != model.header.bvhDepth)
        fail(subject, "header says the BVH has " + str(model.header.bvhDepth) + " levels but it has " + str(depth));
    for (size_t c = 0; c < model.clusters.size(); ++c)
        if (leafTriangles[c] != model.clusters[c].triangleCount)
            fail(subject, "cluster " + str(uint64_t(c)) + ": its leaves hold " + str(leafTriangles[c]) +
                              " triangles, the cluster " + str(model.clusters[c].triangleCount));
}

bool finite3(const float* v)
{
    return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]);
}

bool zero3(const float* v)
{
    return v[0] == 0.0f && v[1] == 0.0f && v[2] == 0.0f;
}

void validateMaterials(const CompressedModel& model, const std::string& subject)
{
    for (size_t m = 0; m < model.materials.size(); ++m)
        for (float c : model.materials[m].baseColor)
            if (!(c >= 0.0f && c <= 1.0f))
                fail(subject, "material " + str(uint64_t(m)) + ": base colour component " + strf(c) + " is outside [0, 1]");
}

void validateCameras(const CompressedModel& model, const std::string& subject)
{
    for (size_t i = 0; i < model.cameras.size(); ++i)
        validateCameraRecord(model.cameras[i], subject + ": camera " + str(uint64_t(i)));
}

void validateLights(const CompressedModel& model, const std::string& subject)
{
    for (size_t i = 0; i < model.lights.size(); ++i)
        validateLightRecord(model.lights[i], subject + ": light " + str(uint64_t(i)));
}

} // namespace

void validateCameraRecord(const CameraRecord& c, const std::string& subject)
{
    auto bad = [&](const std::string& problem) { throw Error(subject + ": " + problem); };
    if (!finite3(c.position) || !finite3(c.target) || !finite3(c.up))
        bad("non-finite position, target or up");
    const float view[3] = {c.target[0] - c.position[0], c.target[1] - c.position[1], c.target[2] - c.position[2]};
    if (zero3(view))
        bad("position and target are equal");
    const float side[3] = {view[1] * c.up[2] - view[2] * c.up[1], view[2] * c.up[0] - view[0] * c.up[2],
                           view[0] * c.up[1] - view[1] * c.up[0]};
    if (zero3(side))
        bad("up is zero or parallel to the view direction");
    if (c.projection > 1)
        bad("unknown projection " + str(c.projection));
    if (!(c.yfovDegrees > 0.0f && c.yfovDegrees < 180.0f))
        bad("field of view " + strf(c.yfovDegrees) + " is outside (0, 180) degrees");
    if (!(c.orthoHeight > 0.0f) || !std::isfinite(c.orthoHeight))
        bad("orthographic height " + strf(c.orthoHeight) + " is not a finite value > 0");
    if (!(c.nearPlane >= 0.0f) || !std::isfinite(c.nearPlane) || !std::isfinite(c.farPlane) ||
        !(c.farPlane == 0.0f || c.farPlane > c.nearPlane))
        bad("near " + strf(c.nearPlane) + " / far " + strf(c.farPlane) + " planes are not 0 <= near < far (or far 0)");
    if (c.reserved[0] != 0 || c.reserved[1] != 0)
        bad("reserved field is not zero");
}

// The renderer's rules for a light (validateLight in scene_file.cpp), plus finite values and a known type.
void validateLightRecord(const LightRecord& l, const std::string& subject)
{
    auto bad = [&](const std::string& problem) { throw Error(subject + ": " + problem); };
    if (l.type > uint32_t(LightType::Sphere))
        bad("unknown type " + str(l.type));
    if (!finite3(l.position) || !finite3(l.direction) || !finite3(l.up) || !finite3(l.color))
        bad("non-finite position, direction, up or colour");
    const float scalars[] = {l.intensity, l.range, l.innerConeDegrees, l.outerConeDegrees, l.width, l.height, l.radius};
    for (float v : scalars)
        if (!std::isfinite(v))
            bad("non-finite intensity, range, cone angle or size");
    if (zero3(l.direction) && l.type != uint32_t(LightType::Point) && l.type != uint32_t(LightType::Sphere))
        bad("zero direction");
    if (l.intensity < 0.0f || l.range < 0.0f || l.width <= 0.0f || l.height <= 0.0f || l.radius <= 0.0f)
        bad("intensity " + strf(l.intensity) + " and range " + strf(l.range) + " must be >= 0, width " + strf(l.width) +
            ", height " + strf(l.height) + " and radius " + strf(l.radius) + " > 0");
    if (l.type == uint32_t(LightType::Spot) &&
        !(l.outerConeDegrees > 0.0f && l.outerConeDegrees < 90.0f && l.innerConeDegrees <= l.outerConeDegrees))
        bad("spot cone inner " + strf(l.innerConeDegrees) + " / outer " + strf(l.outerConeDegrees) +
            " degrees is not inner <= outer, 0 < outer < 90");
}

void validateModel(const CompressedModel& model, const std::string& subject)
{
    const FileHeader& header = model.header;
    validateHeaderFields(header, subject);
    if (header.clusterCount != model.clusters.size())
        fail(subject, "header says " + str(header.clusterCount) + " clusters but there are " +
                          str(uint64_t(model.clusters.size())));
    if (header.nodeCount != model.nodes.size())
        fail(subject,
             "header says " + str(header.nodeCount) + " nodes but there are " + str(uint64_t(model.nodes.size())));
    if (header.vertexCount != model.vertices.size())
        fail(subject, "header says " + str(header.vertexCount) + " vertices but there are " +
                          str(uint64_t(model.vertices.size())));
    if (header.indexBytes != model.indices.size())
        fail(subject, "header says " + str(header.indexBytes) + " index bytes but there are " +
                          str(uint64_t(model.indices.size())));
    if (header.materialCount != model.materials.size())
        fail(subject, "header says " + str(header.materialCount) + " materials but there are " +
                          str(uint64_t(model.materials.size())));
    if (header.cameraCount != model.cameras.size())
        fail(subject, "header says " + str(header.cameraCount) + " cameras but there are " +
                          str(uint64_t(model.cameras.size())));
    if (header.lightCount != model.lights.size())
        fail(subject, "header says " + str(header.lightCount) + " lights but there are " +
                          str(uint64_t(model.lights.size())));
    validateMaterials(model, subject);
    validateCameras(model, subject);
    validateLights(model, subject);
    uint32_t maxIndexBytes = 0;
    validateClusters(model, subject, maxIndexBytes);
    validateNodeLinks(model, subject);
    validateTree(model, subject, maxIndexBytes);
}

CompressedModel openModelMemory(std::span<const uint8_t> bytes, std::shared_ptr<const void> keepAlive,
                                const std::string& subject)
{
    const uint8_t* data = bytes.data();
    const uint64_t size = bytes.size();
    if (reinterpret_cast<uintptr_t>(data) % 8 != 0)
        fail(subject, "internal error: model buffer is not 8-byte aligned");
    if (size >= sizeof(kMagic) && std::memcmp(data, kMagic, sizeof(kMagic)) != 0)
        fail(subject, "not a Penumbra model file (bad magic)");
    // The version first: an older file has another header size.
    if (size >= 12) {
        uint32_t version = 0;
        std::memcpy(&version, data + 8, sizeof(version));
        if (version != kVersion)
            fail(subject, "unsupported version " + str(version) + " (this build reads version " + str(kVersion) +
                              "; run penumbra preprocess on the source model again)");
    }
    if (size < sizeof(FileHeader))
        fail(subject, "truncated: file has " + str(size) + " bytes, the header alone needs " +
                          str(uint64_t(sizeof(FileHeader))));

    // Header.
    FileHeader header;
    std::memcpy(&header, data, sizeof(header));
    if (header.headerSize != sizeof(FileHeader))
        fail(subject, "header size " + str(header.headerSize) + " is not " + str(uint64_t(sizeof(FileHeader))));
    FileHeader unsummed = header;
    unsummed.headerChecksum = 0;
    if (XXH64(&unsummed, sizeof(unsummed), 0) != header.headerChecksum)
        fail(subject, "header checksum mismatch (corrupt header)");
    if (header.fileSize > size)
        fail(subject, "truncated: header says " + str(header.fileSize) + " bytes, file has " + str(size));
    if (header.fileSize < size)
        fail(subject, "trailing data: header says " + str(header.fileSize) + " bytes, file has " + str(size));
    if (header.fileSize % kSectionAlignment != 0)
        fail(subject, "file size " + str(header.fileSize) + " is not a multiple of " + str(kSectionAlignment));
    validateHeaderFields(header, subject);

    // Section table: each type at most once, aligned, inside the file, sized by the header's counts;
    // types 1-5 always, Cameras and Lights exactly when their count is not 0; unused entries all zero.
    std::array<const SectionEntry*, kSectionTypes> byType{};
    std::vector<const SectionEntry*> present;
    for (uint32_t i = 0; i < kSectionSlots; ++i) {
        const SectionEntry& entry = header.sections[i];
        if (entry.type == 0) {
            if (entry.elementSize != 0 || entry.offset != 0 || entry.size != 0 || entry.checksum != 0)
                fail(subject, "section table entry " + str(i) + " is unused (type 0) but not all zero");
            continue;
        }
        if (entry.type > kSectionTypes)
            fail(subject, "section table entry " + str(i) + " has unknown type " + str(entry.type));
        const std::string name = std::string("section ") + sectionName(entry.type);
        if (byType[entry.type - 1])
            fail(subject, name + " appears twice in the section table");
        byType[entry.type - 1] = &entry;
        present.push_back(&entry);
        const uint32_t elementSize = elementSizeOf(entry.type);
        if (entry.elementSize != elementSize)
            fail(subject, name + ": element size " + str(entry.elementSize) + ", expected " + str(elementSize));
        const uint64_t count = declaredCount(header, entry.type);
        if (count > std::numeric_limits<uint64_t>::max() / elementSize || entry.size != count * elementSize)
            fail(subject, name + ": " + str(entry.size) + " bytes, but the header's count " + str(count) + " needs " +
                              str(count) + " x " + str(elementSize));
        if (entry.offset % kSectionAlignment != 0)
            fail(subject, name + ": offset " + str(entry.offset) + " is not a multiple of " + str(kSectionAlignment));
        if (entry.offset < sizeof(FileHeader))
            fail(subject, name + ": offset " + str(entry.offset) + " overlaps the header");
        if (entry.offset > size || entry.size > size - entry.offset)
            fail(subject, name + ": " + str(entry.size) + " bytes at offset " + str(entry.offset) +
                              " run past the end of the file (" + str(size) + " bytes)");
    }
    for (uint32_t type = 1; type <= kSectionTypes; ++type) {
        const bool wanted = declaredCount(header, type) > 0 || type <= uint32_t(SectionType::Materials);
        if (wanted && !byType[type - 1])
            fail(subject, std::string("section ") + sectionName(type) + " is missing from the section table");
        if (!wanted && byType[type - 1])
            fail(subject, std::string("section ") + sectionName(type) + " is present but the header's count is 0");
    }
    std::vector<const SectionEntry*> byOffset = present;
    std::sort(byOffset.begin(), byOffset.end(),
              [](const SectionEntry* a, const SectionEntry* b) { return a->offset < b->offset; });
    for (size_t i = 0; i + 1 < byOffset.size(); ++i)
        if (byOffset[i]->offset + byOffset[i]->size > byOffset[i + 1]->offset)
            fail(subject, std::string("sections ") + sectionName(byOffset[i]->type) + " and " +
                              sectionName(byOffset[i + 1]->type) + " overlap");

    // Every byte outside the header and the payloads is zero padding.
    uint64_t gapBegin = sizeof(FileHeader);
    for (size_t i = 0; i <= byOffset.size(); ++i) {
        const uint64_t gapEnd = i < byOffset.size() ? byOffset[i]->offset : size;
        for (uint64_t at = gapBegin; at < gapEnd; ++at)
            if (data[at] != 0)
                fail(subject, "nonzero padding byte at offset " + str(at));
        if (i < byOffset.size())
            gapBegin = byOffset[i]->offset + byOffset[i]->size;
    }

    for (const SectionEntry* entry : present)
        if (XXH64(data + entry->offset, entry->size, 0) != entry->checksum)
            fail(subject, std::string("checksum mismatch in section ") + sectionName(entry->type));

    // Offsets are multiples of 64 from an 8-byte aligned base: the casts are aligned.
    auto section = [&](SectionType type) { return data + byType[uint32_t(type) - 1]->offset; };
    CompressedModel model;
    model.header = header;
    model.clusters = {reinterpret_cast<const ClusterRecord*>(section(SectionType::Clusters)), header.clusterCount};
    model.nodes = {reinterpret_cast<const Node*>(section(SectionType::Nodes)), header.nodeCount};
    model.vertices = {reinterpret_cast<const QuantizedVertex*>(section(SectionType::Vertices)),
                      size_t(header.vertexCount)};
    model.indices = {section(SectionType::Indices), size_t(header.indexBytes)};
    model.materials = {reinterpret_cast<const MaterialRecord*>(section(SectionType::Materials)), header.materialCount};
    if (header.cameraCount)
        model.cameras = {reinterpret_cast<const CameraRecord*>(section(SectionType::Cameras)), header.cameraCount};
    if (header.lightCount)
        model.lights = {reinterpret_cast<const LightRecord*>(section(SectionType::Lights)), header.lightCount};
    model.storage = std::move(keepAlive);
    validateModel(model, subject);
    return model;
}

} // namespace penumbra
