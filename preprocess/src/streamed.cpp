// Streamed and distributed builds (streamed.h; issue 19, items 6-8):
//   scan       the input once through model_stream.h: counts, checks, the vertex
//              store, a fixed-seed reservoir sample of vertex positions
//   plan       a k-d partition of the sample into chunks of about equal size
//   partition  the input's triangles again, each to the chunk of its centroid,
//              as records in an unnamed temporary file per chunk; a triangle
//              whose box leaves its cell is also written, as a "halo", to every
//              other chunk whose cell its box meets
//   build      per chunk: its mesh (vertex ids sorted, positions read from the
//              store in order), the closed-component test over the chunk and its
//              halo (halo triangles and triangles that leave the cell open their
//              component: a part cut by a chunk boundary counts as open), the
//              in-core builder with the chunk's root at its depth in the final
//              BVH, and a chunk file (chunk_file.h). A chunk too large for the
//              memory limit is partitioned again and built in parts.
//   merge      the chunk roots under a balanced top tree (merge.cpp).
#include "penumbra/streamed.h"

#include <malloc.h>
#include <sys/resource.h>
#include <unistd.h>
#include <xxhash.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <thread>
#include <unordered_map>

#include "penumbra/error.h"
#include "penumbra/file_io.h"
#include "penumbra/model_stream.h"
#include "streamed_internal.h"

namespace penumbra {

namespace streamed_detail {

uint64_t Plan::hash() const
{
    XXH64_state_t* state = XXH64_createState();
    XXH64_reset(state, 0);
    for (const Node& node : nodes) {
        XXH64_update(state, &node.axis, sizeof(node.axis));
        XXH64_update(state, &node.split, sizeof(node.split));
        XXH64_update(state, node.child, sizeof(node.child));
        XXH64_update(state, &node.leaf, sizeof(node.leaf));
    }
    const uint64_t h = XXH64_digest(state);
    XXH64_freeState(state);
    return h;
}

namespace {

// Builds the subtree of points[begin, end) with k leaves into plan; returns its node.
uint32_t planNode(std::vector<float>& points, size_t begin, size_t end, uint32_t k, Cell cell, Plan& plan)
{
    const uint32_t index = uint32_t(plan.nodes.size());
    plan.nodes.emplace_back();
    auto leaf = [&] {
        plan.nodes[index].axis = -1;
        plan.nodes[index].leaf = uint32_t(plan.cells.size());
        plan.cells.push_back(cell);
        return index;
    };
    const size_t n = end - begin;
    if (k <= 1 || n < 2)
        return leaf();
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = begin; i < end; ++i)
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], points[3 * i + size_t(a)]);
            hi[a] = std::max(hi[a], points[3 * i + size_t(a)]);
        }
    int axes[3] = {0, 1, 2};
    std::sort(axes, axes + 3, [&](int a, int b) { return hi[a] - lo[a] > hi[b] - lo[b]; });
    const uint32_t leftLeaves = k / 2;
    for (int axis : axes) {
        if (!(hi[axis] > lo[axis]))
            break;
        // The quantile of the left part's share, by a sort of this range's coordinates on the axis.
        std::vector<std::array<float, 3>> range(n);
        for (size_t i = 0; i < n; ++i)
            std::memcpy(range[i].data(), &points[3 * (begin + i)], 12);
        std::sort(range.begin(), range.end(), [axis](const auto& x, const auto& y) { return x[size_t(axis)] < y[size_t(axis)]; });
        size_t m = size_t(uint64_t(n) * leftLeaves / k);
        m = std::clamp<size_t>(m, 1, n - 1);
        // Near the quantile (within 1/16 of the points either way), cut in the widest gap between
        // points: between objects rather than through one (a part cut by a boundary counts as open).
        // (The window is fixed around the quantile: growing gaps, e.g. exponentially spaced parts,
        // must not drag the cut to the end of the range.)
        const size_t window = n / 16;
        const size_t first = std::max<size_t>(1, m > window ? m - window : 1), last = std::min(n - 1, m + window);
        float widest = range[m][size_t(axis)] - range[m - 1][size_t(axis)];
        for (size_t j = first; j <= last; ++j) {
            const float gap = range[j][size_t(axis)] - range[j - 1][size_t(axis)];
            if (gap > widest) {
                widest = gap;
                m = j;
            }
        }
        float split = range[m][size_t(axis)];
        if (widest > 0.0f) {
            const float middle = range[m - 1][size_t(axis)] + 0.5f * widest;
            if (middle > range[m - 1][size_t(axis)] && middle <= range[m][size_t(axis)])
                split = middle;
        }
        // Points equal to the split go right; move it up if nothing would stay left.
        if (!(split > range[0][size_t(axis)])) {
            size_t j = m;
            while (j < n && !(range[j][size_t(axis)] > range[0][size_t(axis)]))
                ++j;
            if (j == n)
                continue;
            split = range[j][size_t(axis)];
            m = j;
        }
        while (m > 0 && !(range[m - 1][size_t(axis)] < split))
            --m;
        for (size_t i = 0; i < n; ++i)
            std::memcpy(&points[3 * (begin + i)], range[i].data(), 12);
        range = {};
        plan.nodes[index].axis = axis;
        plan.nodes[index].split = split;
        Cell left = cell, right = cell;
        left.hi[axis] = std::min(cell.hi[axis], split);
        right.lo[axis] = std::max(cell.lo[axis], split);
        const uint32_t l = planNode(points, begin, begin + m, leftLeaves, left, plan);
        const uint32_t r = planNode(points, begin + m, end, k - leftLeaves, right, plan);
        plan.nodes[index].child[0] = l;
        plan.nodes[index].child[1] = r;
        return index;
    }
    return leaf();
}

} // namespace

Plan makePlan(std::vector<float>& points, uint32_t count, const Cell& cell)
{
    Plan plan;
    planNode(points, 0, points.size() / 3, std::max(1u, count), cell, plan);
    return plan;
}

} // namespace streamed_detail

using namespace streamed_detail;
using preprocess_detail::BuildExtras;
using preprocess_detail::buildModel;
using preprocess_detail::closedClearance;
using preprocess_detail::closedComponents;
using preprocess_detail::crowdedComponents;

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point start)
{
    return std::chrono::duration<double>(Clock::now() - start).count();
}

// Peak memory of the in-core builder per triangle (PreprocessOptions defaults,
// 2 threads; measured with bench/streamed_memory.sh and Preprocess tests: the
// tree stage's mesh, references, stamps and the cluster stage's output), plus
// the chunk's records, its sorted vertex ids and the closed test's lists
// (+3 B for the closed components' ids, 4 B instead of a flag byte; not re-measured).
constexpr uint64_t kBytesPerChunkTriangle = 99;
// Memory that does not grow with the chunk: buffers of the stream, the vertex
// cache, the partition's temporaries (at most 1/8 of the limit each).
constexpr uint64_t kFixedBytes = uint64_t(12) << 20;

void raiseOpenFileLimit(size_t needed, const std::string& subject);

// Records of the temporary chunk files.
constexpr uint32_t kSeedBit = 0x80000000u; // tag: the triangle's component counts as open

unsigned threadCount(const PreprocessOptions& options)
{
    return options.threads ? options.threads : std::max(1u, std::thread::hardware_concurrency());
}

// Random access to the stream's vertices through a cache of small blocks (positions only),
// evicted by CLOCK (second chance): O(1) per miss. Blocks are small (256 vertices, 3 KiB) so that
// face orders that sweep across vertex rows (a grid's faces along its columns touch a new block
// per triangle) still keep a whole sweep in the cache: the scan's cube faces cross 11 k blocks
// per row at 1.5 G triangles, 33 MiB of 3 KiB blocks, but 537 MiB of 48 KiB ones.
class VertexCache {
  public:
    VertexCache(ModelStream& stream, uint64_t bytes) : stream_(stream)
    {
        const uint64_t blockBytes = kBlock * 12;
        const uint64_t blocks = (stream.vertexCount() + kBlock - 1) / kBlock; // no more than the store holds
        slots_ = size_t(std::max<uint64_t>(1, std::min<uint64_t>(blocks, std::max<uint64_t>(16, bytes / blockBytes))));
        data_.resize(slots_ * kBlock * 3);
        slotBlock_.assign(slots_, ~uint64_t(0));
        referenced_.assign(slots_, 0);
        map_.reserve(slots_ * 2);
    }
    const float* vertex(uint64_t id)
    {
        const uint64_t block = id / kBlock;
        if (block != lastBlock_) {
            auto it = map_.find(block);
            if (it == map_.end()) {
                ++misses_;
                size_t slot = 0;
                if (used_ < slots_) {
                    slot = used_++;
                } else {
                    while (referenced_[hand_]) {
                        referenced_[hand_] = 0;
                        hand_ = (hand_ + 1) % slots_;
                    }
                    slot = hand_;
                    hand_ = (hand_ + 1) % slots_;
                    map_.erase(slotBlock_[slot]);
                }
                const uint64_t first = block * kBlock;
                const uint64_t count = std::min<uint64_t>(kBlock, stream_.vertexCount() - first);
                stream_.readVertices(first, count, &data_[slot * kBlock * 3], nullptr);
                slotBlock_[slot] = block;
                it = map_.emplace(block, slot).first;
            } else {
                ++hits_;
            }
            lastBlock_ = block;
            lastSlot_ = it->second;
            referenced_[lastSlot_] = 1;
        } else {
            ++hits_;
        }
        return &data_[(lastSlot_ * kBlock + (id % kBlock)) * 3];
    }
    double hitRate() const { return hits_ + misses_ ? double(hits_) / double(hits_ + misses_) : 1.0; }

  private:
    static constexpr uint64_t kBlock = 256;
    ModelStream& stream_;
    size_t slots_ = 0, used_ = 0, hand_ = 0;
    std::vector<float> data_;
    std::vector<uint64_t> slotBlock_;
    std::vector<uint8_t> referenced_;
    std::unordered_map<uint64_t, size_t> map_;
    uint64_t lastBlock_ = ~uint64_t(0);
    size_t lastSlot_ = 0;
    uint64_t hits_ = 0, misses_ = 0;
};

// Fixed-seed reservoir sample of points (Vitter's algorithm R with splitmix64).
struct Reservoir {
    size_t capacity;
    std::vector<float> points;
    uint64_t seen = 0, state = 0x9E3779B97F4A7C15ull;
    uint64_t next()
    {
        uint64_t z = (state += 0x9E3779B97F4A7C15ull);
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return z ^ (z >> 31);
    }
    void add(const float* p)
    {
        if (points.size() < 3 * capacity) {
            points.insert(points.end(), p, p + 3);
        } else {
            const uint64_t j = next() % (seen + 1);
            if (j < capacity)
                std::memcpy(&points[3 * j], p, 12);
        }
        ++seen;
    }
};

// The temporaries of one chunk: its triangles' records and the halo (corners).
struct ChunkTemp {
    std::unique_ptr<TemporaryFile> own, halo;
    uint64_t triangles = 0, haloTriangles = 0;
    Cell cell;
};

// What every chunk of one build shares.
struct Build {
    ModelStream* stream = nullptr;
    const StreamedOptions* options = nullptr;
    std::string tempDirectory;
    uint64_t capacity = 0;        // triangles per chunk built in one piece
    uint32_t idBytes = 4;         // 4 or 8 per vertex id in records
    bool materials = false;
    uint64_t fingerprint = 0;
    uint64_t inputTriangles = 0;
    uint32_t chunkCount = 0;
    float boundsMin[3] = {0, 0, 0}, boundsMax[3] = {0, 0, 0}; // of all the input's vertices (the scan)
    StreamedStats* stats = nullptr;
    uint64_t temporaryBytes = 0;  // at the moment
    void addTemporary(int64_t bytes)
    {
        temporaryBytes = uint64_t(int64_t(temporaryBytes) + bytes);
        stats->temporaryBytes = std::max(stats->temporaryBytes, temporaryBytes);
    }
    size_t recordBytes() const { return stream->indexed() ? 3 * idBytes + 4 : 36 + 4; }
    void progress(const std::string& stage, double fraction) const
    {
        if (options->progress)
            options->progress(stage, fraction);
    }
};

// A triangle of a record or of the input: its corners and, for records, the raw record.
struct Corners {
    float p[9];
    void bounds(float* min, float* max) const
    {
        for (int a = 0; a < 3; ++a) {
            min[a] = std::min({p[a], p[3 + a], p[6 + a]});
            max[a] = std::max({p[a], p[3 + a], p[6 + a]});
        }
    }
    void centroid(float* c) const
    {
        for (int a = 0; a < 3; ++a)
            c[a] = (p[a] + p[3 + a] + p[6 + a]) * (1.0f / 3.0f);
    }
};

// Distributes one triangle: its record to the chunk of its centroid (with the seed bit when it
// leaves that chunk's cell), its corners as halo to the other chunks its box meets. only: the one
// chunk kept (distributed builds), or -1.
void distribute(const Plan& plan, std::vector<ChunkTemp>& temps, const Corners& corners, uint8_t* record, size_t recordBytes,
                bool seed, int64_t only)
{
    float c[3], min[3], max[3];
    corners.centroid(c);
    corners.bounds(min, max);
    const uint32_t leaf = plan.locate(c);
    const bool crossing = !plan.cells[leaf].strictlyInside(min, max);
    if (only < 0 || leaf == uint64_t(only)) {
        uint32_t tag;
        std::memcpy(&tag, record + recordBytes - 4, 4);
        if (crossing || seed)
            tag |= kSeedBit;
        std::memcpy(record + recordBytes - 4, &tag, 4);
        temps[leaf].own->append(record, recordBytes);
        temps[leaf].triangles++;
    }
    if (crossing)
        plan.overlapping(min, max, [&](uint32_t other) {
            if (other == leaf || (only >= 0 && other != uint64_t(only)))
                return;
            temps[other].halo->append(corners.p, 36);
            temps[other].haloTriangles++;
        });
}

std::vector<ChunkTemp> makeTemps(const Build& build, const Plan& plan, int64_t only, const std::string& purpose)
{
    std::vector<ChunkTemp> temps(plan.leaves());
    // Buffers: at most 1/16 of the limit for all, 4 KiB to 1 MiB each.
    const uint64_t limit = build.options->memoryLimit;
    const size_t files = only >= 0 ? 2 : 2 * size_t(plan.leaves());
    const size_t buffer = size_t(std::clamp<uint64_t>(limit / 16 / std::max<size_t>(files, 1), 4096, uint64_t(1) << 20));
    for (uint32_t i = 0; i < plan.leaves(); ++i) {
        temps[i].cell = plan.cells[i];
        if (only >= 0 && i != uint64_t(only))
            continue;
        temps[i].own = std::make_unique<TemporaryFile>(build.tempDirectory, purpose + " " + std::to_string(i), buffer);
        temps[i].halo = std::make_unique<TemporaryFile>(build.tempDirectory, purpose + " " + std::to_string(i) + " halo", buffer);
    }
    return temps;
}

// Corners of a record (vertex ids through the cache, or stored corners).
void recordCorners(const Build& build, VertexCache* cache, const uint8_t* record, Corners& corners)
{
    if (build.stream->indexed()) {
        for (int k = 0; k < 3; ++k) {
            uint64_t id = 0;
            std::memcpy(&id, record + size_t(k) * build.idBytes, build.idBytes);
            std::memcpy(corners.p + 3 * k, cache->vertex(id), 12);
        }
    } else {
        std::memcpy(corners.p, record, 36);
    }
}

// ---- one chunk, built in memory -------------------------------------------------------------

// Welds corner positions (-0 = +0) into a vertex table: an open-addressing map position -> index.
class PositionWeld {
  public:
    explicit PositionWeld(Mesh& mesh) : mesh_(mesh) { table_.assign(1024, ~uint32_t(0)); }
    uint32_t index(const float* p)
    {
        if ((mesh_.vertexCount() + 1) * 2 > table_.size())
            grow();
        const uint32_t k[3] = {key(p[0]), key(p[1]), key(p[2])};
        for (size_t slot = hash(k) & (table_.size() - 1);; slot = (slot + 1) & (table_.size() - 1)) {
            const uint32_t v = table_[slot];
            if (v == ~uint32_t(0)) {
                table_[slot] = uint32_t(mesh_.vertexCount());
                mesh_.positions.insert(mesh_.positions.end(), p, p + 3);
                return table_[slot];
            }
            const float* q = &mesh_.positions[3 * size_t(v)];
            if (key(q[0]) == k[0] && key(q[1]) == k[1] && key(q[2]) == k[2])
                return v;
        }
    }

  private:
    static uint32_t key(float f)
    {
        uint32_t bits;
        std::memcpy(&bits, &f, 4);
        return bits == 0x80000000u ? 0u : bits;
    }
    static size_t hash(const uint32_t* k)
    {
        uint64_t h = (uint64_t(k[0]) * 0x9E3779B97F4A7C15ull) ^ (uint64_t(k[1]) * 0xC2B2AE3D27D4EB4Full) ^
                     (uint64_t(k[2]) * 0x165667B19E3779F9ull);
        return size_t(h ^ (h >> 29));
    }
    void grow()
    {
        std::vector<uint32_t> old(table_.size() * 2, ~uint32_t(0));
        old.swap(table_);
        for (uint32_t v = 0; v < mesh_.vertexCount(); ++v) {
            const float* q = &mesh_.positions[3 * size_t(v)];
            const uint32_t k[3] = {key(q[0]), key(q[1]), key(q[2])};
            size_t slot = hash(k) & (table_.size() - 1);
            while (table_[slot] != ~uint32_t(0))
                slot = (slot + 1) & (table_.size() - 1);
            table_[slot] = v;
        }
    }
    Mesh& mesh_;
    std::vector<uint32_t> table_;
};

// The chunk's triangles as a mesh (own triangles first, then the halo's), per triangle its seed.
template <typename Id> void loadIndexed(const Build& build, ChunkTemp& temp, Mesh& mesh, std::vector<uint8_t>& seeds)
{
    const size_t recordBytes = build.recordBytes();
    const uint64_t n = temp.triangles;
    std::vector<Id> ids(3 * n);
    if (build.materials)
        mesh.triangleMaterials.resize(n);
    seeds.assign(n + temp.haloTriangles, 1);
    {
        std::vector<uint8_t> block(recordBytes * 4096);
        for (uint64_t first = 0; first < n; first += 4096) {
            const uint64_t count = std::min<uint64_t>(4096, n - first);
            temp.own->readAt(first * recordBytes, block.data(), size_t(count * recordBytes));
            for (uint64_t t = 0; t < count; ++t) {
                const uint8_t* record = &block[t * recordBytes];
                for (int k = 0; k < 3; ++k) {
                    uint64_t id = 0;
                    std::memcpy(&id, record + size_t(k) * build.idBytes, build.idBytes);
                    ids[3 * (first + t) + uint64_t(k)] = Id(id);
                }
                uint32_t tag;
                std::memcpy(&tag, record + recordBytes - 4, 4);
                seeds[first + t] = (tag & kSeedBit) ? 1 : 0;
                if (build.materials)
                    mesh.triangleMaterials[first + t] = tag & ~kSeedBit;
            }
        }
    }
    // The chunk's vertices in id order, read from the store in runs.
    std::vector<Id> unique(ids);
    std::sort(unique.begin(), unique.end());
    unique.erase(std::unique(unique.begin(), unique.end()), unique.end());
    unique.shrink_to_fit();
    if (unique.size() > 0xFFFFFFFEull)
        fail(build.stream->path(), "internal error: a chunk with more than 2^32 vertices");
    const bool colors = build.stream->vertexColors();
    mesh.positions.resize(unique.size() * 3);
    if (colors)
        mesh.colors.resize(unique.size() * 3);
    {
        const uint64_t maxRun = 1 << 14, maxGap = 64;
        std::vector<float> positions(maxRun * 3), rgb(colors ? maxRun * 3 : 0);
        for (size_t i = 0; i < unique.size();) {
            const uint64_t first = unique[i];
            size_t j = i + 1;
            while (j < unique.size() && unique[j] - unique[j - 1] <= maxGap && unique[j] - first < maxRun)
                ++j;
            const uint64_t count = uint64_t(unique[j - 1]) - first + 1;
            build.stream->readVertices(first, count, positions.data(), colors ? rgb.data() : nullptr);
            for (size_t k = i; k < j; ++k) {
                std::memcpy(&mesh.positions[3 * k], &positions[3 * (uint64_t(unique[k]) - first)], 12);
                if (colors)
                    std::memcpy(&mesh.colors[3 * k], &rgb[3 * (uint64_t(unique[k]) - first)], 12);
            }
            i = j;
        }
    }
    mesh.indices.resize(3 * n);
    for (uint64_t i = 0; i < 3 * n; ++i)
        mesh.indices[i] = uint32_t(std::lower_bound(unique.begin(), unique.end(), ids[i]) - unique.begin());
}

void loadSoup(const Build& build, ChunkTemp& temp, Mesh& mesh, std::vector<uint8_t>& seeds)
{
    const size_t recordBytes = build.recordBytes();
    const uint64_t n = temp.triangles;
    PositionWeld weld(mesh);
    mesh.indices.resize(3 * n);
    if (build.materials)
        mesh.triangleMaterials.resize(n);
    seeds.assign(n + temp.haloTriangles, 1);
    std::vector<uint8_t> block(recordBytes * 4096);
    for (uint64_t first = 0; first < n; first += 4096) {
        const uint64_t count = std::min<uint64_t>(4096, n - first);
        temp.own->readAt(first * recordBytes, block.data(), size_t(count * recordBytes));
        for (uint64_t t = 0; t < count; ++t) {
            const uint8_t* record = &block[t * recordBytes];
            float p[9];
            std::memcpy(p, record, 36);
            for (int k = 0; k < 3; ++k)
                mesh.indices[3 * (first + t) + uint64_t(k)] = weld.index(p + 3 * k);
            uint32_t tag;
            std::memcpy(&tag, record + 36, 4);
            seeds[first + t] = (tag & kSeedBit) ? 1 : 0;
            if (build.materials)
                mesh.triangleMaterials[first + t] = tag & ~kSeedBit;
        }
    }
}

// Appends the halo's triangles (their own vertices) for the closed test.
void appendHalo(ChunkTemp& temp, Mesh& mesh)
{
    const uint64_t n = temp.haloTriangles;
    std::vector<float> block(9 * 4096);
    for (uint64_t first = 0; first < n; first += 4096) {
        const uint64_t count = std::min<uint64_t>(4096, n - first);
        temp.halo->readAt(first * 36, block.data(), size_t(count * 36));
        for (uint64_t t = 0; t < count; ++t) {
            const uint32_t base = uint32_t(mesh.vertexCount());
            mesh.positions.insert(mesh.positions.end(), &block[9 * t], &block[9 * t] + 9);
            mesh.indices.insert(mesh.indices.end(), {base, base + 1, base + 2});
        }
    }
}

chunk::ChunkHeader chunkHeader(const Build& build, uint32_t index, uint32_t count, const Cell& cell, uint32_t rootDepth)
{
    chunk::ChunkHeader header{};
    header.fingerprint = build.fingerprint;
    header.chunkIndex = index;
    header.chunkCount = count;
    header.rootDepth = rootDepth;
    header.inputTriangles = build.inputTriangles;
    for (int a = 0; a < 3; ++a) {
        header.cellMin[a] = cell.lo[a];
        header.cellMax[a] = cell.hi[a];
    }
    return header;
}

void buildChunk(Build& build, ChunkTemp& temp, chunk::ChunkHeader header, const std::string& path, const std::string& stage,
                uint32_t splitLevel);

// A chunk of up to build.capacity triangles: mesh, closed test, in-core build, chunk file.
// header: fingerprint, index, count, root depth and cell.
void buildChunkInMemory(Build& build, ChunkTemp& temp, chunk::ChunkHeader header, const std::string& path)
{
    const uint32_t rootDepth = header.rootDepth;
    header.chunkTriangles = temp.triangles;
    Mesh mesh;
    mesh.materials = build.stream->materials();
    std::vector<uint8_t> seeds;
    if (!build.stream->indexed())
        loadSoup(build, temp, mesh, seeds);
    else if (build.idBytes == 4)
        loadIndexed<uint32_t>(build, temp, mesh, seeds);
    else
        loadIndexed<uint64_t>(build, temp, mesh, seeds);
    temp.own.reset();
    build.addTemporary(-int64_t(temp.triangles * build.recordBytes()));
    const uint64_t own = temp.triangles;
    const uint64_t ownVertices = mesh.vertexCount();
    // Drop triangles with a repeated index now: the builder would, and an all-degenerate chunk is empty.
    uint64_t degenerate = 0;
    for (uint64_t t = 0; t < own; ++t) {
        const uint32_t* i = &mesh.indices[3 * t];
        degenerate += i[0] == i[1] || i[1] == i[2] || i[0] == i[2];
    }
    header.droppedDegenerate = degenerate;
    if (degenerate == own) {
        temp.halo.reset();
        writeChunkFile(path, header, nullptr);
        build.stats->chunks++;
        return;
    }
    // Closed components over the chunk and its halo; halo triangles and triangles that leave the
    // cell seed "open", so a component cut by a chunk boundary is open.
    appendHalo(temp, mesh);
    build.addTemporary(-int64_t(temp.haloTriangles * 36));
    temp.halo.reset();
    const unsigned threads = threadCount(build.options->build);
    // A closed component has no halo triangle (they seed "open"), and its id is its smallest
    // triangle index (closed.cpp), so every id left is below own.
    std::vector<uint32_t> component = closedComponents(mesh, threads, seeds.data());
    seeds = {};
    // Closed components near another surface (the halo's included) or near the cell's faces
    // (a neighbour beyond may be in no halo here) are not flagged.
    std::vector<uint8_t> crowded = crowdedComponents(mesh, component.data(), closedClearance(build.boundsMin, build.boundsMax),
                                                     header.cellMin, header.cellMax, threads);
    component.resize(own);
    crowded.resize(own);
    mesh.indices.resize(3 * own);
    mesh.indices.shrink_to_fit();
    mesh.positions.resize(3 * ownVertices);
    mesh.positions.shrink_to_fit();

    BuildExtras extras;
    extras.rootDepth = rootDepth;
    extras.component = component.data();
    extras.crowded = crowded.data();
    PreprocessOptions options = build.options->build;
    options.progress = nullptr;
    PreprocessStats stats;
    CompressedModel model = buildModel(mesh, options, &stats, nullptr, extras);
    mesh = Mesh();
    component = {};
    crowded = {};
    model = withScene(model, build.stream->cameras(), build.stream->lights(), build.stream->path());
    model.header.sourceTriangleCount = build.inputTriangles;
    header.closedTriangles = stats.closedTriangles;
    header.closedClusterTriangles = stats.closedClusterTriangles;
    header.closedClusters = stats.closedClusters;
    writeChunkFile(path, header, &model);
    build.stats->chunks++;
    build.stats->largestChunk = std::max(build.stats->largestChunk, own);
}

// Partitions a chunk's records (and its halo) into k sub-chunks; returns the plan.
Plan splitChunk(Build& build, ChunkTemp& temp, std::vector<ChunkTemp>& parts)
{
    const size_t recordBytes = build.recordBytes();
    std::unique_ptr<VertexCache> cache;
    if (build.stream->indexed())
        cache = std::make_unique<VertexCache>(*build.stream, build.options->memoryLimit / 4);
    // A sample of the chunk's centroids.
    Reservoir sample{size_t(std::clamp<uint64_t>(build.options->memoryLimit / 96, 1024, 1 << 20)), {}};
    std::vector<uint8_t> block(recordBytes * 4096);
    auto forEachRecord = [&](auto&& fn) {
        for (uint64_t first = 0; first < temp.triangles; first += 4096) {
            const uint64_t count = std::min<uint64_t>(4096, temp.triangles - first);
            temp.own->readAt(first * recordBytes, block.data(), size_t(count * recordBytes));
            for (uint64_t t = 0; t < count; ++t) {
                Corners corners;
                recordCorners(build, cache.get(), &block[t * recordBytes], corners);
                fn(corners, &block[t * recordBytes]);
            }
        }
    };
    forEachRecord([&](const Corners& corners, const uint8_t*) {
        float c[3];
        corners.centroid(c);
        sample.add(c);
    });
    const uint32_t k = uint32_t(std::min<uint64_t>(64, (temp.triangles + build.capacity - 1) / build.capacity * 2));
    Plan plan = makePlan(sample.points, std::max(2u, k), temp.cell);
    sample.points = {};
    const bool byOrder = plan.leaves() < 2;
    if (byOrder) {
        // Centroids that cannot be told apart: parts by record order, every triangle seeded open
        // (the parts' cells coincide, so the halo argument does not hold).
        plan = Plan();
        plan.nodes.resize(1);
        plan.nodes[0].axis = -1;
        const uint32_t parts = uint32_t(std::min<uint64_t>(64, (temp.triangles + build.capacity - 1) / build.capacity));
        plan.cells.assign(std::max(2u, parts), temp.cell);
    }
    parts = makeTemps(build, plan, -1, "chunk part");
    raiseOpenFileLimit(2 * size_t(plan.leaves()) + 8, build.stream->path());
    uint64_t at = 0;
    forEachRecord([&](const Corners& corners, const uint8_t* record) {
        uint8_t copy[64];
        std::memcpy(copy, record, recordBytes);
        uint32_t tag;
        std::memcpy(&tag, copy + recordBytes - 4, 4);
        if (byOrder) {
            const uint32_t part = uint32_t(at++ * plan.leaves() / temp.triangles);
            tag |= kSeedBit;
            std::memcpy(copy + recordBytes - 4, &tag, 4);
            parts[part].own->append(copy, recordBytes);
            parts[part].triangles++;
            return;
        }
        distribute(plan, parts, corners, copy, recordBytes, (tag & kSeedBit) != 0, -1);
    });
    // The parent's halo goes to every part whose cell it meets (all of them when split by order).
    std::vector<float> halo(9 * 4096);
    for (uint64_t first = 0; first < temp.haloTriangles; first += 4096) {
        const uint64_t count = std::min<uint64_t>(4096, temp.haloTriangles - first);
        temp.halo->readAt(first * 36, halo.data(), size_t(count * 36));
        for (uint64_t t = 0; t < count; ++t) {
            Corners corners;
            std::memcpy(corners.p, &halo[9 * t], 36);
            float min[3], max[3];
            corners.bounds(min, max);
            for (uint32_t p = 0; p < plan.leaves(); ++p)
                if (byOrder || plan.cells[p].overlaps(min, max)) {
                    parts[p].halo->append(corners.p, 36);
                    parts[p].haloTriangles++;
                }
        }
    }
    uint64_t bytes = 0;
    for (ChunkTemp& part : parts) {
        part.own->finish();
        part.halo->finish();
        bytes += part.triangles * recordBytes + part.haloTriangles * 36;
    }
    build.addTemporary(int64_t(bytes));
    return plan;
}

// A build killed before its end leaves its chunk files ("<output name>.chunk<i>.tmp-<pid>..."):
// the next build of the same output removes those of processes that no longer run.
void removeStaleChunks(const std::string& folder, const std::string& name)
{
    std::error_code error;
    for (const auto& entry : std::filesystem::directory_iterator(folder, error)) {
        const std::string file = entry.path().filename().string();
        if (file.rfind(name + ".chunk", 0) != 0)
            continue;
        const size_t at = file.find(".tmp-", name.size());
        if (at == std::string::npos)
            continue;
        if (processIsGone(std::strtol(file.c_str() + at + 5, nullptr, 10)))
            std::filesystem::remove(entry.path(), error);
    }
}

// Removes the named files when it goes out of scope (chunk files of a build in
// progress), and if the process is interrupted (trackTemporary).
struct FileSweeper {
    std::vector<std::string> paths;
    std::vector<int> slots;
    void add(const std::string& path)
    {
        paths.push_back(path);
        slots.push_back(trackTemporary(path));
    }
    ~FileSweeper()
    {
        for (const std::string& path : paths) {
            std::error_code ignored;
            std::filesystem::remove(path, ignored);
        }
        for (int slot : slots)
            untrackTemporary(slot);
    }
};

void buildChunk(Build& build, ChunkTemp& temp, chunk::ChunkHeader header, const std::string& path, const std::string& stage,
                uint32_t splitLevel)
{
    if (temp.triangles <= build.capacity) {
        buildChunkInMemory(build, temp, header, path);
        return;
    }
    // Too large for memory: parts, each built (and split again if need be), merged into this chunk file.
    const uint32_t rootDepth = header.rootDepth;
    if (splitLevel >= 8 || rootDepth + 8 > model::kMaxBvhDepth)
        fail(build.stream->path(), "chunk " + std::to_string(header.chunkIndex) + " (" + std::to_string(temp.triangles) +
                                       " triangles) cannot be split to fit the memory limit; raise --memory-limit");
    std::vector<ChunkTemp> parts;
    Plan plan = splitChunk(build, temp, parts);
    build.addTemporary(-int64_t(temp.triangles * build.recordBytes() + temp.haloTriangles * 36));
    temp.own.reset();
    temp.halo.reset();
    const uint32_t partDepth = rootDepth + subtreeRootDepth(plan.leaves()) - 1;
    // The parts are the chunks of an inner build: their own fingerprint, indices and count.
    chunk::ChunkHeader part{};
    part.fingerprint = XXH64(&header, sizeof(header), splitLevel + 1);
    part.chunkCount = plan.leaves();
    part.rootDepth = partDepth;
    part.inputTriangles = build.inputTriangles;
    FileSweeper files;
    for (uint32_t p = 0; p < plan.leaves(); ++p) {
        const std::string partPath = path + ".part" + std::to_string(p);
        files.add(partPath);
        build.progress(stage + " part " + std::to_string(p + 1) + "/" + std::to_string(plan.leaves()), 0.0);
        part.chunkIndex = p;
        for (int a = 0; a < 3; ++a) {
            part.cellMin[a] = plan.cells[p].lo[a];
            part.cellMax[a] = plan.cells[p].hi[a];
        }
        buildChunk(build, parts[p], part, partPath, stage, splitLevel + 1);
        build.addTemporary(int64_t(std::filesystem::file_size(partPath)));
    }
    parts.clear();
    // Checked against each other, merged under this chunk's root at its depth, written with its header.
    header.chunkTriangles = temp.triangles;
    mergeChunks(files.paths, path, &header, {});
    for (const std::string& part : files.paths)
        build.addTemporary(-int64_t(std::filesystem::file_size(part)));
}

// ---- the scan, the plan and the partition pass ---------------------------------------------------

struct Scanned {
    std::unique_ptr<ModelStream> stream;
    Plan plan;
    uint64_t fingerprint = 0;
};

uint64_t inputFingerprint(const std::string& path)
{
    FileReader file(path, 4096);
    XXH64_state_t* state = XXH64_createState();
    XXH64_reset(state, 0x50454E42);
    const uint64_t size = file.size();
    XXH64_update(state, &size, sizeof(size));
    std::vector<uint8_t> bytes(size_t(std::min<uint64_t>(size, 1 << 16)));
    file.readAt(0, bytes.data(), bytes.size());
    XXH64_update(state, bytes.data(), bytes.size());
    file.readAt(size - bytes.size(), bytes.data(), bytes.size());
    XXH64_update(state, bytes.data(), bytes.size());
    const uint64_t h = XXH64_digest(state);
    XXH64_freeState(state);
    return h;
}

// The memory the process may still take from the system for bookkeeping: freed blocks go back
// at once (large ones are mapped, small ones trimmed), so RSS follows what is in use.
void releaseFreedMemory()
{
    mallopt(M_MMAP_THRESHOLD, 256 * 1024);
    mallopt(M_TRIM_THRESHOLD, 1024 * 1024);
    malloc_trim(0);
}

void raiseOpenFileLimit(size_t needed, const std::string& subject)
{
    rlimit limit{};
    if (getrlimit(RLIMIT_NOFILE, &limit) != 0)
        return;
    if (limit.rlim_cur < needed + 64 && limit.rlim_cur < limit.rlim_max) {
        limit.rlim_cur = std::min<rlim_t>(limit.rlim_max, needed + 64);
        setrlimit(RLIMIT_NOFILE, &limit);
        getrlimit(RLIMIT_NOFILE, &limit);
    }
    if (limit.rlim_cur < needed + 16)
        fail(subject, "the partition needs " + std::to_string(needed) + " temporary files open at once, more than the "
                          "open-file limit (" + std::to_string(limit.rlim_cur) + "); raise --memory-limit (fewer chunks) or ulimit -n");
}

Scanned scanAndPlan(const std::string& input, const StreamedOptions& options, uint32_t chunks, Build& build,
                    StreamedStats& stats)
{
    const auto start = Clock::now();
    Scanned scanned;
    ModelStreamOptions streamOptions;
    streamOptions.tempDirectory = build.tempDirectory;
    streamOptions.bufferBytes = size_t(std::clamp<uint64_t>(options.memoryLimit / 32, 64 << 10, 4 << 20));
    scanned.stream = openModelStream(input, streamOptions);
    ModelStream& stream = *scanned.stream;
    Reservoir sample{size_t(std::clamp<uint64_t>(options.memoryLimit / 96, 4096, 1 << 20)), {}};
    uint64_t vertices = 0;
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    stream.scan([&](const float* positions, size_t count) {
        for (size_t v = 0; v < count; ++v) {
            sample.add(positions + 3 * v);
            for (int a = 0; a < 3; ++a) {
                lo[a] = std::min(lo[a], positions[3 * v + size_t(a)]);
                hi[a] = std::max(hi[a], positions[3 * v + size_t(a)]);
            }
        }
        vertices += count;
        if ((vertices & ((1 << 22) - 1)) < count)
            build.progress("scan", 0.0);
    });
    build.progress("scan", 1.0);
    stats.inputTriangles = stream.triangleCount();
    stats.vertices = stream.vertexCount();
    stats.scanSeconds = secondsSince(start);
    // The format's limits, before any chunk is built.
    checkModelLimits(stream.triangleCount(), options.build, input);
    if (chunks == 0)
        chunks = uint32_t(std::min<uint64_t>(1 << 16, std::max<uint64_t>(1, (stream.triangleCount() * 4 / 3 + build.capacity - 1) /
                                                                                    build.capacity)));
    scanned.plan = makePlan(sample.points, chunks, Cell{});
    // Every process of a distributed build computes the same: input, options, counts, partition.
    XXH64_state_t* state = XXH64_createState();
    XXH64_reset(state, 0);
    const uint64_t fields[] = {inputFingerprint(input), stream.triangleCount(), stream.vertexCount(), chunks,
                               scanned.plan.hash(), options.build.maxClusterVertices, options.build.maxClusterTriangles,
                               options.build.maxLeafTriangles, options.build.sahBins, uint64_t(options.build.separateClosed)};
    XXH64_update(state, fields, sizeof(fields));
    scanned.fingerprint = XXH64_digest(state);
    XXH64_freeState(state);
    build.stream = &stream;
    build.fingerprint = scanned.fingerprint;
    build.inputTriangles = stream.triangleCount();
    build.chunkCount = chunks;
    for (int a = 0; a < 3; ++a) {
        build.boundsMin[a] = vertices ? lo[a] : 0.0f;
        build.boundsMax[a] = vertices ? hi[a] : 0.0f;
    }
    build.idBytes = stream.vertexCount() > 0xFFFFFFFFull ? 8 : 4;
    build.materials = !stream.materials().empty();
    return scanned;
}

void partitionInput(Build& build, const Plan& plan, std::vector<ChunkTemp>& temps, int64_t only, StreamedStats& stats)
{
    const auto start = Clock::now();
    ModelStream& stream = *build.stream;
    std::unique_ptr<VertexCache> cache;
    if (stream.indexed())
        cache = std::make_unique<VertexCache>(stream, build.options->memoryLimit / 4);
    const size_t recordBytes = build.recordBytes();
    uint8_t record[64];
    uint64_t done = 0;
    const uint64_t total = std::max<uint64_t>(1, stream.triangleCount());
    stream.triangles([&](const StreamTriangles& batch) {
        for (size_t t = 0; t < batch.count; ++t) {
            Corners corners;
            const uint32_t material = batch.materials ? batch.materials[t] : 0;
            if (batch.vertices) {
                for (int k = 0; k < 3; ++k) {
                    const uint64_t id = batch.vertices[3 * t + size_t(k)];
                    std::memcpy(record + size_t(k) * build.idBytes, &id, build.idBytes);
                    std::memcpy(corners.p + 3 * k, cache->vertex(id), 12);
                }
            } else {
                std::memcpy(corners.p, batch.corners + 9 * t, 36);
                std::memcpy(record, corners.p, 36);
            }
            std::memcpy(record + recordBytes - 4, &material, 4);
            distribute(plan, temps, corners, record, recordBytes, false, only);
        }
        done += batch.count;
        build.progress("partition", double(done) / double(total));
    });
    uint64_t bytes = 0;
    for (ChunkTemp& temp : temps)
        if (temp.own) {
            temp.own->finish(); // flushed, buffer released
            temp.halo->finish();
            bytes += temp.own->size() + temp.halo->size();
        }
    build.addTemporary(int64_t(bytes));
    stats.vertexCacheHitRate = cache ? cache->hitRate() : 1.0;
    stats.partitionSeconds = secondsSince(start);
}

std::string temporaryFolder(const std::string& output, const StreamedOptions& options)
{
    if (!options.tempDirectory.empty())
        return options.tempDirectory;
    const size_t slash = output.find_last_of('/');
    return slash == std::string::npos ? std::string(".") : slash == 0 ? std::string("/") : output.substr(0, slash);
}

void checkMemoryLimit(const StreamedOptions& options)
{
    if (options.memoryLimit < (uint64_t(32) << 20))
        fail("--memory-limit", std::to_string(options.memoryLimit >> 20) + " MiB is below the smallest supported, 32 MiB");
}

StreamedOptions withDefaults(StreamedOptions options)
{
    if (options.memoryLimit == 0)
        options.memoryLimit = uint64_t(1) << 30;
    return options;
}

void fillFromMerge(StreamedStats& stats, const MergeResult& merged)
{
    stats.triangles = merged.triangles;
    stats.clusters = merged.clusters;
    stats.nodes = merged.nodes;
    stats.fileBytes = merged.fileBytes;
    stats.bvhDepth = merged.bvhDepth;
    stats.maxPositionError = merged.maxPositionError;
    stats.closedTriangles = merged.closedTriangles;
    stats.closedClusterTriangles = merged.closedClusterTriangles;
}

} // namespace

uint64_t chunkCapacity(uint64_t memoryLimit, const PreprocessOptions&)
{
    const uint64_t usable = memoryLimit > kFixedBytes ? memoryLimit - kFixedBytes : 0;
    return std::max<uint64_t>(1024, usable / kBytesPerChunkTriangle);
}

StreamedStats preprocessStreamed(const std::string& input, const std::string& output, const StreamedOptions& given)
{
    const auto start = Clock::now();
    const StreamedOptions options = withDefaults(given);
    checkMemoryLimit(options);
    releaseFreedMemory();
    StreamedStats stats;
    Build build;
    build.options = &options;
    build.stats = &stats;
    build.tempDirectory = temporaryFolder(output, options);
    removeStaleChunks(build.tempDirectory, std::filesystem::path(output).filename().string());
    build.capacity = options.chunkTriangles ? options.chunkTriangles : chunkCapacity(options.memoryLimit, options.build);
    stats.chunkCapacity = build.capacity;
    Scanned scanned = scanAndPlan(input, options, options.chunks, build, stats);
    const Plan& plan = scanned.plan;
    raiseOpenFileLimit(2 * size_t(plan.leaves()), input);
    std::vector<ChunkTemp> temps = makeTemps(build, plan, -1, "chunk");
    partitionInput(build, plan, temps, -1, stats);

    const auto buildStart = Clock::now();
    const uint32_t rootDepth = subtreeRootDepth(plan.leaves());
    FileSweeper files;
    const std::string name = std::filesystem::path(output).filename().string();
    for (uint32_t i = 0; i < plan.leaves(); ++i) {
        const std::string path = build.tempDirectory + "/" + name + ".chunk" + std::to_string(i) + ".tmp-" + std::to_string(::getpid());
        files.add(path);
        const std::string stage = "chunk " + std::to_string(i + 1) + "/" + std::to_string(plan.leaves());
        build.progress(stage, 0.0);
        buildChunk(build, temps[i], chunkHeader(build, i, plan.leaves(), temps[i].cell, rootDepth), path, stage, 0);
        build.addTemporary(int64_t(std::filesystem::file_size(path)));
        build.progress(stage, 1.0);
        malloc_trim(0);
    }
    temps.clear();
    stats.buildSeconds = secondsSince(buildStart);
    const auto mergeStart = Clock::now();
    const MergeResult merged = mergeChunks(files.paths, output, nullptr, [&](double f) { build.progress("merge", f); });
    stats.mergeSeconds = secondsSince(mergeStart);
    fillFromMerge(stats, merged);
    stats.totalSeconds = secondsSince(start);
    return stats;
}

StreamedStats preprocessChunk(const std::string& input, const std::string& chunkPath, uint32_t index, uint32_t count,
                              const StreamedOptions& given)
{
    const auto start = Clock::now();
    const StreamedOptions options = withDefaults(given);
    checkMemoryLimit(options);
    if (count == 0 || index >= count)
        fail("--chunk", std::to_string(index) + "/" + std::to_string(count) + " is not I/N with 0 <= I < N");
    releaseFreedMemory();
    StreamedStats stats;
    Build build;
    build.options = &options;
    build.stats = &stats;
    build.tempDirectory = temporaryFolder(chunkPath, options);
    build.capacity = options.chunkTriangles ? options.chunkTriangles : chunkCapacity(options.memoryLimit, options.build);
    stats.chunkCapacity = build.capacity;
    Scanned scanned = scanAndPlan(input, options, count, build, stats);
    const Plan& plan = scanned.plan;
    const uint32_t rootDepth = subtreeRootDepth(count);
    const auto buildStart = Clock::now();
    if (index >= plan.leaves()) {
        // The input's points could not be split into `count` cells: this chunk has no triangles.
        chunk::ChunkHeader header = chunkHeader(build, index, count, Cell{}, rootDepth);
        writeChunkFile(chunkPath, header, nullptr);
        stats.chunks = 1;
    } else {
        std::vector<ChunkTemp> temps = makeTemps(build, plan, index, "chunk");
        partitionInput(build, plan, temps, index, stats);
        stats.triangles = temps[index].triangles;
        buildChunk(build, temps[index], chunkHeader(build, index, count, temps[index].cell, rootDepth), chunkPath,
                   "chunk " + std::to_string(index), 0);
    }
    stats.buildSeconds = secondsSince(buildStart);
    stats.fileBytes = std::filesystem::file_size(chunkPath);
    stats.totalSeconds = secondsSince(start);
    return stats;
}

StreamedStats mergeChunkFiles(const std::vector<std::string>& chunks, const std::string& output, const StreamedOptions& options)
{
    const auto start = Clock::now();
    releaseFreedMemory();
    StreamedStats stats;
    const MergeResult merged = mergeChunks(chunks, output, nullptr, [&](double f) {
        if (options.progress)
            options.progress("merge", f);
    });
    fillFromMerge(stats, merged);
    stats.chunks = uint32_t(chunks.size());
    stats.mergeSeconds = stats.totalSeconds = secondsSince(start);
    return stats;
}

} // namespace penumbra
