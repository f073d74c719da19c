#include "geometry_pages.h"

#include <algorithm>
#include <cstring>

#include "config.h"
#include "passes/pass.h"
#include "penumbra/error.h"

namespace penumbra {

namespace {

std::string mib(uint64_t bytes)
{
    char text[32];
    if (bytes < 1048576)
        std::snprintf(text, sizeof(text), "%.1f KiB", double(bytes) / 1024.0);
    else
        std::snprintf(text, sizeof(text), "%.2f MiB", double(bytes) / 1048576.0);
    return text;
}

} // namespace

void GeometryPages::build(const CompressedModel& model, RasterIndices rasterIndices, uint64_t page, uint64_t budgetBytes, bool withAltitudes)
{
    if (page < 48 * 64 || page % 48 != 0 || page > (uint64_t(1) << 30))
        fail("--geometry-page", std::to_string(page) + " bytes: a page must be a multiple of 48 bytes, 3 KiB .. 1 GiB");
    pageBytes = page;
    budget = budgetBytes;
    raster = rasterIndices;
    altitudes = withAltitudes;
    const size_t clusters = model.clusters.size();
    // Each cluster's own nodes (its subtree from its root), in ascending order: the page holds their records.
    clusterNodesFirst.assign(clusters + 1, 0);
    clusterNodes.clear();
    topNodeCount = 0;
    for (const model::Node& node : model.nodes)
        topNodeCount += node.cluster == model::kNoCluster ? 1u : 0u;
    clusterNodes.reserve(model.nodes.size() - topNodeCount);
    std::vector<uint32_t> pending;
    for (uint32_t c = 0; c < clusters; ++c) {
        clusterNodesFirst[c] = clusterNodes.size();
        pending.assign(1, model.clusters[c].node);
        while (!pending.empty()) {
            const uint32_t n = pending.back();
            pending.pop_back();
            clusterNodes.push_back(n);
            const model::Node& node = model.nodes[n];
            for (uint32_t slot = 0; slot < model::kNodeChildren; ++slot)
                if (model::childKind(node, slot) == model::ChildKind::Interior)
                    pending.push_back(node.child[slot]);
        }
        std::sort(clusterNodes.begin() + int64_t(clusterNodesFirst[c]), clusterNodes.end());
    }
    clusterNodesFirst[clusters] = clusterNodes.size();
    clusterPage.assign(clusters, 0);
    place.assign(clusters, {});
    pageFirstCluster.clear();
    pageUsed.clear();
    totalBytes = 0;
    std::vector<uint8_t> triangles;
    // Greedy: consecutive clusters (spatially coherent: the preprocessor orders them along the BVH) while
    // vertices + strips (16-aligned) + node records + triangle lists fit a page.
    uint64_t vertexBytes = 0, stripBytes = 0, nodeBytes = 0, rasterBytes = 0;
    std::vector<uint32_t> rasterOf(clusters, 0);
    auto align16 = [](uint64_t bytes) { return (bytes + 15) & ~uint64_t(15); };
    auto closePage = [&](uint32_t end) {
        const uint32_t first = pageFirstCluster.back();
        const uint64_t stripBase = align16(vertexBytes), nodeBase = align16(stripBase + stripBytes);
        uint64_t v = 0, s = stripBase, n = nodeBase, r = nodeBase + nodeBytes;
        for (uint32_t c = first; c < end; ++c) {
            const model::ClusterRecord& record = model.clusters[c];
            place[c] = {uint32_t(v), uint32_t(s), uint32_t(r), rasterOf[c], uint32_t(n)};
            v += uint64_t(record.vertexCount) * sizeof(model::QuantizedVertex);
            s += record.indexBytes;
            n += (clusterNodesFirst[c + 1] - clusterNodesFirst[c]) * kNodeRecordBytes;
            r += rasterOf[c];
        }
        pageUsed.push_back(uint32_t(r));
        totalBytes += r;
    };
    for (uint32_t c = 0; c < clusters; ++c) {
        const model::ClusterRecord& record = model.clusters[c];
        uint64_t rb = 0;
        if (raster == RasterIndices::Triangles) {
            triangles.clear();
            appendTriangles(model.indices.data() + record.firstIndex, record.indexBytes, triangles);
            rb = triangles.size();
        }
        rasterOf[c] = uint32_t(rb);
        const uint64_t vb = uint64_t(record.vertexCount) * sizeof(model::QuantizedVertex);
        const uint64_t nb = (clusterNodesFirst[c + 1] - clusterNodesFirst[c]) * kNodeRecordBytes;
        auto size = [&](uint64_t v, uint64_t s, uint64_t n, uint64_t r) { return align16(align16(v) + s) + n + r; };
        if (size(vb, record.indexBytes, nb, rb) > page)
            fail("--geometry-page", std::to_string(page) + " bytes: cluster " + std::to_string(c) + " alone needs " +
                                        std::to_string(size(vb, record.indexBytes, nb, rb)));
        if (pageFirstCluster.empty() || size(vertexBytes + vb, stripBytes + record.indexBytes, nodeBytes + nb, rasterBytes + rb) > page) {
            if (!pageFirstCluster.empty())
                closePage(c);
            pageFirstCluster.push_back(c);
            vertexBytes = stripBytes = nodeBytes = rasterBytes = 0;
        }
        clusterPage[c] = uint32_t(pageFirstCluster.size() - 1);
        vertexBytes += vb;
        stripBytes += record.indexBytes;
        nodeBytes += nb;
        rasterBytes += rb;
    }
    closePage(uint32_t(clusters));
    pageFirstCluster.push_back(uint32_t(clusters));
    const uint64_t pages = pageUsed.size();
    const uint64_t slots = std::min<uint64_t>(budgetBytes / page, pages);
    if (slots == 0)
        fail("--geometry-budget", "a budget of " + mib(budgetBytes) + " holds no page of " + mib(page) + " (the model's geometry is " +
                                      mib(pages * page) + " in " + std::to_string(pages) + " pages)");
    slotCount = uint32_t(slots);
    if (poolBytes() / 16 >= kNodeAbsent)
        fail("--geometry-budget", "a pool of " + mib(poolBytes()) + " is too large for the node table's 31-bit texel indices");
    resetResidency();
}

void GeometryPages::writeNodeRecord(const CompressedModel& model, uint32_t node, uint8_t* out) const
{
    std::memcpy(out, &model.nodes[node], sizeof(model::Node));
    float leaf[model::kNodeChildren] = {};
    if (altitudes)
        nodeLeafAltitudes(model, node, leaf);
    std::memcpy(out + sizeof(model::Node), leaf, sizeof(leaf));
}

PagedBvh GeometryPages::pagedBvh(const CompressedModel& model) const
{
    PagedBvh bvh;
    bvh.poolBytes = poolBytes();
    bvh.topRecordsByte = slotBytes();
    bvh.topRecords.resize(uint64_t(topNodeCount) * kNodeRecordBytes);
    bvh.nodeTable.resize(model.nodes.size());
    uint32_t top = 0;
    for (uint32_t n = 0; n < model.nodes.size(); ++n) {
        const uint32_t cluster = model.nodes[n].cluster;
        if (cluster != model::kNoCluster) {
            bvh.nodeTable[n] = cluster | kNodeAbsent;
            continue;
        }
        writeNodeRecord(model, n, bvh.topRecords.data() + uint64_t(top) * kNodeRecordBytes);
        bvh.nodeTable[n] = uint32_t((bvh.topRecordsByte + uint64_t(top) * kNodeRecordBytes) / 16);
        ++top;
    }
    return bvh;
}

void GeometryPages::resetResidency()
{
    pageSlot.assign(pageUsed.size(), kNone);
    slotPage.assign(slotCount, kNone);
    slotUse.assign(slotCount, 0);
    residentPages = 0;
}

void GeometryPages::destroy(vk::Device& device)
{
    vk::destroyBuffer(device, staging);
    vk::destroyBuffer(device, parking);
    vk::destroyBuffer(device, retraceList);
    vk::destroyBuffer(device, thinMasks);
    parkingCapacity = 0;
}

void GeometryPages::ensureThinMasks(vk::Device& device, uint64_t bytes)
{
    if (thinMasks.size >= bytes && thinMasks.buffer)
        return;
    vk::destroyBuffer(device, thinMasks);
    thinMasks = vk::createBuffer(device, std::max<uint64_t>(bytes, 2 * thinMasks.size), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                 vk::MemoryUse::Upload, vk::Addressable::Yes);
}

std::vector<std::vector<uint32_t>> GeometryPages::cutIntoRanges(const std::vector<uint32_t>& clusters) const
{
    std::vector<std::vector<uint32_t>> ranges(1);
    std::vector<uint32_t> pages; // of the current range, unsorted
    for (uint32_t c : clusters) {
        const uint32_t page = clusterPage[c];
        if (std::find(pages.begin(), pages.end(), page) == pages.end()) {
            if (pages.size() == slotCount) {
                ranges.emplace_back();
                pages.clear();
            }
            pages.push_back(page);
        }
        ranges.back().push_back(c);
    }
    return ranges;
}

void GeometryPages::beginFrame()
{
    frame = {};
    frame.residentPeakBytes = uint64_t(residentPages) * pageBytes;
}

bool GeometryPages::fits(const std::vector<uint32_t>& clusters) const
{
    std::vector<uint32_t> pages;
    pages.reserve(clusters.size());
    for (uint32_t c : clusters)
        pages.push_back(clusterPage[c]);
    std::sort(pages.begin(), pages.end());
    return size_t(std::unique(pages.begin(), pages.end()) - pages.begin()) <= slotCount;
}

bool GeometryPages::allResident(const std::vector<uint32_t>& clusters) const
{
    return std::all_of(clusters.begin(), clusters.end(), [&](uint32_t c) { return resident(c); });
}

bool GeometryPages::ensure(vk::Device& device, GpuGeometry& geometry, const CompressedModel& model, const std::vector<uint32_t>& clusters,
                           const std::string& what)
{
    std::vector<uint32_t> pages;
    pages.reserve(clusters.size());
    for (uint32_t c : clusters)
        pages.push_back(clusterPage[c]);
    std::sort(pages.begin(), pages.end());
    pages.erase(std::unique(pages.begin(), pages.end()), pages.end());
    if (pages.size() > slotCount)
        fail("--geometry-budget", "a budget of " + mib(budget) + " holds " + std::to_string(slotCount) + " pages of " + mib(pageBytes) +
                                      ", smaller than the working set of " + what + " (" + std::to_string(pages.size()) + " pages, " +
                                      mib(pages.size() * pageBytes) + ")");
    ++useClock;
    std::vector<uint32_t> missing;
    std::vector<uint8_t> wanted(slotCount, 0);
    for (uint32_t p : pages) {
        if (pageSlot[p] == kNone)
            missing.push_back(p);
        else {
            slotUse[pageSlot[p]] = useClock;
            wanted[pageSlot[p]] = 1;
        }
    }
    if (missing.empty())
        return false;
    // Slots: free ones first, then the least recently used outside the set.
    std::vector<uint32_t> candidates;
    for (uint32_t s = 0; s < slotCount; ++s)
        if (!wanted[s])
            candidates.push_back(s);
    std::stable_sort(candidates.begin(), candidates.end(), [&](uint32_t a, uint32_t b) {
        const bool freeA = slotPage[a] == kNone, freeB = slotPage[b] == kNone;
        if (freeA != freeB)
            return freeA;
        return slotUse[a] < slotUse[b];
    });
    // Staging: page contents, then per changed cluster its record's firstVertex/firstIndex and its draw.
    std::vector<uint32_t> evicted;
    uint64_t contentBytes = 0;
    size_t changedClusters = 0, changedNodes = 0;
    auto pageNodes = [&](uint32_t page) { return clusterNodesFirst[pageFirstCluster[page + 1]] - clusterNodesFirst[pageFirstCluster[page]]; };
    for (size_t i = 0; i < missing.size(); ++i) {
        const uint32_t slot = candidates[i];
        if (slotPage[slot] != kNone) {
            evicted.push_back(slotPage[slot]);
            changedClusters += pageFirstCluster[slotPage[slot] + 1] - pageFirstCluster[slotPage[slot]];
            changedNodes += pageNodes(slotPage[slot]);
        }
        contentBytes += (pageUsed[missing[i]] + 15) & ~uint64_t(15);
        changedClusters += pageFirstCluster[missing[i] + 1] - pageFirstCluster[missing[i]];
        changedNodes += pageNodes(missing[i]);
    }
    const uint64_t patchBytes = changedClusters * (16 + sizeof(VkDrawIndexedIndirectCommand)) + changedNodes * sizeof(uint32_t);
    const uint64_t stagingBytes = contentBytes + patchBytes;
    if (staging.size < stagingBytes) {
        vk::destroyBuffer(device, staging);
        staging = vk::createBuffer(device, std::max<uint64_t>(stagingBytes, staging.size * 2), VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                                   vk::MemoryUse::Upload);
    }
    auto* out = static_cast<uint8_t*>(staging.mapped);
    std::vector<VkBufferCopy> poolCopies, recordCopies, commandCopies, tableCopies;
    uint64_t at = 0;
    uint64_t patchAt = contentBytes;
    // Node-table words of cluster c's nodes: word(k) for its k-th node, one copy per run of consecutive nodes.
    auto patchNodes = [&](uint32_t c, auto word) {
        const uint32_t* nodes = clusterNodes.data() + clusterNodesFirst[c];
        const uint64_t count = clusterNodesFirst[c + 1] - clusterNodesFirst[c];
        for (uint64_t k = 0; k < count; ++k) {
            const uint32_t value = word(k);
            std::memcpy(out + patchAt, &value, sizeof(value));
            if (k > 0 && nodes[k] == nodes[k - 1] + 1 && tableCopies.back().srcOffset + tableCopies.back().size == patchAt)
                tableCopies.back().size += sizeof(uint32_t);
            else
                tableCopies.push_back({patchAt, uint64_t(nodes[k]) * sizeof(uint32_t), sizeof(uint32_t)});
            patchAt += sizeof(uint32_t);
        }
    };
    auto patch = [&](uint32_t c, uint64_t firstVertex, uint64_t firstIndex, const VkDrawIndexedIndirectCommand& command) {
        std::memcpy(out + patchAt, &firstVertex, 8);
        std::memcpy(out + patchAt + 8, &firstIndex, 8);
        recordCopies.push_back({patchAt, uint64_t(c) * sizeof(model::ClusterRecord) + offsetof(model::ClusterRecord, firstVertex), 16});
        patchAt += 16;
        std::memcpy(out + patchAt, &command, sizeof(command));
        commandCopies.push_back({patchAt, uint64_t(c) * sizeof(VkDrawIndexedIndirectCommand), sizeof(command)});
        patchAt += sizeof(command);
        geometry.commands[c] = command;
    };
    for (uint32_t page : evicted) {
        pageSlot[page] = kNone; // its slot is taken by a missing page below
        for (uint32_t c = pageFirstCluster[page]; c < pageFirstCluster[page + 1]; ++c)
        {
            patch(c, model.clusters[c].firstVertex | kNotResident, model.clusters[c].firstIndex, {0, 1, 0, 0, c});
            patchNodes(c, [&](uint64_t) { return c | kNodeAbsent; });
        }
    }
    std::vector<uint8_t> triangles;
    for (size_t i = 0; i < missing.size(); ++i) {
        const uint32_t page = missing[i], slot = candidates[i];
        if (slotPage[slot] == kNone)
            ++residentPages;
        slotPage[slot] = page;
        pageSlot[page] = slot;
        slotUse[slot] = useClock;
        const uint64_t base = uint64_t(slot) * pageBytes;
        for (uint32_t c = pageFirstCluster[page]; c < pageFirstCluster[page + 1]; ++c) {
            const model::ClusterRecord& record = model.clusters[c];
            const ClusterPlace& p = place[c];
            std::memcpy(out + at + p.vertexByte, model.vertices.data() + record.firstVertex,
                        size_t(record.vertexCount) * sizeof(model::QuantizedVertex));
            std::memcpy(out + at + p.stripByte, model.indices.data() + record.firstIndex, record.indexBytes);
            uint32_t count = record.indexBytes, firstIndex = uint32_t(base + p.stripByte);
            if (raster == RasterIndices::Triangles) {
                triangles.clear();
                appendTriangles(model.indices.data() + record.firstIndex, record.indexBytes, triangles);
                std::memcpy(out + at + p.rasterByte, triangles.data(), triangles.size());
                count = uint32_t(triangles.size());
                firstIndex = uint32_t(base + p.rasterByte);
            }
            const uint32_t* nodes = clusterNodes.data() + clusterNodesFirst[c];
            for (uint64_t k = 0; k < clusterNodesFirst[c + 1] - clusterNodesFirst[c]; ++k)
                writeNodeRecord(model, nodes[k], out + at + p.nodeByte + k * kNodeRecordBytes);
            const uint64_t firstVertex = (base + p.vertexByte) / sizeof(model::QuantizedVertex);
            patch(c, firstVertex, base + p.stripByte, {count, 1, firstIndex, int32_t(firstVertex), c});
            patchNodes(c, [&](uint64_t k) { return uint32_t((base + p.nodeByte + k * kNodeRecordBytes) / 16); });
        }
        poolCopies.push_back({at, base, pageUsed[page]});
        frame.bytesStreamed += pageUsed[page];
        ++frame.pagesUploaded;
        at += (pageUsed[page] + 15) & ~uint64_t(15);
    }
    vk::immediateSubmit(
        device,
        [&](VkCommandBuffer cmd) {
            vkCmdCopyBuffer(cmd, staging.buffer, geometry.pool.buffer, uint32_t(poolCopies.size()), poolCopies.data());
            vkCmdCopyBuffer(cmd, staging.buffer, geometry.clusters.buffer, uint32_t(recordCopies.size()), recordCopies.data());
            vkCmdCopyBuffer(cmd, staging.buffer, geometry.indirect.buffer, uint32_t(commandCopies.size()), commandCopies.data());
            if (!tableCopies.empty())
                vkCmdCopyBuffer(cmd, staging.buffer, geometry.nodeTable.buffer, uint32_t(tableCopies.size()), tableCopies.data());
            vk::memoryBarrier(cmd, passes::kCopy, passes::kTransferWrite, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT,
                              VK_ACCESS_2_MEMORY_READ_BIT);
        },
        "a geometry page upload");
    frame.residentPeakBytes = std::max(frame.residentPeakBytes, uint64_t(residentPages) * pageBytes);
    return true;
}

void GeometryPages::ensureParking(vk::Device& device, uint64_t pixels)
{
    if (parkingCapacity >= pixels && parking.buffer)
        return;
    vk::destroyBuffer(device, parking);
    vk::destroyBuffer(device, retraceList);
    parkingCapacity = 0;
    parking = vk::createBuffer(device, 16 + uint64_t(clusterWords()) * 4 + pixels * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                               vk::MemoryUse::Readback, vk::Addressable::Yes);
    retraceList = vk::createBuffer(device, (PENUMBRA_RAY_LIST_HEADER_UINTS + pixels) * 4, VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                                   vk::MemoryUse::Upload);
    parkingCapacity = pixels;
}

VkDeviceAddress GeometryPages::parkingAddress(const vk::Device& device) const { return vk::bufferAddress(device, parking); }

void GeometryPages::clearParking() { std::memset(parking.mapped, 0, 16 + size_t(clusterWords()) * 4); }

uint32_t GeometryPages::parkedCount() const { return *static_cast<const uint32_t*>(parking.mapped); }

const uint32_t* GeometryPages::parkedEntries() const { return static_cast<const uint32_t*>(parking.mapped) + 4 + clusterWords(); }

std::vector<uint32_t> GeometryPages::visitedClusters() const
{
    std::vector<uint32_t> clusters;
    const uint32_t* bits = static_cast<const uint32_t*>(parking.mapped) + 4;
    for (uint32_t w = 0; w < clusterWords(); ++w)
        for (uint32_t word = bits[w]; word; word &= word - 1)
            clusters.push_back(32 * w + uint32_t(__builtin_ctz(word)));
    return clusters;
}

bool clusterMayReachView(const glm::mat4& viewProj, const glm::vec3& lo, const glm::vec3& hi, uint32_t mapSize, float marginTexels)
{
    const float grow = 1.0f + 2.0f * marginTexels / float(mapSize);
    // Each plane a(p) >= 0 outside; linear in p, so all corners outside means the whole box is.
    bool behind = true, right = true, left = true, top = true, bottom = true, near = true;
    for (int corner = 0; corner < 8; ++corner) {
        const glm::vec4 p(corner & 1 ? hi.x : lo.x, corner & 2 ? hi.y : lo.y, corner & 4 ? hi.z : lo.z, 1.0f);
        const glm::vec4 c = viewProj * p;
        behind = behind && c.w <= 0.0f;
        right = right && c.x > grow * c.w;
        left = left && c.x < -grow * c.w;
        top = top && c.y > grow * c.w;
        bottom = bottom && c.y < -grow * c.w;
        near = near && c.z < 0.0f; // NDC depth below 0 where w > 0: the pass drops the triangle
    }
    return !(behind || right || left || top || bottom || near);
}

} // namespace penumbra
