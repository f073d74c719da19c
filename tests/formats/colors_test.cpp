// Colours read by the importers: PLY vertex and face colours, OBJ 'v x y z r g b'.
// (glTF base colours: tests/runtime/colors_test.cpp renders a two-material glTF.)
#include <gtest/gtest.h>

#include "penumbra/io.h"
#include "test_helpers.h"

namespace penumbra::test {
namespace {

TEST(ImportColors, PlyAsciiVertexColours)
{
    std::string path = writeFile("colors_vertex.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                                                      "property float y\nproperty float z\nproperty uchar red\n"
                                                      "property uchar green\nproperty uchar blue\nelement face 1\n"
                                                      "property list uchar int vertex_indices\nend_header\n"
                                                      "0 0 0 255 0 0\n1 0 0 0 255 0\n0 1 0 51 102 255\n3 0 1 2\n");
    Mesh mesh = importScene(path).mesh;
    ASSERT_EQ(mesh.colors.size(), 9u);
    EXPECT_EQ(mesh.colors[0], 1.0f);
    EXPECT_EQ(mesh.colors[4], 1.0f);
    EXPECT_FLOAT_EQ(mesh.colors[6], 0.2f);
    EXPECT_FLOAT_EQ(mesh.colors[7], 0.4f);
    EXPECT_TRUE(mesh.materials.empty());
    glm::vec3 c = mesh.triangleColor(0);
    EXPECT_FLOAT_EQ(c.r, 1.2f / 3.0f);
    EXPECT_FLOAT_EQ(c.b, 1.0f / 3.0f);
}

TEST(ImportColors, PlyBinaryVertexAndFaceColours)
{
    // Vertices: float xyz + float rgb (fixed stride); faces: list + uchar rgb (generic face path).
    std::string bytes = "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                        "property float z\nproperty float red\nproperty float green\nproperty float blue\n"
                        "element face 2\nproperty list uchar int vertex_indices\nproperty uchar red\nproperty uchar green\n"
                        "property uchar blue\nend_header\n";
    const float vertices[4][6] = {{0, 0, 0, 1, 1, 1}, {1, 0, 0, 0.5f, 0.5f, 0.5f}, {1, 1, 0, 2, -1, 0.25f}, {0, 1, 0, 0, 0, 0}};
    for (const auto& v : vertices)
        for (float f : v)
            append(bytes, f);
    append(bytes, uint8_t(4)); // a quad: two triangles, one colour
    for (int32_t i : {0, 1, 2, 3})
        append(bytes, i);
    for (uint8_t c : {255, 0, 0})
        append(bytes, c);
    append(bytes, uint8_t(3));
    for (int32_t i : {0, 2, 1})
        append(bytes, i);
    for (uint8_t c : {0, 0, 255})
        append(bytes, c);
    Mesh mesh = importScene(writeFile("colors_binary.ply", bytes)).mesh;
    ASSERT_EQ(mesh.triangleCount(), 3u);
    ASSERT_EQ(mesh.colors.size(), 12u);
    EXPECT_EQ(mesh.colors[6], 1.0f); // clamped
    EXPECT_EQ(mesh.colors[7], 0.0f);
    EXPECT_EQ(mesh.colors[8], 0.25f);
    ASSERT_EQ(mesh.materials.size(), 2u); // one per distinct face colour
    EXPECT_EQ(mesh.materials[0].baseColor, glm::vec4(1, 0, 0, 1));
    EXPECT_EQ(mesh.materials[1].baseColor, glm::vec4(0, 0, 1, 1));
    EXPECT_EQ(mesh.triangleMaterials, (std::vector<uint32_t>{0, 0, 1}));
}

TEST(ImportColors, PlyAsciiFaceColours)
{
    std::string path = writeFile("colors_face.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                                                    "property float y\nproperty float z\nelement face 2\n"
                                                    "property list uchar int vertex_indices\nproperty uchar red\n"
                                                    "property uchar green\nproperty uchar blue\nend_header\n"
                                                    "0 0 0\n1 0 0\n0 1 0\n3 0 1 2 0 255 0\n3 0 2 1 0 255 0\n");
    Mesh mesh = importScene(path).mesh;
    ASSERT_EQ(mesh.materials.size(), 1u);
    EXPECT_EQ(mesh.materials[0].baseColor, glm::vec4(0, 1, 0, 1));
    EXPECT_EQ(mesh.triangleMaterials, (std::vector<uint32_t>{0, 0}));
    EXPECT_TRUE(mesh.colors.empty());
}

TEST(ImportColors, ObjVertexColours)
{
    std::string path = writeFile("colors.obj", "v 0 0 0\nv 1 0 0 1 0 0\nv 0 1 0 0.5 2 -1 # comment\nv 1 1 0 1 0 0 1\n"
                                               "f 1 2 3\nf 2 4 3\n");
    Mesh mesh = importScene(path).mesh;
    ASSERT_EQ(mesh.colors.size(), 12u);
    const std::vector<float> expected = {1, 1, 1, 1, 0, 0, 0.5f, 1, 0, 0, 0, 1}; // before any: white; clamped; x y z w r g b
    EXPECT_EQ(mesh.colors, expected);
    EXPECT_EQ(mesh.position(3), glm::vec3(1, 1, 0));
    // Without colours there are none.
    EXPECT_TRUE(importScene(writeFile("plain.obj", "v 0 0 0\nv 1 0 0 1\nv 0 1 0\nf 1 2 3\n")).mesh.colors.empty());
}

} // namespace
} // namespace penumbra::test

namespace penumbra::test {
namespace {

std::vector<std::string> warnings;
void captureWarning(const std::string& line)
{
    warnings.push_back(line);
}

TEST(ImportColors, ObjMaterialsFromTheMtlLibrary)
{
    writeFile("colors_parts.mtl", "# two materials\nnewmtl steel\nKa 0 0 0\nKd 0.5 0.5 0.6\n\nnewmtl paint\nKd 1 0.25 0\n"
                                  "newmtl spectral\nKd spectral curve.spd\n");
    std::string path = writeFile("colors_parts.obj", "mtllib colors_parts.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
                                                     "f 1 2 3\nusemtl paint\nf 2 4 3\nusemtl steel\nf 1 3 2\n"
                                                     "usemtl paint\nf 4 2 3 1\n");
    warnings.clear();
    WarningSink previous = setWarningSink(captureWarning);
    Mesh mesh = importScene(path).mesh;
    setWarningSink(previous);
    EXPECT_TRUE(warnings.empty());
    ASSERT_EQ(mesh.materials.size(), 3u); // default (before the first usemtl), paint, steel
    EXPECT_EQ(mesh.materials[0].baseColor, glm::vec4(1.0f));
    EXPECT_EQ(mesh.materials[1].name, "paint");
    EXPECT_EQ(mesh.materials[1].baseColor, glm::vec4(1, 0.25f, 0, 1));
    EXPECT_EQ(mesh.materials[2].baseColor, glm::vec4(0.5f, 0.5f, 0.6f, 1));
    EXPECT_EQ(mesh.triangleMaterials, (std::vector<uint32_t>{0, 1, 2, 1, 1}));

    // A missing library: one warning, white surfaces, the geometry as before.
    std::string missing = writeFile("colors_missing.obj", "mtllib nowhere.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl x\nf 1 2 3\n");
    setWarningSink(captureWarning);
    Mesh white = importScene(missing).mesh;
    setWarningSink(previous);
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_NE(warnings[0].find("could not read material library 'nowhere.mtl' (surfaces stay white)"), std::string::npos)
        << warnings[0];
    EXPECT_EQ(white.materials.at(1).baseColor, glm::vec4(1.0f));
    EXPECT_EQ(white.triangleCount(), 1u);
}

} // namespace
} // namespace penumbra::test
