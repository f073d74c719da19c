// Dispatch for the procedural benchmark scenes and the unit-parallel build driver.
// The scenes stand in for the models of Lauterbach et al. 2009, "Fast Hard and Soft
// Shadow Generation on Complex Models using Selective Ray Tracing" (City, Sibenik,
// Powerplant, scanned statues), which cannot be shipped with the project.
#include "penumbra/generate.h"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <vector>

#include "generate_internal.h"
#include "penumbra/error.h"
#include "penumbra/parallel.h"

namespace penumbra {

namespace detail {

int spiralRadius(uint64_t count)
{
    if (count <= 1)
        return 0;
    uint64_t last = count - 1;
    uint64_t root = uint64_t(std::sqrt(double(last)));
    while (root * root > last)
        --root;
    while ((root + 1) * (root + 1) <= last)
        ++root;
    return int((root + 1) / 2);
}

glm::ivec2 spiralCell(uint64_t index)
{
    if (index == 0)
        return {0, 0};
    const int r = spiralRadius(index + 1);
    const uint64_t p = index - uint64_t(2 * r - 1) * uint64_t(2 * r - 1);
    const int side = int(p / uint64_t(2 * r)), offset = int(p % uint64_t(2 * r));
    switch (side) {
    case 0:
        return {r, -r + 1 + offset};
    case 1:
        return {r - 1 - offset, r};
    case 2:
        return {-r, r - 1 - offset};
    default:
        return {-r + 1 + offset, -r};
    }
}

Mesh buildUnits(const std::string& subject, uint64_t triangleBudget, uint64_t maxUnits, const UnitBuild& buildUnit,
                const FinishBuild& finish)
{
    struct Plan {
        uint64_t vertexOffset, triangleOffset, triangleLimit, vertices, triangles;
    };
    constexpr uint64_t kFinishReserve = 2; // the finish always gets at least one quad
    constexpr uint64_t kMinUnitRoom = 12;  // stop adding units once less than a box is left

    // Step 1: count units in order until the budget is spent.
    std::vector<Plan> plans;
    uint64_t vertices = 0, triangles = 0;
    const uint64_t unitBudget = triangleBudget > kFinishReserve ? triangleBudget - kFinishReserve : 0;
    for (uint64_t unit = 0; unit < maxUnits && unitBudget - triangles >= kMinUnitRoom; ++unit) {
        MeshBuilder counter(unitBudget - triangles);
        buildUnit(counter, unit);
        if (counter.triangles() == 0)
            break;
        plans.push_back({vertices, triangles, unitBudget - triangles, counter.vertices(), counter.triangles()});
        vertices += counter.vertices();
        triangles += counter.triangles();
        if (counter.truncated())
            break;
    }
    const uint64_t unitCount = plans.size();
    MeshBuilder finishCounter(triangleBudget - triangles);
    finish(finishCounter, unitCount);
    const Plan finishPlan{vertices, triangles, triangleBudget - triangles, finishCounter.vertices(),
                          finishCounter.triangles()};
    vertices += finishPlan.vertices;
    triangles += finishPlan.triangles;
    if (vertices >= (uint64_t(1) << 32))
        fail(subject, "too many vertices for 32-bit indices");

    // Step 2: allocate exactly and emit in parallel at the planned offsets.
    Mesh mesh;
    mesh.positions.resize(vertices * 3);
    mesh.indices.resize(triangles * 3);
    std::atomic<bool> mismatch{false};
    auto emit = [&](const Plan& plan, auto&& build) {
        MeshBuilder builder(mesh.positions.data(), mesh.indices.data(), plan.vertexOffset, plan.triangleOffset,
                            plan.triangleLimit);
        build(builder);
        if (builder.vertices() != plan.vertices || builder.triangles() != plan.triangles)
            mismatch = true;
    };
    parallelFor(0, unitCount + 1, [&](uint64_t unit) {
        if (unit < unitCount)
            emit(plans[unit], [&](MeshBuilder& b) { buildUnit(b, unit); });
        else
            emit(finishPlan, [&](MeshBuilder& b) { finish(b, unitCount); });
    });
    if (mismatch)
        fail(subject, "internal error: emitted geometry differs from the counted plan");
    return mesh;
}

} // namespace detail

namespace {

struct Generator {
    const char* name;
    uint64_t minTriangles;
    uint64_t maxTriangles;
    Scene (*build)(const GenerateOptions&);
};

// Upper limits keep 32-bit indices valid and the mesh within ~24 GB (see README.md).
const Generator kGenerators[] = {
    {"city", 1'000, 200'000'000, detail::generateCity},
    {"interior", 1'000, 100'000'000, detail::generateInterior},
    {"plant", 1'000, 1'200'000'000, detail::generatePlant},
    {"scan", 1'000, 1'300'000'000, detail::generateScan},
};

} // namespace

std::vector<std::string> generatorNames()
{
    std::vector<std::string> names;
    for (const Generator& g : kGenerators)
        names.push_back(g.name);
    return names;
}

bool writeSceneStreamed(const std::string& name, const GenerateOptions& options, const std::string& path, bool binary,
                        uint64_t* triangles, uint64_t* vertices)
{
    std::string extension = path.size() >= 4 ? path.substr(path.size() - 4) : "";
    for (char& c : extension)
        c = char(std::tolower(static_cast<unsigned char>(c)));
    if (name != "scan" || !binary || extension != ".ply")
        return false;
    if (options.triangles < 1'000 || options.triangles > detail::scanStreamingLimit())
        fail("generate " + name, "triangle budget " + std::to_string(options.triangles) + " is outside [1000, " +
                                     std::to_string(detail::scanStreamingLimit()) + "] (streamed binary PLY)");
    uint64_t t = 0, v = 0;
    detail::writeScanPly(options, path, t, v);
    if (triangles)
        *triangles = t;
    if (vertices)
        *vertices = v;
    return true;
}

Scene generateScene(const std::string& name, const GenerateOptions& options)
{
    for (const Generator& g : kGenerators) {
        if (name != g.name)
            continue;
        if (options.triangles < g.minTriangles || options.triangles > g.maxTriangles)
            fail("generate " + name, "triangle budget " + std::to_string(options.triangles) + " is outside [" +
                                         std::to_string(g.minTriangles) + ", " + std::to_string(g.maxTriangles) + "]");
        return g.build(options);
    }
    fail("generate " + name, "unknown scene name (expected city, interior, plant or scan)");
}

} // namespace penumbra
