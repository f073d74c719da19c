// Streamed reading (model_stream.h) gives exactly what importScene gives:
// every real-world and fuzz seed file, generated scenes in every format (with
// small buffers, so records straddle refills), colours and materials; a file
// importScene rejects (truncated at many points, hostile seeds) is rejected too.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>

#include "penumbra/io.h"
#include "penumbra/model_stream.h"
#include "test_helpers.h"

namespace penumbra::test {
namespace {

std::string sourceDir()
{
    return std::filesystem::path(__FILE__).parent_path().parent_path().string();
}

bool sameBits(const std::vector<float>& a, const std::vector<float>& b)
{
    return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0);
}

// Compares a streamed read of path with importScene; returns whether both accepted it.
bool expectSameAsImport(const std::string& path, size_t bufferBytes = size_t(1) << 16)
{
    SCOPED_TRACE(path + " (buffer " + std::to_string(bufferBytes) + ")");
    std::string importError, streamError;
    Scene imported, streamed;
    try {
        imported = importScene(path);
    } catch (const Error& e) {
        importError = e.what();
    }
    try {
        ModelStreamOptions options;
        options.tempDirectory = PENUMBRA_TEST_TMP;
        options.bufferBytes = bufferBytes;
        std::unique_ptr<ModelStream> stream = openModelStream(path, options);
        streamed = readModelStream(*stream);
    } catch (const Error& e) {
        streamError = e.what();
    }
    if (!importError.empty()) {
        EXPECT_NE(streamError, "") << "importScene failed (" << importError << ") but the stream read the file";
        if (!streamError.empty()) {
            EXPECT_EQ(streamError.rfind(path + ": ", 0), 0u) << streamError;
        }
        return false;
    }
    EXPECT_EQ(streamError, "") << "importScene read the file";
    if (!streamError.empty())
        return false;
    const Mesh &a = imported.mesh, &b = streamed.mesh;
    EXPECT_TRUE(sameBits(a.positions, b.positions)) << a.positions.size() << " / " << b.positions.size() << " floats";
    EXPECT_EQ(a.indices, b.indices);
    EXPECT_TRUE(sameBits(a.colors, b.colors)) << a.colors.size() << " / " << b.colors.size() << " colour floats";
    EXPECT_EQ(a.triangleMaterials, b.triangleMaterials);
    EXPECT_EQ(a.materials.size(), b.materials.size());
    for (size_t m = 0; m < std::min(a.materials.size(), b.materials.size()); ++m) {
        EXPECT_EQ(a.materials[m].baseColor, b.materials[m].baseColor) << "material " << m;
        EXPECT_EQ(a.materials[m].name, b.materials[m].name) << "material " << m;
    }
    EXPECT_EQ(imported.cameras.size(), streamed.cameras.size());
    for (size_t c = 0; c < std::min(imported.cameras.size(), streamed.cameras.size()); ++c) {
        EXPECT_EQ(imported.cameras[c].position, streamed.cameras[c].position);
        EXPECT_EQ(imported.cameras[c].target, streamed.cameras[c].target);
        EXPECT_EQ(imported.cameras[c].yfovDegrees, streamed.cameras[c].yfovDegrees);
    }
    EXPECT_EQ(imported.lights.size(), streamed.lights.size());
    for (size_t l = 0; l < std::min(imported.lights.size(), streamed.lights.size()); ++l) {
        EXPECT_EQ(imported.lights[l].position, streamed.lights[l].position);
        EXPECT_EQ(imported.lights[l].direction, streamed.lights[l].direction);
        EXPECT_EQ(imported.lights[l].intensity, streamed.lights[l].intensity);
    }
    return true;
}

TEST(ModelStream, RealWorldAndFuzzSeedFiles)
{
    size_t accepted = 0, files = 0;
    for (const std::string folder : {"/formats/data/real_world", "/fuzz/corpus_obj", "/fuzz/corpus_ply", "/fuzz/corpus_stl",
                                     "/fuzz/corpus_gltf"})
        for (const auto& entry : std::filesystem::directory_iterator(sourceDir() + folder)) {
            const std::string path = entry.path().string();
            std::string name = entry.path().filename().string();
            // Seeds without an extension are named by their folder's format.
            if (path.find(".mtl") != std::string::npos)
                continue;
            std::string copy = path;
            if (entry.path().extension().empty()) {
                const std::string format = folder.substr(folder.rfind('_') + 1);
                copy = writeFile("stream_seed_" + name + "." + (format == "gltf" ? "glb" : format), readFile(path));
            }
            ++files;
            accepted += expectSameAsImport(copy);
        }
    std::printf("[ stream ] %zu of %zu seed files read by both, the others rejected by both\n", accepted, files);
    EXPECT_GT(accepted, files / 2) << "most seed files are valid models";
}

Mesh grid(int n)
{
    Mesh mesh = makeGrid(n);
    return mesh;
}

TEST(ModelStream, GeneratedFilesInEveryFormatAndBufferSize)
{
    Scene scene;
    scene.mesh = grid(40);
    Light light;
    light.type = LightType::Spot;
    light.position = {1, 5, 2};
    light.outerConeDegrees = 40;
    scene.lights.push_back(light);
    Camera camera;
    camera.position = {0, 10, 30};
    camera.target = {20, 0, 20};
    scene.cameras.push_back(camera);
    struct Case {
        const char* name;
        bool binary;
        bool draco;
    } cases[] = {{"stream.ply", true, false},  {"stream_ascii.ply", false, false}, {"stream.obj", true, false},
                 {"stream.stl", true, false},  {"stream_ascii.stl", false, false}, {"stream.gltf", true, false},
                 {"stream.glb", true, false},  {"stream_draco.glb", true, true}};
    for (const Case& c : cases) {
        ExportOptions options;
        options.binary = c.binary;
        options.draco = c.draco;
        const std::string path = tempPath(c.name);
        exportScene(scene, path, options);
        EXPECT_TRUE(expectSameAsImport(path));
        EXPECT_TRUE(expectSameAsImport(path, 4096)); // records and tokens straddle refills
    }
}

TEST(ModelStream, ColoursAndMaterials)
{
    // PLY: ASCII vertex colours; binary float vertex colours and uchar face colours after the list.
    const std::string asciiColours = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\n"
                                     "property float y\nproperty float z\nproperty uchar red\n"
                                     "property uchar green\nproperty uchar blue\nelement face 2\n"
                                     "property list uchar int vertex_indices\nproperty uchar red\nproperty uchar green\n"
                                     "property uchar blue\nend_header\n"
                                     "0 0 0 255 0 0\n1 0 0 0 255 0\n0 1 0 51 102 255\n1 1 0 1 2 3\n"
                                     "3 0 1 2 10 20 30\n3 1 3 2 10 20 30\n";
    EXPECT_TRUE(expectSameAsImport(writeFile("stream_colours.ply", asciiColours)));
    std::string bytes = "ply\nformat binary_big_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                        "property float z\nproperty float red\nproperty float green\nproperty float blue\n"
                        "element face 2\nproperty list uchar int vertex_indices\nproperty uchar red\nproperty uchar green\n"
                        "property uchar blue\nend_header\n";
    auto bigEndian = [&](auto value) {
        char raw[sizeof(value)];
        std::memcpy(raw, &value, sizeof(value));
        std::reverse(raw, raw + sizeof(value));
        bytes.append(raw, sizeof(value));
    };
    const float vertices[4][6] = {{0, 0, 0, 1, 1, 1}, {1, 0, 0, 0.5f, 0.5f, 0.5f}, {1, 1, 0, 2, -1, 0.25f}, {0, 1, 0, 0, 0, 0}};
    for (const auto& v : vertices)
        for (float f : v)
            bigEndian(f);
    bytes += char(4);
    for (int32_t i : {0, 1, 2, 3})
        bigEndian(i);
    bytes += std::string("\xff\x00\x00", 3);
    bytes += char(3);
    for (int32_t i : {0, 2, 1})
        bigEndian(i);
    bytes += std::string("\x00\x00\xff", 3);
    EXPECT_TRUE(expectSameAsImport(writeFile("stream_colours_be.ply", bytes)));
    // A vertex element with a list property (no fixed stride: a temporary vertex store).
    std::string listVertices = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty list uchar float extra\n"
                               "property float x\nproperty float y\nproperty float z\nelement face 1\n"
                               "property list uchar uint vertex_indices\nend_header\n";
    for (int v = 0; v < 3; ++v) {
        append(listVertices, uint8_t(v));
        for (int k = 0; k < v; ++k)
            append(listVertices, 9.0f);
        for (float f : {float(v & 1), float(v >> 1), 0.5f})
            append(listVertices, f);
    }
    append(listVertices, uint8_t(3));
    for (uint32_t i : {0u, 1u, 2u})
        append(listVertices, i);
    EXPECT_TRUE(expectSameAsImport(writeFile("stream_list_vertices.ply", listVertices)));
    // OBJ: vertex colours from the third vertex on, usemtl with an mtl file, continued records, negative indices.
    writeFile("stream_materials.mtl", "newmtl red\nKd 1 0 0\nnewmtl blue\nKd 0 0 1\n");
    const std::string obj = "mtllib stream_materials.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0 0.5 0.25 1\nv 1 1 0\n"
                            "f 1 2 3\nusemtl red\nf 2 4 \\\n 3\nusemtl blue\nf -4 -3 -1\nusemtl red\nf 1/1/1 3//2 4\n"
                            "# comment\nl 1 2\nf 1 2\n";
    EXPECT_TRUE(expectSameAsImport(writeFile("stream_materials.obj", obj)));
    EXPECT_TRUE(expectSameAsImport(writeFile("stream_materials.obj", obj), 4096));
}

TEST(ModelStream, TruncatedAndBadFilesAreRejectedToo)
{
    Scene scene;
    scene.mesh = grid(12);
    for (const char* name : {"stream_cut.ply", "stream_cut_ascii.ply", "stream_cut.obj", "stream_cut.stl", "stream_cut.glb"}) {
        ExportOptions options;
        options.binary = std::string(name).find("ascii") == std::string::npos;
        const std::string path = tempPath(name);
        exportScene(scene, path, options);
        const std::string bytes = readFile(path);
        const std::string extension = std::string(name).substr(std::string(name).rfind('.'));
        for (size_t cut : {size_t(0), size_t(3), size_t(50), bytes.size() / 3, bytes.size() / 2, bytes.size() - 7,
                           bytes.size() - 1})
            expectSameAsImport(writeFile(std::string("stream_cut_") + std::to_string(cut) + extension, bytes.substr(0, cut)));
    }
    // Index out of range, non-finite positions, a point cloud.
    expectSameAsImport(writeFile("stream_bad_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n"));
    expectSameAsImport(writeFile("stream_nan.obj", "v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n"));
    expectSameAsImport(writeFile("stream_points.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                                                      "property float y\nproperty float z\nend_header\n0 0 0\n"));
    expectSameAsImport(writeFile("stream_bad_face.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                                                        "property float y\nproperty float z\nelement face 1\n"
                                                        "property list uchar int vertex_indices\nend_header\n"
                                                        "0 0 0\n1 0 0\n0 1 0\n3 0 1 -1\n"));
    // A Draco file cannot be streamed: one clear line.
    const std::string drc = tempPath("stream.drc");
    exportScene(scene, drc);
    try {
        openModelStream(drc);
        FAIL() << "a .drc file was opened for streaming";
    } catch (const Error& e) {
        EXPECT_EQ(std::string(e.what()), drc + ": a Draco file is one compressed mesh and cannot be streamed; preprocess "
                                               "it without --memory-limit or convert it, e.g. to PLY");
    }
}

} // namespace
} // namespace penumbra::test
