// Frustum and occlusion-query culling of the raster passes with the top of the
// shared BVH (Lauterbach et al. 2009, section 5.1). The scheme and why it
// keeps images bit-identical: culling.h.
#include "culling.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>

#include <glm/mat4x4.hpp>

#include "config.h"
#include "pipelines.h"

namespace penumbra {

namespace {

struct BoxPush {
    glm::mat4 viewProj;
    VkDeviceAddress boxes;
};
static_assert(sizeof(BoxPush) == 72);

struct PredicatePush {
    VkDeviceAddress commands;
    VkDeviceAddress commandQueries;
    VkDeviceAddress queryResults;
    VkDeviceAddress firstPassed;
    uint32_t count;
    uint32_t step;
};
static_assert(sizeof(PredicatePush) == 40);

constexpr VkDeviceSize kCommandBytes = sizeof(VkDrawIndexedIndirectCommand);
// Queries per view: its first and last timestamps, each written twice (vk::writeTimestamp).
constexpr uint32_t kViewTimestampQueries = 2 * vk::kTimestampQueries;

// Box pipeline: the cull_box.vert triangles, depth test LESS_OR_EQUAL (as the
// geometry), no depth or colour writes, no depth bias (a query box is never
// deeper than the geometry inside it, and the shadow bias is >= 0).
VkPipeline createBoxPipeline(vk::Device& device, VkPipelineLayout layout, const std::vector<VkFormat>& colorFormats,
                             VkFormat depthFormat)
{
    vk::GraphicsPipelineDesc desc;
    desc.vertexShader = "cull_box.vert";
    desc.colorFormats = colorFormats;
    desc.colorWrite = false;
    desc.depthFormat = depthFormat;
    desc.depthWrite = false;
    desc.modelGeometry = false;
    desc.layout = layout;
    desc.pushBytes = sizeof(BoxPush);
    return vk::createGraphicsPipeline(device, desc);
}

// Where a box lies against a view's clip volume -w <= x, y <= w, 0 <= z <= w
// (every bound is linear in the world position, so a box is outside when all
// eight corners are outside one bound).
struct BoxTest {
    bool outside = false;     // entirely outside one bound: nothing in it is rasterized
    bool crossesNear = false; // some corner in front of the near plane (or behind the eye): a query could miss it
};

BoxTest testBox(const glm::dmat4& m, const glm::vec3& lo, const glm::vec3& hi)
{
    uint32_t outsideAll = 0x1F; // bits: x < -w, x > w, y < -w, y > w, z > w; near handled separately
    bool allBehindNear = true;
    BoxTest test;
    for (int i = 0; i < 8; ++i) {
        glm::dvec4 c = m * glm::dvec4(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z, 1.0);
        // Tolerance for the GPU's float transform of the geometry.
        const double tolerance = 1e-5 * (std::abs(c.w) + std::abs(c.x) + std::abs(c.y) + std::abs(c.z));
        uint32_t outside = (c.x < -c.w - tolerance ? 1u : 0u) | (c.x > c.w + tolerance ? 2u : 0u) |
                           (c.y < -c.w - tolerance ? 4u : 0u) | (c.y > c.w + tolerance ? 8u : 0u) |
                           (c.z > c.w + tolerance ? 16u : 0u);
        outsideAll &= outside;
        allBehindNear = allBehindNear && c.z < -tolerance;
        test.crossesNear = test.crossesNear || c.z <= tolerance || c.w <= tolerance;
    }
    test.outside = outsideAll != 0 || allBehindNear;
    return test;
}

void ensureBuffer(vk::Device& device, vk::Buffer& buffer, VkDeviceSize bytes, VkBufferUsageFlags usage,
                  vk::MemoryUse use)
{
    if (buffer.buffer && buffer.size >= bytes)
        return;
    vk::destroyBuffer(device, buffer);
    buffer = vk::createBuffer(device, std::max<VkDeviceSize>(bytes + bytes / 2, 256), usage, use, vk::Addressable::Yes);
}

} // namespace

void ReceiverMask::build(const uint32_t* bits, uint32_t cellsPerSide)
{
    resolution = cellsPerSide;
    const uint32_t stride = resolution + 1;
    prefix.assign(size_t(stride) * stride, 0);
    for (uint32_t y = 0; y < resolution; ++y) {
        uint32_t row = 0;
        for (uint32_t x = 0; x < resolution; ++x) {
            const uint32_t index = y * resolution + x;
            row += (bits[index >> 5] >> (index & 31)) & 1u;
            prefix[size_t(y + 1) * stride + x + 1] = prefix[size_t(y) * stride + x + 1] + row;
        }
    }
}

bool ReceiverMask::mayCover(const glm::vec3& lo, const glm::vec3& hi) const
{
    glm::dvec2 footMin(std::numeric_limits<double>::max()), footMax(-std::numeric_limits<double>::max());
    for (int i = 0; i < 8; ++i) {
        glm::dvec4 c = viewProj * glm::dvec4(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z, 1.0);
        if (c.w <= 1e-9 * (std::abs(c.x) + std::abs(c.y) + std::abs(c.z)) || c.w <= 0.0)
            return true; // reaches the eye plane of a perspective map: no bounded footprint
        footMin = glm::min(footMin, glm::dvec2(c) / c.w);
        footMax = glm::max(footMax, glm::dvec2(c) / c.w);
    }
    // Cells from clip units, clamped like the pixels' (view_fit.comp.glsl).
    auto cell = [&](double clip) {
        const double c = std::floor((clip * 0.5 + 0.5) * double(resolution));
        return uint32_t(std::clamp(c, 0.0, double(resolution - 1)));
    };
    const uint32_t x0 = cell(footMin.x - margin.x), x1 = cell(footMax.x + margin.x);
    const uint32_t y0 = cell(footMin.y - margin.y), y1 = cell(footMax.y + margin.y);
    const size_t stride = resolution + 1;
    const uint32_t count = prefix[(y1 + 1) * stride + x1 + 1] - prefix[y0 * stride + x1 + 1] -
                           prefix[(y1 + 1) * stride + x0] + prefix[y0 * stride + x0];
    return count != 0;
}

void Culling::create(vk::Device& device, const std::vector<VkFormat>& cameraColorFormats, VkFormat depthFormat)
{
    boxLayout = vk::createPipelineLayout(device, VK_NULL_HANDLE, sizeof(BoxPush), VK_SHADER_STAGE_VERTEX_BIT);
    predicateLayout =
        vk::createPipelineLayout(device, VK_NULL_HANDLE, sizeof(PredicatePush), VK_SHADER_STAGE_COMPUTE_BIT);
    for (size_t albedo = 0; albedo < 2; ++albedo)
        cameraBoxPipelines[albedo] = createBoxPipeline(
            device, boxLayout, {cameraColorFormats.begin(), cameraColorFormats.begin() + std::min<size_t>(1 + albedo, cameraColorFormats.size())},
            depthFormat);
    shadowBoxPipeline = createBoxPipeline(device, boxLayout, {}, depthFormat);
    predicatePipeline = vk::createComputePipeline(device, "cull_predicates.comp", predicateLayout, sizeof(PredicatePush));
    timestampPeriodNs = device.properties.limits.timestampPeriod;
}

void Culling::destroy(vk::Device& device)
{
    for (vk::Buffer* buffer : {&drawCommands, &commandQueries, &boxes, &queryResults})
        vk::destroyBuffer(device, *buffer);
    VkDevice d = device.device;
    if (queryPool)
        vkDestroyQueryPool(d, queryPool, nullptr);
    if (timestampPool)
        vkDestroyQueryPool(d, timestampPool, nullptr);
    for (VkPipeline p : {cameraBoxPipelines[0], cameraBoxPipelines[1], shadowBoxPipeline, predicatePipeline})
        if (p)
            vkDestroyPipeline(d, p, nullptr);
    for (VkPipelineLayout l : {boxLayout, predicateLayout})
        if (l)
            vkDestroyPipelineLayout(d, l, nullptr);
    queryPool = timestampPool = VK_NULL_HANDLE;
    timestampCapacity = 0;
    cameraBoxPipelines[0] = cameraBoxPipelines[1] = shadowBoxPipeline = predicatePipeline = VK_NULL_HANDLE;
    boxLayout = predicateLayout = VK_NULL_HANDLE;
    queryCapacity = 0;
}

void Culling::clearModel()
{
    model.reset();
    history.clear();
    plans.clear();
    queryCount = 0;
}

void Culling::setModel(std::shared_ptr<const CullModel> cullModel)
{
    clearModel();
    model = std::move(cullModel);
}

CullModel::CullModel(const CompressedModel& model, const GpuGeometry& geometry)
{
    const size_t clusterCount = model.clusters.size();
    clusterMin.resize(clusterCount);
    clusterMax.resize(clusterCount);
    clusterTriangles.resize(clusterCount);
    // Quantization boxes: decoded = boxMin + float(q) * step with q <= 65535, so
    // (float rounding being monotonic) every decoded vertex lies inside.
    for (size_t i = 0; i < clusterCount; ++i) {
        const model::ClusterRecord& c = model.clusters[i];
        for (int a = 0; a < 3; ++a) {
            clusterMin[i][a] = c.boxMin[a];
            clusterMax[i][a] = c.boxMin[a] + 65535.0f * c.step[a];
        }
        clusterTriangles[i] = c.triangleCount;
        totalTriangles += c.triangleCount;
    }
    commands = geometry.commands;
    clusterChunk.resize(clusterCount);
    for (size_t k = 0; k < geometry.chunks.size(); ++k) {
        const GpuGeometry::Chunk& chunk = geometry.chunks[k];
        for (uint32_t i = chunk.firstCluster; i < chunk.firstCluster + chunk.clusterCount; ++i)
            clusterChunk[i] = uint32_t(k);
    }

    // The BVH top: from the root down to the clusters' root nodes, children
    // stored consecutively after their parent; boxes are the unions of the
    // cluster boxes below (the nodes' 8-bit boxes contain them too, but these
    // are tighter).
    std::vector<uint32_t> modelIndex{0};
    topNodes.resize(1);
    for (size_t t = 0; t < topNodes.size(); ++t) {
        const model::Node& node = model.nodes[modelIndex[t]];
        if (node.cluster != model::kNoCluster) {
            topNodes[t].cluster = node.cluster;
            continue;
        }
        const uint32_t children = model::childCount(node);
        if (children == 0)
            fail("model", "BVH node " + std::to_string(modelIndex[t]) + " above the clusters has no children");
        topNodes[t].firstChild = uint32_t(topNodes.size());
        topNodes[t].childCount = children;
        for (uint32_t c = 0; c < children; ++c) {
            topNodes.push_back({});
            modelIndex.push_back(node.child[c]);
        }
    }
    for (size_t t = topNodes.size(); t-- > 0;) {
        CullModel::TopNode& node = topNodes[t];
        if (node.childCount == 0) {
            node.min = clusterMin[node.cluster];
            node.max = clusterMax[node.cluster];
            node.clusterCount = 1;
            continue;
        }
        node.min = topNodes[node.firstChild].min;
        node.max = topNodes[node.firstChild].max;
        for (uint32_t c = 0; c < node.childCount; ++c) {
            const CullModel::TopNode& child = topNodes[node.firstChild + c];
            node.min = glm::min(node.min, child.min);
            node.max = glm::max(node.max, child.max);
            node.clusterCount += child.clusterCount;
        }
    }
    boxMargin = 1e-5f * glm::length(topNodes[0].max - topNodes[0].min) + 1e-7f;
}

void Culling::planView(ViewPlan& plan)
{
    auto start = std::chrono::steady_clock::now();
    const glm::dmat4 viewProj(plan.view.viewProj);
    const bool occlusion = plan.view.occlusion;
    History& state = history[plan.view.slot];
    std::vector<uint8_t>& visible = state.visible;
    visible.resize(model->clusterMin.size(), 0);
    const glm::vec3 margin(model->boxMargin);

    // Clusters of last frame's set below each node (children after parents).
    std::vector<uint32_t> historyBelow;
    if (occlusion) {
        historyBelow.assign(model->topNodes.size(), 0);
        for (size_t t = model->topNodes.size(); t-- > 0;) {
            const CullModel::TopNode& node = model->topNodes[t];
            if (node.childCount == 0)
                historyBelow[t] = visible[node.cluster];
            else
                for (uint32_t c = 0; c < node.childCount; ++c)
                    historyBelow[t] += historyBelow[node.firstChild + c];
        }
    }
    auto addQueryBox = [&](const glm::vec3& lo, const glm::vec3& hi) {
        queryBoxes.push_back(lo - margin);
        queryBoxes.push_back(hi + margin);
    };

    // Depth-first traversal in child order. Occlusion: a subtree without
    // history of at most PENUMBRA_CULL_GROUP_CLUSTERS clusters is one query
    // (tested after phase 1); below that, every cell (subtree of at most
    // PENUMBRA_CULL_CELL_CLUSTERS clusters) with history is drawn in phase 1
    // and its box tested against the final depth (next frame's history); a
    // cell at the near plane is drawn in phase 1 and stays visible.
    enum class Role : uint8_t { Free, Group, HistoryCell, Kept };
    struct Item {
        uint32_t node;
        Role role;
    };
    std::vector<Item> stack{{0, Role::Free}};
    std::vector<uint32_t> historyCells;
    while (!stack.empty()) {
        Item item = stack.back();
        stack.pop_back();
        const CullModel::TopNode& node = model->topNodes[item.node];
        ++plan.nodesTested;
        BoxTest test = testBox(viewProj, node.min - margin, node.max + margin);
        if (test.outside)
            continue;
        if (plan.view.receivers && !plan.view.receivers->mayCover(node.min - margin, node.max + margin)) {
            plan.clustersBesideReceivers += node.clusterCount;
            continue;
        }
        Role role = item.role;
        if (occlusion && role == Role::Free) {
            if (!test.crossesNear && historyBelow[item.node] == 0 &&
                node.clusterCount <= PENUMBRA_CULL_GROUP_CLUSTERS) {
                role = Role::Group;
                plan.groupQueryBegin.push_back(uint32_t(plan.groupClusters.size()));
                addQueryBox(node.min, node.max);
            } else if (node.clusterCount <= PENUMBRA_CULL_CELL_CLUSTERS) {
                // A visible cell is tested every PENUMBRA_CULL_RETEST_FRAMES frames
                // (staggered); in between it is kept, like a cell at the near plane.
                const bool retest = (item.node + state.frame) % PENUMBRA_CULL_RETEST_FRAMES == 0;
                role = test.crossesNear || !retest ? Role::Kept : Role::HistoryCell;
                if (role == Role::HistoryCell) {
                    plan.historyQueryBegin.push_back(uint32_t(plan.historyClusters.size()));
                    historyCells.push_back(item.node);
                }
            }
        }
        if (node.childCount == 0) {
            switch (role) {
            case Role::Free:
                plan.finalPhase.push_back({node.cluster, kNoQuery});
                break;
            case Role::Group:
                plan.finalPhase.push_back({node.cluster, uint32_t(plan.groupQueryBegin.size() - 1)});
                plan.groupClusters.push_back(node.cluster);
                break;
            case Role::HistoryCell:
                plan.firstPhase.push_back(node.cluster);
                plan.historyClusters.push_back(node.cluster);
                break;
            case Role::Kept:
                plan.firstPhase.push_back(node.cluster);
                plan.keptVisible.push_back(node.cluster);
                break;
            }
            continue;
        }
        for (uint32_t c = node.childCount; c-- > 0;)
            stack.push_back({node.firstChild + c, role});
    }
    // Group queries are numbered per view here; beginFrame makes them global.
    // Boxes: the groups' (above, in query order), then the history cells'.
    for (uint32_t cell : historyCells)
        addQueryBox(model->topNodes[cell].min, model->topNodes[cell].max);
    std::sort(plan.firstPhase.begin(), plan.firstPhase.end());
    if (plan.view.camera)
        for (uint32_t cluster : plan.firstPhase)
            plan.finalPhase.push_back({cluster, kNoQuery});
    std::sort(plan.finalPhase.begin(), plan.finalPhase.end(),
              [](const Entry& x, const Entry& y) { return x.cluster < y.cluster; });
    if (occlusion)
        ++state.frame;
    plan.cpuMs += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

void Culling::markClustersNearReceivers(const ReceiverMask& mask, uint32_t* bits) const
{
    if (!model)
        return;
    const glm::vec3 margin(model->boxMargin);
    std::vector<uint32_t> stack{0};
    while (!stack.empty()) {
        const CullModel::TopNode& node = model->topNodes[stack.back()];
        stack.pop_back();
        if (!mask.mayCover(node.min - margin, node.max + margin))
            continue;
        if (node.childCount == 0)
            bits[node.cluster >> 5] |= 1u << (node.cluster & 31);
        for (uint32_t c = 0; c < node.childCount; ++c)
            stack.push_back(node.firstChild + c);
    }
}

void Culling::beginFrame(vk::Device& device, CullMode cullMode, bool adaptiveOcclusion, std::vector<CullView> views)
{
    mode = cullMode;
    adaptive = adaptiveOcclusion;
    plans.clear();
    queryBoxes.clear();
    queryCount = 0;
    if (!model)
        return;
    uint32_t commandCount = 0;
    for (CullView& view : views) {
        ViewPlan plan;
        plan.view = std::move(view);
        History& state = history[plan.view.slot];
        if (!adaptive)
            state.frustumOnlyFrames = 0;
        plan.view.occlusion = plan.view.occlusion && mode == CullMode::All && state.frustumOnlyFrames == 0;
        if (mode == CullMode::All && state.frustumOnlyFrames > 0)
            --state.frustumOnlyFrames;
        plan.firstQuery = queryCount;
        plan.firstCommand = commandCount;
        if (mode != CullMode::None) {
            bool planned = false;
            if (plan.view.occlusion && adaptive) {
                // A view with few triangles in its frustum draws them faster
                // than it tests boxes: a query rasterizes its box's footprint
                // (on lavapipe, a sun's 2048^2 map of a 2,000-triangle model
                // took 21 ms of CPU with one query, 13 ms without).
                // The plan with queries lists every cluster in the frustum
                // (in one of its two phases), so it counts them: a view
                // plans once unless it is that small.
                ViewPlan frustumOnly = plan;
                frustumOnly.view.occlusion = false;
                const size_t boxes = queryBoxes.size();
                const uint32_t frame = state.frame;
                planView(plan);
                planned = true;
                uint64_t triangles = 0;
                for (uint32_t cluster : plan.firstPhase)
                    triangles += model->clusterTriangles[cluster];
                for (const Entry& entry : plan.finalPhase)
                    triangles += model->clusterTriangles[entry.cluster];
                if (triangles < PENUMBRA_CULL_MIN_TRIANGLES) {
                    queryBoxes.resize(boxes); // the plan's own, undone with its frame count
                    state.frame = frame;
                    frustumOnly.cpuMs = plan.cpuMs;
                    planView(frustumOnly);
                    plan = std::move(frustumOnly);
                }
            }
            if (!planned)
                planView(plan);
        }
        for (Entry& entry : plan.finalPhase)
            if (entry.query != kNoQuery)
                entry.query += plan.firstQuery;
        queryCount += uint32_t(plan.groupQueryBegin.size() + plan.historyQueryBegin.size());
        commandCount += uint32_t(plan.firstPhase.size() + plan.finalPhase.size());
        plans.push_back(std::move(plan));
    }
    if (kViewTimestampQueries * plans.size() > timestampCapacity) {
        if (timestampPool)
            vkDestroyQueryPool(device.device, timestampPool, nullptr);
        timestampPool = VK_NULL_HANDLE;
        timestampCapacity = 0;
        VkQueryPoolCreateInfo info{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
        info.queryType = VK_QUERY_TYPE_TIMESTAMP;
        info.queryCount = kViewTimestampQueries * uint32_t(plans.size());
        VK_CHECK(vkCreateQueryPool(device.device, &info, nullptr, &timestampPool));
        timestampCapacity = info.queryCount;
    }
    if (mode == CullMode::None)
        return;

    // Draw lists, per-command queries and query boxes into host-visible buffers.
    const VkBufferUsageFlags storage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
    ensureBuffer(device, drawCommands, commandCount * kCommandBytes, VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT | storage,
                 vk::MemoryUse::Upload);
    ensureBuffer(device, commandQueries, commandCount * sizeof(uint32_t), storage, vk::MemoryUse::Upload);
    ensureBuffer(device, boxes, queryBoxes.size() * sizeof(glm::vec4), storage, vk::MemoryUse::Upload);
    // Query results, then one firstPassed word per view.
    ensureBuffer(device, queryResults, (queryCount + plans.size()) * sizeof(uint32_t),
                 VK_BUFFER_USAGE_TRANSFER_DST_BIT | storage, vk::MemoryUse::DeviceLocal);
    auto* commandOut = static_cast<VkDrawIndexedIndirectCommand*>(drawCommands.mapped);
    auto* queryOut = static_cast<uint32_t*>(commandQueries.mapped);
    for (const ViewPlan& plan : plans) {
        uint32_t i = plan.firstCommand;
        for (uint32_t cluster : plan.firstPhase) {
            commandOut[i] = model->commands[cluster];
            queryOut[i++] = kNoQuery;
        }
        for (const Entry& entry : plan.finalPhase) {
            commandOut[i] = model->commands[entry.cluster];
            commandOut[i].instanceCount = entry.query == kNoQuery ? 1 : 0; // the predicate pass decides
            queryOut[i++] = entry.query;
        }
    }
    drawCommandsAddress = vk::bufferAddress(device, drawCommands);
    commandQueriesAddress = vk::bufferAddress(device, commandQueries);
    boxesAddress = vk::bufferAddress(device, boxes);
    queryResultsAddress = vk::bufferAddress(device, queryResults);
    auto* boxOut = static_cast<glm::vec4*>(boxes.mapped);
    for (size_t i = 0; i < queryBoxes.size(); ++i)
        boxOut[i] = glm::vec4(queryBoxes[i], 0.0f);

    if (queryCount > queryCapacity) {
        if (queryPool)
            vkDestroyQueryPool(device.device, queryPool, nullptr);
        queryPool = VK_NULL_HANDLE;
        queryCapacity = 0;
        VkQueryPoolCreateInfo info{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
        info.queryType = VK_QUERY_TYPE_OCCLUSION;
        info.queryCount = queryCount + queryCount / 2;
        VK_CHECK(vkCreateQueryPool(device.device, &info, nullptr, &queryPool));
        queryCapacity = info.queryCount;
    }
}

void Culling::refreshCommands(const std::vector<VkDrawIndexedIndirectCommand>& commands)
{
    if (!model || mode == CullMode::None || !drawCommands.mapped)
        return;
    auto* out = static_cast<VkDrawIndexedIndirectCommand*>(drawCommands.mapped);
    auto refresh = [&](uint32_t i, uint32_t cluster) {
        out[i].indexCount = commands[cluster].indexCount;
        out[i].firstIndex = commands[cluster].firstIndex;
        out[i].vertexOffset = commands[cluster].vertexOffset;
    };
    for (const ViewPlan& plan : plans) {
        uint32_t i = plan.firstCommand;
        for (uint32_t cluster : plan.firstPhase)
            refresh(i++, cluster);
        for (const Entry& entry : plan.finalPhase)
            refresh(i++, entry.cluster);
    }
}

void Culling::resetQueries(VkCommandBuffer cmd)
{
    if (queryCount)
        vkCmdResetQueryPool(cmd, queryPool, 0, queryCount);
    if (!plans.empty())
        vkCmdResetQueryPool(cmd, timestampPool, 0, kViewTimestampQueries * uint32_t(plans.size()));
}

void Culling::drawList(VkCommandBuffer cmd, const GpuGeometry& geometry, uint32_t firstCommand,
                       const std::vector<uint32_t>& clusters)
{
    // One multi-draw per run of clusters in the same chunk (the list is ascending).
    size_t begin = 0;
    while (begin < clusters.size()) {
        const uint32_t chunkIndex = model->clusterChunk[clusters[begin]];
        size_t end = begin + 1;
        while (end < clusters.size() && model->clusterChunk[clusters[end]] == chunkIndex)
            ++end;
        bindChunk(cmd, geometry, geometry.chunks[chunkIndex]);
        vkCmdDrawIndexedIndirect(cmd, drawCommands.buffer, (firstCommand + begin) * kCommandBytes,
                                 uint32_t(end - begin), uint32_t(kCommandBytes));
        begin = end;
    }
}

std::vector<uint32_t> Culling::viewClusters(uint32_t view) const
{
    std::vector<uint32_t> clusters;
    if (!model)
        return clusters;
    if (mode == CullMode::None || view >= plans.size()) {
        clusters.resize(model->commands.size());
        for (size_t i = 0; i < clusters.size(); ++i)
            clusters[i] = uint32_t(i);
        return clusters;
    }
    const ViewPlan& plan = plans[view];
    clusters = plan.firstPhase;
    for (const Entry& entry : plan.finalPhase)
        clusters.push_back(entry.cluster);
    std::sort(clusters.begin(), clusters.end());
    return clusters;
}

void Culling::drawInRanges(VkCommandBuffer cmd, uint32_t view, const GpuGeometry& geometry, uint32_t firstCommand,
                           const std::vector<uint32_t>& clusters, const std::vector<uint32_t>& drawn, bool clear,
                           const BeginRendering& begin, const EndRendering& end, const std::function<void()>& last)
{
    std::vector<uint32_t> cuts = cutRanges ? cutRanges(drawn) : std::vector<uint32_t>{};
    cuts.insert(cuts.begin(), 0u);
    cuts.push_back(uint32_t(clusters.size()));
    for (size_t r = 0; r + 1 < cuts.size(); ++r) {
        if (ensureRange)
            ensureRange(view, r);
        begin(r == 0 && clear);
        drawList(cmd, geometry, firstCommand + cuts[r], std::vector<uint32_t>(clusters.begin() + cuts[r], clusters.begin() + cuts[r + 1]));
        if (r + 2 == cuts.size() && last)
            last();
        end();
    }
}

std::vector<uint32_t> Culling::finalDrawn(vk::Device& device, uint32_t view) const
{
    const ViewPlan& plan = plans.at(view);
    const uint32_t groupCount = uint32_t(plan.groupQueryBegin.size());
    std::vector<uint32_t> results(groupCount);
    if (groupCount)
        vk::readQueryResults(device, queryPool, plan.firstQuery, groupCount, results.size() * sizeof(uint32_t), results.data(),
                             sizeof(uint32_t), 0, "the occlusion queries");
    std::vector<uint32_t> drawn;
    for (const Entry& entry : plan.finalPhase)
        drawn.push_back(entry.query == kNoQuery || results.at(entry.query - plan.firstQuery) != 0 ? entry.cluster : kNoQuery);
    return drawn;
}

void Culling::resetViewTimestamps(VkCommandBuffer cmd, uint32_t view) const
{
    if (view < plans.size())
        vkCmdResetQueryPool(cmd, timestampPool, kViewTimestampQueries * view, kViewTimestampQueries);
}

void Culling::markView(VkCommandBuffer cmd, uint32_t view, bool end) const
{
    if (view < plans.size())
        vk::writeTimestamp(cmd, timestampPool, kViewTimestampQueries * view + (end ? vk::kTimestampQueries : 0));
}

void drawClusters(VkCommandBuffer cmd, const GpuGeometry& geometry, const CullModel& model, const uint32_t* clusters, size_t count)
{
    size_t begin = 0;
    while (begin < count) {
        const uint32_t chunkIndex = model.clusterChunk[clusters[begin]];
        size_t end = begin + 1;
        while (end < count && clusters[end] == clusters[end - 1] + 1 && model.clusterChunk[clusters[end]] == chunkIndex)
            ++end;
        bindChunk(cmd, geometry, geometry.chunks[chunkIndex]);
        vkCmdDrawIndexedIndirect(cmd, geometry.indirect.buffer, VkDeviceSize(clusters[begin]) * kCommandBytes, uint32_t(end - begin),
                                 uint32_t(kCommandBytes));
        begin = end;
    }
}

void Culling::recordView(VkCommandBuffer cmd, uint32_t viewIndex, const GpuGeometry& geometry,
                         const BeginRendering& begin, const EndRendering& end)
{
    markView(cmd, viewIndex, false);
    recordPhases(cmd, viewIndex, geometry, begin, end);
    markView(cmd, viewIndex, true);
}

void Culling::recordViewAgain(VkCommandBuffer cmd, uint32_t viewIndex, const GpuGeometry& geometry, const BeginRendering& begin,
                              const EndRendering& end)
{
    if (viewIndex < plans.size() && plans[viewIndex].view.occlusion)
        fail("culling", "view " + plans[viewIndex].view.name + " has occlusion queries and cannot be drawn again");
    recordPhases(cmd, viewIndex, geometry, begin, end);
}

void Culling::recordPhases(VkCommandBuffer cmd, uint32_t viewIndex, const GpuGeometry& geometry,
                           const BeginRendering& begin, const EndRendering& end)
{
    if (!model || mode == CullMode::None || viewIndex >= plans.size()) {
        begin(true);
        drawGeometry(cmd, geometry);
        end();
        return;
    }
    const ViewPlan& plan = plans[viewIndex];
    std::vector<uint32_t> finalClusters(plan.finalPhase.size());
    for (size_t i = 0; i < finalClusters.size(); ++i)
        finalClusters[i] = plan.finalPhase[i].cluster;
    const uint32_t firstFinal = plan.firstCommand + uint32_t(plan.firstPhase.size());
    if (!plan.view.occlusion) {
        if (geometry.paged()) { // in ranges that fit the pool
            drawInRanges(cmd, viewIndex, geometry, firstFinal, finalClusters, finalClusters, true, begin, end, {});
            return;
        }
        begin(true);
        if (finalClusters.size() == model->commands.size())
            drawGeometry(cmd, geometry); // the frustum holds everything (a sun's map): the model's own list
        else
            drawList(cmd, geometry, firstFinal, finalClusters);
        end();
        return;
    }

    BoxPush push{plan.view.viewProj, boxesAddress};
    auto queryBoxRange = [&](uint32_t first, uint32_t count) {
        if (count == 0)
            return;
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS,
                          plan.view.camera ? cameraBoxPipelines[plan.view.albedo] : shadowBoxPipeline);
        vkCmdPushConstants(cmd, boxLayout, VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof(push), &push);
        for (uint32_t q = first; q < first + count; ++q) {
            vkCmdBeginQuery(cmd, queryPool, q, 0);
            vkCmdDraw(cmd, 36, 1, 0, q);
            vkCmdEndQuery(cmd, queryPool, q);
        }
    };
    const uint32_t groupCount = uint32_t(plan.groupQueryBegin.size());
    const uint32_t historyFirst = plan.firstQuery + groupCount;

    // Phase 1: last frame's set (and clusters at the near plane), then the
    // boxes of everything else in the frustum against that depth.
    // (Paged geometry: in ranges that fit the pool, the queries inside the last.)
    drawInRanges(cmd, viewIndex, geometry, plan.firstCommand, plan.firstPhase, plan.firstPhase, true, begin, end, [&] {
        queryBoxRange(plan.firstQuery, groupCount);
        if (groupCount == 0) // nothing else can be visible: the depth is final already
            queryBoxRange(historyFirst, uint32_t(plan.historyQueryBegin.size()));
    });
    if (groupCount == 0)
        return;
    const std::vector<uint32_t> drawn = queriesAnswered ? queriesAnswered(viewIndex) : std::vector<uint32_t>{};

    // Query results -> instance counts of the final list.
    constexpr VkPipelineStageFlags2 kAttachments = VK_PIPELINE_STAGE_2_EARLY_FRAGMENT_TESTS_BIT |
                                                   VK_PIPELINE_STAGE_2_LATE_FRAGMENT_TESTS_BIT |
                                                   VK_PIPELINE_STAGE_2_COLOR_ATTACHMENT_OUTPUT_BIT;
    constexpr VkAccessFlags2 kAttachmentAccess = VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT |
                                                 VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT |
                                                 VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT;
    const VkDeviceSize firstPassed = (queryCount + viewIndex) * sizeof(uint32_t);
    vkCmdCopyQueryPoolResults(cmd, queryPool, plan.firstQuery, groupCount, queryResults.buffer,
                              plan.firstQuery * sizeof(uint32_t), sizeof(uint32_t), VK_QUERY_RESULT_WAIT_BIT);
    vkCmdFillBuffer(cmd, queryResults.buffer, firstPassed, sizeof(uint32_t), kNoQuery);
    vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT | VK_PIPELINE_STAGE_2_CLEAR_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                      VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                      VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, predicatePipeline);
    const uint32_t finalCount = uint32_t(plan.finalPhase.size());
    PredicatePush predicate{drawCommandsAddress + firstFinal * kCommandBytes,
                            commandQueriesAddress + firstFinal * sizeof(uint32_t),
                            queryResultsAddress,
                            queryResultsAddress + firstPassed,
                            finalCount,
                            0};
    for (uint32_t step = 0; step < 2; ++step) {
        predicate.step = step;
        vkCmdPushConstants(cmd, predicateLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(predicate), &predicate);
        vkCmdDispatch(cmd, (finalCount + PENUMBRA_CULL_GROUP_SIZE - 1) / PENUMBRA_CULL_GROUP_SIZE, 1, 1);
        if (step == 0)
            vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                              VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_READ_BIT);
    }
    vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | kAttachments,
                      VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT | kAttachmentAccess,
                      VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT | kAttachments,
                      VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT | kAttachmentAccess);

    // Phase 2: the final list over the phase-1 depth, then last frame's set
    // tested against the final depth (next frame's history).
    drawInRanges(cmd, viewIndex, geometry, firstFinal, finalClusters,
                 drawn, false, begin, end,
                 [&] { queryBoxRange(historyFirst, uint32_t(plan.historyQueryBegin.size())); });
}

std::vector<ViewCullStats> Culling::endFrame(vk::Device& device)
{
    std::vector<ViewCullStats> out;
    if (!model)
        return out;
    std::vector<uint32_t> results(queryCount);
    std::vector<uint64_t> ticks(kViewTimestampQueries * plans.size());
    if (!ticks.empty())
        vk::readQueryResults(device, timestampPool, 0, uint32_t(ticks.size()), ticks.size() * sizeof(uint64_t), ticks.data(),
                             sizeof(uint64_t), VK_QUERY_RESULT_64_BIT, "the culled views' timestamps");
    if (queryCount)
        vk::readQueryResults(device, queryPool, 0, queryCount, results.size() * sizeof(uint32_t), results.data(), sizeof(uint32_t), 0,
                             "the occlusion queries");
    for (const ViewPlan& plan : plans) {
        ViewCullStats stats;
        stats.name = plan.view.name;
        stats.nodesTested = plan.nodesTested;
        stats.clustersBesideReceivers = plan.clustersBesideReceivers;
        stats.cpuMs = plan.cpuMs;
        const size_t v = &plan - plans.data();
        stats.gpuMs = double(ticks[kViewTimestampQueries * v + vk::kTimestampQueries] - ticks[kViewTimestampQueries * v]) * timestampPeriodNs * 1e-6;
        const uint32_t groupCount = uint32_t(plan.groupQueryBegin.size());
        const uint32_t historyCount = uint32_t(plan.historyQueryBegin.size());
        stats.queriesIssued = groupCount + historyCount;
        std::vector<uint8_t>* visible = nullptr;
        if (plan.view.occlusion) {
            visible = &history[plan.view.slot].visible;
            std::fill(visible->begin(), visible->end(), uint8_t(0));
        }
        auto drawn = [&](uint32_t cluster) {
            ++stats.clustersDrawn;
            stats.trianglesDrawn += model->clusterTriangles[cluster];
        };
        if (mode == CullMode::None) {
            for (uint32_t cluster = 0; cluster < model->clusterTriangles.size(); ++cluster)
                drawn(cluster);
        } else if (!plan.view.occlusion) {
            for (const Entry& entry : plan.finalPhase)
                drawn(entry.cluster);
        } else {
            for (uint32_t cluster : plan.firstPhase)
                drawn(cluster);
            for (uint32_t cluster : plan.keptVisible)
                (*visible)[cluster] = 1;
            for (uint32_t g = 0; g < groupCount; ++g) {
                uint32_t last = g + 1 < groupCount ? plan.groupQueryBegin[g + 1] : uint32_t(plan.groupClusters.size());
                if (results[plan.firstQuery + g] == 0) {
                    stats.clustersOccluded += last - plan.groupQueryBegin[g];
                    continue;
                }
                for (uint32_t i = plan.groupQueryBegin[g]; i < last; ++i) {
                    drawn(plan.groupClusters[i]);
                    (*visible)[plan.groupClusters[i]] = 1;
                }
            }
            uint64_t hiddenHistory = 0;
            for (uint32_t h = 0; h < historyCount; ++h) {
                uint32_t last =
                    h + 1 < historyCount ? plan.historyQueryBegin[h + 1] : uint32_t(plan.historyClusters.size());
                if (results[plan.firstQuery + groupCount + h] == 0) {
                    hiddenHistory += last - plan.historyQueryBegin[h];
                    continue;
                }
                for (uint32_t i = plan.historyQueryBegin[h]; i < last; ++i)
                    (*visible)[plan.historyClusters[i]] = 1;
            }
            // With a history, the clusters found hidden (now or for the next
            // frame) measure what occlusion culling buys in this view; when it
            // is little, the queries and the second phase cost more than they
            // save, so the view goes frustum-only for a while.
            const uint64_t inFrustum = plan.historyClusters.size() + plan.groupClusters.size(); // the tested ones
            if (adaptive && historyCount > 0 &&
                double(stats.clustersOccluded + hiddenHistory) < PENUMBRA_CULL_MIN_OCCLUDED * double(inFrustum))
                history[plan.view.slot].frustumOnlyFrames = PENUMBRA_CULL_RETRY_FRAMES;
        }
        stats.clustersCulled = model->clusterTriangles.size() - stats.clustersDrawn;
        stats.trianglesCulled = model->totalTriangles - stats.trianglesDrawn;
        out.push_back(std::move(stats));
    }
    return out;
}

} // namespace penumbra
