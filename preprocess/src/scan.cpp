// "scan": a dense, closed, lumpy surface standing on a ground quad, standing in for
// the scanned statues of Lauterbach et al. 2009. A cube-sphere (six n x n grids that
// share their seam vertices, so the surface is watertight) is pushed out along the
// sphere direction by multi-octave gradient noise and cut flat where it meets the ground.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "generate_internal.h"
#include "penumbra/error.h"
#include "penumbra/parallel.h"
#include "penumbra/file_io.h"

namespace penumbra::detail {

namespace {

constexpr float kHalfHeight = 1.0f;    // statue half height before displacement, metres
constexpr float kCentreY = 0.8f;       // statue centre above the ground
constexpr float kBaseCutY = -0.02f;    // anything lower is flattened just under the ground
constexpr float kDisplacement = 0.30f; // relative radius change at noise amplitude 1
constexpr int kOctaves = 6;
constexpr float kGroundHalfSize = 3.0f;
// The streaming writer keeps vertex indices in 32 bits: 6 n^2 + 2 < 2^32.
constexpr uint64_t kScanStreamingLimit = 8'000'000'000ull;

uint32_t hash3(int x, int y, int z, uint32_t seed)
{
    uint32_t h = seed ^ (uint32_t(x) * 0x8da6b343u) ^ (uint32_t(y) * 0xd8163841u) ^ (uint32_t(z) * 0xcb1ab31fu);
    h ^= h >> 16;
    h *= 0x7feb352du;
    h ^= h >> 15;
    h *= 0x846ca68bu;
    h ^= h >> 16;
    return h;
}

float gradient(uint32_t h, float x, float y, float z)
{
    switch (h & 15u) { // the 12 cube edge directions (Perlin 2002), 4 repeated
    case 0:
        return x + y;
    case 1:
        return -x + y;
    case 2:
        return x - y;
    case 3:
        return -x - y;
    case 4:
        return x + z;
    case 5:
        return -x + z;
    case 6:
        return x - z;
    case 7:
        return -x - z;
    case 8:
        return y + z;
    case 9:
        return -y + z;
    case 10:
        return y - z;
    case 11:
        return -y - z;
    case 12:
        return x + y;
    case 13:
        return -y + z;
    case 14:
        return -x + y;
    default:
        return -y - z;
    }
}

float fade(float t)
{
    return t * t * t * (t * (t * 6.0f - 15.0f) + 10.0f);
}
float lerp(float a, float b, float t)
{
    return a + (b - a) * t;
}

// Gradient noise in about [-1, 1].
float gradientNoise(glm::vec3 p, uint32_t seed)
{
    const float fx = std::floor(p.x), fy = std::floor(p.y), fz = std::floor(p.z);
    const int x = int(fx), y = int(fy), z = int(fz);
    const float dx = p.x - fx, dy = p.y - fy, dz = p.z - fz;
    const float u = fade(dx), v = fade(dy), w = fade(dz);
    auto g = [&](int ox, int oy, int oz) {
        return gradient(hash3(x + ox, y + oy, z + oz, seed), dx - float(ox), dy - float(oy), dz - float(oz));
    };
    return lerp(lerp(lerp(g(0, 0, 0), g(1, 0, 0), u), lerp(g(0, 1, 0), g(1, 1, 0), u), v),
                lerp(lerp(g(0, 0, 1), g(1, 0, 1), u), lerp(g(0, 1, 1), g(1, 1, 1), u), v), w);
}

// Fractal sum; low octaves shape the body, high ones add the scan-like roughness.
float fbm(glm::vec3 p, uint32_t seed)
{
    float sum = 0.0f, amplitude = 0.55f;
    for (int octave = 0; octave < kOctaves; ++octave) {
        sum += amplitude * gradientNoise(p, seed + uint32_t(octave) * 0x9e3779b9u);
        p = p * 2.03f + glm::vec3(17.1f, -3.7f, 9.2f);
        amplitude *= 0.5f;
    }
    return sum;
}

// Cube-sphere lattice: points (i, j, k) in [0, n]^3 with one coordinate at 0 or n.
// Each surface point has one owner block so that shared seam vertices appear once:
// +X, -X own full (n+1)^2 faces; +Y, -Y own i in [1, n-1]; +Z, -Z own i, j in [1, n-1].
struct Lattice {
    uint64_t n;
    uint64_t base[6];
    explicit Lattice(uint64_t n_) : n(n_)
    {
        const uint64_t sizes[6] = {(n + 1) * (n + 1), (n + 1) * (n + 1), (n - 1) * (n + 1),
                                   (n - 1) * (n + 1), (n - 1) * (n - 1), (n - 1) * (n - 1)};
        uint64_t offset = 0;
        for (int b = 0; b < 6; ++b) {
            base[b] = offset;
            offset += sizes[b];
        }
    }
    uint64_t vertexCount() const { return 6 * n * n + 2; }
    uint32_t index(uint64_t i, uint64_t j, uint64_t k) const
    {
        if (i == n)
            return uint32_t(base[0] + j * (n + 1) + k);
        if (i == 0)
            return uint32_t(base[1] + j * (n + 1) + k);
        if (j == n)
            return uint32_t(base[2] + (i - 1) * (n + 1) + k);
        if (j == 0)
            return uint32_t(base[3] + (i - 1) * (n + 1) + k);
        if (k == n)
            return uint32_t(base[4] + (i - 1) * (n - 1) + (j - 1));
        return uint32_t(base[5] + (i - 1) * (n - 1) + (j - 1));
    }
};

} // namespace

namespace {

// The statue's size and shape for a budget and seed (shared by generateScan and the
// streaming writer, so both give the same geometry).
struct ScanShape {
    uint64_t n = 0;
    Lattice lattice{2};
    uint64_t statueVertices = 0, statueTriangles = 0;
    uint32_t noiseSeed = 0;
    glm::vec3 shapeScale{1.0f}, noiseOffset{0.0f};
    float taper = 0;
    std::vector<float> warp;

    ScanShape(const GenerateOptions& options)
    {
        const uint64_t budget = options.triangles;
        n = uint64_t(std::sqrt(double(budget - 2) / 12.0));
        while (12 * (n + 1) * (n + 1) + 2 <= budget)
            ++n;
        while (n > 2 && 12 * n * n + 2 > budget)
            --n;
        if (n < 2)
            fail("generate scan", "triangle budget too small");
        lattice = Lattice(n);
        statueVertices = lattice.vertexCount();
        statueTriangles = 12 * n * n;
        noiseSeed = uint32_t(mixSeed(options.seed, 0x5ca9) >> 32);
        Rng shapeRng(mixSeed(options.seed, 0x5ca10));
        shapeScale = glm::vec3(shapeRng.uniform(0.45f, 0.65f), kHalfHeight, shapeRng.uniform(0.4f, 0.55f));
        noiseOffset = glm::vec3(shapeRng.uniform(-50.0f, 50.0f), shapeRng.uniform(-50.0f, 50.0f),
                                shapeRng.uniform(-50.0f, 50.0f));
        taper = shapeRng.uniform(0.1f, 0.3f);
        // Cube coordinate -> sphere direction uses the tangent warp for even spacing.
        warp.resize(n + 1);
        for (uint64_t i = 0; i <= n; ++i)
            warp[i] = std::tan((float(i) / float(n) * 2.0f - 1.0f) * 0.78539816339744831f);
    }

    glm::vec3 position(uint64_t i, uint64_t j, uint64_t k) const
    {
        const glm::vec3 d = glm::normalize(glm::vec3(warp[i], warp[j], warp[k]));
        const float h = fbm(d * 1.7f + noiseOffset, noiseSeed);
        const float radius = (1.0f + kDisplacement * h) * (1.0f - taper * d.y);
        glm::vec3 p = d * radius * shapeScale;
        p.y = std::max(p.y + kCentreY, kBaseCutY);
        return p;
    }

    // Vertex rows in index order: one per lattice row of an owner block (see Lattice).
    uint64_t rowCount() const { return 2 * (n + 1) + 4 * (n - 1); }
    // Writes row `job`'s positions to dst; returns the index of its first vertex and the count.
    void row(uint64_t job, float* dst, uint64_t& firstVertex, uint64_t& count) const
    {
        const uint64_t rows[6] = {n + 1, n + 1, n - 1, n - 1, n - 1, n - 1};
        int block = 0;
        uint64_t r = job;
        while (r >= rows[block])
            r -= rows[block++];
        auto put = [&](glm::vec3 p) {
            dst[0] = p.x, dst[1] = p.y, dst[2] = p.z;
            dst += 3;
        };
        switch (block) {
        case 0:
        case 1: {
            const uint64_t i = block == 0 ? n : 0, j = r;
            firstVertex = lattice.index(i, j, 0);
            count = n + 1;
            for (uint64_t k = 0; k <= n; ++k)
                put(position(i, j, k));
            break;
        }
        case 2:
        case 3: {
            const uint64_t i = r + 1, j = block == 2 ? n : 0;
            firstVertex = lattice.index(i, j, 0);
            count = n + 1;
            for (uint64_t k = 0; k <= n; ++k)
                put(position(i, j, k));
            break;
        }
        default: {
            const uint64_t i = r + 1, k = block == 4 ? n : 0;
            firstVertex = lattice.index(i, 1, k);
            count = n - 1;
            for (uint64_t j = 1; j < n; ++j)
                put(position(i, j, k));
            break;
        }
        }
    }

    // Triangles of face row `job` (6 faces x n rows, 2n triangles each): face f spans
    // origin + a*du + b*dv with du x dv pointing outward.
    void faceRow(uint64_t job, uint32_t* dst) const
    {
        struct Face {
            int origin[3], du[3], dv[3];
        };
        const int ni = int(n);
        const Face faces[6] = {
            {{ni, 0, 0}, {0, 1, 0}, {0, 0, 1}}, {{0, 0, 0}, {0, 0, 1}, {0, 1, 0}},  {{0, ni, 0}, {0, 0, 1}, {1, 0, 0}},
            {{0, 0, 0}, {1, 0, 0}, {0, 0, 1}},  {{0, 0, ni}, {1, 0, 0}, {0, 1, 0}}, {{0, 0, 0}, {0, 1, 0}, {1, 0, 0}},
        };
        const Face& f = faces[job / n];
        const uint64_t a = job % n;
        auto at = [&](uint64_t u, uint64_t v) {
            return lattice.index(uint64_t(f.origin[0]) + u * f.du[0] + v * f.dv[0],
                                 uint64_t(f.origin[1]) + u * f.du[1] + v * f.dv[1],
                                 uint64_t(f.origin[2]) + u * f.du[2] + v * f.dv[2]);
        };
        for (uint64_t b = 0; b < n; ++b, dst += 6) {
            const uint32_t v00 = at(a, b), v10 = at(a + 1, b), v11 = at(a + 1, b + 1), v01 = at(a, b + 1);
            dst[0] = v00, dst[1] = v10, dst[2] = v11;
            dst[3] = v00, dst[4] = v11, dst[5] = v01;
        }
    }
};

void addScanCameraAndLight(Scene& scene)
{
    Camera camera;
    camera.position = {3.4f, 1.4f, 1.2f};
    camera.target = {0.0f, 0.75f, 0.0f};
    camera.yfovDegrees = 40.0f;
    scene.cameras.push_back(camera);

    Light sun;
    sun.type = LightType::Directional;
    sun.direction = glm::normalize(glm::vec3(-0.3f, -0.42f, -0.85f)); // ~25 degrees elevation
    sun.intensity = 1.0f;
    scene.lights.push_back(sun);
}

} // namespace

Scene generateScan(const GenerateOptions& options)
{
    const ScanShape shape(options);
    const uint64_t budget = options.triangles;
    const uint64_t n = shape.n;

    // Ground grid takes up the triangles the n x n faces could not.
    MeshBuilder groundCounter(budget - shape.statueTriangles);
    groundCounter.fillGround(-kGroundHalfSize, -kGroundHalfSize, kGroundHalfSize, kGroundHalfSize, 0.0f);

    Scene scene;
    Mesh& mesh = scene.mesh;
    mesh.positions.resize((shape.statueVertices + groundCounter.vertices()) * 3);
    mesh.indices.resize((shape.statueTriangles + groundCounter.triangles()) * 3);

    // Vertices, one job per lattice row of an owner block, at the row's place in the array.
    float* out = mesh.positions.data();
    parallelFor(0, shape.rowCount(), [&](uint64_t job) {
        std::vector<float> row(3 * (n + 1));
        uint64_t first = 0, count = 0;
        shape.row(job, row.data(), first, count);
        std::copy(row.begin(), row.begin() + long(3 * count), out + 3 * first);
    });
    uint32_t* tri = mesh.indices.data();
    parallelFor(0, 6 * n, [&](uint64_t job) { shape.faceRow(job, tri + job * n * 6); });

    MeshBuilder ground(mesh.positions.data(), mesh.indices.data(), shape.statueVertices, shape.statueTriangles,
                       budget - shape.statueTriangles);
    ground.fillGround(-kGroundHalfSize, -kGroundHalfSize, kGroundHalfSize, kGroundHalfSize, 0.0f);
    addScanCameraAndLight(scene);
    return scene;
}

uint64_t scanStreamingLimit()
{
    return kScanStreamingLimit;
}

void writeScanPly(const GenerateOptions& options, const std::string& path, uint64_t& triangles, uint64_t& vertices)
{
    const ScanShape shape(options);
    const uint64_t budget = options.triangles;
    const uint64_t n = shape.n;
    MeshBuilder groundCounter(budget - shape.statueTriangles);
    groundCounter.fillGround(-kGroundHalfSize, -kGroundHalfSize, kGroundHalfSize, kGroundHalfSize, 0.0f);
    vertices = shape.statueVertices + groundCounter.vertices();
    triangles = shape.statueTriangles + groundCounter.triangles();
    if (vertices > 0xFFFFFFFFull)
        fail("generate scan", "too many vertices for 32-bit indices");
    std::vector<float> groundPositions(3 * groundCounter.vertices());
    std::vector<uint32_t> groundIndices(3 * groundCounter.triangles());
    MeshBuilder ground(MeshBuilder::OwnArrays{}, groundPositions.data(), groundIndices.data(), shape.statueVertices,
                       budget - shape.statueTriangles);
    ground.fillGround(-kGroundHalfSize, -kGroundHalfSize, kGroundHalfSize, kGroundHalfSize, 0.0f);

    // exportPly's binary layout, byte for byte.
    AtomicFileWriter out(path);
    out.write("ply\nformat binary_little_endian 1.0\ncomment written by penumbra\nelement vertex " + std::to_string(vertices) +
              "\nproperty float x\nproperty float y\nproperty float z\nelement face " + std::to_string(triangles) +
              "\nproperty list uchar uint vertex_indices\nend_header\n");
    // Vertex rows in batches computed in parallel, written in order.
    const uint64_t batchRows = 256;
    std::vector<float> batch(3 * (n + 1) * batchRows);
    std::vector<uint64_t> counts(batchRows);
    for (uint64_t first = 0; first < shape.rowCount(); first += batchRows) {
        const uint64_t rows = std::min(batchRows, shape.rowCount() - first);
        parallelFor(0, rows, [&](uint64_t r) {
            uint64_t start = 0;
            shape.row(first + r, &batch[3 * (n + 1) * r], start, counts[r]);
        });
        for (uint64_t r = 0; r < rows; ++r)
            out.write(&batch[3 * (n + 1) * r], size_t(counts[r]) * 12);
    }
    out.write(groundPositions.data(), groundPositions.size() * sizeof(float));
    // Faces: statue rows, then the ground; each "3 a b c" as uchar + 3 uint.
    std::vector<uint32_t> faces(6 * n * batchRows);
    auto writeTriangles = [&](const uint32_t* idx, uint64_t count) {
        for (uint64_t t = 0; t < count; ++t) {
            char* p = out.reserve(13);
            p[0] = 3;
            std::memcpy(p + 1, idx + 3 * t, 12);
            out.advance(13);
        }
    };
    for (uint64_t first = 0; first < 6 * n; first += batchRows) {
        const uint64_t rows = std::min(batchRows, 6 * n - first);
        parallelFor(0, rows, [&](uint64_t r) { shape.faceRow(first + r, &faces[6 * n * r]); });
        writeTriangles(faces.data(), 2 * n * rows);
    }
    writeTriangles(groundIndices.data(), groundCounter.triangles());
    out.commit(AtomicFileWriter::Durability::Synced);
}

} // namespace penumbra::detail
