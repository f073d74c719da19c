// The preprocessor driver: mesh -> CompressedModel (Lauterbach et al. 2009,
// section 5.1: a ReduceM-like strip representation that is rasterized directly
// and ray traced, with one BVH for culling and traversal). Stages:
//   filter   validate indices and positions, drop repeated-index triangles,
//            centroids (16 bytes per triangle, the only per-triangle array)
//   tree     top-level binned SAH down to clusters (cluster_bvh.cpp)
//   clusters per cluster, in parallel: remap, quantize, local SAH tree, strips
//            (cluster_tree.cpp, quantize.cpp, strips.cpp)
//   layout   node array with 8-bit bounds (node_layout.cpp), sections
#include <algorithm>
#include <array>
#include <atomic>
#include <map>
#include <chrono>
#include <cmath>
#include <cstring>
#include <string>
#include <thread>

#include <glm/vec3.hpp>

#include "penumbra/error.h"
#include "preprocess_internal.h"

namespace penumbra {

using namespace preprocess_detail;

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point start)
{
    return std::chrono::duration<double>(Clock::now() - start).count();
}

// Rate-limited progress: forwards when the fraction moved by >= 0.5% (and at 0 and 1).
struct Progress {
    const PreprocessOptions& options;
    const char* stage = "";
    double last = -1.0;
    void begin(const char* name)
    {
        stage = name;
        last = -1.0;
        report(0.0);
    }
    void report(double fraction)
    {
        if (!options.progress || (fraction - last < 0.005 && fraction < 1.0) || fraction == last)
            return;
        last = fraction;
        options.progress(stage, fraction);
    }
};

void checkOptions(const PreprocessOptions& o)
{
    auto bad = [](const std::string& what) { fail("preprocess", "invalid option " + what); };
    if (o.maxClusterVertices < 3 || o.maxClusterVertices > model::kMaxClusterVertices)
        bad("maxClusterVertices " + std::to_string(o.maxClusterVertices) + " (3.." +
            std::to_string(model::kMaxClusterVertices) + ")");
    if (o.maxClusterTriangles < 1 || o.maxClusterTriangles > model::kMaxClusterTriangles)
        bad("maxClusterTriangles " + std::to_string(o.maxClusterTriangles) + " (1.." +
            std::to_string(model::kMaxClusterTriangles) + ")");
    // 4 bytes per triangle is the worst case of a strip range (3 indices + restart).
    if (o.maxLeafTriangles < 1 || o.maxLeafTriangles > o.maxClusterTriangles ||
        uint64_t(o.maxLeafTriangles) * 4 > model::kMaxLeafIndexBytes)
        bad("maxLeafTriangles " + std::to_string(o.maxLeafTriangles) + " (1..maxClusterTriangles)");
    if (o.sahBins < 2 || o.sahBins > 256)
        bad("sahBins " + std::to_string(o.sahBins) + " (2..256)");
}

} // namespace

std::vector<uint8_t> findClosedTriangles(const Mesh& mesh, unsigned threads)
{
    if (mesh.positions.size() % 3 != 0 || mesh.indices.size() % 3 != 0)
        fail("preprocess", "mesh arrays are not multiples of 3");
    const uint64_t vertexCount = mesh.vertexCount();
    for (uint32_t i : mesh.indices)
        if (i >= vertexCount)
            fail("preprocess", "vertex index out of range");
    return closedTriangles(mesh, threads ? threads : std::max(1u, std::thread::hardware_concurrency()));
}

namespace {

uint64_t estimatedNodes(uint64_t triangles, uint64_t leafTriangles)
{
    // 4-wide nodes: at most one per binary interior node (fewer than the leaves)
    // plus the clusters' roots; leaves at least half full: 2 per leafTriangles, rounded up.
    return triangles / leafTriangles * 2 + (triangles % leafTriangles != 0 ? 2 : 0) + 1;
}

} // namespace

void checkModelLimits(uint64_t triangles, const PreprocessOptions& options, const std::string& subject)
{
    const uint64_t leaf = std::max<uint32_t>(1, options.maxLeafTriangles);
    const uint64_t cluster = std::max<uint32_t>(1, options.maxClusterTriangles);
    const uint64_t nodes = estimatedNodes(triangles, leaf);
    if (nodes > model::kMaxNodes) {
        uint64_t enough = leaf;
        while (enough < model::kMaxClusterTriangles && estimatedNodes(triangles, enough) > model::kMaxNodes)
            ++enough;
        fail(subject, std::to_string(triangles) + " triangles may need about " + std::to_string(nodes) +
                          " BVH nodes (2 per " + std::to_string(leaf) + " triangles), more than the format's " +
                          std::to_string(model::kMaxNodes) + " (32-bit node indices)" +
                          (estimatedNodes(triangles, enough) <= model::kMaxNodes
                               ? "; use --leaf-triangles " + std::to_string(enough) + " or more"
                               : std::string("; split the model")));
    }
    if (triangles / cluster * 2 + 2 > model::kMaxClusters)
        fail(subject, std::to_string(triangles) + " triangles may need more clusters than the format's " +
                          std::to_string(model::kMaxClusters) + " (32-bit cluster indices)");
}

CompressedModel buildCompressedModel(const Mesh& mesh, const PreprocessOptions& options, PreprocessStats* statsOut,
                                     std::vector<uint32_t>* decodedTriangleSource)
{
    return buildModel(mesh, options, statsOut, decodedTriangleSource, {});
}

namespace preprocess_detail {

CompressedModel buildModel(const Mesh& mesh, const PreprocessOptions& options, PreprocessStats* statsOut,
                           std::vector<uint32_t>* decodedTriangleSource, const BuildExtras& extras)
{
    if (extras.rootDepth < 1 || extras.rootDepth + 4 > model::kMaxBvhDepth)
        fail("preprocess", "internal error: root depth " + std::to_string(extras.rootDepth));
    const uint32_t binaryRootDepth = 2 * (extras.rootDepth - 1) + 1;
    const auto start = Clock::now();
    checkOptions(options);
    const unsigned threads = options.threads ? options.threads : std::max(1u, std::thread::hardware_concurrency());
    PreprocessStats stats;
    Progress progress{options};

    // ---- filter ------------------------------------------------------------------
    progress.begin("filter");
    auto stageStart = Clock::now();
    if (mesh.positions.size() % 3 != 0 || mesh.indices.size() % 3 != 0)
        fail("preprocess", "mesh arrays are not multiples of 3");
    const uint64_t inputTriangles = mesh.triangleCount();
    const uint64_t vertexCount = mesh.vertexCount();
    if (inputTriangles > 0xFFFFFFFEull)
        fail("preprocess", "more than 2^32-2 triangles in one in-core build (use --memory-limit: streamed builds have no such limit)");
    checkModelLimits(inputTriangles, options);
    stats.inputTriangles = inputTriangles;
    const uint64_t chunkSize = 1 << 16;
    const uint64_t chunks = (inputTriangles + chunkSize - 1) / chunkSize;
    std::vector<uint64_t> kept(chunks + 1, 0);
    std::atomic<bool> badIndex{false}, badPosition{false};
    parallelFor(threads, chunks, [&](uint64_t c) {
        uint64_t count = 0;
        const uint32_t* idx = mesh.indices.data();
        for (uint64_t t = c * chunkSize, e = std::min(inputTriangles, t + chunkSize); t < e; ++t) {
            uint32_t a = idx[3 * t], b = idx[3 * t + 1], d = idx[3 * t + 2];
            if (a >= vertexCount || b >= vertexCount || d >= vertexCount)
                badIndex = true;
            count += (a != b && b != d && a != d) ? 1 : 0;
        }
        kept[c + 1] = count;
    });
    if (badIndex)
        fail("preprocess", "vertex index out of range");
    parallelFor(threads, (vertexCount + chunkSize - 1) / chunkSize, [&](uint64_t c) {
        for (uint64_t i = c * chunkSize * 3, e = std::min(vertexCount, (c + 1) * chunkSize) * 3; i < e; ++i)
            if (!std::isfinite(mesh.positions[i]))
                badPosition = true;
    });
    if (badPosition)
        fail("preprocess", "non-finite vertex position");
    // Colours (mesh.h): materials kept apart by the clusters, or a colour per cluster.
    if (!mesh.colors.empty() && mesh.colors.size() != mesh.positions.size())
        fail("preprocess", "vertex colours do not match the vertices");
    for (float c : mesh.colors)
        if (!(c >= 0.0f && c <= 1.0f))
            fail("preprocess", "vertex colour component outside [0, 1]");
    for (const Material& material : mesh.materials)
        for (int k = 0; k < 4; ++k)
            if (!(material.baseColor[k] >= 0.0f && material.baseColor[k] <= 1.0f))
                fail("preprocess", "material base colour component outside [0, 1]");
    if (!mesh.triangleMaterials.empty()) {
        if (mesh.triangleMaterials.size() != inputTriangles)
            fail("preprocess", "triangle materials do not match the triangles");
        for (uint32_t m : mesh.triangleMaterials)
            if (m >= mesh.materials.size())
                fail("preprocess", "triangle material index out of range");
    }
    const bool splitMaterials = mesh.colors.empty() && mesh.materials.size() > 1 &&
                                mesh.materials.size() <= kMaxSplitMaterials && !mesh.triangleMaterials.empty();
    const bool clusterColors = !mesh.colors.empty() || mesh.materials.size() > kMaxSplitMaterials;
    for (uint64_t c = 0; c < chunks; ++c)
        kept[c + 1] += kept[c];
    const uint64_t triangleCount = kept[chunks];
    stats.droppedDegenerate = inputTriangles - triangleCount;
    if (triangleCount == 0)
        fail("preprocess", inputTriangles == 0 ? "mesh has no triangles"
                                               : "mesh has no non-degenerate triangles (all repeat a vertex index)");
    // Closed components (kClusterClosed), before the per-triangle arrays of the tree stage so that
    // its temporary memory does not add to their peak.
    const auto closedStart = Clock::now();
    std::vector<uint32_t> component = extras.component ? std::vector<uint32_t>(extras.component, extras.component + inputTriangles)
                                                       : closedComponents(mesh, threads);
    // Closed components that another surface comes within the shadow rays' offset of are not
    // flagged (crowdedComponents); closedTriangles still counts them.
    std::vector<uint8_t> crowded;
    if (!extras.component) {
        float lo[3], hi[3];
        meshBounds(mesh, lo, hi);
        crowded = crowdedComponents(mesh, component.data(), closedClearance(lo, hi), nullptr, nullptr, threads);
    }
    const uint8_t* crowdedOf = extras.component ? extras.crowded : crowded.data();
    for (uint64_t t = 0; t < inputTriangles; ++t)
        if (component[t] != kOpenComponent) {
            ++stats.closedTriangles;
            if (crowdedOf && crowdedOf[component[t]])
                component[t] = kOpenComponent;
        }
    crowded = {};
    stats.closedSeconds = secondsSince(closedStart);
    std::vector<TriangleRef> refs(triangleCount);
    std::vector<glm::dvec3> extentSums(chunks, glm::dvec3(0.0));
    parallelFor(threads, chunks, [&](uint64_t c) {
        glm::vec3 extentSum(0.0f);
        uint64_t out = kept[c];
        const uint32_t* idx = mesh.indices.data();
        const float* p = mesh.positions.data();
        for (uint64_t t = c * chunkSize, e = std::min(inputTriangles, t + chunkSize); t < e; ++t) {
            uint32_t a = idx[3 * t], b = idx[3 * t + 1], d = idx[3 * t + 2];
            if (a == b || b == d || a == d)
                continue;
            TriangleRef& r = refs[out++];
            for (int k = 0; k < 3; ++k) {
                float x = p[3 * a + k], y = p[3 * b + k], z = p[3 * d + k];
                r.centroid[k] = x + y + z;
                extentSum[k] += std::max({x, y, z}) - std::min({x, y, z});
            }
            r.triangle = uint32_t(t);
        }
        extentSums[c] = glm::dvec3(extentSum);
    });
    glm::dvec3 extentTotal(0.0);
    for (const glm::dvec3& e : extentSums)
        extentTotal += e;
    const glm::vec3 meanExtent = glm::vec3(extentTotal / double(triangleCount));
    kept = {};
    stats.filterSeconds = secondsSince(stageStart);
    progress.report(1.0);

    // ---- tree --------------------------------------------------------------------
    progress.begin("tree");
    stageStart = Clock::now();
    // Clusters keep apart what their keys tell apart: materials (when split) and, with
    // separateClosed, closed components from open ones, so that closed ones get kClusterClosed.
    std::vector<uint32_t> splitKeys;
    if (splitMaterials || options.separateClosed) {
        uint8_t seen = 0; // bit 0: an open triangle, bit 1: a closed one
        for (uint64_t t = 0; t < inputTriangles && seen != 3; ++t)
            seen |= component[t] != kOpenComponent ? 2 : 1;
        if (splitMaterials || seen == 3) {
            splitKeys.resize(inputTriangles);
            const bool byClosed = options.separateClosed && seen == 3;
            parallelFor(threads, chunks, [&](uint64_t c) {
                for (uint64_t t = c * chunkSize, e = std::min(inputTriangles, t + chunkSize); t < e; ++t)
                    splitKeys[t] = (splitMaterials ? mesh.triangleMaterials[t] : 0u) * 2u + (byClosed && component[t] != kOpenComponent ? 1u : 0u);
            });
        }
    }
    TopTree tree = buildTopTree(mesh, refs, meanExtent, options, threads, [&](double f) { progress.report(f); },
                                splitKeys.empty() ? nullptr : splitKeys.data(), binaryRootDepth);
    splitKeys = {};
    std::vector<uint32_t> triangles(triangleCount);
    parallelFor(threads, (triangleCount + chunkSize - 1) / chunkSize, [&](uint64_t c) {
        for (uint64_t i = c * chunkSize, e = std::min(triangleCount, (c + 1) * chunkSize); i < e; ++i)
            triangles[i] = refs[i].triangle;
    });
    refs = {};
    stats.treeSeconds = secondsSince(stageStart);
    progress.report(1.0);

    // ---- clusters ----------------------------------------------------------------
    // Vertex counts are known from the tree stage and clusters are already in
    // file order, so every worker quantizes straight into the final vertex section.
    progress.begin("clusters");
    stageStart = Clock::now();
    const size_t clusterCount = tree.clusters.size();
    std::vector<uint64_t> vertexOffset(clusterCount + 1, 0);
    for (size_t i = 0; i < clusterCount; ++i)
        vertexOffset[i + 1] = vertexOffset[i] + tree.clusters[i].vertices;
    const uint64_t vertexTotal = vertexOffset[clusterCount];
    auto data = std::make_shared<CompressedModelData>();
    data->vertices.resize(vertexTotal);
    std::vector<BuiltCluster> built(clusterCount);
    const bool wantSource = decodedTriangleSource != nullptr;
    // Per cluster: its material (split: the first triangle's; all the same unless the depth budget
    // forbade the split) or the mean colour of its triangles.
    std::vector<uint32_t> clusterMaterial(clusterCount, 0);
    const std::vector<uint8_t> clusterClosed =
        closedClusterFlags(component.data(), triangles.data(), tree.clusters.data(), clusterCount, inputTriangles, threads);
    std::vector<glm::vec3> clusterColor(clusterColors ? clusterCount : 0);
    parallelFor(
        threads, clusterCount,
        [&](uint64_t c) {
            const ClusterRange& r = tree.clusters[c];
            if (splitMaterials)
                clusterMaterial[c] = mesh.triangleMaterials[triangles[r.begin]];
            if (clusterColors) {
                glm::dvec3 sum(0.0);
                for (uint32_t i = r.begin; i < r.end; ++i)
                    sum += glm::dvec3(mesh.triangleColor(triangles[i]));
                clusterColor[c] = glm::clamp(glm::vec3(sum / double(r.end - r.begin)), 0.0f, 1.0f);
            }
            buildCluster(mesh, triangles.data() + r.begin, r.end - r.begin, r.vertices, r.depth, options, wantSource,
                         data->vertices.data() + vertexOffset[c], built[c]);
        },
        [&](uint64_t done) { progress.report(double(done) / double(clusterCount)); });
    if (splitMaterials)
        for (size_t c = 0; c < clusterCount; ++c)
            for (uint32_t i = tree.clusters[c].begin; i < tree.clusters[c].end; ++i)
                stats.mixedMaterialTriangles += mesh.triangleMaterials[triangles[i]] != clusterMaterial[c];
    // The material table: the mesh's materials, a palette of the clusters' colours (equal ones
    // shared), or one white material.
    if (clusterColors) {
        std::map<std::array<float, 3>, uint32_t> palette;
        for (size_t c = 0; c < clusterCount; ++c) {
            const std::array<float, 3> key = {clusterColor[c].x, clusterColor[c].y, clusterColor[c].z};
            auto [it, added] = palette.emplace(key, uint32_t(data->materials.size()));
            if (added)
                data->materials.push_back({{key[0], key[1], key[2], 1.0f}});
            clusterMaterial[c] = it->second;
        }
    } else if (!mesh.materials.empty()) {
        // One material (no splitting needed) or the split ones.
        for (const Material& material : mesh.materials)
            data->materials.push_back({{material.baseColor.r, material.baseColor.g, material.baseColor.b, material.baseColor.a}});
    } else {
        data->materials.push_back({{1.0f, 1.0f, 1.0f, 1.0f}});
    }
    for (size_t c = 0; c < clusterCount; ++c) {
        const uint32_t n = tree.clusters[c].end - tree.clusters[c].begin;
        stats.closedClusters += clusterClosed[c];
        stats.closedClusterTriangles += clusterClosed[c] ? n : 0;
    }
    component = {};
    triangles = {};
    stats.clusterSeconds = secondsSince(stageStart);

    // ---- layout ------------------------------------------------------------------
    progress.begin("layout");
    stageStart = Clock::now();
    std::vector<Box> topBoxes(tree.nodes.size());
    for (size_t i = tree.nodes.size(); i-- > 0;) {
        const TopNode& node = tree.nodes[i];
        if (node.cluster != kNone)
            topBoxes[i] = built[node.cluster].nodes[0].box;
        else
            for (uint32_t c = 0; c < node.childCount; ++c)
                topBoxes[i].grow(topBoxes[node.child[c]]);
    }
    // Root box: the input bounds of the used vertices, grown to hold every decoded vertex.
    Box root = topBoxes[0];
    float maxError = 0.0f;
    for (const BuiltCluster& c : built) {
        root.grow(c.inputBox);
        maxError = std::max(maxError, c.maxError);
    }
    Layout layout = layoutNodes(tree, topBoxes, built, model::kMaxBvhDepth - (extras.rootDepth - 1));
    tree = TopTree();
    topBoxes = {};
    for (size_t i = 0; i < clusterCount; ++i)
        if (layout.clusterOrder[i] != i)
            fail("preprocess", "internal error: cluster order of the tree and the node layout differ");

    data->clusters.resize(clusterCount);
    uint64_t byteTotal = 0;
    std::vector<uint64_t> byteOffset(clusterCount);
    for (size_t i = 0; i < clusterCount; ++i) {
        const BuiltCluster& c = built[i];
        byteOffset[i] = byteTotal;
        byteTotal += c.bytes.size();
        stats.leaves += c.leaves;
        stats.stripFallbackLeaves += c.fallbackLeaves;
    }
    data->indices.resize(byteTotal);
    std::vector<uint64_t> sourceOffset;
    if (wantSource) {
        sourceOffset.resize(clusterCount + 1, 0);
        for (size_t i = 0; i < clusterCount; ++i)
            sourceOffset[i + 1] = sourceOffset[i] + built[i].source.size();
        decodedTriangleSource->assign(sourceOffset.back(), 0);
    }
    parallelFor(threads, clusterCount, [&](uint64_t i) {
        BuiltCluster& c = built[i];
        model::ClusterRecord record = c.record;
        record.firstVertex = vertexOffset[i];
        record.firstIndex = byteOffset[i];
        record.indexBytes = uint32_t(c.bytes.size());
        record.node = layout.clusterNode[i];
        record.material = clusterMaterial[i];
        record.flags = clusterClosed[i] ? model::kClusterClosed : 0u;
        record.reserved = 0;
        data->clusters[i] = record;
        std::copy(c.bytes.begin(), c.bytes.end(), data->indices.begin() + byteOffset[i]);
        if (wantSource)
            std::copy(c.source.begin(), c.source.end(), decodedTriangleSource->begin() + sourceOffset[i]);
        c = BuiltCluster();
    });
    built = {};
    data->nodes = std::move(layout.nodes);

    model::FileHeader& h = data->header;
    h.headerSize = sizeof(model::FileHeader);
    h.triangleCount = triangleCount;
    h.sourceTriangleCount = inputTriangles;
    h.vertexCount = vertexTotal;
    h.indexBytes = byteTotal;
    h.clusterCount = uint32_t(clusterCount);
    h.nodeCount = uint32_t(data->nodes.size());
    h.materialCount = uint32_t(data->materials.size());
    h.bvhDepth = layout.depth;
    for (int a = 0; a < 3; ++a) {
        h.boundsMin[a] = root.min[a];
        h.boundsMax[a] = root.max[a];
    }
    h.maxPositionError = maxError;
    h.simplifyError = 0.0f;
    h.build.maxClusterVertices = options.maxClusterVertices;
    h.build.maxClusterTriangles = options.maxClusterTriangles;
    h.build.maxLeafTriangles = options.maxLeafTriangles;
    h.build.sahBins = options.sahBins;
    h.build.positionBits = model::kPositionBits;
    h.build.nodeBoundsBits = model::kNodeBoundsBits;
    h.build.simplifyTarget = 1.0f;
    h.build.reserved = 0;
    stats.layoutSeconds = secondsSince(stageStart);
    progress.report(1.0);

    stats.totalSeconds = secondsSince(start);
    stats.triangles = triangleCount;
    stats.clusters = clusterCount;
    stats.nodes = h.nodeCount;
    stats.vertices = vertexTotal;
    stats.indexBytes = byteTotal;
    stats.widenedBounds = layout.widened;
    stats.bvhDepth = h.bvhDepth;
    stats.maxPositionError = maxError;
    stats.materials = h.materialCount;
    stats.bytesPerTriangle = double(clusterCount * sizeof(model::ClusterRecord) + h.nodeCount * sizeof(model::Node) +
                                    vertexTotal * sizeof(model::QuantizedVertex) + byteTotal +
                                    h.materialCount * sizeof(model::MaterialRecord)) /
                             double(triangleCount);
    if (statsOut)
        *statsOut = stats;
    return makeCompressedModel(std::move(data));
}

} // namespace preprocess_detail

} // namespace penumbra
