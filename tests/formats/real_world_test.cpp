// Odd but valid files in the shapes other tools write (tests/formats/data/real_world/):
// exporter banners, CRLF, relative OBJ indices, binary STL headers starting
// with "solid", glTF hierarchies, quantized and sparse accessors. Each must load
// with an exact triangle count; skipped features give one warning line per kind.
#include <gtest/gtest.h>

#include <filesystem>

#include "penumbra/io.h"
#include "test_helpers.h"

namespace penumbra::test {
namespace {

std::string realWorldPath(const std::string& name)
{
    return (std::filesystem::path(__FILE__).parent_path() / "data" / "real_world" / name).string();
}

std::vector<std::string> capturedWarnings;

void captureWarning(const std::string& line)
{
    capturedWarnings.push_back(line);
}

// Imports a file with warnings captured instead of printed.
Scene importCapturing(const std::string& path)
{
    capturedWarnings.clear();
    WarningSink previous = setWarningSink(captureWarning);
    struct Restore {
        WarningSink sink;
        ~Restore() { setWarningSink(sink); }
    } restore{previous};
    return importScene(path);
}

bool hasVertex(const Mesh& mesh, glm::vec3 expected, float tolerance = 1e-5f)
{
    for (size_t v = 0; v < mesh.vertexCount(); ++v)
        if (glm::length(mesh.position(v) - expected) <= tolerance)
            return true;
    return false;
}

struct Expected {
    const char* file;
    size_t triangles;
    std::vector<std::string> warnings; // a fragment of each expected warning line, in order
};

TEST(RealWorld, TriangleCountsAndWarnings)
{
    const std::vector<Expected> files = {
        {"banner_crlf_ascii.ply", 12, {"skipped 1 faces with fewer than 3 vertices", "skipped elements 'edge' (2)"}},
        {"meshlab_binary_le.ply", 6, {}},
        {"big_endian.ply", 4, {}},
        {"blender_crlf.obj", 12, {"skipped 1 'l'/'p' records"}},
        {"relative_indices.obj", 7, {}},
        {"solid_header_binary.stl", 2, {}},
        {"crlf_ascii.stl", 4, {}},
        {"hierarchy.gltf", 8, {"skipped 1 point and line primitives"}},
        {"quantized.glb", 5, {}},
        {"sparse.gltf", 3, {}},
    };
    for (const Expected& expected : files) {
        SCOPED_TRACE(expected.file);
        Scene scene;
        try {
            scene = importCapturing(realWorldPath(expected.file));
        } catch (const Error& e) {
            ADD_FAILURE() << e.what();
            continue;
        }
        EXPECT_EQ(scene.mesh.triangleCount(), expected.triangles);
        ASSERT_EQ(capturedWarnings.size(), expected.warnings.size());
        for (size_t i = 0; i < expected.warnings.size(); ++i) {
            EXPECT_NE(capturedWarnings[i].find(expected.file), std::string::npos) << capturedWarnings[i];
            EXPECT_NE(capturedWarnings[i].find(expected.warnings[i]), std::string::npos) << capturedWarnings[i];
            EXPECT_EQ(capturedWarnings[i].find('\n'), std::string::npos);
        }
    }
}

TEST(RealWorld, PlyValues)
{
    // Double coordinates and extra properties (MeshLab), big-endian floats.
    Scene pyramid = importCapturing(realWorldPath("meshlab_binary_le.ply"));
    ASSERT_EQ(pyramid.mesh.vertexCount(), 5u);
    EXPECT_EQ(pyramid.mesh.position(4), glm::vec3(1.0f, 1.0f, 1.5f));
    Scene big = importCapturing(realWorldPath("big_endian.ply"));
    ASSERT_EQ(big.mesh.vertexCount(), 6u);
    EXPECT_EQ(big.mesh.position(5), glm::vec3(4.0f, 1.0f, 0.0f));
    // The quad 0 3 5 2 is fanned into 0 3 5, 0 5 2.
    EXPECT_EQ(std::vector<uint32_t>(big.mesh.indices.end() - 6, big.mesh.indices.end()),
              (std::vector<uint32_t>{0, 3, 5, 0, 5, 2}));
}

TEST(RealWorld, ObjRelativeIndicesAndContinuations)
{
    Scene scene = importCapturing(realWorldPath("relative_indices.obj"));
    ASSERT_EQ(scene.mesh.vertexCount(), 10u);
    EXPECT_EQ(scene.mesh.position(7), glm::vec3(6.0f, 0.0f, 0.0f)); // "v 6 0 \" continued on the next line
    // "f -3 -2 -1" after the 9th vertex is 6 7 8 (0-based); "f -4 -1 -2 -3" after the 10th is 6 9 8 7.
    EXPECT_EQ(std::vector<uint32_t>(scene.mesh.indices.begin() + 12, scene.mesh.indices.end()),
              (std::vector<uint32_t>{6, 7, 8, 6, 9, 8, 6, 8, 7}));
}

TEST(RealWorld, StlSolidHeaderIsBinary)
{
    Scene scene = importCapturing(realWorldPath("solid_header_binary.stl"));
    EXPECT_EQ(scene.mesh.vertexCount(), 4u); // two triangles sharing an edge, welded
    EXPECT_TRUE(hasVertex(scene.mesh, {1.0f, 1.0f, 0.0f}));
}

TEST(RealWorld, GltfTransforms)
{
    Scene scene = importCapturing(realWorldPath("hierarchy.gltf"));
    // Vertex (1,0,0) of mesh 0 under matrix T(10,0,0), then T(0,1,0) Rz(90) S(2), then T(1,0,0):
    // (1,0,0) -> (2,0,0) -> (4,0,0) -> (0,4,0) -> (0,5,0) -> (10,5,0).
    EXPECT_TRUE(hasVertex(scene.mesh, {10.0f, 5.0f, 0.0f}));
    // Vertex (1,1,0) -> (2,1,0) -> (4,2,0) -> (-2,4,0) -> (-2,5,0) -> (8,5,0).
    EXPECT_TRUE(hasVertex(scene.mesh, {8.0f, 5.0f, 0.0f}));
    // Mesh 1 under T(0,0,-5) and, mirrored, under T(0,0,-5) S(-1,1,1).
    EXPECT_TRUE(hasVertex(scene.mesh, {1.0f, 0.0f, -5.0f}));
    EXPECT_TRUE(hasVertex(scene.mesh, {-1.0f, 0.0f, -5.0f}));
    EXPECT_FALSE(hasVertex(scene.mesh, {1.0f, 0.0f, 0.0f}));
    // The mirrored copy keeps its front face: both copies' normals point along +z.
    for (size_t t = scene.mesh.triangleCount() - 2; t < scene.mesh.triangleCount(); ++t) {
        glm::vec3 a = scene.mesh.position(scene.mesh.indices[t * 3]);
        glm::vec3 b = scene.mesh.position(scene.mesh.indices[t * 3 + 1]);
        glm::vec3 c = scene.mesh.position(scene.mesh.indices[t * 3 + 2]);
        EXPECT_GT(glm::cross(b - a, c - a).z, 0.0f) << "triangle " << t;
    }
}

TEST(RealWorld, GltfQuantizedPositions)
{
    Scene scene = importCapturing(realWorldPath("quantized.glb"));
    // Node scale 4 dequantizes: normalized int16 32767 -> 1 -> 4; int8 10 -> 40;
    // normalized uint8 255 -> 1 -> 4; uint16 7 -> 28.
    EXPECT_TRUE(hasVertex(scene.mesh, {0.0f, 4.0f, 0.0f}));
    EXPECT_TRUE(hasVertex(scene.mesh, {40.0f, 40.0f, 0.0f}));
    EXPECT_TRUE(hasVertex(scene.mesh, {4.0f, 0.0f, 4.0f}));
    EXPECT_TRUE(hasVertex(scene.mesh, {4.0f, 0.0f, 28.0f}));
    EXPECT_EQ(scene.mesh.vertexCount(), 13u);
}

TEST(RealWorld, GltfSparseAccessors)
{
    Scene scene = importCapturing(realWorldPath("sparse.gltf"));
    ASSERT_EQ(scene.mesh.vertexCount(), 7u);
    EXPECT_EQ(scene.mesh.position(2), glm::vec3(5.0f, 5.0f, 0.0f)); // replaced by the sparse value
    EXPECT_EQ(scene.mesh.position(3), glm::vec3(0.0f, 1.0f, 0.0f)); // kept from the bufferView
    EXPECT_EQ(scene.mesh.position(4), glm::vec3(0.0f));             // zero-filled accessor
    EXPECT_EQ(scene.mesh.position(5), glm::vec3(1.0f, 0.0f, 0.0f)); // its sparse values
    EXPECT_EQ(scene.mesh.position(6), glm::vec3(0.0f, 1.0f, 0.0f));
}

// Blender's OBJ names its material library (cube.mtl, beside it) and material.
TEST(RealWorld, ObjMaterialFromBlendersLibrary)
{
    Scene scene = importCapturing(realWorldPath("blender_crlf.obj"));
    ASSERT_EQ(scene.mesh.materials.size(), 2u); // the default before usemtl, and 'Material'
    EXPECT_EQ(scene.mesh.materials[1].name, "Material");
    EXPECT_EQ(scene.mesh.materials[1].baseColor, glm::vec4(0.8f, 0.3f, 0.1f, 1.0f));
    ASSERT_EQ(scene.mesh.triangleMaterials.size(), 12u);
    for (uint32_t m : scene.mesh.triangleMaterials)
        EXPECT_EQ(m, 1u);
}

TEST(RealWorld, MemoryImportMatchesFile)
{
    for (const char* name : {"banner_crlf_ascii.ply", "blender_crlf.obj", "crlf_ascii.stl", "quantized.glb"}) {
        SCOPED_TRACE(name);
        std::string bytes = readFile(realWorldPath(name));
        Scene fromFile = importCapturing(realWorldPath(name));
        Scene fromMemory = importSceneMemory(
            {reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()}, name);
        EXPECT_EQ(fromMemory.mesh.positions, fromFile.mesh.positions);
        EXPECT_EQ(fromMemory.mesh.indices, fromFile.mesh.indices);
    }
    expectError([] { importSceneMemory({}, "nothing.obj"); }, {"nothing.obj", "empty file"});
}

} // namespace
} // namespace penumbra::test

namespace penumbra::test {
namespace {

// Writes the seeds of the importer fuzz targets that only penumbra's own
// writers can produce (Draco data). Run by hand when they change
// (formats_tests --gtest_also_run_disabled_tests --gtest_filter='*FuzzSeeds*',
// then copy tmp/fuzz_seed_*.drc to tests/fuzz/corpus_drc/ and
// tmp/fuzz_seed_*.gl* to tests/fuzz/corpus_gltf/).
TEST(RealWorld, DISABLED_WriteFuzzSeeds)
{
    Scene scene;
    scene.mesh = makeGrid(2);
    ExportOptions draco;
    draco.draco = true;
    exportScene(scene, tempPath("fuzz_seed_grid2.drc"), draco);
    draco.dracoPositionBits = 8;
    draco.dracoSpeed = 10;
    exportScene(scene, tempPath("fuzz_seed_grid2_q8_fast.drc"), draco);
    scene.mesh = makeGrid(3);
    scene.cameras.push_back(Camera{});
    Light light;
    light.type = LightType::Spot;
    scene.lights.push_back(light);
    exportScene(scene, tempPath("fuzz_seed_grid3_draco.glb"), draco);
    exportScene(scene, tempPath("fuzz_seed_grid3_draco.gltf"), draco);
}

} // namespace
} // namespace penumbra::test
