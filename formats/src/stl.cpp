// STL import (binary and ASCII; identical corner positions are welded into
// shared vertices) and export. A file is binary when its size is exactly
// 84 + 50 * (triangle count at byte 80); otherwise it must start with "solid".
#include <cmath>

#include <glm/geometric.hpp>

#include "io_internal.h"

namespace penumbra::detail {
namespace {

Scene importBinaryStl(const std::string& path, const MappedFile& file, uint32_t triangleCount)
{
    std::vector<float> corners(size_t(triangleCount) * 9);
    const uint8_t* record = file.data() + 84;
    for (size_t t = 0; t < triangleCount; ++t, record += 50)
        std::memcpy(&corners[t * 9], record + 12, 36);
    Scene scene;
    weldTriangles(corners, scene.mesh);
    return scene;
}

// The ASCII STL grammar over any cursor with TextCursor's interface (the
// mapped file's, or StreamCursor over a FileReader): add(nine) gets each
// facet's triangles (a polygon is fanned; facets are triangles in practice).
// Returns how many it gave; fails on the first malformed line.
template <typename Cursor, typename Add> uint64_t parseAsciiStl(const std::string& path, Cursor& cursor, Add&& add)
{
    auto lineFail = [&](const std::string& problem) {
        fail(path, "line " + std::to_string(cursor.line) + ": " + problem);
    };
    std::vector<float> loop;
    bool inLoop = false;
    size_t loopLine = 0;
    uint64_t complete = 0;
    cursor.skipWhitespace();
    cursor.token();    // "solid"
    cursor.skipLine(); // solid name
    for (;;) {
        cursor.skipWhitespace();
        if (cursor.atEnd())
            break;
        std::string_view token = cursor.token();
        if (token == "vertex") {
            if (!inLoop)
                lineFail("vertex outside an 'outer loop'");
            for (int c = 0; c < 3; ++c) {
                std::string_view number = cursor.token();
                float value;
                if (number.empty())
                    lineFail("vertex has fewer than 3 coordinates");
                if (!parseFloat(number, value))
                    lineFail("malformed number " + quoteToken(number));
                loop.push_back(value);
            }
        } else if (token == "outer") {
            if (cursor.token() != "loop")
                lineFail("expected 'outer loop'");
            if (inLoop)
                lineFail("nested 'outer loop'");
            inLoop = true;
            loopLine = cursor.line;
            loop.clear();
        } else if (token == "endloop") {
            if (!inLoop)
                lineFail("'endloop' without 'outer loop'");
            inLoop = false;
            const size_t n = loop.size() / 3;
            for (size_t k = 2; k < n; ++k) { // fan (facets are triangles in practice)
                float nine[9];
                std::memcpy(nine, &loop[0], 12);
                std::memcpy(nine + 3, &loop[(k - 1) * 3], 12);
                std::memcpy(nine + 6, &loop[k * 3], 12);
                add(nine);
                ++complete;
            }
        } else if (token == "facet" || token == "endfacet" || token == "solid" || token == "endsolid") {
            cursor.skipLine(); // the rest (normal, solid name) is not needed
        } else {
            lineFail("unexpected token " + quoteToken(token));
        }
    }
    if (inLoop)
        fail(path, "truncated: file ends inside the facet that starts on line " + std::to_string(loopLine));
    if (complete == 0)
        fail(path, "no triangles (no complete facets)");
    return complete;
}

Scene importAsciiStl(const std::string& path, const MappedFile& file)
{
    TextCursor cursor{reinterpret_cast<const char*>(file.data()),
                      reinterpret_cast<const char*>(file.data()) + file.size()};
    std::vector<float> corners;
    parseAsciiStl(path, cursor, [&](const float* nine) { corners.insert(corners.end(), nine, nine + 9); });
    Scene scene;
    weldTriangles(corners, scene.mesh);
    return scene;
}

} // namespace

Scene importStl(const std::string& path, const MappedFile& file)
{
    const size_t size = file.size();
    uint32_t triangleCount = 0;
    if (size >= 84)
        std::memcpy(&triangleCount, file.data() + 80, 4);
    if (size >= 84 && uint64_t(size) == 84 + 50 * uint64_t(triangleCount)) {
        if (triangleCount == 0)
            fail(path, "no triangles (binary STL with 0 facets)");
        return importBinaryStl(path, file, triangleCount);
    }
    std::string_view text = file.text();
    size_t start = text.find_first_not_of(" \t\r\n");
    // Some binary exporters also start their header with "solid"; ASCII files
    // name a facet (or end the solid) within the first kilobyte.
    if (start != std::string_view::npos && text.substr(start, 5) == "solid") {
        std::string_view head = text.substr(0, 1024);
        if (head.find("facet") != std::string_view::npos || head.find("endsolid") != std::string_view::npos)
            return importAsciiStl(path, file);
    }
    if (size < 84)
        fail(path, "truncated: " + std::to_string(size) + " bytes is shorter than a binary STL header (84 bytes)");
    uint64_t expected = 84 + 50 * uint64_t(triangleCount);
    if (expected > size)
        fail(path, "truncated: header claims " + std::to_string(triangleCount) + " triangles (" +
                       std::to_string(expected) + " bytes) but the file has " + std::to_string(size) + " bytes");
    fail(path, "malformed binary STL: header claims " + std::to_string(triangleCount) + " triangles (" +
                   std::to_string(expected) + " bytes) but the file has " + std::to_string(size) + " bytes");
}

void exportStl(const Scene& scene, AtomicFileWriter& out, bool binary)
{
    const Mesh& mesh = scene.mesh;
    const size_t triangles = mesh.triangleCount();
    auto normalOf = [&](size_t t) {
        glm::vec3 a = mesh.position(mesh.indices[t * 3]);
        glm::vec3 b = mesh.position(mesh.indices[t * 3 + 1]);
        glm::vec3 c = mesh.position(mesh.indices[t * 3 + 2]);
        glm::vec3 n = glm::cross(b - a, c - a);
        float length = glm::length(n);
        return length > 0.0f && std::isfinite(length) ? n / length : glm::vec3(0.0f);
    };
    if (binary) {
        if (triangles > UINT32_MAX)
            fail(out.path(), "binary STL holds at most 4294967295 triangles");
        char header[84] = "binary STL written by penumbra";
        uint32_t count = uint32_t(triangles);
        std::memcpy(header + 80, &count, 4);
        out.write(header, 84);
        for (size_t t = 0; t < triangles; ++t) {
            char* p = out.reserve(50);
            glm::vec3 n = normalOf(t);
            std::memcpy(p, &n, 12);
            for (int k = 0; k < 3; ++k)
                std::memcpy(p + 12 + k * 12, &mesh.positions[size_t(mesh.indices[t * 3 + size_t(k)]) * 3], 12);
            p[48] = 0;
            p[49] = 0;
            out.advance(50);
        }
        return;
    }
    out.write("solid penumbra\n");
    for (size_t t = 0; t < triangles; ++t) {
        char* start = out.reserve(512);
        char* p = start;
        glm::vec3 n = normalOf(t);
        auto put = [&](const char* text) {
            size_t length = std::strlen(text);
            std::memcpy(p, text, length);
            p += length;
        };
        put("facet normal ");
        p = formatFloat(p, n.x, ' ');
        p = formatFloat(p, n.y, ' ');
        p = formatFloat(p, n.z, '\n');
        put(" outer loop\n");
        for (int k = 0; k < 3; ++k) {
            const float* v = &mesh.positions[size_t(mesh.indices[t * 3 + size_t(k)]) * 3];
            put("  vertex ");
            p = formatFloat(p, v[0], ' ');
            p = formatFloat(p, v[1], ' ');
            p = formatFloat(p, v[2], '\n');
        }
        put(" endloop\nendfacet\n");
        out.advance(size_t(p - start));
    }
    out.write("endsolid penumbra\n");
}

// ---- streaming (model_stream.h) ----

namespace {

class StlStream : public ModelStream {
  public:
    StlStream(const std::string& path, const ModelStreamOptions& options) : in_(path, options.bufferBytes)
    {
        path_ = path;
        indexed_ = false;
    }

    void scan(const std::function<void(const float*, size_t)>& onVertices) override
    {
        // Binary or ASCII, decided exactly as importStl does.
        const uint64_t size = in_.size();
        if (size == 0)
            fail(path_, "empty file");
        uint32_t count = 0;
        if (size >= 84) {
            in_.readAt(80, &count, 4);
        }
        if (size >= 84 && size == 84 + 50 * uint64_t(count)) {
            if (count == 0)
                fail(path_, "no triangles (binary STL with 0 facets)");
            binary_ = true;
            binaryCount_ = count;
        } else {
            in_.seek(0);
            in_.ensure(size_t(std::min<uint64_t>(size, std::min<size_t>(1024, in_.bufferSize()))));
            std::string_view head(reinterpret_cast<const char*>(in_.data()), in_.available());
            head = head.substr(0, 1024);
            const size_t start = head.find_first_not_of(" \t\r\n");
            const bool ascii = start != std::string_view::npos && head.substr(start, 5) == "solid" &&
                               (head.find("facet") != std::string_view::npos || head.find("endsolid") != std::string_view::npos);
            if (!ascii) {
                if (size < 84)
                    fail(path_, "truncated: " + std::to_string(size) +
                                    " bytes is shorter than a binary STL header (84 bytes)");
                const uint64_t expected = 84 + 50 * uint64_t(count);
                if (expected > size)
                    fail(path_, "truncated: header claims " + std::to_string(count) + " triangles (" +
                                    std::to_string(expected) + " bytes) but the file has " + std::to_string(size) + " bytes");
                fail(path_, "malformed binary STL: header claims " + std::to_string(count) + " triangles (" +
                                std::to_string(expected) + " bytes) but the file has " + std::to_string(size) + " bytes");
            }
        }
        uint64_t triangles = 0;
        read([&](const float* corners, size_t n) {
            for (size_t i = 0; i < 9 * n; ++i)
                if (!std::isfinite(corners[i]))
                    fail(path_, "triangle " + std::to_string(triangles + i / 9) + " has a non-finite corner");
            onVertices(corners, 3 * n);
            triangles += n;
        });
        if (triangles == 0)
            fail(path_, "no triangles (no complete facets)");
        triangleCount_ = triangles;
        scanned_ = true;
    }

    void triangles(const std::function<void(const StreamTriangles&)>& onTriangles) override
    {
        if (!scanned_)
            fail(path_, "internal error: triangles() before scan()");
        read([&](const float* corners, size_t n) {
            StreamTriangles batch;
            batch.count = n;
            batch.corners = corners;
            onTriangles(batch);
        });
    }

    void readVertices(uint64_t, uint64_t, float*, float*) override
    {
        fail(path_, "internal error: an STL file has no shared vertices");
    }

  private:
    // Every triangle's corners, in batches (9 floats per triangle).
    void read(const std::function<void(const float*, size_t)>& batch)
    {
        std::vector<float> corners;
        const size_t perBatch = 1 << 14;
        corners.reserve(perBatch * 9);
        auto add = [&](const float* nine) {
            corners.insert(corners.end(), nine, nine + 9);
            if (corners.size() == perBatch * 9) {
                batch(corners.data(), perBatch);
                corners.clear();
            }
        };
        if (binary_) {
            in_.seek(84);
            float nine[9];
            for (uint64_t t = 0; t < binaryCount_; ++t) {
                if (!in_.ensure(50))
                    fail(path_, "truncated: file ends inside facet " + std::to_string(t));
                std::memcpy(nine, in_.data() + 12, 36);
                in_.advance(50);
                add(nine);
            }
        } else {
            readAscii(add);
        }
        if (!corners.empty())
            batch(corners.data(), corners.size() / 9);
    }

    // importAsciiStl's parser over the stream.
    template <typename Add> void readAscii(Add&& add)
    {
        in_.seek(0);
        StreamCursor cursor(in_, 1);
        parseAsciiStl(path_, cursor, add);
    }

    FileReader in_;
    bool binary_ = false;
    bool scanned_ = false;
    uint64_t binaryCount_ = 0;
};

} // namespace

std::unique_ptr<ModelStream> openStlStream(const std::string& path, const ModelStreamOptions& options)
{
    return std::make_unique<StlStream>(path, options);
}

} // namespace penumbra::detail
