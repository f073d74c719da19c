// "interior": a church nave standing in for the Sibenik cathedral of Lauterbach et al.
// 2009. Nave along +z: stone floor, thick side walls with real window openings (with a
// mullion), two arcades of columns carrying round arches, transverse arches, a barrel
// vault with ribs, and end walls with a door and a rose opening. The number of bays grows
// with the square root of the budget; the tessellation of every curved part is then
// chosen (binary search over a counting pass) to spend the rest.
#include <algorithm>
#include <cmath>
#include <vector>

#include <glm/geometric.hpp>

#include "generate_internal.h"

namespace penumbra::detail {

namespace {

constexpr float kPi = 3.14159265358979f;
constexpr float kBay = 6.0f;   // bay length along z
constexpr float kWallX = 7.5f; // inner face of the side walls
constexpr float kWallThickness = 1.0f;
constexpr float kWallHeight = 14.0f;  // vault springing line
constexpr float kColumnX = 4.0f;      // arcade column rows
constexpr float kColumnHeight = 7.5f; // arch springing line
constexpr float kSillHeight = 5.5f;
constexpr float kWindowTop = 11.0f;
constexpr float kWindowWidth = 3.0f;

struct Layout {
    uint32_t bays;
    uint32_t segments; // circle / arc tessellation
};

// Points on a circular arc in the plane spanned by u (horizontal) and up.
void arcPath(const MeshBuilder& b, std::vector<glm::vec3>& path, glm::vec3 centre, glm::vec3 u, float radius,
             uint32_t segments)
{
    path.resize(segments + 1);
    if (b.counting())
        return; // only the point count matters
    for (uint32_t i = 0; i <= segments; ++i) {
        float a = kPi * float(i) / float(segments);
        path[i] = centre + u * (radius * std::cos(a)) + glm::vec3(0, radius * std::sin(a), 0);
    }
}

void nave(MeshBuilder& b, const Layout& layout, uint64_t seed)
{
    Rng rng(mixSeed(seed, 0x1e7));
    const float length = float(layout.bays) * kBay;
    const uint32_t s = layout.segments;
    std::vector<glm::vec3> path;

    // Side walls, per bay: solid below the sill, piers and a mullion beside the window, solid above.
    for (int side = -1; side <= 1; side += 2) {
        const float x0 = side < 0 ? -kWallX - kWallThickness : kWallX, x1 = x0 + kWallThickness;
        for (uint32_t bay = 0; bay < layout.bays; ++bay) {
            const float z0 = float(bay) * kBay, z1 = z0 + kBay, zc = (z0 + z1) * 0.5f;
            const float w = kWindowWidth * 0.5f;
            b.box({x0, 0.0f, z0}, {x1, kSillHeight, z1});
            b.box({x0, kSillHeight, z0}, {x1, kWindowTop, zc - w});
            b.box({x0, kSillHeight, zc + w}, {x1, kWindowTop, z1});
            b.box({x0, kWindowTop, z0}, {x1, kWallHeight, z1});
            b.box({x0 + 0.3f, kSillHeight, zc - 0.06f}, {x0 + 0.45f, kWindowTop, zc + 0.06f});
            b.box({x0 + 0.3f, 8.2f, zc - w}, {x0 + 0.45f, 8.32f, zc + w});
        }
    }
    // End walls: a door at z = 0, a square rose opening at the far end.
    const float outer = kWallX + kWallThickness;
    for (int end = 0; end < 2; ++end) {
        const float z0 = end == 0 ? -kWallThickness : length, z1 = z0 + kWallThickness;
        const float holeLo = end == 0 ? 0.0f : 7.5f, holeHi = end == 0 ? 4.5f : 12.0f, holeW = end == 0 ? 1.5f : 2.5f;
        b.box({-outer, 0.0f, z0}, {-holeW, kWallHeight + kWallX, z1});
        b.box({holeW, 0.0f, z0}, {outer, kWallHeight + kWallX, z1});
        if (holeLo > 0.0f)
            b.box({-holeW, 0.0f, z0}, {holeW, holeLo, z1});
        b.box({-holeW, holeHi, z0}, {holeW, kWallHeight + kWallX, z1});
    }

    // Columns at every bay boundary: plinth, base moulding, shaft, capital, abacus.
    const float shaft = rng.uniform(0.38f, 0.5f);
    const glm::vec2 column[] = {{0.0f, 0.0f},
                                {shaft + 0.3f, 0.0f},
                                {shaft + 0.3f, 0.4f},
                                {shaft + 0.12f, 0.55f},
                                {shaft, 0.7f},
                                {shaft, kColumnHeight - 1.0f},
                                {shaft + 0.08f, kColumnHeight - 0.9f},
                                {shaft + 0.3f, kColumnHeight - 0.3f},
                                {shaft + 0.35f, kColumnHeight - 0.3f},
                                {shaft + 0.35f, kColumnHeight},
                                {0.0f, kColumnHeight}};
    for (uint32_t i = 0; i <= layout.bays; ++i)
        for (int side = -1; side <= 1; side += 2) {
            Frame f;
            f.origin = {float(side) * kColumnX, 0.0f, float(i) * kBay};
            b.lathe(f, column, std::max(3u, s));
        }

    // Arches: rectangular sections swept along half circles.
    const glm::vec2 arcade[] = {{-0.35f, -0.4f}, {0.35f, -0.4f}, {0.35f, 0.4f}, {-0.35f, 0.4f}};
    const glm::vec2 rib[] = {{-0.25f, -0.3f}, {0.25f, -0.3f}, {0.25f, 0.3f}, {-0.25f, 0.3f}};
    const uint32_t arcSegments = std::max(2u, s / 2);
    for (uint32_t i = 0; i < layout.bays; ++i)
        for (int side = -1; side <= 1; side += 2) {
            arcPath(b, path, {float(side) * kColumnX, kColumnHeight, (float(i) + 0.5f) * kBay}, {0, 0, 1}, kBay * 0.5f,
                    arcSegments);
            b.sweep(path, arcade, {1, 0, 0}, true);
        }
    for (uint32_t i = 0; i <= layout.bays; ++i) {
        arcPath(b, path, {0.0f, kColumnHeight, float(i) * kBay}, {1, 0, 0}, kColumnX, arcSegments);
        b.sweep(path, arcade, {0, 0, 1}, true);
        arcPath(b, path, {0.0f, kWallHeight, float(i) * kBay}, {1, 0, 0}, kWallX - 0.3f, arcSegments);
        b.sweep(path, rib, {0, 0, 1}, true);
    }

    // Barrel vault, one segment per bay (normal along z, binormal radial).
    const glm::vec2 shell[] = {{-kBay * 0.5f, -0.2f}, {kBay * 0.5f, -0.2f}, {kBay * 0.5f, 0.2f}, {-kBay * 0.5f, 0.2f}};
    for (uint32_t i = 0; i < layout.bays; ++i) {
        arcPath(b, path, {0.0f, kWallHeight, (float(i) + 0.5f) * kBay}, {1, 0, 0}, kWallX + 0.2f, std::max(2u, s));
        b.sweep(path, shell, {0, 0, 1}, true);
    }
}

uint64_t countNave(const Layout& layout, uint64_t seed)
{
    MeshBuilder counter(~uint64_t(0));
    nave(counter, layout, seed);
    return counter.triangles();
}

} // namespace

Scene generateInterior(const GenerateOptions& options)
{
    const uint64_t budget = options.triangles, seed = options.seed;
    // Bays grow with sqrt(budget); then the largest tessellation that leaves >= 2% for the floor.
    Layout layout;
    layout.bays = uint32_t(std::clamp(std::sqrt(double(budget) / 2500.0), 1.0, 40.0));
    layout.segments = 3;
    const uint64_t target = budget - budget / 50;
    while (layout.bays > 1 && countNave(layout, seed) > target)
        --layout.bays;
    uint32_t lo = 3, hi = uint32_t(std::clamp<uint64_t>(budget / (16ull * layout.bays), 3, 1u << 20));
    while (lo < hi) {
        const uint32_t mid = lo + (hi - lo + 1) / 2;
        if (countNave({layout.bays, mid}, seed) <= target)
            lo = mid;
        else
            hi = mid - 1;
    }
    layout.segments = lo;
    const float length = float(layout.bays) * kBay;

    Scene scene;
    scene.mesh = buildUnits(
        "generate interior", budget, 1, [&](MeshBuilder& b, uint64_t) { nave(b, layout, seed); },
        [&](MeshBuilder& b, uint64_t) {
            b.fillGround(-kWallX - kWallThickness, -kWallThickness, kWallX + kWallThickness, length + kWallThickness,
                         0.0f);
        });

    Camera camera;
    camera.position = {-1.5f, 1.7f, 1.0f};
    camera.target = {0.5f, 6.0f, length};
    camera.yfovDegrees = 65.0f;
    scene.cameras.push_back(camera);

    // Low sun from +x: enters the +x windows and falls across the floor and columns.
    Light sun;
    sun.type = LightType::Directional;
    sun.direction = glm::normalize(glm::vec3(-0.62f, -0.5f, 0.3f));
    sun.intensity = 1.0f;
    scene.lights.push_back(sun);
    return scene;
}

} // namespace penumbra::detail
