// Strip ranges of 8-bit local indices (the strip part of the ReduceM-like
// representation, Lauterbach et al. 2009, section 5.1): one leaf's triangles
// are ordered with meshopt_optimizeVertexCacheStrip and turned into strips by
// meshopt_stripify with restart index kStripRestart. The result is decoded
// again with forEachStripTriangle (the reader's and the shaders' rule: odd
// triangles swap their first two indices, repeated-index triangles are skipped)
// and must give back exactly the leaf's triangles with their winding (as a
// multiset of rotation-normalized triples); otherwise every triangle is stored
// as its own 3-index strip.
#include <algorithm>
#include <array>

#include <meshoptimizer.h>

#include "preprocess_internal.h"

namespace penumbra::preprocess_detail {

namespace {

using Triple = std::array<uint32_t, 3>;

// Rotates so the smallest index comes first; keeps the winding.
Triple normalized(uint32_t a, uint32_t b, uint32_t c)
{
    if (b < a && b < c)
        return {b, c, a};
    if (c < a && c < b)
        return {c, a, b};
    return {a, b, c};
}

struct Scratch {
    std::vector<uint32_t> optimized, strip;
    std::vector<uint8_t> bytes;
    std::vector<std::pair<Triple, uint32_t>> expected, decoded;
};

} // namespace

bool appendLeafStrips(const uint32_t* localIndices, uint32_t count, uint32_t vertexCount, std::vector<uint8_t>& out,
                      const uint32_t* source, std::vector<uint32_t>* sourceOut)
{
    thread_local Scratch s;
    const size_t indexCount = size_t(count) * 3;
    s.optimized.resize(indexCount);
    s.strip.resize(meshopt_stripifyBound(indexCount));
    meshopt_optimizeVertexCacheStrip(s.optimized.data(), localIndices, indexCount, vertexCount);
    size_t length = meshopt_stripify(s.strip.data(), s.optimized.data(), indexCount, vertexCount, model::kStripRestart);

    // Bytes without leading, trailing or doubled restarts.
    s.bytes.clear();
    for (size_t i = 0; i < length; ++i) {
        uint32_t v = s.strip[i];
        if (v == model::kStripRestart) {
            if (!s.bytes.empty() && s.bytes.back() != model::kStripRestart)
                s.bytes.push_back(model::kStripRestart);
        } else {
            s.bytes.push_back(uint8_t(v));
        }
    }
    while (!s.bytes.empty() && s.bytes.back() == model::kStripRestart)
        s.bytes.pop_back();

    // Verify: the decoded triangles are exactly the input ones.
    s.expected.clear();
    for (uint32_t t = 0; t < count; ++t)
        s.expected.push_back({normalized(localIndices[3 * t], localIndices[3 * t + 1], localIndices[3 * t + 2]),
                              source ? source[t] : t});
    s.decoded.clear();
    forEachStripTriangle(s.bytes.data(), s.bytes.data() + s.bytes.size(), [&](uint32_t a, uint32_t b, uint32_t c) {
        s.decoded.push_back({normalized(a, b, c), uint32_t(s.decoded.size())});
    });
    auto byTriple = [](const auto& x, const auto& y) { return x.first < y.first; };
    std::sort(s.expected.begin(), s.expected.end(), byTriple);
    bool ok = s.decoded.size() == count;
    if (ok) {
        std::sort(s.decoded.begin(), s.decoded.end(), byTriple);
        for (uint32_t t = 0; t < count && ok; ++t)
            ok = s.decoded[t].first == s.expected[t].first;
    }
    if (!ok) {
        // Fallback: one strip per triangle, in the sorted order.
        s.bytes.clear();
        s.decoded.clear();
        for (uint32_t t = 0; t < count; ++t) {
            if (t > 0)
                s.bytes.push_back(model::kStripRestart);
            const Triple& tri = s.expected[t].first;
            s.bytes.insert(s.bytes.end(), {uint8_t(tri[0]), uint8_t(tri[1]), uint8_t(tri[2])});
            s.decoded.push_back({tri, t});
        }
    }
    out.insert(out.end(), s.bytes.begin(), s.bytes.end());
    if (sourceOut) {
        // decoded is sorted by triple like expected; pair them up, then restore decode order.
        size_t base = sourceOut->size();
        sourceOut->resize(base + count);
        for (uint32_t t = 0; t < count; ++t)
            (*sourceOut)[base + s.decoded[t].second] = s.expected[t].second;
    }
    return ok;
}

} // namespace penumbra::preprocess_detail
