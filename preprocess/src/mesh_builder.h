// Triangle-budgeted mesh builder used by the procedural generators: boxes, sweeps
// (tubes, pipes, arches, wires), lathes (columns, tanks) and grids, each emitted as
// one part with shared vertices and counter-clockwise outward-facing triangles.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace penumbra::detail {

// Right-handed orthonormal frame (x cross y == z) placed at origin.
struct Frame {
    glm::vec3 origin{0.0f};
    glm::vec3 x{1.0f, 0.0f, 0.0f};
    glm::vec3 y{0.0f, 1.0f, 0.0f};
    glm::vec3 z{0.0f, 0.0f, 1.0f};
};

// Two modes. A counting builder only adds up what the calls would emit; an emitting
// builder writes vertices and indices into preallocated arrays at fixed offsets, so the
// same build code run twice (count, then emit) needs no reallocation and can run units
// on several threads. Every primitive is all-or-nothing: when its triangles do not fit
// in what is left of triangleLimit it is skipped, truncated() becomes true and the call
// returns false. Both modes skip the same primitives for the same limit.
class MeshBuilder {
  public:
    // Counting builder.
    explicit MeshBuilder(uint64_t triangleLimit);
    // Emitting builder: vertex v goes to positions[3 * (vertexOffset + v)], triangle t to
    // indices[3 * (triangleOffset + t)]; indices written are absolute (vertexOffset + v).
    MeshBuilder(float* positions, uint32_t* indices, uint64_t vertexOffset, uint64_t triangleOffset,
                uint64_t triangleLimit);
    // Emitting into arrays of its own: vertex v goes to positions[3 * v], triangle t to
    // indices[3 * t]; indices written are still absolute (vertexBase + v).
    struct OwnArrays {};
    MeshBuilder(OwnArrays, float* positions, uint32_t* indices, uint64_t vertexBase, uint64_t triangleLimit);

    bool counting() const { return positions_ == nullptr; }
    uint64_t vertices() const { return vertices_; }
    uint64_t triangles() const { return triangles_; }
    uint64_t remaining() const { return limit_ - triangles_; }
    bool truncated() const { return truncated_; }

    // Axis-aligned box: 8 vertices, 12 triangles.
    bool box(glm::vec3 min, glm::vec3 max);
    // Box centred on frame.origin with the given half extents along frame.x/y/z.
    bool orientedBox(const Frame& frame, glm::vec3 halfExtents);
    // Box from 'from' to 'to' with a width x height cross-section; height is measured
    // along upHint made perpendicular to the beam.
    bool beam(glm::vec3 from, glm::vec3 to, glm::vec3 upHint, float width, float height);
    // Capped circular cylinder: 2*segments vertices, 4*segments-4 triangles.
    bool tube(glm::vec3 from, glm::vec3 to, float radius, uint32_t segments);
    // Capped circular tube along a polyline (parallel-transport frames).
    bool pipe(std::span<const glm::vec3> path, float radius, uint32_t segments);
    // Sweeps a convex counter-clockwise cross-section (x along the frame normal, y along
    // the binormal) along path (>= 2 points). normalHint fixes the first frame's normal.
    // path.size()*section.size() vertices, 2*section*(path-1) (+2*(section-2) with caps) triangles.
    bool sweep(std::span<const glm::vec3> path, std::span<const glm::vec2> section, glm::vec3 normalHint, bool caps);
    // Surface of revolution about frame.y: profile point (r, h) maps to
    // origin + r*(cos a * x + sin a * z) + h*y. Points with r == 0 become single pole
    // vertices. A profile going from bottom to top (solid on the axis side) faces outward.
    bool lathe(const Frame& frame, std::span<const glm::vec2> profile, uint32_t segments);
    // cellsU x cellsV grid of quads spanning corner + [0,1]*edgeU + [0,1]*edgeV, facing edgeU x edgeV.
    bool grid(glm::vec3 corner, glm::vec3 edgeU, glm::vec3 edgeV, uint32_t cellsU, uint32_t cellsV);
    // Horizontal grid at height y over [minX,maxX]x[minZ,maxZ] facing +Y that uses up as much
    // of remaining() as possible (at least one quad); returns false if not even 2 triangles fit.
    bool fillGround(float minX, float minZ, float maxX, float maxZ, float y);

    // Triangle cost of the primitives above.
    static uint64_t tubeTriangles(uint32_t segments) { return 4ull * segments - 4; }
    static uint64_t sweepTriangles(uint64_t pathPoints, uint64_t sectionPoints, bool caps)
    {
        return 2 * sectionPoints * (pathPoints - 1) + (caps ? 2 * (sectionPoints - 2) : 0);
    }

  private:
    bool fits(uint64_t triangles);
    bool countOnly(uint64_t vertices, uint64_t triangles);
    uint32_t vertex(glm::vec3 p);
    void triangle(uint32_t a, uint32_t b, uint32_t c);

    float* positions_ = nullptr;
    uint32_t* indices_ = nullptr;
    uint64_t vertexBase_ = 0;
    uint64_t limit_ = 0;
    uint64_t vertices_ = 0;
    uint64_t triangles_ = 0;
    bool truncated_ = false;
    std::vector<glm::vec2> sectionScratch_;
    std::vector<glm::vec2> trigScratch_;
    std::vector<glm::vec3> pathScratch_;
};

} // namespace penumbra::detail
