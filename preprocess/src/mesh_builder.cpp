#include "mesh_builder.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

namespace penumbra::detail {

namespace {

constexpr float kTwoPi = 6.28318530717958647692f;

glm::vec3 anyPerpendicular(glm::vec3 t)
{
    glm::vec3 axis = std::abs(t.x) < 0.9f ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0);
    return glm::normalize(glm::cross(t, axis));
}

glm::vec3 orthogonalize(glm::vec3 v, glm::vec3 t)
{
    glm::vec3 n = v - t * glm::dot(t, v);
    float len = glm::length(n);
    return len > 1e-6f ? n / len : anyPerpendicular(t);
}

glm::vec3 safeNormalize(glm::vec3 v, glm::vec3 fallback)
{
    float len = glm::length(v);
    return len > 1e-12f ? v / len : fallback;
}

} // namespace

MeshBuilder::MeshBuilder(uint64_t triangleLimit) : limit_(triangleLimit) {}

MeshBuilder::MeshBuilder(float* positions, uint32_t* indices, uint64_t vertexOffset, uint64_t triangleOffset,
                         uint64_t triangleLimit)
    : positions_(positions + vertexOffset * 3), indices_(indices + triangleOffset * 3), vertexBase_(vertexOffset),
      limit_(triangleLimit)
{
}

MeshBuilder::MeshBuilder(OwnArrays, float* positions, uint32_t* indices, uint64_t vertexBase, uint64_t triangleLimit)
    : positions_(positions), indices_(indices), vertexBase_(vertexBase), limit_(triangleLimit)
{
}

bool MeshBuilder::fits(uint64_t triangles)
{
    if (triangles > remaining()) {
        truncated_ = true;
        return false;
    }
    return true;
}

bool MeshBuilder::countOnly(uint64_t vertices, uint64_t triangles)
{
    if (!counting())
        return false;
    vertices_ += vertices;
    triangles_ += triangles;
    return true;
}

uint32_t MeshBuilder::vertex(glm::vec3 p)
{
    float* out = positions_ + vertices_ * 3;
    out[0] = p.x;
    out[1] = p.y;
    out[2] = p.z;
    return uint32_t(vertexBase_ + vertices_++);
}

void MeshBuilder::triangle(uint32_t a, uint32_t b, uint32_t c)
{
    uint32_t* out = indices_ + triangles_ * 3;
    out[0] = a;
    out[1] = b;
    out[2] = c;
    ++triangles_;
}

bool MeshBuilder::box(glm::vec3 min, glm::vec3 max)
{
    Frame frame;
    frame.origin = (min + max) * 0.5f;
    return orientedBox(frame, (max - min) * 0.5f);
}

bool MeshBuilder::orientedBox(const Frame& f, glm::vec3 h)
{
    if (!fits(12))
        return false;
    if (countOnly(8, 12))
        return true;
    // Corner c has bit 0 = +x, bit 1 = +y, bit 2 = +z.
    uint32_t base = 0;
    for (int c = 0; c < 8; ++c) {
        glm::vec3 p =
            f.origin + f.x * ((c & 1) ? h.x : -h.x) + f.y * ((c & 2) ? h.y : -h.y) + f.z * ((c & 4) ? h.z : -h.z);
        uint32_t index = vertex(p);
        if (c == 0)
            base = index;
    }
    static const uint8_t kFaces[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4},
                                         {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
    for (const auto& q : kFaces) {
        triangle(base + q[0], base + q[1], base + q[2]);
        triangle(base + q[0], base + q[2], base + q[3]);
    }
    return true;
}

bool MeshBuilder::beam(glm::vec3 from, glm::vec3 to, glm::vec3 upHint, float width, float height)
{
    glm::vec3 d = to - from;
    float len = glm::length(d);
    Frame f;
    f.origin = (from + to) * 0.5f;
    f.x = safeNormalize(d, glm::vec3(1, 0, 0));
    f.y = orthogonalize(upHint, f.x);
    f.z = glm::cross(f.x, f.y);
    return orientedBox(f, glm::vec3(len * 0.5f, height * 0.5f, width * 0.5f));
}

bool MeshBuilder::tube(glm::vec3 from, glm::vec3 to, float radius, uint32_t segments)
{
    glm::vec3 path[2] = {from, to};
    return pipe(path, radius, segments);
}

bool MeshBuilder::pipe(std::span<const glm::vec3> path, float radius, uint32_t segments)
{
    sectionScratch_.resize(segments);
    for (uint32_t k = 0; k < segments; ++k) {
        float a = kTwoPi * float(k) / float(segments);
        sectionScratch_[k] = glm::vec2(std::cos(a), std::sin(a)) * radius;
    }
    glm::vec3 hint =
        path.size() >= 2 ? anyPerpendicular(safeNormalize(path[1] - path[0], glm::vec3(1, 0, 0))) : glm::vec3(1, 0, 0);
    return sweep(path, sectionScratch_, hint, true);
}

bool MeshBuilder::sweep(std::span<const glm::vec3> path, std::span<const glm::vec2> section, glm::vec3 normalHint,
                        bool caps)
{
    const uint64_t n = path.size(), m = section.size();
    if (n < 2 || m < 3)
        return false;
    const uint64_t tris = sweepTriangles(n, m, caps);
    if (!fits(tris))
        return false;
    if (countOnly(n * m, tris))
        return true;

    // Rings: parallel-transported frame (N, B = T x N); section (x, y) -> N*x + B*y.
    glm::vec3 normal = normalHint;
    uint32_t base = 0;
    for (uint64_t i = 0; i < n; ++i) {
        glm::vec3 t;
        if (i == 0) {
            t = safeNormalize(path[1] - path[0], glm::vec3(1, 0, 0));
        } else if (i == n - 1) {
            t = safeNormalize(path[i] - path[i - 1], glm::vec3(1, 0, 0));
        } else {
            glm::vec3 a = safeNormalize(path[i] - path[i - 1], glm::vec3(1, 0, 0));
            glm::vec3 b = safeNormalize(path[i + 1] - path[i], a);
            t = safeNormalize(a + b, a);
        }
        normal = orthogonalize(normal, t);
        glm::vec3 binormal = glm::cross(t, normal);
        for (uint64_t k = 0; k < m; ++k) {
            uint32_t index = vertex(path[i] + normal * section[k].x + binormal * section[k].y);
            if (i == 0 && k == 0)
                base = index;
        }
    }
    for (uint64_t i = 0; i + 1 < n; ++i) {
        uint32_t ring = base + uint32_t(i * m), next = ring + uint32_t(m);
        for (uint32_t k = 0; k < m; ++k) {
            uint32_t k1 = (k + 1) % uint32_t(m);
            triangle(ring + k, ring + k1, next + k1);
            triangle(ring + k, next + k1, next + k);
        }
    }
    if (caps) {
        uint32_t first = base, last = base + uint32_t((n - 1) * m);
        for (uint32_t k = 1; k + 1 < m; ++k)
            triangle(first, first + k + 1, first + k);
        for (uint32_t k = 1; k + 1 < m; ++k)
            triangle(last, last + k, last + k + 1);
    }
    return true;
}

bool MeshBuilder::lathe(const Frame& f, std::span<const glm::vec2> profile, uint32_t segments)
{
    const uint64_t n = profile.size();
    if (n < 2 || segments < 3)
        return false;
    uint64_t verts = 0, tris = 0;
    for (uint64_t i = 0; i < n; ++i) {
        bool pole = profile[i].x <= 0.0f;
        verts += pole ? 1 : segments;
        if (i + 1 < n) {
            bool nextPole = profile[i + 1].x <= 0.0f;
            if (pole && nextPole)
                return false;
            tris += (pole || nextPole) ? segments : 2ull * segments;
        }
    }
    if (!fits(tris))
        return false;
    if (countOnly(verts, tris))
        return true;

    trigScratch_.resize(segments);
    for (uint32_t k = 0; k < segments; ++k) {
        float a = kTwoPi * float(k) / float(segments);
        trigScratch_[k] = glm::vec2(std::cos(a), std::sin(a));
    }
    uint32_t previous = 0;
    bool previousPole = false;
    for (uint64_t i = 0; i < n; ++i) {
        const float r = profile[i].x, h = profile[i].y;
        const bool pole = r <= 0.0f;
        uint32_t start;
        if (pole) {
            start = vertex(f.origin + f.y * h);
        } else {
            start = vertex(f.origin + f.y * h + (f.x * trigScratch_[0].x + f.z * trigScratch_[0].y) * r);
            for (uint32_t k = 1; k < segments; ++k)
                vertex(f.origin + f.y * h + (f.x * trigScratch_[k].x + f.z * trigScratch_[k].y) * r);
        }
        if (i > 0) {
            for (uint32_t k = 0; k < segments; ++k) {
                uint32_t k1 = (k + 1) % segments;
                if (previousPole) {
                    triangle(previous, start + k, start + k1);
                } else if (pole) {
                    triangle(previous + k, start, previous + k1);
                } else {
                    triangle(previous + k, start + k, start + k1);
                    triangle(previous + k, start + k1, previous + k1);
                }
            }
        }
        previous = start;
        previousPole = pole;
    }
    return true;
}

bool MeshBuilder::grid(glm::vec3 corner, glm::vec3 edgeU, glm::vec3 edgeV, uint32_t cellsU, uint32_t cellsV)
{
    if (cellsU == 0 || cellsV == 0)
        return false;
    const uint64_t tris = 2ull * cellsU * cellsV;
    if (!fits(tris))
        return false;
    if (countOnly(uint64_t(cellsU + 1) * (cellsV + 1), tris))
        return true;
    uint32_t base = 0;
    for (uint32_t i = 0; i <= cellsU; ++i)
        for (uint32_t j = 0; j <= cellsV; ++j) {
            uint32_t index = vertex(corner + edgeU * (float(i) / float(cellsU)) + edgeV * (float(j) / float(cellsV)));
            if (i == 0 && j == 0)
                base = index;
        }
    const uint32_t row = cellsV + 1;
    for (uint32_t i = 0; i < cellsU; ++i)
        for (uint32_t j = 0; j < cellsV; ++j) {
            uint32_t v00 = base + i * row + j, v10 = v00 + row, v01 = v00 + 1, v11 = v10 + 1;
            triangle(v00, v10, v11);
            triangle(v00, v11, v01);
        }
    return true;
}

bool MeshBuilder::fillGround(float minX, float minZ, float maxX, float maxZ, float y)
{
    const uint64_t quads = remaining() / 2;
    if (quads == 0) {
        truncated_ = true;
        return false;
    }
    // Cells along z (u) and x (v) with roughly square cells and as many quads as fit.
    const double aspect = double(maxZ - minZ) / double(maxX - minX);
    const uint64_t guess = std::max<uint64_t>(1, uint64_t(std::llround(std::sqrt(double(quads) * aspect))));
    uint64_t bestU = 1, bestV = 1;
    for (uint64_t u = guess > 16 ? guess - 16 : 1; u <= guess + 16 && u <= quads; ++u) {
        uint64_t v = quads / u;
        if (v >= 1 && u * v > bestU * bestV)
            bestU = u, bestV = v;
    }
    return grid(glm::vec3(minX, y, minZ), glm::vec3(0, 0, maxZ - minZ), glm::vec3(maxX - minX, 0, 0), uint32_t(bestU),
                uint32_t(bestV));
}

} // namespace penumbra::detail
