// Negative tests: every malformed, truncated or hostile input is rejected with
// a one-line penumbra::Error naming the file and the problem, and never crashes.
#include <gtest/gtest.h>

#include <filesystem>
#include <random>

#include "penumbra/io.h"
#include "test_helpers.h"

namespace penumbra::test {
namespace {

void expectImportError(const std::string& name, const std::string& bytes, const std::vector<std::string>& fragments)
{
    std::string path = writeFile(name, bytes);
    std::vector<std::string> all = fragments;
    all.push_back(name);
    expectError([&] { importScene(path); }, all);
}

std::string plyHeader(const std::string& format, const std::string& vertexCount, const std::string& faceCount)
{
    return "ply\nformat " + format + " 1.0\nelement vertex " + vertexCount +
           "\nproperty float x\nproperty float y\nproperty float z\nelement face " + faceCount +
           "\nproperty list uchar int vertex_indices\nend_header\n";
}

std::string binaryPly(std::vector<float> positions, std::vector<std::vector<int32_t>> faces)
{
    std::string bytes =
        plyHeader("binary_little_endian", std::to_string(positions.size() / 3), std::to_string(faces.size()));
    for (float f : positions)
        append(bytes, f);
    for (const auto& face : faces) {
        bytes += char(face.size());
        for (int32_t i : face)
            append(bytes, i);
    }
    return bytes;
}

const std::vector<float> kQuad = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};

// ---- generic ----

TEST(BadInput, MissingFile)
{
    expectError([] { importScene(tempPath("does_not_exist.ply")); }, {"does_not_exist.ply", "file not found"});
}

TEST(BadInput, EmptyFileEveryFormat)
{
    for (const char* name : {"empty.ply", "empty.obj", "empty.stl", "empty.glb", "empty.gltf", "empty.drc"})
        expectImportError(name, "", {"empty file"});
}

TEST(BadInput, UnknownExtension)
{
    expectImportError("model.fbx", "whatever", {"unknown model format '.fbx'"});
    expectError([] { importScene(tempPath("noextension")); }, {"noextension", "unknown model format"});
    expectError([] { formatFromPath("dir.v2/model"); }, {"dir.v2/model", "no file extension"});
}

TEST(BadInput, DirectoryIsNotAFile)
{
    std::filesystem::create_directories(tempPath("folder.ply"));
    expectError([] { importScene(tempPath("folder.ply")); }, {"folder.ply", "not a regular file"});
}

// ---- PLY ----

TEST(BadPly, TruncatedVertexData)
{
    std::string bytes = binaryPly(kQuad, {{0, 1, 2}});
    std::string header = plyHeader("binary_little_endian", "4", "1");
    expectImportError("truncated_vertices.ply", bytes.substr(0, header.size() + 20),
                      {"truncated", "4 vertices", "20 bytes of data"});
}

TEST(BadPly, TruncatedFaceData)
{
    std::string bytes = binaryPly(kQuad, {{0, 1, 2}, {0, 2, 3}});
    expectImportError("truncated_faces.ply", bytes.substr(0, bytes.size() - 5), {"truncated", "face 1"});
}

TEST(BadPly, HostileVertexCount)
{
    std::string bytes = plyHeader("binary_little_endian", "1099511627776", "1") + std::string(64, '\0');
    expectImportError("huge_vertices.ply", bytes, {"truncated", "1099511627776 vertices"});
    std::string maxed = plyHeader("binary_little_endian", "18446744073709551615", "1") + std::string(64, '\0');
    expectImportError("max_vertices.ply", maxed, {"malformed element line"});
    std::string ascii = plyHeader("ascii", "1099511627776", "1") + "0 0 0\n";
    expectImportError("huge_vertices_ascii.ply", ascii, {"truncated", "1099511627776"});
}

TEST(BadPly, HostileFaceCountAndListLength)
{
    std::string bytes = plyHeader("binary_little_endian", "4", "4000000000");
    for (float f : kQuad)
        append(bytes, f);
    bytes += std::string(64, '\0');
    expectImportError("huge_faces.ply", bytes, {"truncated", "4000000000 faces"});

    std::string list = plyHeader("binary_little_endian", "4", "1");
    for (float f : kQuad)
        append(list, f);
    list += char(255); // 255 indices claimed, 8 bytes present
    append(list, int32_t(0));
    append(list, int32_t(1));
    expectImportError("huge_list.ply", list, {"truncated", "face 0"});
}

TEST(BadPly, IndexOutOfRange)
{
    expectImportError("bad_index.ply", binaryPly(kQuad, {{0, 1, 2}, {0, 2, 99}}),
                      {"face 1 references vertex 99 but there are 4 vertices"});
    expectImportError("negative_index.ply", binaryPly(kQuad, {{0, -1, 2}}),
                      {"face 0 references vertex -1 but there are 4 vertices"});
    expectImportError("bad_index_quad.ply", binaryPly(kQuad, {{0, 1, 2, 7}}), {"face 0 references vertex 7"});
    std::string ascii = plyHeader("ascii", "4", "1") + "0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 4\n";
    expectImportError("bad_index_ascii.ply", ascii, {"face 0 references vertex 4 but there are 4 vertices"});
}

TEST(BadPly, EmptyVertexElement)
{
    // Found by fuzz_ply: an empty vertex element in the fast float x,y,z path
    // copied 0 bytes into a null pointer (undefined behaviour).
    expectImportError("zero_vertices.ply", binaryPly({}, {{0, 1, 2}}),
                      {"face 0 references vertex 0 but there are 0 vertices"});
}

TEST(BadPly, NonFinitePositions)
{
    std::vector<float> positions = kQuad;
    positions[4] = std::numeric_limits<float>::quiet_NaN();
    expectImportError("nan.ply", binaryPly(positions, {{0, 1, 2}}), {"vertex 1 has a non-finite position"});
    std::string ascii = plyHeader("ascii", "3", "1") + "0 0 0\n1 inf 0\n1 1 0\n3 0 1 2\n";
    expectImportError("inf_ascii.ply", ascii, {"vertex 1 has a non-finite position"});
}

TEST(BadPly, MalformedHeader)
{
    expectImportError("not_ply.ply", "solid x\n", {"not a PLY file"});
    expectImportError("no_end.ply", "ply\nformat ascii 1.0\nelement vertex 3\n", {"no end_header"});
    expectImportError("bad_keyword.ply", "ply\nformat ascii 1.0\nelephant vertex 3\nend_header\n",
                      {"header line 3", "unknown keyword 'elephant'"});
    expectImportError("bad_type.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float3 x\nend_header\n",
                      {"header line 4", "unknown property type 'float3'"});
    expectImportError("bad_count.ply", "ply\nformat ascii 1.0\nelement vertex three\nend_header\n",
                      {"header line 3", "malformed element line"});
    expectImportError("bad_format.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n", {"unknown format"});
    expectImportError("orphan_property.ply", "ply\nformat ascii 1.0\nproperty float x\nend_header\n",
                      {"property before any element"});
    expectImportError("no_xyz.ply",
                      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float u\nelement face 0\n"
                      "property list uchar int vertex_indices\nend_header\n0\n",
                      {"no triangles"});
}

TEST(BadPly, NoTrianglesAndMissingXyz)
{
    std::string cloud =
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
        "end_header\n0 0 0\n";
    expectImportError("cloud.ply", cloud, {"no triangles", "point cloud"});
    expectImportError("lines.ply", binaryPly(kQuad, {{0, 1}, {2, 3}}), {"no triangles"});
    std::string noY = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float z\nelement face 1\n"
                      "property list uchar int vertex_indices\nend_header\n0 0\n3 0 0 0\n";
    expectImportError("no_y.ply", noY, {"no x, y and z"});
}

TEST(BadPly, AsciiMalformedNumber)
{
    std::string ascii = plyHeader("ascii", "3", "1") + "0 0 0\n1 0 zero\n1 1 0\n3 0 1 2\n";
    expectImportError("bad_number.ply", ascii, {"line 11", "malformed number 'zero'"});
    std::string shortFile = plyHeader("ascii", "3", "1") + "0 0 0\n1 0 0\n";
    expectImportError("short_ascii.ply", shortFile, {"truncated"});
}

// ---- OBJ ----

TEST(BadObj, Problems)
{
    expectImportError("lines.obj", "v 0 0 0\nv 1 0 0\nl 1 2\n", {"no triangles (points or lines only)"});
    expectImportError("no_faces.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n", {"no triangles", "no faces"});
    expectImportError("bad_number.obj", "v 0 0 0\nv 1 x 0\n", {"line 2", "malformed number 'x'"});
    expectImportError("short_vertex.obj", "v 0 0\n", {"line 1", "fewer than 3 coordinates"});
    expectImportError("bad_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n",
                      {"line 5", "references vertex 9 but there are 3 vertices"});
    expectImportError("zero_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", {"line 4", "vertex 0"});
    expectImportError("negative_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n",
                      {"line 4", "vertex -4", "only 3 vertices precede it"});
    expectImportError("bad_corner.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 three\n", {"malformed face corner 'three'"});
    expectImportError("inf.obj", "v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n", {"vertex 1 has a non-finite position"});
    expectImportError("nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", {"non-finite"});
    expectImportError("binary.obj", std::string("\x7f\x45LF\0\0\0", 7), {"no vertices or faces"});
}

// ---- STL ----

TEST(BadStl, Problems)
{
    std::string bytes(80, ' ');
    append(bytes, uint32_t(10)); // claims 10 triangles, holds 1
    bytes += std::string(50, '\0');
    expectImportError("truncated.stl", bytes, {"truncated", "10 triangles", "584 bytes"});
    std::string hostile(80, ' ');
    append(hostile, uint32_t(0xffffffff));
    expectImportError("hostile.stl", hostile, {"truncated", "4294967295 triangles"});
    expectImportError("tiny.stl", "abc", {"truncated", "84 bytes"});
    std::string solidHeader = "solid exported by some tool";
    solidHeader.resize(80, ' ');
    append(solidHeader, uint32_t(3));
    solidHeader += std::string(70, '\0');
    expectImportError("solid_truncated.stl", solidHeader, {"truncated", "3 triangles"});
    expectImportError("unterminated.stl", "solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n",
                      {"truncated", "line 3"});
    expectImportError("bad_number.stl",
                      "solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 one 0\n"
                      "endloop\nendfacet\nendsolid\n",
                      {"line 6", "malformed number 'one'"});
    expectImportError("empty_solid.stl", "solid a\nendsolid a\n", {"no triangles"});
    std::string nan(80, ' ');
    append(nan, uint32_t(1));
    for (float f : {0.f, 0.f, 1.f, 0.f, 0.f, 0.f, std::numeric_limits<float>::infinity(), 0.f, 0.f, 0.f, 1.f, 0.f})
        append(nan, f);
    append(nan, uint16_t(0));
    expectImportError("inf.stl", nan, {"non-finite position"});
}

// ---- glTF / GLB ----

std::string triangleBin(uint16_t lastIndex = 2)
{
    std::string bin;
    for (float f : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f})
        append(bin, f);
    for (uint16_t i : {uint16_t(0), uint16_t(1), lastIndex, uint16_t(0)})
        append(bin, i);
    return bin;
}

// A one-triangle glTF; the parts can be overridden to inject faults.
const std::string kAccessors = R"([{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
                {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}])";
const std::string kPrimitive = R"({"attributes": {"POSITION": 0}, "indices": 1})";

std::string triangleJson(const std::string& accessors = kAccessors, const std::string& primitive = kPrimitive,
                         const std::string& nodes = R"([{"mesh": 0}])",
                         const std::string& bufferViews =
                             R"([{"buffer": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 8}])")
{
    return R"({"asset": {"version": "2.0"}, "buffers": [{"byteLength": 44}], "bufferViews": )" + bufferViews +
           R"(, "accessors": )" + accessors + R"(, "meshes": [{"primitives": [)" + primitive + R"(]}], "nodes": )" +
           nodes + "}";
}

TEST(BadGltf, Container)
{
    expectImportError("bad_magic.glb", "glTX0000000000000000000000", {"not a glTF binary (bad magic)"});
    expectImportError("short.glb", "glTF", {"not a glTF binary", "too short"});
    std::string good = makeGlb(triangleJson(), triangleBin());
    ASSERT_NO_THROW(importScene(writeFile("good.glb", good)));
    expectImportError("truncated.glb", good.substr(0, good.size() - 10), {"truncated", "header says"});
    std::string bigChunk = good;
    uint32_t huge = 0x7ffffff0;
    std::memcpy(&bigChunk[12], &huge, 4);
    expectImportError("big_chunk.glb", bigChunk, {"truncated", "JSON chunk"});
    std::string version = good;
    version[4] = 3;
    expectImportError("version.glb", version, {"unsupported glTF binary version 3"});
    expectImportError("bad_json.glb", makeGlb("{\"asset\": ", triangleBin()), {"malformed JSON"});
    expectImportError("bad_json.gltf", "{]", {"malformed JSON"});
    expectImportError("no_asset.gltf", "{}", {"missing asset.version"});
    expectImportError("deep.gltf", std::string(200000, '[') + std::string(200000, ']'), {"not a JSON object"});
    expectImportError("deep_open.gltf", std::string(200000, '{'), {"malformed JSON"});
    expectImportError("v1.gltf", R"({"asset": {"version": "1.0"}})", {"unsupported glTF version '1.0'"});
    expectImportError("ext.gltf", R"({"asset": {"version": "2.0"}, "extensionsRequired": ["EXT_meshopt_compression"]})",
                      {"unsupported extension 'EXT_meshopt_compression'"});
}

TEST(BadGltf, ReferencesAndBounds)
{
    expectImportError("bad_accessor_ref.glb", makeGlb(triangleJson(R"([])"), triangleBin()),
                      {"references accessor 0 but there are 0"});
    expectImportError("index_range.glb", makeGlb(triangleJson(), triangleBin(7)),
                      {"mesh 0 primitive 0", "triangle 0 references vertex 7 but there are 3 vertices"});
    expectImportError("accessor_overrun.glb",
                      makeGlb(triangleJson(R"([{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
                                           {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}])"),
                          triangleBin()),
                      {"truncated", "accessor 0", "runs past the end of its bufferView"});
    expectImportError(
        "hostile_count.glb",
        makeGlb(triangleJson(R"([{"bufferView": 0, "componentType": 5126, "count": 1099511627776, "type": "VEC3"},
                                           {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}])"),
            triangleBin()),
        {"truncated", "1099511627776 elements"});
    expectImportError(
        "view_overrun.glb",
        makeGlb(triangleJson(R"([{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
                                           {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}])",
                         R"({"attributes": {"POSITION": 0}, "indices": 1})", R"([{"mesh": 0}])",
                         R"([{"buffer": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 40, "byteLength": 8}])"),
            triangleBin()),
        {"bufferView 1", "runs past the end of its buffer"});
    expectImportError(
        "buffer_short.gltf",
        R"({"asset": {"version": "2.0"}, "buffers": [{"byteLength": 44, "uri": "data:application/octet-stream;base64,AAAA"}],
                          "bufferViews": [{"buffer": 0, "byteLength": 36}], "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}],
                          "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}], "nodes": [{"mesh": 0}]})",
        {"truncated", "buffer 0 declares 44 bytes but only 3"});
    expectImportError("missing_bin.gltf",
                      R"({"asset": {"version": "2.0"}, "buffers": [{"byteLength": 44, "uri": "nowhere.bin"}],
                          "bufferViews": [{"buffer": 0, "byteLength": 36}], "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}],
                          "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}], "nodes": [{"mesh": 0}]})",
                      {"buffer 0", "nowhere.bin: file not found"});
    expectImportError("wrong_type.glb",
                      makeGlb(triangleJson(R"([{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}])",
                                       R"({"attributes": {"POSITION": "zero"}})"),
                          triangleBin()),
                      {"POSITION", "expected a non-negative integer"});
    expectImportError(
        "sparse.glb",
        makeGlb(triangleJson(R"([{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "sparse": {}},
                                           {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}])"),
            triangleBin()),
        {"accessor 0 sparse has no 'count'"});
    // Sparse indices outside the accessor, sparse values past their bufferView.
    const std::string sparseAccessors = R"([{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
        "sparse": {"count": 1, "indices": {"bufferView": 1, "componentType": 5123}, "values": {"bufferView": 0, "byteOffset": VALUES}}},
        {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}])";
    auto sparseGlb = [&](const std::string& valuesOffset, uint16_t firstIndex) {
        std::string accessors = sparseAccessors;
        accessors.replace(accessors.find("VALUES"), 6, valuesOffset);
        return makeGlb(triangleJson(accessors), triangleBin(2).replace(36, 2, std::string(reinterpret_cast<const char*>(&firstIndex), 2)));
    };
    expectImportError("sparse_index.glb", sparseGlb("0", 7), {"accessor 0 sparse: index 7 is outside the accessor's 3 elements"});
    expectImportError("sparse_values.glb", sparseGlb("30", 0), {"truncated", "accessor 0 sparse values", "12 bytes at offset 30"});
    // A zero-filled accessor (no bufferView) may not claim far more memory than the file holds.
    expectImportError("zero_filled.glb",
                      makeGlb(triangleJson(R"([{"componentType": 5126, "count": 1000000000, "type": "VEC3"}])",
                                           R"({"attributes": {"POSITION": 0}})"),
                              triangleBin()),
                      {"accessor 0 has no bufferView and 1000000000 elements", "times the input size"});
}

TEST(BadGltf, CycleAndNonTriangles)
{
    std::string cyclic =
        triangleJson(R"([{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
                {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}])",
                     R"({"attributes": {"POSITION": 0}, "indices": 1})",
                     R"([{"mesh": 0, "children": [1]}, {"children": [0]}], "scenes": [{"nodes": [0]}])");
    expectImportError("cycle2.glb", makeGlb(cyclic, triangleBin()), {"node 0 appears more than once"});
    std::string points = triangleJson(R"([{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}])",
                                      R"({"attributes": {"POSITION": 0}, "mode": 0})");
    expectImportError("points.glb", makeGlb(points, triangleBin()), {"no triangles (points or lines only)"});
    std::string lines = triangleJson(R"([{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}])",
                                     R"({"attributes": {"POSITION": 0}, "mode": 3})");
    expectImportError("lines.gltf", lines, {"no triangles (points or lines only)"});
    std::string noMesh = R"({"asset": {"version": "2.0"}, "nodes": [{}]})";
    expectImportError("nomesh.gltf", noMesh, {"no triangles"});
    std::string badMode = triangleJson(R"([{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}])",
                                       R"({"attributes": {"POSITION": 0}, "mode": 9})");
    expectImportError("badmesh.glb", makeGlb(triangleJson(kAccessors, kPrimitive, R"([{"mesh": 3}])"), triangleBin()),
                      {"node 0 references mesh 3 but there are 1"});
    expectImportError("badmode.glb", makeGlb(badMode, triangleBin()), {"invalid mode 9"});
}

TEST(BadGltf, CorruptDraco)
{
    Scene scene;
    scene.mesh = makeGrid(6);
    ExportOptions options;
    options.draco = true;
    std::string path = tempPath("draco_source.glb");
    exportScene(scene, path, options);
    std::string bytes = readFile(path);
    // The Draco blob is the BIN chunk payload at the end: zero out its middle.
    uint32_t jsonLength;
    std::memcpy(&jsonLength, &bytes[12], 4);
    size_t binStart = 20 + jsonLength + 8;
    std::string corrupt = bytes;
    for (size_t i = binStart; i < corrupt.size(); ++i)
        corrupt[i] = char(0xA5);
    expectImportError("corrupt_draco.glb", corrupt, {"mesh 0 primitive 0", "Draco"});
}

// ---- Draco ----

TEST(BadDraco, GarbageAndTruncation)
{
    expectImportError("garbage.drc", "this is not draco data at all", {"not Draco data"});
    Scene scene;
    scene.mesh = makeGrid(6);
    std::string path = tempPath("source.drc");
    exportScene(scene, path);
    std::string bytes = readFile(path);
    expectImportError("truncated.drc", bytes.substr(0, bytes.size() / 2), {"Draco"});
}

TEST(BadDraco, HostileCounts)
{
    // Found by fuzz_drc: 44 bytes (bitstream 1.248, edgebreaker, uint32 counts)
    // claiming 269 M faces made libdraco allocate a 3.2 GB corner table.
    const unsigned char bomb[] = {0x44, 0x52, 0x41, 0x43, 0x4f, 0x01, 0xf8, 0x01, 0x01, 0x4f, 0x4f, 0x02, 0x02, 0x01, 0x01,
                                  0x08, 0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x10,
                                  0x10, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x08, 0x00};
    expectImportError("bomb.drc", std::string(reinterpret_cast<const char*>(bomb), sizeof(bomb)),
                      {"corrupt Draco data (claims 269488144 faces and 269488144 vertices in 44 bytes)"});
    // The same in a current (2.2, varint) edgebreaker header: 2^27 faces in a 24-byte file.
    std::string current = std::string("DRACO\x02\x02\x01\x01\x00\x00\x00", 12) + "\x80\x80\x80\x40" +
                          "\x80\x80\x80\x40" + std::string(4, '\0');
    expectImportError("bomb22.drc", current, {"claims 134217728 faces and 134217728 vertices in 24 bytes"});
    // Found by fuzz_drc next: bitstream 1.1 with the metadata flag set (metadata exists only
    // from 1.3, so libdraco ignores the flag) claiming 505 M faces (a 6 GB corner table).
    const unsigned char oldFlag[] = {0x44, 0x52, 0x41, 0x43, 0x4f, 0x01, 0x01, 0x01, 0x01, 0x00, 0xab, 0x00,
                                     0x09, 0x08, 0x52, 0x44, 0x00, 0x01, 0x7e, 0x1e, 0x1e, 0x1e, 0x1e, 0x1e,
                                     0x1e, 0x1e, 0x1e, 0x1e, 0x1e, 0x1e, 0x1e, 0x1e, 0x1e, 0x1e, 0x1e, 0x1e};
    expectImportError("bomb_flag.drc", std::string(reinterpret_cast<const char*>(oldFlag), sizeof(oldFlag)),
                      {"claims 505290270 faces"});
    // 2.2 with metadata (one file entry "k" = 1 byte, one empty sub-element "s") before the counts.
    std::string withMetadata = std::string("DRACO\x02\x02\x01\x01\x00\x80", 11) +
                               std::string("\x00\x01\x01k\x01v\x01\x01s\x00\x00", 11) + std::string(1, '\0') +
                               "\x80\x80\x80\x40" + "\x80\x80\x80\x40" + std::string(4, '\0');
    expectImportError("bomb_metadata.drc", withMetadata, {"claims 134217728 faces and 134217728 vertices"});
}

// ---- export ----

TEST(BadExport, Failures)
{
    Scene empty;
    expectError([] { exportScene(Scene{}, tempPath("nothing.ply")); }, {"nothing.ply", "no triangles"});
    Scene scene;
    scene.mesh = makeGrid(1);
    expectError([&] { exportScene(scene, tempPath("model.xyz")); }, {"model.xyz", "unknown model format"});
    std::string missingDir = tempPath("no_such_dir/model.ply");
    expectError([&] { exportScene(scene, missingDir); }, {"model.ply", "cannot create"});
    Scene broken = scene;
    broken.mesh.indices[2] = 42;
    expectError([&] { exportScene(broken, tempPath("broken.glb")); }, {"broken.glb", "references vertex 42"});
    EXPECT_FALSE(std::filesystem::exists(tempPath("broken.glb")));
    Scene nan = scene;
    nan.mesh.positions[0] = std::numeric_limits<float>::quiet_NaN();
    expectError([&] { exportScene(nan, tempPath("nan.obj")); }, {"nan.obj", "non-finite"});
}

// ---- robustness sweep: truncations and byte flips of valid files ----

TEST(BadInput, TruncationAndCorruptionNeverCrash)
{
    Scene scene;
    scene.mesh = makeGrid(3);
    scene.cameras.push_back(Camera{});
    scene.lights.push_back(Light{});
    struct Variant {
        const char* name;
        bool binary;
        bool draco;
    };
    std::mt19937 random(1234);
    for (Variant variant :
         {Variant{"fuzz.ply", true, false}, Variant{"fuzz_ascii.ply", false, false}, Variant{"fuzz.obj", true, false},
          Variant{"fuzz.stl", true, false}, Variant{"fuzz_ascii.stl", false, false}, Variant{"fuzz.glb", true, false},
          Variant{"fuzz_draco.glb", true, true}, Variant{"fuzz.gltf", true, false}, Variant{"fuzz.drc", true, false}}) {
        std::string source = tempPath(std::string("source_") + variant.name);
        ExportOptions options;
        options.binary = variant.binary;
        options.draco = variant.draco;
        exportScene(scene, source, options);
        std::string bytes = readFile(source);
        std::string target = tempPath(variant.name);
        size_t step = std::max<size_t>(1, bytes.size() / 97);
        for (size_t length = 0; length < bytes.size(); length += step) {
            writeFile(variant.name, bytes.substr(0, length));
            try {
                importScene(target);
            } catch (const Error&) {
            }
        }
        for (int trial = 0; trial < 150; ++trial) {
            std::string mutated = bytes;
            int flips = 1 + int(random() % 4);
            for (int f = 0; f < flips; ++f)
                mutated[random() % mutated.size()] = char(random());
            writeFile(variant.name, mutated);
            try {
                Scene loaded = importScene(target);
                for (uint32_t index : loaded.mesh.indices)
                    ASSERT_LT(index, loaded.mesh.vertexCount());
            } catch (const Error&) {
            }
        }
    }
}

} // namespace
} // namespace penumbra::test
