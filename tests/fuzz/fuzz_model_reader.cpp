// libFuzzer target for the .penumbra model reader (openModelMemory).
// Each input is tried twice: as is, and with its section and header
// checksums recomputed so that mutations get past the checksums and reach
// the structural checks. When the reader accepts a model, every index it
// vouched for is used (strip triangles, vertices, leaf ranges, child bounds)
// so that AddressSanitizer catches anything the validator let through.
#include <xxhash.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <new>
#include <span>

#include "penumbra/error.h"
#include "penumbra/model_format.h"

namespace {

using namespace penumbra;
using namespace penumbra::model;

void check(bool condition)
{
    if (!condition)
        std::abort(); // an accepted model broke an invariant the validator promises
}

// Reads everything an accepted model lets a consumer read.
void useModel(const CompressedModel& model)
{
    float sum = 0.0f;
    for (const ClusterRecord& cluster : model.clusters) {
        const uint8_t* strip = model.indices.data() + cluster.firstIndex;
        const QuantizedVertex* vertices = model.vertices.data() + cluster.firstVertex;
        uint32_t triangles = 0;
        forEachStripTriangle(strip, strip + cluster.indexBytes, [&](uint32_t a, uint32_t b, uint32_t c) {
            check(a < cluster.vertexCount && b < cluster.vertexCount && c < cluster.vertexCount);
            sum += decodePosition(cluster, vertices[a]).x + decodePosition(cluster, vertices[b]).y +
                   decodePosition(cluster, vertices[c]).z;
            ++triangles;
        });
        check(triangles == cluster.triangleCount);
        check(model.nodes[cluster.node].cluster == uint32_t(&cluster - model.clusters.data()));
        check(cluster.material < model.materials.size());
        check((cluster.flags & ~kClusterFlagsMask) == 0 && cluster.reserved == 0);
        // 64-bit offsets: the whole range lies inside its section.
        check(cluster.firstVertex <= model.vertices.size() && cluster.vertexCount <= model.vertices.size() - cluster.firstVertex);
        check(cluster.firstIndex <= model.indices.size() && cluster.indexBytes <= model.indices.size() - cluster.firstIndex);
        sum += float(model.vertices[cluster.firstVertex + cluster.vertexCount - 1].y);
        sum += model.materials[cluster.material].baseColor[0];
    }
    for (const Camera& camera : modelCameras(model))
        sum += camera.position.x + camera.yfovDegrees;
    for (const Light& light : modelLights(model)) {
        check(uint32_t(light.type) <= uint32_t(LightType::Sphere));
        sum += light.intensity;
    }
    // Fixed-size traversal stack, as the runtime uses (3 x depth + 1 entries).
    uint32_t stack[3 * kMaxBvhDepth + 4];
    size_t top = 0;
    stack[top++] = 0;
    uint64_t visited = 0;
    while (top > 0) {
        const Node& node = model.nodes[stack[--top]];
        ++visited;
        for (uint32_t k = 0; k < childCount(node); ++k) {
            glm::vec3 min, max;
            decodeChildBox(node, k, min, max);
            sum += min.x + max.y;
            if (childKind(node, k) == ChildKind::Leaf) {
                const ClusterRecord& cluster = model.clusters[node.cluster];
                const uint32_t start = node.child[k] & 0xFFFF, count = node.child[k] >> 16;
                check(start + count <= cluster.indexBytes);
                const uint8_t* strip = model.indices.data() + cluster.firstIndex;
                forEachStripTriangle(strip + start, strip + start + count, [&](uint32_t a, uint32_t, uint32_t) {
                    sum += float(model.vertices[cluster.firstVertex + a].x);
                });
                continue;
            }
            check(top < sizeof(stack) / sizeof(stack[0]));
            stack[top++] = node.child[k];
        }
    }
    check(visited == model.nodes.size());
    volatile float sink = sum;
    (void)sink;
}

void tryOpen(std::span<const uint8_t> bytes)
{
    try {
        CompressedModel model = openModelMemory(bytes, nullptr, "fuzz");
        useModel(model);
    } catch (const Error&) {
    }
}

// Recomputes the checksums of every section that lies inside the buffer, then the header's.
void fixChecksums(uint8_t* bytes, size_t size)
{
    FileHeader header;
    std::memcpy(&header, bytes, sizeof(header));
    for (SectionEntry& entry : header.sections)
        if (entry.type != 0 && entry.offset <= size && entry.size <= size - entry.offset)
            entry.checksum = XXH64(bytes + entry.offset, size_t(entry.size), 0);
    header.headerChecksum = 0;
    header.headerChecksum = XXH64(&header, sizeof(header), 0);
    std::memcpy(bytes, &header, sizeof(header));
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    // An exact-size, 64-byte aligned copy (like a mapping) so that AddressSanitizer
    // flags any read past the end and the reader's aligned casts hold.
    uint8_t* bytes = static_cast<uint8_t*>(::operator new(size, std::align_val_t(64)));
    if (size > 0)
        std::memcpy(bytes, data, size);
    tryOpen({bytes, size});
    if (size >= sizeof(FileHeader)) {
        fixChecksums(bytes, size);
        tryOpen({bytes, size});
    }
    ::operator delete(bytes, std::align_val_t(64));
    return 0;
}
