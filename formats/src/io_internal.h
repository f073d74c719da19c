// Shared helpers for the model importers and exporters in formats/src (private header).
#pragma once

#include <charconv>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "penumbra/error.h"
#include "penumbra/file_io.h"
#include "penumbra/io.h"
#include "penumbra/mesh.h"
#include "penumbra/model_format.h"
#include "penumbra/model_stream.h"

namespace penumbra::detail {

// Read-only view of a whole file, memory-mapped. Throws Error("<path>: file not
// found" / "empty file" / "not a regular file" / "cannot open: ...").
class MappedFile {
  public:
    explicit MappedFile(const std::string& path);
    // A view of bytes owned by the caller (in-memory import); throws
    // Error("<path>: empty file") when there are none.
    MappedFile(const std::string& path, const uint8_t* data, size_t size);
    ~MappedFile();
    MappedFile(const MappedFile&) = delete;
    MappedFile& operator=(const MappedFile&) = delete;

    const uint8_t* data() const { return data_; }
    size_t size() const { return size_; }
    // Drops the mapped pages from the process (they stay in the page cache and
    // are read again where touched): after a whole-file pass over a model
    // that is then read sparsely (paged geometry), resident memory is what is used.
    void release() const;
    std::string_view text() const { return {reinterpret_cast<const char*>(data_), size_}; }

  private:
    const uint8_t* data_ = nullptr;
    size_t size_ = 0;
    bool mapped_ = false;
};

using penumbra::AtomicFileWriter;
using penumbra::FileReader;
using penumbra::TemporaryFile;

// Appends the shortest round-trip decimal form of value plus `separator`.
inline char* formatFloat(char* out, float value, char separator)
{
    out = std::to_chars(out, out + 32, value).ptr;
    *out++ = separator;
    return out;
}
inline char* formatUint(char* out, uint64_t value, char separator)
{
    out = std::to_chars(out, out + 24, value).ptr;
    *out++ = separator;
    return out;
}

// Cursor over ASCII model text that tracks the line number for messages.
struct TextCursor {
    const char* p;
    const char* end;
    size_t line = 1;

    bool atEnd() const { return p >= end; }
    // Skips spaces and tabs (and '\r'), not newlines.
    void skipBlanks()
    {
        while (p < end && (*p == ' ' || *p == '\t' || *p == '\r'))
            ++p;
    }
    // Skips all whitespace including newlines.
    void skipWhitespace()
    {
        while (p < end) {
            char c = *p;
            if (c == '\n')
                ++line;
            else if (c != ' ' && c != '\t' && c != '\r' && c != '\f' && c != '\v')
                break;
            ++p;
        }
    }
    // Moves past the next '\n'.
    void skipLine()
    {
        const void* nl = std::memchr(p, '\n', size_t(end - p));
        if (!nl) {
            p = end;
            return;
        }
        p = static_cast<const char*>(nl) + 1;
        ++line;
    }
    // Next whitespace-delimited token (does not cross newlines; empty at end of line).
    std::string_view token()
    {
        skipBlanks();
        const char* start = p;
        while (p < end && !(*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n' || *p == '\f' || *p == '\v'))
            ++p;
        return {start, size_t(p - start)};
    }
};

// Records a non-fatal problem of the import in progress (a skipped feature).
// importScene reports the first message of each kind once, through
// penumbra::warn(path, message), when the import succeeds; outside
// importScene the message is reported at once.
void importWarning(const std::string& path, const std::string& kind, const std::string& message);

// Token text for an error message: at most 40 characters, printable only.
std::string quoteToken(std::string_view token);

// Parses a whole token as a float / integer; false on malformed text.
inline bool parseFloat(std::string_view token, float& value)
{
    if (token.empty())
        return false;
    const char* first = token.data();
    if (*first == '+')
        ++first;
    auto result = std::from_chars(first, token.data() + token.size(), value);
    if (result.ec == std::errc::result_out_of_range) {
        // Denormal underflow rounds to zero; overflow is rejected later as non-finite.
        double d = 0.0;
        auto r2 = std::from_chars(first, token.data() + token.size(), d);
        if (r2.ec != std::errc() || r2.ptr != token.data() + token.size())
            return false;
        value = float(d);
        return true;
    }
    return result.ec == std::errc() && result.ptr == token.data() + token.size();
}
inline bool parseInt(std::string_view token, int64_t& value)
{
    if (token.empty())
        return false;
    const char* first = token.data();
    if (*first == '+')
        ++first;
    auto result = std::from_chars(first, token.data() + token.size(), value);
    return result.ec == std::errc() && result.ptr == token.data() + token.size();
}

// Checks that every index is < vertex count and every position finite; throws Error naming path.
void validateMesh(const std::string& path, const Mesh& mesh);

// Welds bit-identical positions (treating -0 as +0); used by STL which stores
// unindexed triangles. corners holds 9 floats per triangle.
void weldTriangles(const std::vector<float>& corners, Mesh& mesh);

// Format importers; file is non-empty. Each returns the scene before validateMesh.
Scene importObj(const std::string& path, const MappedFile& file);
Scene importPly(const std::string& path, const MappedFile& file);
Scene importStl(const std::string& path, const MappedFile& file);
Scene importGltf(const std::string& path, const MappedFile& file, bool binary);
Scene importDraco(const std::string& path, const MappedFile& file);

// Format exporters; the mesh has been validated and has at least one triangle.
void exportObj(const Scene& scene, AtomicFileWriter& out);
void exportPly(const Scene& scene, AtomicFileWriter& out, bool binary);
void exportStl(const Scene& scene, AtomicFileWriter& out, bool binary);
void exportGltf(const Scene& scene, const std::string& path, AtomicFileWriter& out, bool binary,
                const ExportOptions& options);
void exportDraco(const Scene& scene, const std::string& path, AtomicFileWriter& out, const ExportOptions& options);

// Triangles decoded from a Draco buffer (positions as floats, indices < vertex count).
struct DecodedDraco {
    std::vector<float> positions;
    std::vector<uint32_t> indices;
};

// Decodes a Draco mesh. positionUniqueId selects the position attribute
// (glTF KHR_draco_mesh_compression); -1 uses the attribute named POSITION.
// Throws Error("<path>: <what>: ...") for point clouds and corrupt data.
DecodedDraco decodeDraco(const std::string& path, const std::string& what, const uint8_t* data, size_t size,
                         int64_t positionUniqueId);

// Encodes a mesh with Draco (positions quantized to options.dracoPositionBits).
// Returns the encoded bytes; positionId receives the position attribute's unique
// id, encodedPoints/encodedFaces the counts the decoder will produce.
std::vector<char> encodeDracoMesh(const std::string& path, const Mesh& mesh, const ExportOptions& options,
                                  uint32_t* positionId, size_t* encodedPoints, size_t* encodedFaces);

// Writes a whole .penumbra file image of model (header, sections, padding) at the
// writer's position, validated first as writeModelFile does; returns its size.
uint64_t writeModelImage(const CompressedModel& model, AtomicFileWriter& out, const std::string& path);

// ---- streaming (model_stream.h) ----

// TextCursor's reading over a FileReader: tokens, blanks and lines of a file
// read through a buffer. A token (at most the buffer size) stays valid until
// the next call.
class StreamCursor {
  public:
    explicit StreamCursor(FileReader& in, size_t line = 1) : in_(in), line(line) {}
    bool atEnd() { return !in_.ensure(1); }
    // Skips spaces and tabs (and '\r'), not newlines.
    void skipBlanks();
    // Skips all whitespace including newlines.
    void skipWhitespace();
    // Moves past the next '\n'.
    void skipLine();
    // Next whitespace-delimited token (does not cross newlines; empty at end of line).
    std::string_view token();
    uint64_t offset() const { return in_.offset(); }

  private:
    FileReader& in_;

  public:
    size_t line;
};

// Whole lines of a text file (without the '\n'), read through a buffer;
// a line may be at most the buffer size. line() is the number of the last one.
class LineReader {
  public:
    explicit LineReader(FileReader& in) : in_(in) {}
    bool next(std::string_view& line);
    size_t line() const { return line_; }

  private:
    FileReader& in_;
    size_t line_ = 0;
    size_t pending_ = 0; // bytes of the previous line still to skip
};

// Random access to the vertices a streamed model stores (ModelStream::readVertices).
class VertexStore {
  public:
    virtual ~VertexStore() = default;
    virtual void read(uint64_t first, uint64_t count, float* positions, float* colors) = 0;
};

// A temporary file of float records: x y z, plus r g b when it keeps colours.
class TemporaryVertexStore : public VertexStore {
  public:
    TemporaryVertexStore(const std::string& directory, const std::string& purpose, bool colors);
    void append(const float* xyz, const float* rgb);
    void finish() { file_.finish(); }
    uint64_t count() const { return count_; }
    bool colors() const { return colors_; }
    void read(uint64_t first, uint64_t count, float* positions, float* colors) override;

  private:
    TemporaryFile file_;
    bool colors_;
    uint64_t count_ = 0;
    std::vector<float> scratch_;
};

// The folder for temporary files: options.tempDirectory, else path's folder.
std::string temporaryDirectory(const std::string& path, const ModelStreamOptions& options);

// Batches of triangles for ModelStream::triangles: filled one triangle at a
// time, handed on when full and at the end.
struct TriangleBatcher {
    const std::function<void(const StreamTriangles&)>& sink;
    bool withMaterials = false;
    std::vector<uint64_t> vertices;
    std::vector<float> corners;
    std::vector<uint32_t> materials;
    size_t count = 0;
    static constexpr size_t kBatch = 1 << 15;
    void add(uint64_t a, uint64_t b, uint64_t c, uint32_t material)
    {
        if (vertices.empty())
            vertices.resize(3 * kBatch);
        vertices[3 * count] = a;
        vertices[3 * count + 1] = b;
        vertices[3 * count + 2] = c;
        addMaterial(material);
    }
    void addCorners(const float* nine, uint32_t material)
    {
        if (corners.empty())
            corners.resize(9 * kBatch);
        std::memcpy(&corners[9 * count], nine, 36);
        addMaterial(material);
    }
    void addMaterial(uint32_t material)
    {
        if (withMaterials) {
            if (materials.empty())
                materials.resize(kBatch);
            materials[count] = material;
        }
        if (++count == kBatch)
            flush();
    }
    void flush()
    {
        if (count == 0)
            return;
        StreamTriangles batch;
        batch.count = count;
        batch.vertices = vertices.empty() ? nullptr : vertices.data();
        batch.corners = corners.empty() ? nullptr : corners.data();
        batch.materials = withMaterials ? materials.data() : nullptr;
        count = 0;
        sink(batch);
    }
};

std::unique_ptr<ModelStream> openPlyStream(const std::string& path, const ModelStreamOptions& options);
std::unique_ptr<ModelStream> openObjStream(const std::string& path, const ModelStreamOptions& options);
std::unique_ptr<ModelStream> openStlStream(const std::string& path, const ModelStreamOptions& options);
std::unique_ptr<ModelStream> openGltfStream(const std::string& path, const ModelStreamOptions& options, bool binary);

} // namespace penumbra::detail
