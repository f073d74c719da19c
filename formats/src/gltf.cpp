// glTF 2.0 import and export (.gltf with external or data: buffers, .glb),
// including KHR_draco_mesh_compression and KHR_lights_punctual.
// Reference: Khronos glTF 2.0 specification, sections 3.5-3.7 (nodes,
// buffers, accessors, meshes), 3.10 (cameras), 4.4 (GLB container).
// The JSON is parsed with nlohmann::json; every index, offset and length is
// range-checked against the arrays and buffers before it is used.
#include <cmath>
#include <functional>
#include <map>
#include <memory>
#include <span>

#include <draco/compression/decode.h>
#include <glm/ext/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <nlohmann/json.hpp>

#include "io_internal.h"

namespace penumbra::detail {
namespace {

using json = nlohmann::json;

constexpr uint32_t kGlbMagic = 0x46546C67;            // "glTF"
constexpr uint32_t kChunkJson = 0x4E4F534A;           // "JSON"
constexpr uint32_t kChunkBin = 0x004E4942;            // "BIN\0"
constexpr uint64_t kMaxTriangles = uint64_t(1) << 30; // after instancing; bounds memory for hostile node graphs
constexpr uint64_t kMaxVertices = uint64_t(1) << 30;  // after instancing
// Streaming: the primitive in memory stays below the in-core limits; the whole
// scene may expand to this many (a hostile node graph still ends in finite time).
constexpr uint64_t kMaxStreamTriangles = uint64_t(1) << 40;
constexpr uint64_t kMaxStreamRead = uint64_t(1) << 34; // bytes of one accessor range or Draco primitive
constexpr size_t kMaxNodeDepth = 1024;
// Accessors without a bufferView (zeros plus sparse values) may take at most
// this many times the input size (plus 1 MiB), so a tiny file cannot claim gigabytes.
constexpr uint64_t kMaterializeFactor = 16;
constexpr double kPi = 3.14159265358979323846;

const json* member(const json& object, const char* key)
{
    if (!object.is_object())
        return nullptr;
    auto it = object.find(key);
    return it == object.end() ? nullptr : &*it;
}

// ---- base64 (data: URIs) ----

bool decodeBase64(std::string_view text, std::vector<uint8_t>& out)
{
    auto value = [](char c) -> int {
        if (c >= 'A' && c <= 'Z')
            return c - 'A';
        if (c >= 'a' && c <= 'z')
            return c - 'a' + 26;
        if (c >= '0' && c <= '9')
            return c - '0' + 52;
        if (c == '+' || c == '-')
            return 62;
        if (c == '/' || c == '_')
            return 63;
        return -1;
    };
    out.clear();
    out.reserve(text.size() / 4 * 3 + 3);
    uint32_t accumulator = 0;
    int bits = 0;
    for (char c : text) {
        if (c == '=')
            break;
        int v = value(c);
        if (v < 0)
            return false;
        accumulator = (accumulator << 6) | uint32_t(v);
        bits += 6;
        if (bits >= 8) {
            bits -= 8;
            out.push_back(uint8_t(accumulator >> bits));
        }
    }
    return true;
}

std::string encodeBase64(const uint8_t* data, size_t size)
{
    static const char table[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    out.reserve((size + 2) / 3 * 4);
    size_t i = 0;
    for (; i + 2 < size; i += 3) {
        uint32_t v = (uint32_t(data[i]) << 16) | (uint32_t(data[i + 1]) << 8) | data[i + 2];
        out += table[v >> 18];
        out += table[(v >> 12) & 63];
        out += table[(v >> 6) & 63];
        out += table[v & 63];
    }
    if (i < size) {
        uint32_t v = uint32_t(data[i]) << 16;
        if (i + 1 < size)
            v |= uint32_t(data[i + 1]) << 8;
        out += table[v >> 18];
        out += table[(v >> 12) & 63];
        out += i + 1 < size ? table[(v >> 6) & 63] : '=';
        out += '=';
    }
    return out;
}

std::string percentDecode(const std::string& uri)
{
    std::string out;
    for (size_t i = 0; i < uri.size(); ++i) {
        if (uri[i] == '%' && i + 2 < uri.size() && std::isxdigit(static_cast<unsigned char>(uri[i + 1])) &&
            std::isxdigit(static_cast<unsigned char>(uri[i + 2]))) {
            out += char(std::stoi(uri.substr(i + 1, 2), nullptr, 16));
            i += 2;
        } else {
            out += uri[i];
        }
    }
    return out;
}

// ---- reader ----

struct AccessorView {
    const uint8_t* data = nullptr;
    uint64_t count = 0;
    size_t stride = 0;
    int componentType = 0;
    int components = 0;
    bool normalized = false;
};

struct PendingCamera {
    Camera camera;
    glm::vec3 forward{0.0f, 0.0f, -1.0f};
    bool hasTargetDistance = false;
};

// Where a buffer's bytes are: in memory (mapped, decoded from a data: URI or,
// streaming, the GLB's BIN chunk is not), or in a file read with pread (streaming).
struct BufferSource {
    std::span<const uint8_t> memory;
    FileReader* file = nullptr;
    uint64_t base = 0;   // file offset of byte 0 (file sources)
    uint64_t length = 0; // the buffer's byteLength
};

// A bufferView: its buffer and its byte range there (checked against the buffer's length).
struct ViewRange {
    uint64_t buffer = 0;
    uint64_t offset = 0;
    uint64_t length = 0;
};

class GltfReader {
  public:
    GltfReader(const std::string& path, const MappedFile& file, bool binary) : path_(path), binary_(binary)
    {
        std::string_view jsonText;
        if (binary)
            jsonText = parseGlbContainer(file);
        else
            jsonText = file.text();
        init(jsonText, file.size());
    }

    // Streaming (model_stream.h): nothing is mapped; the JSON is read whole, buffer bytes with pread
    // as accessors need them, and each primitive goes to the sink instead of into one mesh.
    GltfReader(const std::string& path, FileReader& file, bool binary) : path_(path), binary_(binary), streaming_(true)
    {
        if (file.size() == 0)
            fail(path, "empty file");
        glbFile_ = &file;
        if (binary) {
            parseGlbStream(file);
        } else {
            if (file.size() > (uint64_t(1) << 32))
                fail(path, "a .gltf file (JSON) of more than 4 GiB; put the buffers in .bin files or use .glb");
            jsonStorage_.resize(size_t(file.size()));
            file.readAt(0, jsonStorage_.data(), jsonStorage_.size());
        }
        init(jsonStorage_, file.size());
    }

    // Streaming: receives each primitive instance (positions in world space, its indices, with the
    // winding fixed for mirroring transforms) and its material; the mesh is cleared after the call.
    using PrimitiveSink = std::function<void(const Mesh& primitive, uint32_t material, const std::string& where)>;
    void setSink(PrimitiveSink sink) { sink_ = std::move(sink); }

    // Streaming: what read() does with the finished mesh, from the traversal's results.
    uint64_t streamedTriangles() const { return streamedTriangles_; }
    bool materialUsed() const { return materialUsed_; }

  private:
    void init(std::string_view jsonText, uint64_t fileSize)
    {
        const std::string& path = path_;
        size_t slash = path.find_last_of('/');
        directory_ = slash == std::string::npos ? std::string() : path.substr(0, slash + 1);
        try {
            doc_ = json::parse(jsonText.begin(), jsonText.end());
        } catch (const json::exception& e) {
            fail(path, std::string("malformed JSON: ") + e.what());
        }
        if (!doc_.is_object())
            fail(path, "malformed glTF: top level is not a JSON object");
        const json* asset = member(doc_, "asset");
        const json* version = asset ? member(*asset, "version") : nullptr;
        if (!version || !version->is_string())
            fail(path, "malformed glTF: missing asset.version");
        std::string v = version->get<std::string>();
        if (v.empty() || v[0] != '2')
            fail(path, "unsupported glTF version " + quoteToken(v) + " (only 2.x)");
        if (const json* required = member(doc_, "extensionsRequired"); required && required->is_array()) {
            for (const json& name : *required) {
                std::string extension = name.is_string() ? name.get<std::string>() : std::string("?");
                if (extension != "KHR_draco_mesh_compression" && extension != "KHR_lights_punctual" &&
                    extension != "KHR_mesh_quantization" && extension != "KHR_materials_unlit" &&
                    extension != "KHR_texture_transform")
                    fail(path, "requires unsupported extension " + quoteToken(extension));
            }
        }
        materializeBudget_ = (uint64_t(1) << 20) + kMaterializeFactor * fileSize;
        buffers_.resize(arraySize("buffers"));
        bufferLoaded_.resize(buffers_.size(), false);
    }

  public:
    Scene read()
    {
        Scene scene;
        std::vector<PendingCamera> cameras;
        traverse(scene, cameras);
        // Materials: only when some primitive names one (the others get a white default).
        if (!materialUsed_) {
            scene.mesh.materials.clear();
            scene.mesh.triangleMaterials.clear();
        }
        if (scene.mesh.indices.empty())
            failNoTriangles();
        warnSkipped();
        finishCameras(cameras, computeBounds(scene.mesh).center(), scene);
        return scene;
    }

    [[noreturn]] void failNoTriangles()
    {
        if (nonTriangle_ > 0)
            fail(path_, "no triangles (points or lines only)");
        fail(path_, "no triangles (the scene has no mesh primitives)");
    }

    void warnSkipped()
    {
        if (nonTriangle_ > 0)
            importWarning(path_, "gltf-modes", "skipped " + std::to_string(nonTriangle_) + " point and line primitives");
        if (instancedNodes_ > 0)
            importWarning(path_, "gltf-instancing",
                          "ignored EXT_mesh_gpu_instancing on " + std::to_string(instancedNodes_) +
                              " nodes (each mesh is placed once, at its node)");
    }

    // Cameras without a stored target distance aim at the scene's centre distance.
    static void finishCameras(std::vector<PendingCamera>& cameras, glm::vec3 center, Scene& scene)
    {
        for (PendingCamera& pending : cameras) {
            if (!pending.hasTargetDistance) {
                float distance = glm::length(center - pending.camera.position);
                pending.camera.target =
                    pending.camera.position +
                    pending.forward * (distance > 1e-6f && std::isfinite(distance) ? distance : 1.0f);
            }
            scene.cameras.push_back(pending.camera);
        }
    }

    // The node hierarchy: meshes into scene.mesh (or the sink), cameras (pending their targets), lights.
    void traverse(Scene& scene, std::vector<PendingCamera>& cameras)
    {
        std::vector<uint64_t> roots = rootNodes();
        const size_t nodeCount = arraySize("nodes");
        std::vector<bool> visited(nodeCount, false);
        struct Pending {
            uint64_t node;
            glm::dmat4 parent;
            size_t depth;
        };
        std::vector<Pending> stack;
        for (auto it = roots.rbegin(); it != roots.rend(); ++it)
            stack.push_back({*it, glm::dmat4(1.0), 0});
        while (!stack.empty()) {
            Pending pending = stack.back();
            stack.pop_back();
            const std::string where = "node " + std::to_string(pending.node);
            if (pending.node >= nodeCount)
                fail(path_, "reference to node " + std::to_string(pending.node) + " but there are " +
                                std::to_string(nodeCount) + " nodes");
            if (visited[pending.node])
                fail(path_, where + " appears more than once in the node hierarchy (not a tree)");
            if (pending.depth > kMaxNodeDepth)
                fail(path_, where + ": node hierarchy deeper than " + std::to_string(kMaxNodeDepth));
            visited[pending.node] = true;
            const json& node = doc_["nodes"][pending.node];
            if (!node.is_object())
                fail(path_, where + " is not an object");
            glm::dmat4 world = pending.parent * localTransform(node, where);
            if (const json* mesh = member(node, "mesh"))
                appendMesh(index(*mesh, where + " mesh"), world, scene.mesh, where);
            if (const json* camera = member(node, "camera"))
                cameras.push_back(readCamera(index(*camera, where + " camera"), world));
            if (const json* extensions = member(node, "extensions"); extensions && member(*extensions, "EXT_mesh_gpu_instancing"))
                ++instancedNodes_;
            if (const json* extensions = member(node, "extensions"))
                if (const json* lights = member(*extensions, "KHR_lights_punctual"))
                    if (const json* light = member(*lights, "light"))
                        scene.lights.push_back(readLight(index(*light, where + " light"), world));
            if (const json* children = member(node, "children")) {
                if (!children->is_array())
                    fail(path_, where + ": children is not an array");
                for (size_t c = children->size(); c-- > 0;)
                    stack.push_back({index((*children)[c], where + " child"), world, pending.depth + 1});
            }
        }
    }

  private:
    // ---- container ----

    std::string_view parseGlbContainer(const MappedFile& file)
    {
        const uint8_t* data = file.data();
        const size_t size = file.size();
        auto u32 = [&](size_t offset) {
            uint32_t v;
            std::memcpy(&v, data + offset, 4);
            return v;
        };
        if (size < 12)
            fail(path_, "not a glTF binary (file too short for the header)");
        if (u32(0) != kGlbMagic)
            fail(path_, "not a glTF binary (bad magic)");
        if (u32(4) != 2)
            fail(path_, "unsupported glTF binary version " + std::to_string(u32(4)));
        const size_t length = u32(8);
        if (length > size)
            fail(path_,
                 "truncated: header says " + std::to_string(length) + " bytes, file has " + std::to_string(size));
        if (length < 20)
            fail(path_, "truncated: no JSON chunk");
        const size_t jsonLength = u32(12);
        if (u32(16) != kChunkJson)
            fail(path_, "malformed glTF binary: first chunk is not JSON");
        if (jsonLength > length - 20)
            fail(path_,
                 "truncated: JSON chunk of " + std::to_string(jsonLength) + " bytes runs past the end of the file");
        std::string_view jsonText(reinterpret_cast<const char*>(data + 20), jsonLength);
        size_t offset = 20 + ((jsonLength + 3) & ~size_t(3));
        if (offset + 8 <= length) {
            const size_t binLength = u32(offset);
            if (u32(offset + 4) == kChunkBin) {
                if (binLength > length - offset - 8)
                    fail(path_, "truncated: BIN chunk of " + std::to_string(binLength) +
                                    " bytes runs past the end of the file");
                bin_ = std::span<const uint8_t>(data + offset + 8, binLength);
                haveBin_ = true;
            }
        }
        return jsonText;
    }

    // The GLB container read with pread: the JSON chunk into memory, the BIN chunk's place.
    void parseGlbStream(FileReader& file)
    {
        const uint64_t size = file.size();
        if (size < 12)
            fail(path_, "not a glTF binary (file too short for the header)");
        uint32_t head[5] = {0, 0, 0, 0, 0};
        file.readAt(0, head, size_t(std::min<uint64_t>(size, 20)));
        if (head[0] != kGlbMagic)
            fail(path_, "not a glTF binary (bad magic)");
        if (head[1] != 2)
            fail(path_, "unsupported glTF binary version " + std::to_string(head[1]));
        const uint64_t length = head[2];
        if (length > size)
            fail(path_, "truncated: header says " + std::to_string(length) + " bytes, file has " + std::to_string(size));
        if (length < 20)
            fail(path_, "truncated: no JSON chunk");
        const uint64_t jsonLength = head[3];
        if (head[4] != kChunkJson)
            fail(path_, "malformed glTF binary: first chunk is not JSON");
        if (jsonLength > length - 20)
            fail(path_, "truncated: JSON chunk of " + std::to_string(jsonLength) + " bytes runs past the end of the file");
        jsonStorage_.resize(size_t(jsonLength));
        file.readAt(20, jsonStorage_.data(), jsonStorage_.size());
        const uint64_t offset = 20 + ((jsonLength + 3) & ~uint64_t(3));
        if (offset + 8 <= length) {
            uint32_t chunk[2];
            file.readAt(offset, chunk, 8);
            if (chunk[1] == kChunkBin) {
                if (chunk[0] > length - offset - 8)
                    fail(path_, "truncated: BIN chunk of " + std::to_string(chunk[0]) +
                                    " bytes runs past the end of the file");
                binOffset_ = offset + 8;
                binLength_ = chunk[0];
                haveBin_ = true;
            }
        }
    }

    // ---- JSON helpers ----

    size_t arraySize(const char* name)
    {
        const json* array = member(doc_, name);
        if (!array)
            return 0;
        if (!array->is_array())
            fail(path_, std::string("malformed glTF: '") + name + "' is not an array");
        return array->size();
    }

    uint64_t index(const json& value, const std::string& where)
    {
        if (!value.is_number_unsigned())
            fail(path_, where + ": expected a non-negative integer index");
        return value.get<uint64_t>();
    }

    const json& item(const char* arrayName, uint64_t i, const std::string& where)
    {
        size_t count = arraySize(arrayName);
        if (i >= count) {
            std::string singular = arrayName;
            singular.resize(singular == "meshes" ? 4 : singular.size() - 1);
            fail(path_, where + " references " + singular + " " + std::to_string(i) + " but there are " +
                            std::to_string(count));
        }
        const json& value = doc_[arrayName][i];
        if (!value.is_object())
            fail(path_, std::string(arrayName) + "[" + std::to_string(i) + "] is not an object");
        return value;
    }

    double number(const json& object, const char* key, double fallback, const std::string& where)
    {
        const json* value = member(object, key);
        if (!value)
            return fallback;
        if (!value->is_number())
            fail(path_, where + ": '" + key + "' is not a number");
        double d = value->get<double>();
        if (!std::isfinite(d))
            fail(path_, where + ": '" + key + "' is not finite");
        return d;
    }

    uint64_t requiredUint(const json& object, const char* key, const std::string& where)
    {
        const json* value = member(object, key);
        if (!value)
            fail(path_, where + " has no '" + key + "'");
        if (!value->is_number_unsigned())
            fail(path_, where + ": '" + key + "' is not a non-negative integer");
        return value->get<uint64_t>();
    }

    uint64_t optionalUint(const json& object, const char* key, uint64_t fallback, const std::string& where)
    {
        return member(object, key) ? requiredUint(object, key, where) : fallback;
    }

    template <size_t N>
    bool numberArray(const json& object, const char* key, double (&out)[N], const std::string& where)
    {
        const json* value = member(object, key);
        if (!value)
            return false;
        if (!value->is_array() || value->size() != N)
            fail(path_, where + ": '" + key + "' must be an array of " + std::to_string(N) + " numbers");
        for (size_t i = 0; i < N; ++i) {
            if (!(*value)[i].is_number())
                fail(path_, where + ": '" + key + "' must be an array of " + std::to_string(N) + " numbers");
            out[i] = (*value)[i].get<double>();
            if (!std::isfinite(out[i]))
                fail(path_, where + ": '" + key + "' has a non-finite value");
        }
        return true;
    }

    // ---- buffers and accessors ----

    const BufferSource& buffer(uint64_t i, const std::string& where)
    {
        const json& b = item("buffers", i, where);
        if (bufferLoaded_[i])
            return buffers_[i];
        const std::string name = "buffer " + std::to_string(i);
        uint64_t byteLength = requiredUint(b, "byteLength", name);
        BufferSource source;
        uint64_t present = 0;
        const json* uri = member(b, "uri");
        if (!uri) {
            if (!binary_ || i != 0 || !haveBin_)
                fail(path_, name + " has no uri and there is no GLB BIN chunk");
            if (streaming_) {
                source.file = glbFile_;
                source.base = binOffset_;
                present = binLength_;
            } else {
                source.memory = bin_;
                present = bin_.size();
            }
        } else {
            if (!uri->is_string())
                fail(path_, name + ": uri is not a string");
            std::string text = uri->get<std::string>();
            if (text.rfind("data:", 0) == 0) {
                size_t comma = text.find(',');
                if (comma == std::string::npos || text.substr(0, comma).find(";base64") == std::string::npos)
                    fail(path_, name + ": data URI is not base64");
                decoded_.emplace_back();
                if (!decodeBase64(std::string_view(text).substr(comma + 1), decoded_.back()))
                    fail(path_, name + ": malformed base64 data URI");
                source.memory = decoded_.back();
                present = source.memory.size();
            } else {
                std::string file = directory_ + percentDecode(text);
                try {
                    if (streaming_) {
                        externalFiles_.push_back(std::make_unique<FileReader>(file, 4096));
                        source.file = externalFiles_.back().get();
                        present = source.file->size();
                    } else {
                        external_.push_back(std::make_unique<MappedFile>(file));
                        source.memory = std::span<const uint8_t>(external_.back()->data(), external_.back()->size());
                        present = source.memory.size();
                    }
                } catch (const Error& e) {
                    fail(path_, name + ": " + e.what());
                }
            }
        }
        if (present < byteLength)
            fail(path_, "truncated: " + name + " declares " + std::to_string(byteLength) + " bytes but only " +
                            std::to_string(present) + " are present");
        if (!source.file)
            source.memory = source.memory.first(size_t(byteLength));
        source.length = byteLength;
        buffers_[i] = source;
        bufferLoaded_[i] = true;
        return buffers_[i];
    }

    // Bytes [offset, offset + length) of buffer i (the caller checked the range): a view of the
    // buffer in memory, or (streaming) a copy read with pread that lives until releaseScratch().
    std::span<const uint8_t> bytes(uint64_t i, uint64_t offset, uint64_t length, const std::string& where)
    {
        const BufferSource& source = buffer(i, where);
        if (!source.file)
            return source.memory.subspan(size_t(offset), size_t(length));
        if (length > kMaxStreamRead)
            fail(path_, where + ": " + std::to_string(length) + " bytes in one accessor or Draco primitive, more than " +
                            std::to_string(kMaxStreamRead) + " (streaming reads one primitive at a time)");
        scratch_.emplace_back(size_t(length));
        source.file->readAt(source.base + offset, scratch_.back().data(), size_t(length));
        return scratch_.back();
    }

    // Streaming: forgets what one primitive read.
    void releaseScratch()
    {
        scratch_.clear();
        materialized_.clear();
    }

    ViewRange bufferView(uint64_t i, const std::string& where, size_t* byteStride)
    {
        const json& view = item("bufferViews", i, where);
        const std::string name = "bufferView " + std::to_string(i);
        const uint64_t bufferIndex = requiredUint(view, "buffer", name);
        const uint64_t bufferLength = buffer(bufferIndex, name).length;
        uint64_t offset = optionalUint(view, "byteOffset", 0, name);
        uint64_t length = requiredUint(view, "byteLength", name);
        if (offset > bufferLength || length > bufferLength - offset)
            fail(path_, name + " (bytes " + std::to_string(offset) + "+" + std::to_string(length) +
                            ") runs past the end of its buffer (" + std::to_string(bufferLength) + " bytes)");
        if (byteStride)
            *byteStride = size_t(optionalUint(view, "byteStride", 0, name));
        return {bufferIndex, offset, length};
    }

    AccessorView accessor(uint64_t i, const std::string& where)
    {
        const json& a = item("accessors", i, where);
        const std::string name = "accessor " + std::to_string(i);
        AccessorView view;
        view.componentType = int(requiredUint(a, "componentType", name));
        size_t componentSize = 0;
        switch (view.componentType) {
        case 5120:
        case 5121:
            componentSize = 1;
            break;
        case 5122:
        case 5123:
            componentSize = 2;
            break;
        case 5125:
        case 5126:
            componentSize = 4;
            break;
        default:
            fail(path_, name + ": unknown componentType " + std::to_string(view.componentType));
        }
        const json* type = member(a, "type");
        std::string typeName = type && type->is_string() ? type->get<std::string>() : std::string();
        if (typeName == "SCALAR")
            view.components = 1;
        else if (typeName == "VEC2")
            view.components = 2;
        else if (typeName == "VEC3")
            view.components = 3;
        else if (typeName == "VEC4" || typeName == "MAT2")
            view.components = 4;
        else if (typeName == "MAT3")
            view.components = 9;
        else if (typeName == "MAT4")
            view.components = 16;
        else
            fail(path_, name + ": unknown type " + quoteToken(typeName));
        if (const json* normalized = member(a, "normalized"))
            view.normalized = normalized->is_boolean() && normalized->get<bool>();
        view.count = requiredUint(a, "count", name);
        const size_t elementSize = componentSize * size_t(view.components);
        const json* sparse = member(a, "sparse");
        const bool hasView = member(a, "bufferView") != nullptr;
        if (hasView) {
            size_t stride = 0;
            const ViewRange range = bufferView(requiredUint(a, "bufferView", name), name, &stride);
            if (stride == 0)
                stride = elementSize;
            if (stride < elementSize)
                fail(path_, name + ": byteStride " + std::to_string(stride) + " is smaller than the element size " +
                                std::to_string(elementSize));
            uint64_t offset = optionalUint(a, "byteOffset", 0, name);
            if (view.count > 0) {
                if (offset > range.length || view.count - 1 > (range.length - offset) / stride ||
                    (view.count - 1) * stride + elementSize > range.length - offset)
                    fail(path_, "truncated: " + name + " (" + std::to_string(view.count) + " elements of " +
                                    std::to_string(elementSize) + " bytes, stride " + std::to_string(stride) +
                                    ") runs past the end of its bufferView (" + std::to_string(range.length) +
                                    " bytes)");
                view.data = bytes(range.buffer, range.offset + offset, (view.count - 1) * stride + elementSize, name).data();
            }
            view.stride = stride;
            if (!sparse)
                return view;
        }
        // Without a bufferView the accessor is all zeros; sparse values replace some elements.
        // Both are materialized once per accessor, tightly packed.
        auto cached = materialized_.find(i);
        if (cached == materialized_.end()) {
            std::vector<uint8_t> values;
            if (!hasView) {
                if (view.count > materializeBudget_ / elementSize)
                    fail(path_, name + " has no bufferView and " + std::to_string(view.count) + " elements of " +
                                    std::to_string(elementSize) + " bytes: more than " +
                                    std::to_string(kMaterializeFactor) +
                                    " times the input size in zero-filled accessors");
                materializeBudget_ -= view.count * elementSize;
                values.assign(size_t(view.count) * elementSize, 0);
            } else {
                values.resize(size_t(view.count) * elementSize);
                for (uint64_t e = 0; e < view.count; ++e)
                    std::memcpy(values.data() + e * elementSize, view.data + e * view.stride, elementSize);
            }
            if (sparse)
                applySparse(*sparse, name, view.count, elementSize, values);
            cached = materialized_.emplace(i, std::move(values)).first;
        }
        view.data = cached->second.empty() ? nullptr : cached->second.data();
        view.stride = elementSize;
        return view;
    }

    // Bytes [offset, offset + size) of bufferView `viewIndex` (glTF sparse indices and values).
    const uint8_t* viewBytes(const json& object, uint64_t size, const std::string& where)
    {
        const ViewRange range = bufferView(requiredUint(object, "bufferView", where), where, nullptr);
        uint64_t offset = optionalUint(object, "byteOffset", 0, where);
        if (offset > range.length || size > range.length - offset)
            fail(path_, "truncated: " + where + " (" + std::to_string(size) + " bytes at offset " +
                            std::to_string(offset) + ") runs past the end of its bufferView (" +
                            std::to_string(range.length) + " bytes)");
        return bytes(range.buffer, range.offset + offset, size, where).data();
    }

    // Replaces the elements listed by a sparse accessor's indices with its values.
    void applySparse(const json& sparse, const std::string& name, uint64_t count, size_t elementSize,
                     std::vector<uint8_t>& values)
    {
        const std::string where = name + " sparse";
        const uint64_t sparseCount = requiredUint(sparse, "count", where);
        const json* indices = member(sparse, "indices");
        const json* replacements = member(sparse, "values");
        if (!indices || !indices->is_object() || !replacements || !replacements->is_object())
            fail(path_, where + " needs 'indices' and 'values' objects");
        const uint64_t indexType = requiredUint(*indices, "componentType", where + " indices");
        const size_t indexSize = indexType == 5121 ? 1 : indexType == 5123 ? 2 : indexType == 5125 ? 4 : 0;
        if (indexSize == 0)
            fail(path_, where + " indices: componentType " + std::to_string(indexType) +
                            " is not unsigned byte, short or int");
        // Both arrays must lie in their bufferViews, which bounds sparseCount by the input size.
        if (sparseCount > UINT64_MAX / 64)
            fail(path_, where + ": count " + std::to_string(sparseCount) + " is too large");
        const uint8_t* indexBytes = viewBytes(*indices, sparseCount * indexSize, where + " indices");
        const uint8_t* valueBytes = viewBytes(*replacements, sparseCount * elementSize, where + " values");
        for (uint64_t k = 0; k < sparseCount; ++k) {
            uint32_t target = 0;
            if (indexSize == 1)
                target = indexBytes[k];
            else if (indexSize == 2) {
                uint16_t v;
                std::memcpy(&v, indexBytes + k * 2, 2);
                target = v;
            } else
                std::memcpy(&target, indexBytes + k * 4, 4);
            if (target >= count)
                fail(path_, where + ": index " + std::to_string(target) + " is outside the accessor's " +
                                std::to_string(count) + " elements");
            std::memcpy(values.data() + size_t(target) * elementSize, valueBytes + k * elementSize, elementSize);
        }
    }

    // ---- scene graph ----

    std::vector<uint64_t> rootNodes()
    {
        const size_t sceneCount = arraySize("scenes");
        std::vector<uint64_t> roots;
        if (sceneCount > 0) {
            uint64_t sceneIndex = member(doc_, "scene") ? index(doc_["scene"], "scene") : 0;
            const json& scene = item("scenes", sceneIndex, "scene");
            if (const json* nodes = member(scene, "nodes")) {
                if (!nodes->is_array())
                    fail(path_, "scene " + std::to_string(sceneIndex) + ": nodes is not an array");
                for (const json& n : *nodes)
                    roots.push_back(index(n, "scene " + std::to_string(sceneIndex) + " node"));
            }
            return roots;
        }
        // No scenes: every node that is nobody's child is a root.
        const size_t nodeCount = arraySize("nodes");
        std::vector<bool> isChild(nodeCount, false);
        for (size_t n = 0; n < nodeCount; ++n)
            if (const json* children = member(doc_["nodes"][n], "children"); children && children->is_array())
                for (const json& c : *children)
                    if (c.is_number_unsigned() && c.get<uint64_t>() < nodeCount)
                        isChild[c.get<uint64_t>()] = true;
        for (size_t n = 0; n < nodeCount; ++n)
            if (!isChild[n])
                roots.push_back(n);
        return roots;
    }

    glm::dmat4 localTransform(const json& node, const std::string& where)
    {
        double m[16];
        if (numberArray(node, "matrix", m, where))
            return glm::make_mat4(m);
        double t[3] = {0, 0, 0}, r[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
        numberArray(node, "translation", t, where);
        numberArray(node, "rotation", r, where);
        numberArray(node, "scale", s, where);
        glm::dquat q(r[3], r[0], r[1], r[2]);
        double length = glm::length(q);
        q = length > 0.0 ? q / length : glm::dquat(1, 0, 0, 0);
        glm::dmat4 result = glm::translate(glm::dmat4(1.0), glm::dvec3(t[0], t[1], t[2])) * glm::mat4_cast(q);
        return glm::scale(result, glm::dvec3(s[0], s[1], s[2]));
    }

    // ---- meshes ----

    // The material of a primitive: its index in out.materials, the document's
    // materials (base colour factor) read on first use, then a white default.
    uint32_t primitiveMaterial(const json& primitive, const std::string& where, Mesh& out)
    {
        const size_t count = arraySize("materials");
        if (out.materials.empty()) {
            for (size_t m = 0; m < count; ++m) {
                const std::string name = "material " + std::to_string(m);
                const json& material = item("materials", m, name);
                Material result;
                if (const json* nameValue = member(material, "name"); nameValue && nameValue->is_string())
                    result.name = nameValue->get<std::string>();
                if (const json* pbr = member(material, "pbrMetallicRoughness")) {
                    if (!pbr->is_object())
                        fail(path_, name + ": pbrMetallicRoughness is not an object");
                    double factor[4] = {1, 1, 1, 1};
                    numberArray(*pbr, "baseColorFactor", factor, name + " pbrMetallicRoughness");
                    for (int k = 0; k < 4; ++k)
                        result.baseColor[k] = float(std::clamp(factor[k], 0.0, 1.0));
                }
                out.materials.push_back(result);
            }
            out.materials.push_back({glm::vec4(1.0f), "default"});
        }
        const json* index = member(primitive, "material");
        if (!index)
            return uint32_t(count);
        materialUsed_ = true;
        if (!index->is_number_unsigned() || index->get<uint64_t>() >= count)
            fail(path_, where + ": material must be an index below " + std::to_string(count));
        return uint32_t(index->get<uint64_t>());
    }

    void appendMesh(uint64_t meshIndex, const glm::dmat4& world, Mesh& out, const std::string& nodeName)
    {
        const std::string meshName = "mesh " + std::to_string(meshIndex);
        const json& mesh = item("meshes", meshIndex, nodeName);
        const json* primitives = member(mesh, "primitives");
        if (!primitives || !primitives->is_array())
            fail(path_, meshName + " has no primitives array");
        const glm::mat4 matrix(world);
        const bool flip = glm::determinant(glm::dmat3(world)) < 0.0;
        for (size_t p = 0; p < primitives->size(); ++p) {
            const json& primitive = (*primitives)[p];
            const std::string where = meshName + " primitive " + std::to_string(p);
            if (!primitive.is_object())
                fail(path_, where + " is not an object");
            uint64_t mode = optionalUint(primitive, "mode", 4, where);
            if (mode > 6)
                fail(path_, where + ": invalid mode " + std::to_string(mode));
            if (mode < 4) {
                ++nonTriangle_;
                continue;
            }
            const json* extensions = member(primitive, "extensions");
            const json* draco = extensions ? member(*extensions, "KHR_draco_mesh_compression") : nullptr;
            const uint32_t material = primitiveMaterial(primitive, where, out);
            if (sink_) {
                // Streaming: one primitive at a time.
                primitive_.positions.clear();
                primitive_.indices.clear();
                if (draco)
                    appendDracoPrimitive(*draco, where, matrix, flip, primitive_);
                else
                    appendPlainPrimitive(primitive, mode, where, matrix, flip, primitive_);
                streamedTriangles_ += primitive_.triangleCount();
                streamedVertices_ += primitive_.vertexCount();
                if (streamedTriangles_ > kMaxStreamTriangles || streamedVertices_ > kMaxStreamTriangles)
                    fail(path_, where + ": scene expands to more than " + std::to_string(kMaxStreamTriangles) +
                                    " triangles or vertices after instancing");
                if (primitive_.triangleCount() > 0)
                    sink_(primitive_, material, where);
                releaseScratch();
                continue;
            }
            if (draco)
                appendDracoPrimitive(*draco, where, matrix, flip, out);
            else
                appendPlainPrimitive(primitive, mode, where, matrix, flip, out);
            out.triangleMaterials.resize(out.triangleCount(), material);
        }
    }

    void reserveTriangles(uint64_t triangles, uint64_t vertices, const std::string& where, const Mesh& out)
    {
        if (sink_) {
            // Streaming: the primitive alone is held in memory; totals are checked by appendMesh.
            if (triangles > kMaxTriangles || vertices > kMaxVertices)
                fail(path_, where + ": one primitive of more than " + std::to_string(kMaxTriangles) + " triangles");
            return;
        }
        if (out.triangleCount() + triangles > kMaxTriangles)
            fail(path_, where + ": scene expands to more than " + std::to_string(kMaxTriangles) +
                            " triangles after instancing");
        if (out.vertexCount() + vertices > kMaxVertices)
            fail(path_,
                 where + ": scene expands to more than " + std::to_string(kMaxVertices) + " vertices after instancing");
    }

    static void transformInto(float* dst, const float* src, size_t count, const glm::mat4& m)
    {
        if (m == glm::mat4(1.0f)) {
            if (count > 0) // dst and src may be null when there is nothing to copy
                std::memcpy(dst, src, count * 12);
            return;
        }
        for (size_t i = 0; i < count; ++i) {
            glm::vec3 p(src[i * 3], src[i * 3 + 1], src[i * 3 + 2]);
            glm::vec3 q = glm::vec3(m[0]) * p.x + glm::vec3(m[1]) * p.y + glm::vec3(m[2]) * p.z + glm::vec3(m[3]);
            dst[i * 3] = q.x;
            dst[i * 3 + 1] = q.y;
            dst[i * 3 + 2] = q.z;
        }
    }

    void appendDracoPrimitive(const json& draco, const std::string& where, const glm::mat4& matrix, bool flip,
                              Mesh& out)
    {
        size_t stride = 0;
        const ViewRange range =
            bufferView(requiredUint(draco, "bufferView", where + " KHR_draco_mesh_compression"), where, &stride);
        std::span<const uint8_t> bytes = this->bytes(range.buffer, range.offset, range.length, where);
        const json* attributes = member(draco, "attributes");
        const json* position = attributes ? member(*attributes, "POSITION") : nullptr;
        if (!position)
            fail(path_, where + ": KHR_draco_mesh_compression has no POSITION attribute");
        uint64_t id = index(*position, where + " Draco POSITION");
        DecodedDraco decoded =
            decodeDraco(path_, where, bytes.data(), bytes.size(), int64_t(std::min<uint64_t>(id, INT32_MAX)));
        const size_t vertexCount = decoded.positions.size() / 3;
        reserveTriangles(decoded.indices.size() / 3, vertexCount, where, out);
        const size_t base = out.vertexCount();
        out.positions.resize(out.positions.size() + decoded.positions.size());
        transformInto(out.positions.data() + base * 3, decoded.positions.data(), vertexCount, matrix);
        const size_t first = out.indices.size();
        out.indices.resize(first + decoded.indices.size());
        uint32_t* dst = out.indices.data() + first;
        for (size_t i = 0; i < decoded.indices.size(); i += 3) {
            dst[i] = decoded.indices[i] + uint32_t(base);
            dst[i + 1] = decoded.indices[i + (flip ? 2 : 1)] + uint32_t(base);
            dst[i + 2] = decoded.indices[i + (flip ? 1 : 2)] + uint32_t(base);
        }
    }

    void appendPlainPrimitive(const json& primitive, uint64_t mode, const std::string& where, const glm::mat4& matrix,
                              bool flip, Mesh& out)
    {
        const json* attributes = member(primitive, "attributes");
        const json* positionRef = attributes ? member(*attributes, "POSITION") : nullptr;
        if (!positionRef)
            fail(path_, where + " has no POSITION attribute");
        AccessorView positions = accessor(index(*positionRef, where + " POSITION"), where);
        if (positions.components != 3)
            fail(path_, where + ": POSITION accessor is not VEC3");
        const uint64_t vertexCount = positions.count;

        // Corner list: the index accessor, or 0..count-1.
        AccessorView indices;
        const json* indicesRef = member(primitive, "indices");
        uint64_t cornerCount = vertexCount;
        if (indicesRef) {
            indices = accessor(index(*indicesRef, where + " indices"), where);
            if (indices.components != 1 ||
                (indices.componentType != 5121 && indices.componentType != 5123 && indices.componentType != 5125))
                fail(path_, where + ": indices accessor must be SCALAR unsigned byte, short or int");
            cornerCount = indices.count;
        }
        auto corner = [&](uint64_t k) -> uint64_t {
            if (!indicesRef)
                return k;
            const uint8_t* p = indices.data + size_t(k) * indices.stride;
            if (indices.componentType == 5121)
                return *p;
            if (indices.componentType == 5123) {
                uint16_t v;
                std::memcpy(&v, p, 2);
                return v;
            }
            uint32_t v;
            std::memcpy(&v, p, 4);
            return v;
        };
        uint64_t triangles = 0;
        if (mode == 4) {
            if (cornerCount % 3 != 0)
                fail(path_, where + ": " + std::to_string(cornerCount) + " corners is not a multiple of 3");
            triangles = cornerCount / 3;
        } else {
            triangles = cornerCount >= 3 ? cornerCount - 2 : 0;
        }
        if (triangles == 0)
            return;
        reserveTriangles(triangles, vertexCount, where, out);

        const size_t base = out.vertexCount();
        out.positions.resize(out.positions.size() + size_t(vertexCount) * 3);
        float* dst = out.positions.data() + base * 3;
        if (positions.componentType == 5126 && positions.stride == 12) {
            if (vertexCount > 0) // positions.data and dst are null for an empty accessor
                std::memcpy(dst, positions.data, size_t(vertexCount) * 12);
            if (matrix != glm::mat4(1.0f))
                transformInto(dst, dst, size_t(vertexCount), matrix);
        } else {
            for (uint64_t v = 0; v < vertexCount; ++v) {
                float xyz[3];
                readComponents(positions, v, xyz);
                transformInto(dst + v * 3, xyz, 1, matrix);
            }
        }

        const size_t first = out.indices.size();
        out.indices.resize(first + size_t(triangles) * 3);
        uint32_t* idx = out.indices.data() + first;
        auto emit = [&](uint64_t t, uint64_t a, uint64_t b, uint64_t c) {
            if (a >= vertexCount || b >= vertexCount || c >= vertexCount) {
                uint64_t bad = a >= vertexCount ? a : b >= vertexCount ? b : c;
                fail(path_, where + ": triangle " + std::to_string(t) + " references vertex " + std::to_string(bad) +
                                " but there are " + std::to_string(vertexCount) + " vertices");
            }
            idx[t * 3] = uint32_t(a + base);
            idx[t * 3 + 1] = uint32_t((flip ? c : b) + base);
            idx[t * 3 + 2] = uint32_t((flip ? b : c) + base);
        };
        if (mode == 4) {
            for (uint64_t t = 0; t < triangles; ++t)
                emit(t, corner(t * 3), corner(t * 3 + 1), corner(t * 3 + 2));
        } else if (mode == 5) { // strip: odd triangles swap their first two corners
            for (uint64_t t = 0; t < triangles; ++t) {
                if (t % 2 == 0)
                    emit(t, corner(t), corner(t + 1), corner(t + 2));
                else
                    emit(t, corner(t + 1), corner(t), corner(t + 2));
            }
        } else { // fan
            uint64_t hub = corner(0);
            for (uint64_t t = 0; t < triangles; ++t)
                emit(t, hub, corner(t + 1), corner(t + 2));
        }
    }

    void readComponents(const AccessorView& view, uint64_t element, float* out) const
    {
        const uint8_t* p = view.data + size_t(element) * view.stride;
        for (int c = 0; c < 3; ++c) {
            float value = 0.0f;
            switch (view.componentType) {
            case 5120: {
                int8_t v = int8_t(p[c]);
                value = view.normalized ? std::max(float(v) / 127.0f, -1.0f) : float(v);
                break;
            }
            case 5121:
                value = view.normalized ? float(p[c]) / 255.0f : float(p[c]);
                break;
            case 5122: {
                int16_t v;
                std::memcpy(&v, p + c * 2, 2);
                value = view.normalized ? std::max(float(v) / 32767.0f, -1.0f) : float(v);
                break;
            }
            case 5123: {
                uint16_t v;
                std::memcpy(&v, p + c * 2, 2);
                value = view.normalized ? float(v) / 65535.0f : float(v);
                break;
            }
            case 5125: {
                uint32_t v;
                std::memcpy(&v, p + c * 4, 4);
                value = float(v);
                break;
            }
            default:
                std::memcpy(&value, p + c * 4, 4);
                break;
            }
            out[c] = value;
        }
    }

    // ---- cameras and lights ----

    static glm::vec3 safeNormalize(glm::dvec3 v, glm::vec3 fallback)
    {
        double length = glm::length(v);
        return length > 1e-12 && std::isfinite(length) ? glm::vec3(v / length) : fallback;
    }

    PendingCamera readCamera(uint64_t cameraIndex, const glm::dmat4& world)
    {
        const std::string where = "camera " + std::to_string(cameraIndex);
        const json& camera = item("cameras", cameraIndex, "a node");
        PendingCamera pending;
        Camera& result = pending.camera;
        const json* type = member(camera, "type");
        std::string typeName = type && type->is_string() ? type->get<std::string>() : std::string();
        if (typeName == "perspective") {
            const json* p = member(camera, "perspective");
            if (!p || !p->is_object())
                fail(path_, where + " has no perspective object");
            result.projection = Projection::Perspective;
            double yfov = number(*p, "yfov", -1.0, where);
            if (!(yfov > 0.0 && yfov < kPi))
                fail(path_, where + ": yfov must be in (0, pi) radians");
            result.yfovDegrees = float(yfov * 180.0 / kPi);
            result.nearPlane = float(number(*p, "znear", 0.0, where));
            result.farPlane = float(number(*p, "zfar", 0.0, where));
        } else if (typeName == "orthographic") {
            const json* o = member(camera, "orthographic");
            if (!o || !o->is_object())
                fail(path_, where + " has no orthographic object");
            result.projection = Projection::Orthographic;
            double ymag = number(*o, "ymag", 0.0, where);
            if (ymag == 0.0)
                fail(path_, where + ": orthographic ymag must be non-zero");
            result.orthoHeight = float(2.0 * std::abs(ymag));
            result.nearPlane = float(number(*o, "znear", 0.0, where));
            result.farPlane = float(number(*o, "zfar", 0.0, where));
        } else {
            fail(path_, where + ": unknown camera type " + quoteToken(typeName));
        }
        result.position = glm::vec3(world[3]);
        pending.forward = safeNormalize(glm::dmat3(world) * glm::dvec3(0, 0, -1), glm::vec3(0, 0, -1));
        result.up = safeNormalize(glm::dmat3(world) * glm::dvec3(0, 1, 0), glm::vec3(0, 1, 0));
        result.target = result.position + pending.forward;
        if (const json* extras = member(camera, "extras"))
            if (const json* penumbra = member(*extras, "penumbra")) {
                double distance = number(*penumbra, "targetDistance", 0.0, where);
                if (distance > 0.0) {
                    result.target = result.position + pending.forward * float(distance);
                    pending.hasTargetDistance = true;
                }
                result.nearPlane = float(number(*penumbra, "nearPlane", result.nearPlane, where));
                result.farPlane = float(number(*penumbra, "farPlane", result.farPlane, where));
            }
        return pending;
    }

    Light readLight(uint64_t lightIndex, const glm::dmat4& world)
    {
        const std::string where = "light " + std::to_string(lightIndex);
        const json* extensions = member(doc_, "extensions");
        const json* punctual = extensions ? member(*extensions, "KHR_lights_punctual") : nullptr;
        const json* lights = punctual ? member(*punctual, "lights") : nullptr;
        if (!lights || !lights->is_array() || lightIndex >= lights->size())
            fail(path_, "node references " + where + " but the file defines " +
                            std::to_string(lights && lights->is_array() ? lights->size() : 0) + " lights");
        const json& light = (*lights)[lightIndex];
        if (!light.is_object())
            fail(path_, where + " is not an object");
        Light result;
        const json* type = member(light, "type");
        std::string typeName = type && type->is_string() ? type->get<std::string>() : std::string();
        if (typeName == "point")
            result.type = LightType::Point;
        else if (typeName == "spot")
            result.type = LightType::Spot;
        else if (typeName == "directional")
            result.type = LightType::Directional;
        else
            fail(path_, where + ": unknown light type " + quoteToken(typeName));
        double color[3] = {1, 1, 1};
        numberArray(light, "color", color, where);
        result.color = glm::vec3(float(color[0]), float(color[1]), float(color[2]));
        result.intensity = float(number(light, "intensity", 1.0, where));
        result.range = float(number(light, "range", 0.0, where));
        if (result.type == LightType::Spot) {
            const json* spot = member(light, "spot");
            double inner = spot ? number(*spot, "innerConeAngle", 0.0, where) : 0.0;
            double outer = spot ? number(*spot, "outerConeAngle", kPi / 4.0, where) : kPi / 4.0;
            result.innerConeDegrees = float(inner * 180.0 / kPi);
            result.outerConeDegrees = float(outer * 180.0 / kPi);
        }
        result.position = glm::vec3(world[3]);
        result.direction = safeNormalize(glm::dmat3(world) * glm::dvec3(0, 0, -1), glm::vec3(0, 0, -1));
        result.up = safeNormalize(glm::dmat3(world) * glm::dvec3(0, 1, 0), glm::vec3(0, 1, 0));
        // Area lights written by penumbra travel as point lights plus extras.
        if (const json* extras = member(light, "extras"))
            if (const json* penumbra = member(*extras, "penumbra"))
                if (const json* area = member(*penumbra, "type"); area && area->is_string()) {
                    std::string areaName = area->get<std::string>();
                    if (areaName == "rectangle" || areaName == "disk" || areaName == "sphere") {
                        result.type = parseLightType(areaName);
                        result.width = float(number(*penumbra, "width", result.width, where));
                        result.height = float(number(*penumbra, "height", result.height, where));
                        result.radius = float(number(*penumbra, "radius", result.radius, where));
                    }
                }
        return result;
    }

    const std::string& path_;
    bool binary_;
    bool streaming_ = false;
    std::string directory_;
    json doc_;
    std::string jsonStorage_; // streaming: the JSON text
    std::span<const uint8_t> bin_;
    bool haveBin_ = false;
    FileReader* glbFile_ = nullptr; // streaming: the input file
    uint64_t binOffset_ = 0, binLength_ = 0;
    std::vector<std::unique_ptr<FileReader>> externalFiles_;
    std::vector<std::vector<uint8_t>> scratch_;
    PrimitiveSink sink_;
    Mesh primitive_;
    uint64_t streamedTriangles_ = 0, streamedVertices_ = 0;
    std::vector<BufferSource> buffers_;
    std::vector<bool> bufferLoaded_;
    std::vector<std::vector<uint8_t>> decoded_;
    std::vector<std::unique_ptr<MappedFile>> external_;
    std::map<uint64_t, std::vector<uint8_t>> materialized_; // sparse and zero-filled accessors
    uint64_t materializeBudget_ = 0; // bytes zero-filled accessors may still take
    bool materialUsed_ = false; // some primitive names a material
    size_t nonTriangle_ = 0;
    size_t instancedNodes_ = 0;
};

// ---- export helpers ----

// Rotation taking glTF's local -Z to forward and +Y towards up.
glm::quat orientation(glm::vec3 forward, glm::vec3 up)
{
    float length = glm::length(forward);
    forward = length > 1e-12f ? forward / length : glm::vec3(0, 0, -1);
    glm::vec3 right = glm::cross(forward, up);
    if (glm::length(right) < 1e-6f) {
        right = glm::cross(forward, std::abs(forward.y) < 0.9f ? glm::vec3(0, 1, 0) : glm::vec3(1, 0, 0));
    }
    right = glm::normalize(right);
    glm::vec3 trueUp = glm::cross(right, forward);
    glm::mat3 basis(right, trueUp, -forward);
    return glm::normalize(glm::quat_cast(basis));
}

json vec3Json(glm::vec3 v)
{
    return json::array({v.x, v.y, v.z});
}

json nodeTransform(glm::vec3 position, glm::quat rotation)
{
    json node;
    node["translation"] = vec3Json(position);
    node["rotation"] = json::array({rotation.x, rotation.y, rotation.z, rotation.w});
    return node;
}

} // namespace

Scene importGltf(const std::string& path, const MappedFile& file, bool binary)
{
    try {
        GltfReader reader(path, file, binary);
        return reader.read();
    } catch (const json::exception& e) {
        fail(path, std::string("malformed glTF: ") + e.what());
    }
}

void exportGltf(const Scene& scene, const std::string& path, AtomicFileWriter& out, bool binary,
                const ExportOptions& options)
{
    const Mesh& mesh = scene.mesh;
    const size_t vertexCount = mesh.vertexCount();
    const size_t indexCount = mesh.indices.size();
    Bounds bounds = computeBounds(mesh);

    // Binary payload: either raw positions + indices or one Draco blob.
    std::vector<char> dracoBytes;
    uint32_t dracoPositionId = 0;
    size_t encodedPoints = vertexCount, encodedFaces = mesh.triangleCount();
    if (options.draco)
        dracoBytes = encodeDracoMesh(path, mesh, options, &dracoPositionId, &encodedPoints, &encodedFaces);
    const uint64_t positionBytes = uint64_t(vertexCount) * 12;
    const uint64_t indexBytes = uint64_t(indexCount) * 4;
    const uint64_t payloadBytes = options.draco ? dracoBytes.size() : positionBytes + indexBytes;
    const uint64_t paddedPayload = (payloadBytes + 3) & ~uint64_t(3);

    json doc;
    doc["asset"] = {{"version", "2.0"}, {"generator", "penumbra"}};
    json buffer = {{"byteLength", payloadBytes}};
    json positionAccessor = {{"componentType", 5126},
                             {"count", encodedPoints},
                             {"type", "VEC3"},
                             {"min", vec3Json(bounds.min)},
                             {"max", vec3Json(bounds.max)}};
    json indexAccessor = {{"componentType", 5125}, {"count", encodedFaces * 3}, {"type", "SCALAR"}};
    json primitive = {{"attributes", {{"POSITION", 0}}}, {"indices", 1}, {"mode", 4}};
    std::vector<std::string> extensionsUsed;
    if (options.draco) {
        doc["bufferViews"] = json::array({{{"buffer", 0}, {"byteOffset", 0}, {"byteLength", dracoBytes.size()}}});
        primitive["extensions"]["KHR_draco_mesh_compression"] = {{"bufferView", 0},
                                                                 {"attributes", {{"POSITION", dracoPositionId}}}};
        extensionsUsed.push_back("KHR_draco_mesh_compression");
        doc["extensionsRequired"] = json::array({"KHR_draco_mesh_compression"});
    } else {
        doc["bufferViews"] = json::array(
            {{{"buffer", 0}, {"byteOffset", 0}, {"byteLength", positionBytes}, {"target", 34962}},
             {{"buffer", 0}, {"byteOffset", positionBytes}, {"byteLength", indexBytes}, {"target", 34963}}});
        positionAccessor["bufferView"] = 0;
        indexAccessor["bufferView"] = 1;
    }
    doc["accessors"] = json::array({positionAccessor, indexAccessor});
    doc["meshes"] = json::array({{{"primitives", json::array({primitive})}}});

    json nodes = json::array({{{"mesh", 0}, {"name", "mesh"}}});
    json cameras = json::array();
    for (size_t c = 0; c < scene.cameras.size(); ++c) {
        const Camera& camera = scene.cameras[c];
        glm::vec3 forward = camera.target - camera.position;
        float distance = glm::length(forward);
        json extras = {{"targetDistance", distance}, {"nearPlane", camera.nearPlane}, {"farPlane", camera.farPlane}};
        json entry;
        if (camera.projection == Projection::Perspective) {
            json perspective = {{"yfov", double(camera.yfovDegrees) * kPi / 180.0},
                                {"znear", camera.nearPlane > 0.0f ? camera.nearPlane : 0.01f}};
            if (camera.farPlane > 0.0f)
                perspective["zfar"] = camera.farPlane;
            entry = {{"type", "perspective"}, {"perspective", perspective}};
        } else {
            // glTF needs xmag; the aspect comes from the image, so write a square view.
            float half = camera.orthoHeight * 0.5f;
            entry = {{"type", "orthographic"},
                     {"orthographic",
                      {{"xmag", half},
                       {"ymag", half},
                       {"znear", std::max(camera.nearPlane, 0.0f)},
                       {"zfar", camera.farPlane > camera.nearPlane ? camera.farPlane : 1.0e6f}}}};
        }
        entry["extras"]["penumbra"] = extras;
        cameras.push_back(entry);
        json node = nodeTransform(camera.position, orientation(forward, camera.up));
        node["camera"] = c;
        node["name"] = "camera " + std::to_string(c);
        nodes.push_back(node);
    }
    json lights = json::array();
    for (size_t l = 0; l < scene.lights.size(); ++l) {
        const Light& light = scene.lights[l];
        json entry = {{"color", vec3Json(light.color)}, {"intensity", light.intensity}};
        if (light.range > 0.0f)
            entry["range"] = light.range;
        switch (light.type) {
        case LightType::Point:
            entry["type"] = "point";
            break;
        case LightType::Directional:
            entry["type"] = "directional";
            break;
        case LightType::Spot:
            entry["type"] = "spot";
            entry["spot"] = {{"innerConeAngle", double(light.innerConeDegrees) * kPi / 180.0},
                             {"outerConeAngle", double(light.outerConeDegrees) * kPi / 180.0}};
            break;
        case LightType::Rectangle:
        case LightType::Disk:
        case LightType::Sphere:
            // KHR_lights_punctual has no area lights: a point light at the centre,
            // with the shape kept in extras for penumbra's own importer.
            entry["type"] = "point";
            entry["extras"]["penumbra"] = {{"type", lightTypeName(light.type)},
                                           {"width", light.width},
                                           {"height", light.height},
                                           {"radius", light.radius}};
            break;
        }
        lights.push_back(entry);
        json node = nodeTransform(light.position, orientation(light.direction, light.up));
        node["extensions"]["KHR_lights_punctual"] = {{"light", l}};
        node["name"] = "light " + std::to_string(l);
        nodes.push_back(node);
    }
    if (!lights.empty()) {
        doc["extensions"]["KHR_lights_punctual"] = {{"lights", lights}};
        extensionsUsed.push_back("KHR_lights_punctual");
    }
    if (!cameras.empty())
        doc["cameras"] = cameras;
    json rootList = json::array();
    for (size_t n = 0; n < nodes.size(); ++n)
        rootList.push_back(n);
    doc["nodes"] = nodes;
    doc["scenes"] = json::array({{{"nodes", rootList}}});
    doc["scene"] = 0;
    if (!extensionsUsed.empty())
        doc["extensionsUsed"] = extensionsUsed;

    auto writePayload = [&](AtomicFileWriter& writer) {
        if (options.draco) {
            writer.write(dracoBytes.data(), dracoBytes.size());
        } else {
            writer.write(mesh.positions.data(), size_t(positionBytes));
            writer.write(mesh.indices.data(), size_t(indexBytes));
        }
        static const char zeros[4] = {0, 0, 0, 0};
        writer.write(zeros, size_t(paddedPayload - payloadBytes));
    };

    if (!binary) {
        // .gltf: one self-contained file with the payload as a base64 data URI.
        std::vector<uint8_t> payload;
        payload.reserve(size_t(payloadBytes));
        if (options.draco) {
            payload.assign(dracoBytes.begin(), dracoBytes.end());
        } else {
            const uint8_t* p = reinterpret_cast<const uint8_t*>(mesh.positions.data());
            payload.assign(p, p + positionBytes);
            const uint8_t* i = reinterpret_cast<const uint8_t*>(mesh.indices.data());
            payload.insert(payload.end(), i, i + indexBytes);
        }
        buffer["uri"] = "data:application/octet-stream;base64," + encodeBase64(payload.data(), payload.size());
        doc["buffers"] = json::array({buffer});
        out.write(doc.dump(1));
        out.write("\n");
        return;
    }
    doc["buffers"] = json::array({buffer});
    std::string jsonText = doc.dump();
    while (jsonText.size() % 4 != 0)
        jsonText += ' ';
    const uint64_t total = 12 + 8 + jsonText.size() + 8 + paddedPayload;
    if (total > UINT32_MAX)
        fail(path, "mesh too large for GLB (" + std::to_string(total) + " bytes; the format's limit is 4 GiB)");
    uint32_t header[5] = {kGlbMagic, 2, uint32_t(total), uint32_t(jsonText.size()), kChunkJson};
    out.write(header, sizeof(header));
    out.write(jsonText);
    uint32_t binHeader[2] = {uint32_t(paddedPayload), kChunkBin};
    out.write(binHeader, sizeof(binHeader));
    writePayload(out);
}

// ---- streaming (model_stream.h) ----

namespace {

class GltfStream : public ModelStream {
  public:
    GltfStream(const std::string& path, const ModelStreamOptions& options, bool binary)
        : file_(path, options.bufferBytes), options_(options), binary_(binary)
    {
        path_ = path;
    }

    void scan(const std::function<void(const float*, size_t)>& onVertices) override
    {
        try {
            GltfReader reader(path_, file_, binary_);
            store_ = std::make_unique<TemporaryVertexStore>(temporaryDirectory(path_, options_),
                                                            "the vertices of " + path_, false);
            Bounds bounds;
            uint64_t triangles = 0;
            reader.setSink([&](const Mesh& primitive, uint32_t, const std::string&) {
                const float* p = primitive.positions.data();
                for (size_t v = 0; v < primitive.vertexCount(); ++v) {
                    const float* xyz = p + 3 * v;
                    if (!std::isfinite(xyz[0]) || !std::isfinite(xyz[1]) || !std::isfinite(xyz[2])) {
                        char text[160];
                        std::snprintf(text, sizeof(text), "vertex %llu has a non-finite position (%g, %g, %g)",
                                      (unsigned long long)(store_->count()), double(xyz[0]), double(xyz[1]),
                                      double(xyz[2]));
                        fail(path_, text);
                    }
                    store_->append(xyz, nullptr);
                    bounds.min = glm::min(bounds.min, glm::vec3(xyz[0], xyz[1], xyz[2]));
                    bounds.max = glm::max(bounds.max, glm::vec3(xyz[0], xyz[1], xyz[2]));
                }
                onVertices(p, primitive.vertexCount());
                triangles += primitive.triangleCount();
            });
            Scene scene;
            std::vector<PendingCamera> cameras;
            reader.traverse(scene, cameras);
            if (triangles == 0)
                reader.failNoTriangles();
            reader.warnSkipped();
            GltfReader::finishCameras(cameras, bounds.center(), scene);
            store_->finish();
            vertexCount_ = store_->count();
            triangleCount_ = triangles;
            if (reader.materialUsed())
                materials_ = scene.mesh.materials;
            cameras_ = scene.cameras;
            lights_ = scene.lights;
        } catch (const json::exception& e) {
            fail(path_, std::string("malformed glTF: ") + e.what());
        }
    }

    void triangles(const std::function<void(const StreamTriangles&)>& onTriangles) override
    {
        if (!store_)
            fail(path_, "internal error: triangles() before scan()");
        try {
            GltfReader reader(path_, file_, binary_);
            TriangleBatcher batcher{onTriangles};
            batcher.withMaterials = !materials_.empty();
            uint64_t base = 0;
            reader.setSink([&](const Mesh& primitive, uint32_t material, const std::string&) {
                const uint32_t* idx = primitive.indices.data();
                for (size_t t = 0; t < primitive.triangleCount(); ++t)
                    batcher.add(base + idx[3 * t], base + idx[3 * t + 1], base + idx[3 * t + 2], material);
                base += primitive.vertexCount();
            });
            Scene scene;
            std::vector<PendingCamera> cameras;
            reader.traverse(scene, cameras);
            batcher.flush();
        } catch (const json::exception& e) {
            fail(path_, std::string("malformed glTF: ") + e.what());
        }
    }

    void readVertices(uint64_t first, uint64_t count, float* positions, float*) override
    {
        if (!store_)
            fail(path_, "internal error: readVertices() before scan()");
        store_->read(first, count, positions, nullptr);
    }

  private:
    FileReader file_;
    ModelStreamOptions options_;
    bool binary_;
    std::unique_ptr<TemporaryVertexStore> store_;
};

} // namespace

std::unique_ptr<ModelStream> openGltfStream(const std::string& path, const ModelStreamOptions& options, bool binary)
{
    return std::make_unique<GltfStream>(path, options, binary);
}

} // namespace penumbra::detail
