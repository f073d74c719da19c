// "plant": a CAD-like process plant standing in for the Powerplant model of Lauterbach
// et al. 2009. Each 40 m module (one unit; modules are added in square rings around the
// origin until the budget is spent) holds a two- or three-level steel structure of
// I-beams with bar-grating floors and a stair, vertical and horizontal tanks, a tall stack
// and a bundle of pipes routed along axis-aligned legs with rounded bends and flanges.
// Tessellation rises with the budget (8, 12, then 16 sides per pipe).
#include <algorithm>
#include <cmath>
#include <vector>

#include <glm/geometric.hpp>

#include "generate_internal.h"

namespace penumbra::detail {

namespace {

constexpr float kPi = 3.14159265358979f;
constexpr float kModulePitch = 40.0f;
constexpr float kModuleHalf = 19.0f; // pipes stay inside the module
constexpr float kLevelHeight = 5.0f;
constexpr float kGratingPitch = 0.06f; // bearing bar spacing
constexpr float kGratingBar = 0.005f;  // bearing bar thickness
constexpr float kGratingDepth = 0.03f;

struct Detail {
    uint32_t pipeSides;
    uint32_t bendSteps;
};

// I-beam: two flanges and a web, 'up' is the web direction.
void iBeam(MeshBuilder& b, glm::vec3 from, glm::vec3 to, glm::vec3 up, float depth, float flange)
{
    const float t = std::max(0.012f, depth * 0.06f);
    glm::vec3 dir = glm::normalize(to - from);
    glm::vec3 u = glm::normalize(up - dir * glm::dot(dir, up));
    glm::vec3 o = u * (depth * 0.5f - t * 0.5f);
    b.beam(from + o, to + o, u, flange, t);
    b.beam(from - o, to - o, u, flange, t);
    b.beam(from, to, u, t, depth - 2.0f * t);
}

// Bar grating panel over [lo, hi] (x, z) at height y: bearing bars along x, cross bars along z.
void grating(MeshBuilder& b, glm::vec2 lo, glm::vec2 hi, float y)
{
    const glm::vec3 up(0, 1, 0);
    const int bars = int((hi.y - lo.y) / kGratingPitch);
    for (int i = 0; i <= bars; ++i) {
        float z = lo.y + (hi.y - lo.y) * float(i) / float(bars);
        b.beam({lo.x, y - kGratingDepth * 0.5f, z}, {hi.x, y - kGratingDepth * 0.5f, z}, up, kGratingBar,
               kGratingDepth);
    }
    const int cross = std::max(1, int((hi.x - lo.x) / 1.0f));
    for (int i = 0; i <= cross; ++i) {
        float x = lo.x + (hi.x - lo.x) * float(i) / float(cross);
        b.beam({x, y - 0.01f, lo.y}, {x, y - 0.01f, hi.y}, up, 0.006f, 0.02f);
    }
}

void stair(MeshBuilder& b, glm::vec3 foot, glm::vec3 dir, float rise, const Detail& d)
{
    const glm::vec3 up(0, 1, 0);
    const glm::vec3 side = glm::cross(dir, up) * 0.5f;
    const float run = rise * 0.8f;
    const glm::vec3 top = foot + dir * run + up * rise;
    b.beam(foot + side, top + side, side, 0.02f, 0.25f);
    b.beam(foot - side, top - side, side, 0.02f, 0.25f);
    const int steps = int(rise / 0.2f);
    for (int i = 1; i < steps; ++i) {
        float t = float(i) / float(steps);
        glm::vec3 p = foot + (top - foot) * t;
        b.beam(p - side, p + side, dir, 0.22f, 0.03f);
    }
    const glm::vec3 rail(0, 1.0f, 0);
    b.tube(foot + side * 1.05f + rail, top + side * 1.05f + rail, 0.025f, d.pipeSides / 2 + 2);
    b.tube(foot - side * 1.05f + rail, top - side * 1.05f + rail, 0.025f, d.pipeSides / 2 + 2);
    for (int i = 0; i <= 4; ++i) {
        glm::vec3 p = foot + (top - foot) * (float(i) / 4.0f);
        b.tube(p + side * 1.05f, p + side * 1.05f + rail, 0.02f, 4);
        b.tube(p - side * 1.05f, p - side * 1.05f + rail, 0.02f, 4);
    }
}

// Vertical tank with a domed roof on a short skirt.
void verticalTank(MeshBuilder& b, glm::vec3 base, float radius, float height, const Detail& d)
{
    std::vector<glm::vec2> profile = {{0.0f, 0.0f}, {radius + 0.1f, 0.0f}, {radius + 0.1f, 0.4f}, {radius, 0.4f}};
    const uint32_t domeSteps = std::max(2u, d.pipeSides / 2);
    for (uint32_t i = 0; i <= domeSteps; ++i) {
        float a = 0.5f * kPi * float(i) / float(domeSteps);
        profile.push_back({radius * std::cos(a), height + radius * 0.45f * std::sin(a)});
    }
    profile.back().x = 0.0f;
    Frame f;
    f.origin = base;
    b.lathe(f, profile, d.pipeSides * 2);
    // Ring platform around the top and a ladder.
    b.tube(base + glm::vec3(radius + 0.3f, 0.0f, 0.0f), base + glm::vec3(radius + 0.3f, height + 1.0f, 0.0f), 0.02f, 4);
    b.tube(base + glm::vec3(radius + 0.3f, 0.0f, 0.4f), base + glm::vec3(radius + 0.3f, height + 1.0f, 0.4f), 0.02f, 4);
    for (float y = 0.3f; y < height + 1.0f; y += 0.3f)
        b.tube(base + glm::vec3(radius + 0.3f, y, 0.0f), base + glm::vec3(radius + 0.3f, y, 0.4f), 0.012f, 4);
}

// Horizontal bullet tank along x on two saddles.
void horizontalTank(MeshBuilder& b, glm::vec3 centre, float radius, float length, const Detail& d)
{
    std::vector<glm::vec2> profile;
    const uint32_t capSteps = std::max(2u, d.pipeSides / 2);
    for (uint32_t i = 0; i <= capSteps; ++i) {
        float a = 0.5f * kPi * float(i) / float(capSteps);
        profile.push_back({radius * std::sin(a), -length * 0.5f - radius * 0.5f * std::cos(a)});
    }
    for (uint32_t i = 0; i <= capSteps; ++i) {
        float a = 0.5f * kPi * float(i) / float(capSteps);
        profile.push_back({radius * std::cos(a), length * 0.5f + radius * 0.5f * std::sin(a)});
    }
    Frame f;
    f.origin = centre;
    f.x = {0, 1, 0};
    f.y = {1, 0, 0};
    f.z = {0, 0, -1};
    b.lathe(f, profile, d.pipeSides * 2);
    for (int s = -1; s <= 1; s += 2) {
        glm::vec3 p = centre + glm::vec3(float(s) * length * 0.3f, 0, 0);
        b.box({p.x - 0.3f, 0.0f, p.z - radius * 0.8f}, {p.x + 0.3f, centre.y - radius * 0.6f, p.z + radius * 0.8f});
    }
}

// Pipe along axis-aligned legs with rounded bends; flanges at both ends.
void routedPipe(MeshBuilder& b, Rng& rng, glm::vec3 origin, glm::vec3 start, float radius, const Detail& d,
                std::vector<glm::vec3>& corners, std::vector<glm::vec3>& path)
{
    corners.clear();
    corners.push_back(start);
    const int legs = 3 + int(rng.below(4));
    int axis = int(rng.below(3));
    glm::vec3 p = start;
    for (int leg = 0; leg < legs; ++leg) {
        axis = (axis + 1 + int(rng.below(2))) % 3;
        float length = rng.uniform(2.0f, 14.0f) * (rng.chance(0.5f) ? 1.0f : -1.0f);
        glm::vec3 q = p;
        q[axis] += length;
        const float lo = origin[axis] + (axis == 1 ? 0.6f : -kModuleHalf);
        const float hi = origin[axis] + (axis == 1 ? 18.0f : kModuleHalf);
        if (q[axis] < lo || q[axis] > hi)
            q[axis] = p[axis] - length;
        q[axis] = std::clamp(q[axis], lo, hi);
        if (std::abs(q[axis] - p[axis]) < 1.5f)
            continue;
        corners.push_back(q);
        p = q;
    }
    if (corners.size() < 2)
        return;
    // Fillet every corner with a quarter arc.
    path.clear();
    path.push_back(corners[0]);
    for (size_t i = 1; i + 1 < corners.size(); ++i) {
        const glm::vec3 a = corners[i - 1], c = corners[i], e = corners[i + 1];
        const float in = glm::length(c - a), out = glm::length(e - c);
        const glm::vec3 d0 = (c - a) / in, d1 = (e - c) / out;
        if (std::abs(glm::dot(d0, d1)) > 0.01f) { // straight on or reversal: no bend
            path.push_back(c);
            continue;
        }
        const float r = std::min({std::max(radius * 3.0f, 0.3f), in * 0.4f, out * 0.4f});
        const glm::vec3 centre = c - d0 * r + d1 * r;
        for (uint32_t s = 0; s <= d.bendSteps; ++s) {
            float t = 0.5f * kPi * float(s) / float(d.bendSteps);
            path.push_back(centre - d1 * (r * std::cos(t)) + d0 * (r * std::sin(t)));
        }
    }
    path.push_back(corners.back());
    b.pipe(path, radius, d.pipeSides);
    const glm::vec3 first = glm::normalize(path[1] - path[0]);
    const glm::vec3 last = glm::normalize(path[path.size() - 1] - path[path.size() - 2]);
    b.tube(path.front(), path.front() + first * 0.08f, radius * 1.5f, d.pipeSides);
    b.tube(path.back() - last * 0.08f, path.back(), radius * 1.5f, d.pipeSides);
}

void plantModule(MeshBuilder& b, uint64_t seed, uint64_t unit, const Detail& d)
{
    Rng rng(mixSeed(seed, unit));
    const glm::ivec2 cell = spiralCell(unit);
    const glm::vec3 o(float(cell.x) * kModulePitch, 0.0f, float(cell.y) * kModulePitch);
    const glm::vec3 up(0, 1, 0), xAxis(1, 0, 0), zAxis(0, 0, 1);
    std::vector<glm::vec3> corners, path;

    // Stack: tall, thin, casts the longest shadow.
    {
        const float height = rng.uniform(25.0f, 45.0f), r = rng.uniform(0.8f, 1.4f);
        const glm::vec2 profile[] = {
            {0.0f, 0.0f},        {r * 1.4f, 0.0f},           {r * 1.4f, 1.0f},         {r, 1.5f},
            {r * 0.75f, height}, {r * 0.85f, height + 0.3f}, {r * 0.7f, height + 0.3f}};
        Frame f;
        f.origin = o + glm::vec3(rng.uniform(8.0f, 14.0f), 0.0f, rng.uniform(8.0f, 14.0f));
        b.lathe(f, profile, d.pipeSides * 2);
    }

    // Steel structure over [-18, -2]^2 with 2 or 3 levels.
    const int levels = 2 + int(rng.below(2));
    const float lo = -18.0f, span = 8.0f;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            glm::vec3 foot = o + glm::vec3(lo + span * float(i), 0.0f, lo + span * float(j));
            iBeam(b, foot, foot + up * (kLevelHeight * float(levels) + 1.0f), xAxis, 0.35f, 0.25f);
        }
    for (int level = 1; level <= levels; ++level) {
        const float y = kLevelHeight * float(level);
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 2; ++j) {
                glm::vec3 a = o + glm::vec3(lo + span * float(i), y, lo + span * float(j));
                iBeam(b, a, a + zAxis * span, up, 0.4f, 0.2f);
                glm::vec3 c = o + glm::vec3(lo + span * float(j), y, lo + span * float(i));
                iBeam(b, c, c + xAxis * span, up, 0.4f, 0.2f);
            }
        for (int i = 0; i < 2; ++i)
            for (int j = 0; j < 2; ++j) {
                if (rng.chance(0.15f))
                    continue; // open bay
                glm::vec2 pmin(o.x + lo + span * float(i) + 0.1f, o.z + lo + span * float(j) + 0.1f);
                grating(b, pmin, pmin + glm::vec2(span - 0.2f), y + 0.2f);
            }
        // Handrail around the level edge.
        const float edge = lo + 2.0f * span;
        const glm::vec3 c0 = o + glm::vec3(lo, y + 1.2f, lo), c1 = o + glm::vec3(edge, y + 1.2f, lo),
                        c2 = o + glm::vec3(edge, y + 1.2f, edge), c3 = o + glm::vec3(lo, y + 1.2f, edge);
        b.tube(c0, c1, 0.025f, 6);
        b.tube(c1, c2, 0.025f, 6);
        b.tube(c2, c3, 0.025f, 6);
        b.tube(c3, c0, 0.025f, 6);
    }
    stair(b, o + glm::vec3(-1.0f, 0.0f, -17.0f), zAxis, kLevelHeight + 0.2f, d);

    // Tanks.
    const int vertical = 1 + int(rng.below(3));
    for (int i = 0; i < vertical; ++i) {
        const float r = rng.uniform(1.5f, 3.0f);
        verticalTank(b, o + glm::vec3(3.0f + r + 7.0f * float(i), 0.0f, rng.uniform(-17.0f, -13.0f) + r), r,
                     rng.uniform(5.0f, 12.0f), d);
    }
    const int horizontal = 1 + int(rng.below(2));
    for (int i = 0; i < horizontal; ++i) {
        const float r = rng.uniform(1.0f, 1.8f);
        horizontalTank(b, o + glm::vec3(-10.0f, r + 0.8f, 4.0f + 6.0f * float(i)), r, rng.uniform(6.0f, 12.0f), d);
    }

    // Pipe rack along the module's +z edge and the pipes.
    for (int i = 0; i <= 4; ++i) {
        glm::vec3 foot = o + glm::vec3(-18.0f + 9.0f * float(i), 0.0f, 17.0f);
        iBeam(b, foot, foot + up * 7.0f, xAxis, 0.3f, 0.2f);
        iBeam(b, foot + up * 7.0f - zAxis * 1.5f, foot + up * 7.0f + zAxis * 1.5f, up, 0.3f, 0.15f);
    }
    const int pipes = 14 + int(rng.below(10));
    for (int i = 0; i < pipes; ++i) {
        const float u = rng.uniform();
        const float radius = u < 0.6f   ? rng.uniform(0.04f, 0.12f)
                             : u < 0.9f ? rng.uniform(0.12f, 0.3f)
                                        : rng.uniform(0.3f, 0.6f);
        glm::vec3 start = o + glm::vec3(rng.uniform(-kModuleHalf, kModuleHalf), rng.uniform(0.8f, 15.0f),
                                        rng.uniform(-kModuleHalf, kModuleHalf));
        routedPipe(b, rng, o, start, radius, d, corners, path);
    }
}

} // namespace

Scene generatePlant(const GenerateOptions& options)
{
    const uint64_t budget = options.triangles, seed = options.seed;
    Detail detail;
    detail.pipeSides = budget < 200'000 ? 8 : budget < 5'000'000 ? 12 : 16;
    detail.bendSteps = budget < 200'000 ? 3 : 5;

    Scene scene;
    scene.mesh = buildUnits(
        "generate plant", budget, uint64_t(1) << 32,
        [&](MeshBuilder& b, uint64_t unit) { plantModule(b, seed, unit, detail); },
        [](MeshBuilder& b, uint64_t units) {
            const float half = (float(spiralRadius(units)) + 0.5f) * kModulePitch;
            b.fillGround(-half, -half, half, half, 0.0f);
        });

    Camera camera;
    camera.position = {-45.0f, 32.0f, -55.0f};
    camera.target = {0.0f, 6.0f, 0.0f};
    camera.yfovDegrees = 50.0f;
    scene.cameras.push_back(camera);

    Light sun;
    sun.type = LightType::Directional;
    sun.direction = glm::normalize(glm::vec3(-0.55f, -0.45f, 0.4f)); // ~27 degrees elevation
    sun.intensity = 1.0f;
    scene.lights.push_back(sun);
    return scene;
}

} // namespace penumbra::detail
