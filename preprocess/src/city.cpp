// "city": a game-like city of street blocks standing in for the City model of
// Lauterbach et al. 2009. Each block (one unit, added in square rings around the origin
// as the budget grows) holds setback buildings with pilasters, window ledges, parapets and
// roof equipment, plus the thin geometry shadow maps miss: street-light poles (8 cm),
// cables strung between them (1.6 cm) and railings with 2 cm bars.
#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

#include "generate_internal.h"

namespace penumbra::detail {

namespace {

constexpr float kBlockPitch = 80.0f;   // block + street, metres
constexpr float kBlockHalf = 32.0f;    // building area half size
constexpr float kSidewalkHalf = 35.0f; // sidewalk slab half size
constexpr float kSidewalkTop = 0.15f;
constexpr float kFurnitureLine = 34.4f; // poles and railings, distance from block centre
constexpr float kFloorHeight = 3.5f;
constexpr float kPoleRadius = 0.04f;
constexpr float kPoleHeight = 7.0f;
constexpr float kPoleSpacing = 17.0f;
constexpr float kCableRadius = 0.008f;
constexpr float kBarSize = 0.02f;
constexpr float kBarSpacing = 0.12f;

// Facade decoration and setbacks of one building on footprint [lo, hi] (x, z).
void building(MeshBuilder& b, Rng& rng, glm::vec2 lo, glm::vec2 hi)
{
    const float height = 9.0f + 55.0f * rng.uniform() * rng.uniform() + (rng.chance(0.08f) ? 40.0f : 0.0f);
    const int tiers = 1 + int(rng.below(3));
    float y0 = 0.0f;
    for (int tier = 0; tier < tiers; ++tier) {
        const bool top = tier == tiers - 1;
        const float y1 = top ? height : y0 + (height - y0) * rng.uniform(0.45f, 0.75f);
        b.box({lo.x, y0, lo.y}, {hi.x, y1, hi.y});

        // Window ledges on every floor, all four facades.
        for (float y = y0 + kFloorHeight; y < y1 - 1.0f; y += kFloorHeight) {
            b.box({lo.x - 0.25f, y, lo.y - 0.25f}, {hi.x + 0.25f, y + 0.12f, lo.y});
            b.box({lo.x - 0.25f, y, hi.y}, {hi.x + 0.25f, y + 0.12f, hi.y + 0.25f});
            b.box({lo.x - 0.25f, y, lo.y}, {lo.x, y + 0.12f, hi.y});
            b.box({hi.x, y, lo.y}, {hi.x + 0.25f, y + 0.12f, hi.y});
        }
        // Pilasters on the lowest tier.
        if (tier == 0) {
            const int alongX = std::max(1, int((hi.x - lo.x) / 4.5f)), alongZ = std::max(1, int((hi.y - lo.y) / 4.5f));
            for (int i = 0; i <= alongX; ++i) {
                float x = lo.x + (hi.x - lo.x) * float(i) / float(alongX);
                b.box({x - 0.18f, y0, lo.y - 0.3f}, {x + 0.18f, y1, lo.y});
                b.box({x - 0.18f, y0, hi.y}, {x + 0.18f, y1, hi.y + 0.3f});
            }
            for (int i = 1; i < alongZ; ++i) {
                float z = lo.y + (hi.y - lo.y) * float(i) / float(alongZ);
                b.box({lo.x - 0.3f, y0, z - 0.18f}, {lo.x, y1, z + 0.18f});
                b.box({hi.x, y0, z - 0.18f}, {hi.x + 0.3f, y1, z + 0.18f});
            }
        }
        y0 = y1;
        if (!top) {
            const float setback = rng.uniform(1.5f, 4.0f);
            if (hi.x - lo.x < 2.0f * setback + 6.0f || hi.y - lo.y < 2.0f * setback + 6.0f)
                break;
            lo += setback;
            hi -= setback;
        }
    }

    // Roof: parapet, equipment boxes, sometimes a water tank on thin legs or a mast.
    const float roof = y0;
    b.box({lo.x, roof, lo.y}, {hi.x, roof + 1.0f, lo.y + 0.25f});
    b.box({lo.x, roof, hi.y - 0.25f}, {hi.x, roof + 1.0f, hi.y});
    b.box({lo.x, roof, lo.y + 0.25f}, {lo.x + 0.25f, roof + 1.0f, hi.y - 0.25f});
    b.box({hi.x - 0.25f, roof, lo.y + 0.25f}, {hi.x, roof + 1.0f, hi.y - 0.25f});
    const int units = 1 + int(rng.below(4));
    for (int i = 0; i < units; ++i) {
        glm::vec2 size(rng.uniform(1.5f, 4.0f), rng.uniform(1.5f, 4.0f));
        glm::vec2 at(rng.uniform(lo.x + 1.0f, std::max(lo.x + 1.0f, hi.x - 1.0f - size.x)),
                     rng.uniform(lo.y + 1.0f, std::max(lo.y + 1.0f, hi.y - 1.0f - size.y)));
        b.box({at.x, roof, at.y}, {at.x + size.x, roof + rng.uniform(1.0f, 2.5f), at.y + size.y});
    }
    const glm::vec2 centre = (lo + hi) * 0.5f;
    if (rng.chance(0.3f)) {
        const float legs = 3.0f, r = 1.6f;
        for (int i = 0; i < 4; ++i) {
            glm::vec2 o = centre + glm::vec2((i & 1) ? r : -r, (i & 2) ? r : -r) * 0.7f;
            b.tube({o.x, roof, o.y}, {o.x, roof + legs, o.y}, 0.05f, 6);
        }
        Frame f;
        f.origin = {centre.x, roof + legs, centre.y};
        const glm::vec2 profile[] = {{0.0f, 0.0f}, {r, 0.0f}, {r, 3.0f}, {r * 0.6f, 3.8f}, {0.0f, 4.0f}};
        b.lathe(f, profile, 16);
    } else if (rng.chance(0.4f)) {
        b.tube({centre.x, roof, centre.y}, {centre.x, roof + rng.uniform(4.0f, 9.0f), centre.y}, 0.03f, 6);
    }
}

// Street light with an arm and lamp head; returns the cable attachment point.
glm::vec3 streetLight(MeshBuilder& b, glm::vec3 foot, glm::vec3 towardStreet)
{
    const glm::vec3 top = foot + glm::vec3(0, kPoleHeight, 0);
    b.tube(foot, top, kPoleRadius, 6);
    const glm::vec3 armEnd = top + towardStreet * 1.6f - glm::vec3(0, 0.2f, 0);
    b.tube(top - glm::vec3(0, 0.3f, 0), armEnd, 0.025f, 5);
    b.beam(armEnd - towardStreet * 0.3f, armEnd + towardStreet * 0.3f, {0, 1, 0}, 0.25f, 0.12f);
    return top - glm::vec3(0, 0.15f, 0);
}

// Sagging cable between two attachment points.
void cable(MeshBuilder& b, glm::vec3 a, glm::vec3 c, float sag)
{
    constexpr int kPoints = 9;
    glm::vec3 path[kPoints];
    for (int i = 0; i < kPoints; ++i) {
        float t = float(i) / float(kPoints - 1);
        path[i] = a + (c - a) * t - glm::vec3(0, sag * 4.0f * t * (1.0f - t), 0);
    }
    b.pipe(path, kCableRadius, 4);
}

// Railing from a to c (horizontal) with posts, rails and thin vertical bars.
void railing(MeshBuilder& b, glm::vec3 a, glm::vec3 c)
{
    const glm::vec3 up(0, 1, 0);
    const float length = glm::length(c - a);
    const glm::vec3 dir = (c - a) / length;
    b.beam(a + up * 1.05f, c + up * 1.05f, up, 0.05f, 0.05f);
    b.beam(a + up * 0.15f, c + up * 0.15f, up, 0.03f, 0.03f);
    const int posts = std::max(1, int(length / 2.0f));
    for (int i = 0; i <= posts; ++i) {
        glm::vec3 p = a + dir * (length * float(i) / float(posts));
        b.box(p - glm::vec3(0.03f, 0, 0.03f), p + glm::vec3(0.03f, 1.08f, 0.03f));
    }
    const int bars = int(length / kBarSpacing);
    for (int i = 1; i < bars; ++i) {
        glm::vec3 p = a + dir * (kBarSpacing * float(i));
        b.box(p + glm::vec3(-kBarSize * 0.5f, 0.15f, -kBarSize * 0.5f),
              p + glm::vec3(kBarSize * 0.5f, 1.03f, kBarSize * 0.5f));
    }
}

void block(MeshBuilder& b, uint64_t seed, uint64_t unit)
{
    Rng rng(mixSeed(seed, unit));
    const glm::ivec2 cell = spiralCell(unit);
    const glm::vec2 c(float(cell.x) * kBlockPitch, float(cell.y) * kBlockPitch);

    b.box({c.x - kSidewalkHalf, 0.0f, c.y - kSidewalkHalf}, {c.x + kSidewalkHalf, kSidewalkTop, c.y + kSidewalkHalf});

    // Street furniture first so small budgets still show thin geometry.
    // Side s runs along 'along' at offset 'out' (outward normal) from the centre.
    const glm::vec3 centre(c.x, kSidewalkTop, c.y);
    for (int side = 0; side < 4; ++side) {
        const glm::vec3 out = side == 0   ? glm::vec3(0, 0, -1)
                              : side == 1 ? glm::vec3(1, 0, 0)
                              : side == 2 ? glm::vec3(0, 0, 1)
                                          : glm::vec3(-1, 0, 0);
        const glm::vec3 along = glm::cross(glm::vec3(0, 1, 0), out);
        const glm::vec3 start = centre + out * kFurnitureLine - along * kFurnitureLine;
        const int poles = int(2.0f * kFurnitureLine / kPoleSpacing);
        glm::vec3 previous{};
        for (int i = 0; i < poles; ++i) {
            glm::vec3 foot = start + along * (3.0f + kPoleSpacing * float(i));
            glm::vec3 attach = streetLight(b, foot, out);
            if (i > 0)
                cable(b, previous, attach, rng.uniform(0.2f, 0.6f));
            previous = attach;
        }
        if (rng.chance(0.6f)) {
            const float from = rng.uniform(6.0f, 30.0f), length = rng.uniform(8.0f, 30.0f);
            railing(b, start + along * from - out * 0.3f, start + along * std::min(from + length, 66.0f) - out * 0.3f);
        }
    }

    // Buildings: one tower over the whole block or up to four on 2 x 2 lots.
    if (rng.chance(0.3f)) {
        const float inset = rng.uniform(1.0f, 4.0f);
        building(b, rng, glm::vec2(c.x - kBlockHalf + inset, c.y - kBlockHalf + inset),
                 glm::vec2(c.x + kBlockHalf - inset, c.y + kBlockHalf - inset));
        return;
    }
    for (int lot = 0; lot < 4; ++lot) {
        if (rng.chance(0.12f))
            continue; // an empty lot (plaza)
        glm::vec2 lo(c.x - kBlockHalf + ((lot & 1) ? kBlockHalf : 0.0f),
                     c.y - kBlockHalf + ((lot & 2) ? kBlockHalf : 0.0f));
        glm::vec2 hi = lo + kBlockHalf;
        building(b, rng, lo + rng.uniform(0.8f, 3.0f), hi - rng.uniform(0.8f, 3.0f));
    }
}

} // namespace

Scene generateCity(const GenerateOptions& options)
{
    const uint64_t seed = options.seed;
    Scene scene;
    scene.mesh = buildUnits(
        "generate city", options.triangles, uint64_t(1) << 32,
        [seed](MeshBuilder& b, uint64_t unit) { block(b, seed, unit); },
        [](MeshBuilder& b, uint64_t units) {
            const float half = (float(spiralRadius(units)) + 0.5f) * kBlockPitch;
            b.fillGround(-half, -half, half, half, 0.0f);
        });

    // Street level in the street east of the first block, looking down it (-z).
    Camera camera;
    camera.position = {kBlockPitch * 0.5f, 1.7f, 30.0f};
    camera.target = {kBlockPitch * 0.5f, 6.0f, -200.0f};
    camera.yfovDegrees = 60.0f;
    scene.cameras.push_back(camera);

    Light sun;
    sun.type = LightType::Directional;
    sun.direction = glm::normalize(glm::vec3(0.3f, -0.72f, 0.62f)); // ~46 degrees elevation, slanting along the streets
    sun.intensity = 1.0f;
    scene.lights.push_back(sun);
    return scene;
}

} // namespace penumbra::detail
