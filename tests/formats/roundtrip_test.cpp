// Export-then-import round trips for every format, plus hand-written files
// exercising triangulation, glTF transforms, cameras and lights.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "penumbra/io.h"
#include "test_helpers.h"

namespace penumbra::test {
namespace {

void expectSameTriangles(const Mesh& a, const Mesh& b)
{
    ASSERT_EQ(a.triangleCount(), b.triangleCount());
    EXPECT_EQ(canonicalTriangles(a), canonicalTriangles(b));
}

// Grid vertices lie on integer x, z with a height pattern; check each imported
// vertex is within tolerance of one, and every triangle still faces +y.
void expectNearGrid(const Mesh& mesh, int n, float tolerance)
{
    for (size_t v = 0; v < mesh.vertexCount(); ++v) {
        glm::vec3 p = mesh.position(v);
        int x = int(std::lround(p.x)), z = int(std::lround(p.z));
        ASSERT_TRUE(x >= 0 && x <= n && z >= 0 && z <= n) << v;
        float y = 0.25f * float((x * 7 + z * 3) % 5);
        EXPECT_NEAR(p.x, float(x), tolerance);
        EXPECT_NEAR(p.y, y, tolerance);
        EXPECT_NEAR(p.z, float(z), tolerance);
    }
    for (size_t t = 0; t < mesh.triangleCount(); ++t) {
        glm::vec3 a = mesh.position(mesh.indices[t * 3]), b = mesh.position(mesh.indices[t * 3 + 1]),
                  c = mesh.position(mesh.indices[t * 3 + 2]);
        glm::vec3 normal = glm::cross(b - a, c - a);
        EXPECT_GT(normal.y, 0.0f) << "triangle " << t << " flipped";
    }
}

struct RoundTripCase {
    const char* name;
    const char* extension;
    bool binary;
    bool draco;
};

class RoundTrip : public ::testing::TestWithParam<RoundTripCase> {};

TEST_P(RoundTrip, GridSurvivesExportAndImport)
{
    const RoundTripCase& param = GetParam();
    Scene scene;
    scene.mesh = makeGrid(24);
    std::string path = tempPath(std::string("roundtrip_") + param.name + param.extension);
    ExportOptions options;
    options.binary = param.binary;
    options.draco = param.draco;
    exportScene(scene, path, options);
    Scene loaded = importScene(path);
    ASSERT_EQ(loaded.mesh.triangleCount(), scene.mesh.triangleCount());
    bool quantized = param.draco || std::string(param.extension) == ".drc";
    if (quantized) {
        // 14-bit quantization over a 24-unit range: step ~0.0015.
        expectNearGrid(loaded.mesh, 24, 0.002f);
    } else {
        expectSameTriangles(loaded.mesh, scene.mesh);
        expectNearGrid(loaded.mesh, 24, 0.0f);
    }
    // No temporary file of this export left behind (other tests run in parallel
    // processes and may have theirs in flight, so only this file's prefix counts).
    const std::string prefix = std::filesystem::path(path).filename().string() + ".tmp-";
    for (const auto& entry : std::filesystem::directory_iterator(PENUMBRA_TEST_TMP))
        EXPECT_NE(entry.path().filename().string().rfind(prefix, 0), 0u) << entry.path();
}

INSTANTIATE_TEST_SUITE_P(
    AllFormats, RoundTrip,
    ::testing::Values(RoundTripCase{"ply_binary", ".ply", true, false},
                      RoundTripCase{"ply_ascii", ".ply", false, false}, RoundTripCase{"obj", ".obj", true, false},
                      RoundTripCase{"stl_binary", ".stl", true, false},
                      RoundTripCase{"stl_ascii", ".stl", false, false}, RoundTripCase{"glb", ".glb", true, false},
                      RoundTripCase{"gltf", ".gltf", true, false}, RoundTripCase{"glb_draco", ".glb", true, true},
                      RoundTripCase{"gltf_draco", ".gltf", true, true}, RoundTripCase{"drc", ".drc", true, false}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(RoundTrip, StlWeldsSharedCorners)
{
    Scene scene;
    scene.mesh = makeGrid(5);
    std::string path = tempPath("weld.stl");
    exportScene(scene, path);
    Scene loaded = importScene(path);
    EXPECT_EQ(loaded.mesh.vertexCount(), scene.mesh.vertexCount());
}

TEST(RoundTrip, UpperCaseExtensionAndOverwrite)
{
    Scene scene;
    scene.mesh = makeGrid(2);
    std::string path = tempPath("UPPER.PLY");
    exportScene(scene, path);
    scene.mesh = makeGrid(3);
    exportScene(scene, path); // replaces the file atomically
    EXPECT_EQ(importScene(path).mesh.triangleCount(), 18u);
}

// A writer killed before it could remove its temporary file (SIGKILL) leaves
// "<path>.tmp-<pid>"; the next write of the same path removes it, but not the
// temporary file of a writer still running, nor look-alike names.
TEST(RoundTrip, TheNextWriteRemovesAKilledWritersTemporaryFile)
{
    const std::string path = tempPath("killed_writer.ply");
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0)
        _exit(0);
    ASSERT_EQ(waitpid(child, nullptr, 0), child); // its pid names no process now
    auto touch = [](const std::string& file) { std::ofstream(file) << "partial"; };
    const std::string dead = path + ".tmp-" + std::to_string(child);
    const std::string alive = path + ".tmp-" + std::to_string(getppid()); // ctest, which runs
    const std::string other = path + ".tmp-" + std::to_string(child) + "x";
    for (const std::string& file : {dead, alive, other})
        touch(file);
    Scene scene;
    scene.mesh = makeGrid(2);
    exportScene(scene, path);
    EXPECT_FALSE(std::filesystem::exists(dead));
    EXPECT_TRUE(std::filesystem::exists(alive));
    EXPECT_TRUE(std::filesystem::exists(other));
    EXPECT_EQ(importScene(path).mesh.triangleCount(), 8u);
    std::filesystem::remove(alive);
    std::filesystem::remove(other);
}

Scene cameraLightScene()
{
    Scene scene;
    scene.mesh = makeGrid(4);
    Camera perspective;
    perspective.position = {1.0f, 2.0f, 8.0f};
    perspective.target = {2.0f, 0.5f, 2.0f};
    perspective.up = {0.0f, 1.0f, 0.0f};
    perspective.yfovDegrees = 50.0f;
    perspective.nearPlane = 0.1f;
    perspective.farPlane = 100.0f;
    Camera ortho;
    ortho.projection = Projection::Orthographic;
    ortho.position = {2.0f, 10.0f, 2.0f};
    ortho.target = {2.0f, 0.0f, 2.0f};
    ortho.up = {0.0f, 0.0f, -1.0f};
    ortho.orthoHeight = 6.0f;
    scene.cameras = {perspective, ortho};

    Light sun;
    sun.type = LightType::Directional;
    sun.direction = glm::normalize(glm::vec3(0.3f, -1.0f, 0.2f));
    sun.color = {1.0f, 0.9f, 0.8f};
    sun.intensity = 3.0f;
    Light point;
    point.type = LightType::Point;
    point.position = {1.0f, 4.0f, 1.0f};
    point.intensity = 20.0f;
    point.range = 15.0f;
    Light spot;
    spot.type = LightType::Spot;
    spot.position = {0.0f, 5.0f, 0.0f};
    spot.direction = glm::normalize(glm::vec3(0.2f, -1.0f, 0.1f));
    spot.innerConeDegrees = 10.0f;
    spot.outerConeDegrees = 25.0f;
    Light rect;
    rect.type = LightType::Rectangle;
    rect.position = {2.0f, 3.0f, 2.0f};
    rect.direction = {0.0f, -1.0f, 0.0f};
    rect.up = {0.0f, 0.0f, 1.0f};
    rect.width = 2.0f;
    rect.height = 0.5f;
    scene.lights = {sun, point, spot, rect};
    return scene;
}

void expectVec(glm::vec3 a, glm::vec3 b, float tolerance, const char* what)
{
    EXPECT_NEAR(a.x, b.x, tolerance) << what;
    EXPECT_NEAR(a.y, b.y, tolerance) << what;
    EXPECT_NEAR(a.z, b.z, tolerance) << what;
}

class CameraLightRoundTrip : public ::testing::TestWithParam<bool> {};

TEST_P(CameraLightRoundTrip, GltfKeepsCamerasAndLights)
{
    Scene scene = cameraLightScene();
    ExportOptions options;
    options.draco = GetParam();
    std::string path = tempPath(GetParam() ? "cameras_lights_draco.glb" : "cameras_lights.glb");
    exportScene(scene, path, options);
    Scene loaded = importScene(path);
    ASSERT_EQ(loaded.cameras.size(), scene.cameras.size());
    ASSERT_EQ(loaded.lights.size(), scene.lights.size());
    for (size_t i = 0; i < scene.cameras.size(); ++i) {
        const Camera& a = scene.cameras[i];
        const Camera& b = loaded.cameras[i];
        EXPECT_EQ(a.projection, b.projection);
        expectVec(a.position, b.position, 1e-4f, "camera position");
        expectVec(a.target, b.target, 1e-4f, "camera target");
        // up comes back orthogonalised against the view direction
        glm::vec3 forward = glm::normalize(a.target - a.position);
        glm::vec3 expectedUp = glm::normalize(a.up - forward * glm::dot(a.up, forward));
        expectVec(expectedUp, b.up, 1e-4f, "camera up");
        EXPECT_NEAR(a.yfovDegrees, b.yfovDegrees, 1e-3f);
        if (a.projection == Projection::Orthographic) {
            EXPECT_NEAR(a.orthoHeight, b.orthoHeight, 1e-4f);
        }
        EXPECT_NEAR(a.nearPlane, b.nearPlane, 1e-6f);
        EXPECT_NEAR(a.farPlane, b.farPlane, 1e-6f);
    }
    for (size_t i = 0; i < scene.lights.size(); ++i) {
        const Light& a = scene.lights[i];
        const Light& b = loaded.lights[i];
        EXPECT_EQ(a.type, b.type) << i;
        if (a.type != LightType::Directional)
            expectVec(a.position, b.position, 1e-4f, "light position");
        expectVec(a.direction, b.direction, 1e-4f, "light direction");
        expectVec(a.color, b.color, 1e-6f, "light color");
        EXPECT_NEAR(a.intensity, b.intensity, 1e-5f);
        EXPECT_NEAR(a.range, b.range, 1e-5f);
        if (a.type == LightType::Spot) {
            EXPECT_NEAR(a.innerConeDegrees, b.innerConeDegrees, 1e-3f);
            EXPECT_NEAR(a.outerConeDegrees, b.outerConeDegrees, 1e-3f);
        }
        if (a.type == LightType::Rectangle) {
            EXPECT_NEAR(a.width, b.width, 1e-6f);
            EXPECT_NEAR(a.height, b.height, 1e-6f);
            expectVec(a.up, b.up, 1e-4f, "light up");
        }
    }
}

INSTANTIATE_TEST_SUITE_P(Plain, CameraLightRoundTrip, ::testing::Values(false, true));

// ---- hand-written inputs ----

TEST(ImportObj, PolygonsNegativeIndicesAndCornerForms)
{
    std::string path = writeFile("forms.obj", "# comment\n"
                                              "mtllib x.mtl\n"
                                              "o thing\n"
                                              "v 0 0 0\n"
                                              "v 1 0 0\n"
                                              "v 1 1 0\n"
                                              "v 0 1 0\n"
                                              "vt 0 0\nvn 0 0 1\n"
                                              "g quad\nusemtl m\ns off\n"
                                              "f 1/1/1 2/1/1 3/1/1 4/1/1\n"
                                              "v 2 0 0\r\n"
                                              "f -4//1 -1//1 -3//1\r\n"
                                              "f 1/1 2/1 3/1\n"
                                              "l 1 2\n");
    Scene scene = importScene(path);
    ASSERT_EQ(scene.mesh.triangleCount(), 4u);
    ASSERT_EQ(scene.mesh.vertexCount(), 5u);
    std::vector<uint32_t> expected = {0, 1, 2, 0, 2, 3, 1, 4, 2, 0, 1, 2};
    EXPECT_EQ(scene.mesh.indices, expected);
}

TEST(ImportPly, BigEndianWithExtraPropertiesAndQuads)
{
    std::string header = "ply\nformat binary_big_endian 1.0\ncomment test\n"
                         "element vertex 4\nproperty double x\nproperty uchar red\nproperty float y\nproperty float z\n"
                         "element edge 1\nproperty int vertex1\nproperty list uchar int extra\n"
                         "element face 2\nproperty uchar flags\nproperty list uchar int vertex_indices\n"
                         "end_header\n";
    auto be32 = [](std::string& s, uint32_t v) {
        for (int i = 3; i >= 0; --i)
            s += char((v >> (i * 8)) & 0xff);
    };
    auto beFloat = [&](std::string& s, float f) {
        uint32_t v;
        std::memcpy(&v, &f, 4);
        be32(s, v);
    };
    auto beDouble = [](std::string& s, double d) {
        uint64_t v;
        std::memcpy(&v, &d, 8);
        for (int i = 7; i >= 0; --i)
            s += char((v >> (i * 8)) & 0xff);
    };
    std::string bytes = header;
    float xyz[4][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
    for (auto& v : xyz) {
        beDouble(bytes, v[0]);
        bytes += char(200);
        beFloat(bytes, v[1]);
        beFloat(bytes, v[2]);
    }
    be32(bytes, 7);   // edge vertex1
    bytes += char(2); // edge list of 2
    be32(bytes, 1);
    be32(bytes, 2);
    bytes += char(0); // face 0 flags
    bytes += char(4); // quad
    for (uint32_t i : {0u, 1u, 2u, 3u})
        be32(bytes, i);
    bytes += char(0);
    bytes += char(3);
    for (uint32_t i : {0u, 2u, 3u})
        be32(bytes, i);
    Scene scene = importScene(writeFile("bigendian.ply", bytes));
    ASSERT_EQ(scene.mesh.triangleCount(), 3u);
    EXPECT_EQ(scene.mesh.position(2), glm::vec3(1, 1, 0));
    std::vector<uint32_t> expected = {0, 1, 2, 0, 2, 3, 0, 2, 3};
    EXPECT_EQ(scene.mesh.indices, expected);
}

TEST(ImportPly, AsciiWithQuadAndExtraProperties)
{
    std::string path = writeFile("ascii.ply", "ply\r\nformat ascii 1.0\r\n"
                                              "element vertex 4\r\nproperty float x\r\nproperty float y\r\n"
                                              "property float z\r\nproperty uchar red\r\n"
                                              "element face 1\r\nproperty list uchar uint vertex_index\r\n"
                                              "end_header\r\n"
                                              "0 0 0 1\r\n1 0 0 2\r\n1 1 0 3\r\n0 1 -1e-1 4\r\n"
                                              "4 0 1 2 3\r\n");
    Scene scene = importScene(path);
    ASSERT_EQ(scene.mesh.triangleCount(), 2u);
    EXPECT_FLOAT_EQ(scene.mesh.positions[11], -0.1f);
}

TEST(ImportPly, BinaryLittleEndianGenericFaceLayout)
{
    // ushort list count and ushort indices take the generic face path.
    std::string bytes = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                        "property float z\nelement face 1\nproperty list ushort ushort vertex_indices\nend_header\n";
    for (float f : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f})
        append(bytes, f);
    append(bytes, uint16_t(3));
    for (uint16_t i : {0, 1, 2})
        append(bytes, i);
    Scene scene = importScene(writeFile("generic.ply", bytes));
    EXPECT_EQ(scene.mesh.triangleCount(), 1u);
}

TEST(ImportStl, BinaryHeaderStartingWithSolid)
{
    std::string bytes = "solid but actually binary";
    bytes.resize(80, ' ');
    append(bytes, uint32_t(1));
    for (float f : {0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f})
        append(bytes, f);
    append(bytes, uint16_t(0));
    Scene scene = importScene(writeFile("solidbinary.stl", bytes));
    EXPECT_EQ(scene.mesh.triangleCount(), 1u);
    EXPECT_EQ(scene.mesh.vertexCount(), 3u);
}

// One triangle (0,0,0) (1,0,0) (0,1,0), indices as uint16, then 4 corners for a strip.
std::string triangleBin()
{
    std::string bin;
    for (float f : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f, 1.f, 1.f, 0.f})
        append(bin, f);
    for (uint16_t i : {0, 1, 2, 0})
        append(bin, i);
    return bin;
}

const char* kTriangleBuffers = R"(
  "buffers": [{"byteLength": 56}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 8}],
  "accessors": [
    {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
    {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"},
    {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"}
  ],)";

TEST(ImportGltf, NodeTransformsInstancingStripsAndMirroring)
{
    std::string json = std::string(R"({"asset": {"version": "2.0"},)") + kTriangleBuffers + R"(
  "meshes": [
    {"primitives": [{"attributes": {"POSITION": 0}, "indices": 1},
                    {"attributes": {"POSITION": 0}, "mode": 1}]},
    {"primitives": [{"attributes": {"POSITION": 2}, "mode": 5}]}
  ],
  "nodes": [
    {"children": [1, 2], "translation": [10, 0, 0]},
    {"mesh": 0, "scale": [2, 2, 2]},
    {"mesh": 0, "rotation": [0, 0, 0.7071067811865476, 0.7071067811865476]},
    {"mesh": 1, "matrix": [-1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,5,1]},
    {"mesh": 1}
  ],
  "scenes": [{"nodes": [0, 3]}, {"nodes": [4]}],
  "scene": 0
})";
    Scene scene = importScene(writeFile("transforms.glb", makeGlb(json, triangleBin())));
    ASSERT_EQ(scene.mesh.triangleCount(), 4u); // 2 instances + strip of 2; node 4 is in another scene
    // Instance 1: scaled by 2 then translated by 10 in x.
    EXPECT_EQ(scene.mesh.position(1), glm::vec3(12, 0, 0));
    // Instance 2: rotated 90 degrees about z: (1,0,0) -> (0,1,0), then translated.
    glm::vec3 rotated = scene.mesh.position(4);
    EXPECT_NEAR(rotated.x, 10.0f, 1e-5f);
    EXPECT_NEAR(rotated.y, 1.0f, 1e-5f);
    // Every triangle keeps +z facing (the mirrored strip has its winding flipped back).
    for (size_t t = 0; t < scene.mesh.triangleCount(); ++t) {
        glm::vec3 a = scene.mesh.position(scene.mesh.indices[t * 3]),
                  b = scene.mesh.position(scene.mesh.indices[t * 3 + 1]),
                  c = scene.mesh.position(scene.mesh.indices[t * 3 + 2]);
        glm::vec3 normal = glm::cross(b - a, c - a);
        EXPECT_GT(normal.z, 0.0f) << "triangle " << t;
    }
}

TEST(ImportGltf, CamerasAndLightsFromNodes)
{
    std::string json = std::string(R"({"asset": {"version": "2.0"},)") + kTriangleBuffers + R"(
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
  "cameras": [{"type": "perspective", "perspective": {"yfov": 0.7853981633974483, "znear": 0.5}},
              {"type": "orthographic", "orthographic": {"xmag": 3, "ymag": 2, "znear": 0, "zfar": 50}}],
  "extensions": {"KHR_lights_punctual": {"lights": [
     {"type": "spot", "color": [1, 0, 0], "intensity": 5, "range": 9,
      "spot": {"innerConeAngle": 0.1, "outerConeAngle": 0.5}},
     {"type": "directional"}]}},
  "extensionsUsed": ["KHR_lights_punctual"],
  "nodes": [
    {"mesh": 0},
    {"camera": 0, "translation": [0, 0, 10]},
    {"camera": 1, "translation": [0, 5, 0], "rotation": [-0.7071067811865476, 0, 0, 0.7071067811865476]},
    {"children": [4], "translation": [1, 2, 3]},
    {"extensions": {"KHR_lights_punctual": {"light": 0}}},
    {"extensions": {"KHR_lights_punctual": {"light": 1}}, "rotation": [-0.7071067811865476, 0, 0, 0.7071067811865476]}
  ],
  "scenes": [{"nodes": [0, 1, 2, 3, 5]}]
})";
    Scene scene = importScene(writeFile("cameras.glb", makeGlb(json, triangleBin())));
    ASSERT_EQ(scene.cameras.size(), 2u);
    const Camera& p = scene.cameras[0];
    EXPECT_EQ(p.projection, Projection::Perspective);
    EXPECT_NEAR(p.yfovDegrees, 45.0f, 1e-4f);
    EXPECT_NEAR(p.nearPlane, 0.5f, 1e-6f);
    EXPECT_EQ(p.farPlane, 0.0f);
    expectVec(p.position, {0, 0, 10}, 1e-5f, "position");
    glm::vec3 view = glm::normalize(p.target - p.position);
    expectVec(view, {0, 0, -1}, 1e-5f, "view direction");
    expectVec(p.up, {0, 1, 0}, 1e-5f, "up");
    const Camera& o = scene.cameras[1];
    EXPECT_EQ(o.projection, Projection::Orthographic);
    EXPECT_NEAR(o.orthoHeight, 4.0f, 1e-6f);
    EXPECT_NEAR(o.farPlane, 50.0f, 1e-6f);
    expectVec(glm::normalize(o.target - o.position), {0, -1, 0}, 1e-5f, "ortho view direction");
    expectVec(o.up, {0, 0, -1}, 1e-5f, "ortho up");

    ASSERT_EQ(scene.lights.size(), 2u);
    const Light& spot = scene.lights[0];
    EXPECT_EQ(spot.type, LightType::Spot);
    expectVec(spot.position, {1, 2, 3}, 1e-6f, "spot position");
    expectVec(spot.direction, {0, 0, -1}, 1e-6f, "spot direction");
    expectVec(spot.color, {1, 0, 0}, 0.0f, "spot color");
    EXPECT_FLOAT_EQ(spot.intensity, 5.0f);
    EXPECT_FLOAT_EQ(spot.range, 9.0f);
    EXPECT_NEAR(spot.innerConeDegrees, 0.1f * 180.0f / 3.14159265f, 1e-3f);
    EXPECT_NEAR(spot.outerConeDegrees, 0.5f * 180.0f / 3.14159265f, 1e-3f);
    const Light& sun = scene.lights[1];
    EXPECT_EQ(sun.type, LightType::Directional);
    expectVec(sun.direction, {0, -1, 0}, 1e-5f, "sun direction");
}

TEST(ImportGltf, ExternalBufferAndDataUri)
{
    std::string bin = triangleBin();
    writeFile("external buffer.bin", bin);
    std::string json = R"({"asset": {"version": "2.0"},
  "buffers": [{"byteLength": 56, "uri": "external%20buffer.bin"}],
  "bufferViews": [{"buffer": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 8}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
                {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
  "nodes": [{"mesh": 0}]
})";
    Scene scene = importScene(writeFile("external.gltf", json));
    EXPECT_EQ(scene.mesh.triangleCount(), 1u);
}

TEST(ImportGltf, DracoGlbWrittenByDracosOwnEncoder)
{
    // Fixture: the 24 x 24 grid re-encoded by draco::GltfEncoder (11-bit positions, uint16 indices, a material).
    std::string fixture =
        (std::filesystem::path(__FILE__).parent_path() / "data" / "grid24_draco_by_draco_gltf_encoder.glb").string();
    Scene scene = importScene(fixture);
    EXPECT_EQ(scene.mesh.triangleCount(), 1152u);
    expectNearGrid(scene.mesh, 24, 24.0f / 2047.0f);
}

} // namespace
} // namespace penumbra::test
