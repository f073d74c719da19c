// Wavefront OBJ import (v and f records; polygons fan-triangulated; negative
// relative indices; v, v/vt, v//vn and v/vt/vn corners) and export.
// Colours: 'v x y z r g b' vertex colours, and materials from 'usemtl' with
// their Kd from the 'mtllib' files. Everything else (vt, vn, groups,
// smoothing, the other mtl properties) is ignored.
#include <algorithm>
#include <cstdio>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <unordered_map>

#include <glm/vec3.hpp>

#include "io_internal.h"

namespace penumbra::detail {
namespace {

// Next token of a v or f record: a lone '\' continues the record on the next
// line, and '#' starts a comment that ends it (an empty token at the end).
std::string_view recordToken(TextCursor& cursor)
{
    for (;;) {
        std::string_view token = cursor.token();
        if (token == "\\") {
            cursor.skipLine();
            continue;
        }
        if (!token.empty() && token[0] == '#') {
            const void* nl = std::memchr(cursor.p, '\n', size_t(cursor.end - cursor.p));
            cursor.p = nl ? static_cast<const char*>(nl) : cursor.end;
            return {};
        }
        return token;
    }
}

// Parses the vertex part of a face corner ("12", "-3/4/5", "7//2").
bool parseCorner(std::string_view token, int64_t& index)
{
    size_t slash = token.find('/');
    return parseInt(token.substr(0, slash), index);
}

// The fields of a 'v' record after "v ": x y z into xyz, then up to four
// optional numbers into extra (w, or the common colour extension r g b, also
// after a w; anything else after the position is ignored). Returns how many
// optional numbers there were; lineFail(problem) on a bad position.
template <typename Fail> size_t parseVertexRecord(TextCursor& cursor, Fail&& lineFail, float xyz[3], float extra[4])
{
    for (int i = 0; i < 3; ++i) {
        std::string_view token = recordToken(cursor);
        if (token.empty())
            lineFail("vertex has fewer than 3 coordinates");
        if (!parseFloat(token, xyz[i]))
            lineFail("malformed number " + quoteToken(token));
    }
    size_t extraCount = 0;
    for (std::string_view token = recordToken(cursor); !token.empty() && extraCount < 4;
         token = extraCount < 4 ? recordToken(cursor) : std::string_view{}) {
        if (!parseFloat(token, extra[extraCount]))
            break;
        ++extraCount;
    }
    return extraCount;
}

} // namespace

// True when the record at cursor.p is `keyword` followed by a blank.
bool isRecord(const TextCursor& cursor, std::string_view keyword)
{
    return size_t(cursor.end - cursor.p) > keyword.size() && std::memcmp(cursor.p, keyword.data(), keyword.size()) == 0 &&
           (cursor.p[keyword.size()] == ' ' || cursor.p[keyword.size()] == '\t');
}

// Kd of every `newmtl` in an mtl file (later definitions of a name win).
void readMtl(const std::string& path, std::unordered_map<std::string, glm::vec3>& kd)
{
    std::error_code error;
    if (!std::filesystem::is_regular_file(path, error)) // never a device or a pipe
        fail(path, "not a regular file");
    MappedFile file(path);
    TextCursor cursor{reinterpret_cast<const char*>(file.data()), reinterpret_cast<const char*>(file.data()) + file.size()};
    std::string current;
    while (!cursor.atEnd()) {
        cursor.skipBlanks();
        if (isRecord(cursor, "newmtl")) {
            cursor.p += 6;
            current = std::string(cursor.token());
        } else if (isRecord(cursor, "Kd") && !current.empty()) {
            cursor.p += 2;
            glm::vec3 color(1.0f);
            bool ok = true;
            for (int k = 0; k < 3; ++k) {
                std::string_view token = cursor.token();
                float value = 0.0f;
                if (token.empty() || !parseFloat(token, value) || !std::isfinite(value)) {
                    ok = false; // 'Kd spectral ...', 'Kd xyz ...': not read
                    break;
                }
                color[k] = std::clamp(value, 0.0f, 1.0f);
            }
            if (ok)
                kd[current] = color;
        }
        cursor.skipLine();
    }
}

Scene importObj(const std::string& path, const MappedFile& file)
{
    Scene scene;
    Mesh& mesh = scene.mesh;
    TextCursor cursor{reinterpret_cast<const char*>(file.data()),
                      reinterpret_cast<const char*>(file.data()) + file.size()};
    auto lineFail = [&](const std::string& problem) {
        fail(path, "line " + std::to_string(cursor.line) + ": " + problem);
    };

    size_t pointOrLineRecords = 0;
    size_t degenerateFaces = 0;
    int64_t maxForwardIndex = 0; // largest positive index, checked once all vertices are known
    size_t maxForwardLine = 0;
    std::vector<uint32_t> polygon;
    // Materials: `mtllib` files (next to the OBJ), `usemtl` names in order of first use.
    std::vector<std::string> mtlFiles;
    std::unordered_map<std::string, uint32_t> materialIndex;
    uint32_t currentMaterial = 0; // faces before the first usemtl: material 0, a white default

    while (!cursor.atEnd()) {
        cursor.skipBlanks();
        if (cursor.atEnd())
            break;
        char c = *cursor.p;
        if (c == 'v' && cursor.p + 1 < cursor.end && (cursor.p[1] == ' ' || cursor.p[1] == '\t')) {
            cursor.p += 2;
            float xyz[3], extra[4];
            const size_t extraCount = parseVertexRecord(cursor, lineFail, xyz, extra);
            if (extraCount >= 3) {
                if (mesh.colors.empty())
                    mesh.colors.assign(mesh.positions.size(), 1.0f); // earlier vertices: white
                for (size_t k = extraCount - 3; k < extraCount; ++k)
                    mesh.colors.push_back(std::isfinite(extra[k]) ? std::clamp(extra[k], 0.0f, 1.0f) : 0.0f);
            } else if (!mesh.colors.empty()) {
                mesh.colors.insert(mesh.colors.end(), {1.0f, 1.0f, 1.0f});
            }
            mesh.positions.insert(mesh.positions.end(), xyz, xyz + 3);
        } else if (c == 'f' && cursor.p + 1 < cursor.end && (cursor.p[1] == ' ' || cursor.p[1] == '\t')) {
            cursor.p += 2;
            polygon.clear();
            const int64_t vertexCount = int64_t(mesh.positions.size() / 3);
            for (;;) {
                std::string_view token = recordToken(cursor);
                if (token.empty())
                    break;
                int64_t index = 0;
                if (!parseCorner(token, index))
                    lineFail("malformed face corner " + quoteToken(token));
                if (index < 0) {
                    int64_t resolved = vertexCount + index;
                    if (resolved < 0)
                        lineFail("face references vertex " + std::to_string(index) + " but only " +
                                 std::to_string(vertexCount) + " vertices precede it");
                    index = resolved;
                } else if (index == 0) {
                    lineFail("face references vertex 0 (OBJ indices start at 1)");
                } else {
                    if (index > UINT32_MAX)
                        lineFail("face references vertex " + std::to_string(index) + " (too large)");
                    if (index > maxForwardIndex) {
                        maxForwardIndex = index;
                        maxForwardLine = cursor.line;
                    }
                    index -= 1;
                }
                polygon.push_back(uint32_t(index));
            }
            if (polygon.size() < 3) {
                ++degenerateFaces;
            } else {
                for (size_t k = 2; k < polygon.size(); ++k) {
                    mesh.indices.push_back(polygon[0]);
                    mesh.indices.push_back(polygon[k - 1]);
                    mesh.indices.push_back(polygon[k]);
                }
                if (!mesh.materials.empty())
                    mesh.triangleMaterials.resize(mesh.triangleCount(), currentMaterial);
            }
        } else if (isRecord(cursor, "usemtl")) {
            cursor.p += 6;
            const std::string name(cursor.token());
            if (mesh.materials.empty()) {
                mesh.materials.push_back({glm::vec4(1.0f), "default"});
                mesh.triangleMaterials.assign(mesh.triangleCount(), 0);
            }
            auto [it, added] = materialIndex.emplace(name, uint32_t(mesh.materials.size()));
            if (added)
                mesh.materials.push_back({glm::vec4(1.0f), name});
            currentMaterial = it->second;
        } else if (isRecord(cursor, "mtllib")) {
            cursor.p += 6;
            for (std::string_view token = cursor.token(); !token.empty(); token = cursor.token())
                mtlFiles.emplace_back(token);
        } else if ((c == 'l' || c == 'p') && cursor.p + 1 < cursor.end && (cursor.p[1] == ' ' || cursor.p[1] == '\t')) {
            ++pointOrLineRecords;
        }
        cursor.skipLine();
    }

    const size_t vertexCount = mesh.vertexCount();
    if (uint64_t(maxForwardIndex) > vertexCount)
        fail(path, "line " + std::to_string(maxForwardLine) + ": face references vertex " +
                       std::to_string(maxForwardIndex) + " but there are " + std::to_string(vertexCount) + " vertices");
    if (mesh.indices.empty()) {
        if (pointOrLineRecords > 0 || degenerateFaces > 0)
            fail(path, "no triangles (points or lines only)");
        if (vertexCount == 0)
            fail(path, "no vertices or faces (not an OBJ file?)");
        fail(path, "no triangles (" + std::to_string(vertexCount) + " vertices but no faces)");
    }
    // Base colours from the mtl files' Kd; a missing file or material is a warning (the surface stays white).
    if (!mesh.materials.empty()) {
        std::unordered_map<std::string, glm::vec3> kd;
        const size_t slash = path.find_last_of('/');
        const std::string directory = slash == std::string::npos ? std::string() : path.substr(0, slash + 1);
        std::string missingFiles;
        for (const std::string& name : mtlFiles) {
            try {
                readMtl(directory + name, kd);
            } catch (const Error&) {
                missingFiles += (missingFiles.empty() ? "'" : ", '") + name + "'";
            }
        }
        if (!missingFiles.empty())
            importWarning(path, "obj-mtllib", "could not read material library " + missingFiles + " (surfaces stay white)");
        size_t unknown = 0;
        for (size_t m = 1; m < mesh.materials.size(); ++m) {
            auto it = kd.find(mesh.materials[m].name);
            if (it != kd.end())
                mesh.materials[m].baseColor = glm::vec4(it->second, 1.0f);
            else
                ++unknown;
        }
        if (unknown > 0 && missingFiles.empty())
            importWarning(path, "obj-usemtl", std::to_string(unknown) + " material(s) named by usemtl have no Kd in the material libraries (white)");
    }
    if (pointOrLineRecords > 0)
        importWarning(path, "obj-lines",
                      "skipped " + std::to_string(pointOrLineRecords) + " 'l'/'p' records (lines and points)");
    if (degenerateFaces > 0)
        importWarning(path, "obj-degenerate",
                      "skipped " + std::to_string(degenerateFaces) + " faces with fewer than 3 vertices");
    return scene;
}

void exportObj(const Scene& scene, AtomicFileWriter& out)
{
    const Mesh& mesh = scene.mesh;
    out.write("# written by penumbra\n# " + std::to_string(mesh.vertexCount()) + " vertices, " +
              std::to_string(mesh.triangleCount()) + " triangles\n");
    for (size_t v = 0; v < mesh.vertexCount(); ++v) {
        char* start = out.reserve(128);
        char* p = start;
        *p++ = 'v';
        *p++ = ' ';
        p = formatFloat(p, mesh.positions[v * 3], ' ');
        p = formatFloat(p, mesh.positions[v * 3 + 1], ' ');
        p = formatFloat(p, mesh.positions[v * 3 + 2], '\n');
        out.advance(size_t(p - start));
    }
    for (size_t t = 0; t < mesh.triangleCount(); ++t) {
        char* start = out.reserve(128);
        char* p = start;
        *p++ = 'f';
        *p++ = ' ';
        p = formatUint(p, uint64_t(mesh.indices[t * 3]) + 1, ' ');
        p = formatUint(p, uint64_t(mesh.indices[t * 3 + 1]) + 1, ' ');
        p = formatUint(p, uint64_t(mesh.indices[t * 3 + 2]) + 1, '\n');
        out.advance(size_t(p - start));
    }
}

// ---- streaming (model_stream.h) ----

namespace {

// True when a record line continues on the next one: a lone '\' token before any '#' comment
// (recordToken's rule).
bool continuesRecord(std::string_view line)
{
    TextCursor cursor{line.data(), line.data() + line.size()};
    for (std::string_view token = cursor.token(); !token.empty(); token = cursor.token()) {
        if (token[0] == '#')
            return false;
        if (token == "\\")
            return true;
    }
    return false;
}

class ObjStream : public ModelStream {
  public:
    ObjStream(const std::string& path, const ModelStreamOptions& options)
        : in_(path, options.bufferBytes), options_(options)
    {
        path_ = path;
    }

    void scan(const std::function<void(const float*, size_t)>& onVertices) override
    {
        if (in_.size() == 0)
            fail(path_, "empty file");
        positions_ = std::make_unique<TemporaryVertexStore>(temporaryDirectory(path_, options_),
                                                            "the vertices of " + path_, false);
        std::vector<float> batch;
        const size_t batchVertices = 1 << 14;
        uint64_t pointOrLineRecords = 0, degenerateFaces = 0, triangles = 0;
        int64_t maxForwardIndex = 0;
        size_t maxForwardLine = 0;
        parse(
            [&](const float* xyz, const float* rgb, size_t line) {
                if (!std::isfinite(xyz[0]) || !std::isfinite(xyz[1]) || !std::isfinite(xyz[2])) {
                    char text[160];
                    std::snprintf(text, sizeof(text), "vertex %llu has a non-finite position (%g, %g, %g)",
                                  (unsigned long long)positions_->count(), double(xyz[0]), double(xyz[1]), double(xyz[2]));
                    fail(path_, text);
                }
                (void)line;
                if (rgb && !colors_) {
                    // The first coloured vertex: the earlier ones are white.
                    colors_ = std::make_unique<TemporaryVertexStore>(temporaryDirectory(path_, options_),
                                                                     "the vertex colours of " + path_, false);
                    const float white[3] = {1, 1, 1};
                    for (uint64_t v = 0; v < positions_->count(); ++v)
                        colors_->append(white, nullptr);
                }
                if (colors_) {
                    const float white[3] = {1, 1, 1};
                    colors_->append(rgb ? rgb : white, nullptr);
                }
                positions_->append(xyz, nullptr);
                batch.insert(batch.end(), xyz, xyz + 3);
                if (batch.size() == batchVertices * 3) {
                    onVertices(batch.data(), batchVertices);
                    batch.clear();
                }
            },
            [&](const std::vector<uint64_t>& polygon, uint32_t, size_t) {
                if (polygon.size() < 3)
                    ++degenerateFaces;
                else
                    triangles += polygon.size() - 2;
            },
            [&](int64_t index, size_t line) {
                if (index > maxForwardIndex) {
                    maxForwardIndex = index;
                    maxForwardLine = line;
                }
            },
            pointOrLineRecords);
        if (!batch.empty())
            onVertices(batch.data(), batch.size() / 3);
        positions_->finish();
        if (colors_)
            colors_->finish();
        vertexCount_ = positions_->count();
        vertexColors_ = colors_ != nullptr;
        triangleCount_ = triangles;

        if (uint64_t(maxForwardIndex) > vertexCount_)
            fail(path_, "line " + std::to_string(maxForwardLine) + ": face references vertex " +
                            std::to_string(maxForwardIndex) + " but there are " + std::to_string(vertexCount_) + " vertices");
        if (triangles == 0) {
            if (pointOrLineRecords > 0 || degenerateFaces > 0)
                fail(path_, "no triangles (points or lines only)");
            if (vertexCount_ == 0)
                fail(path_, "no vertices or faces (not an OBJ file?)");
            fail(path_, "no triangles (" + std::to_string(vertexCount_) + " vertices but no faces)");
        }
        // Base colours from the mtl files' Kd, as importObj.
        if (!materials_.empty()) {
            std::unordered_map<std::string, glm::vec3> kd;
            const size_t slash = path_.find_last_of('/');
            const std::string directory = slash == std::string::npos ? std::string() : path_.substr(0, slash + 1);
            std::string missingFiles;
            for (const std::string& name : mtlFiles_) {
                try {
                    readMtl(directory + name, kd);
                } catch (const Error&) {
                    missingFiles += (missingFiles.empty() ? "'" : ", '") + name + "'";
                }
            }
            if (!missingFiles.empty())
                warn(path_, "could not read material library " + missingFiles + " (surfaces stay white)");
            size_t unknown = 0;
            for (size_t m = 1; m < materials_.size(); ++m) {
                auto it = kd.find(materials_[m].name);
                if (it != kd.end())
                    materials_[m].baseColor = glm::vec4(it->second, 1.0f);
                else
                    ++unknown;
            }
            if (unknown > 0 && missingFiles.empty())
                warn(path_, std::to_string(unknown) + " material(s) named by usemtl have no Kd in the material libraries (white)");
        }
        if (pointOrLineRecords > 0)
            warn(path_, "skipped " + std::to_string(pointOrLineRecords) + " 'l'/'p' records (lines and points)");
        if (degenerateFaces > 0)
            warn(path_, "skipped " + std::to_string(degenerateFaces) + " faces with fewer than 3 vertices");
        scanned_ = true;
    }

    void triangles(const std::function<void(const StreamTriangles&)>& onTriangles) override
    {
        if (!scanned_)
            fail(path_, "internal error: triangles() before scan()");
        TriangleBatcher batcher{onTriangles};
        batcher.withMaterials = !materials_.empty();
        uint64_t ignored = 0;
        std::vector<Material> keep = materials_; // parse() rebuilds the usemtl table in the same order
        parse([](const float*, const float*, size_t) {},
              [&](const std::vector<uint64_t>& polygon, uint32_t material, size_t) {
                  for (size_t k = 2; k < polygon.size(); ++k)
                      batcher.add(polygon[0], polygon[k - 1], polygon[k], material);
              },
              [](int64_t, size_t) {}, ignored);
        materials_ = std::move(keep);
        batcher.flush();
    }

    void readVertices(uint64_t first, uint64_t count, float* positions, float* colors) override
    {
        if (!positions_)
            fail(path_, "internal error: readVertices() before scan()");
        positions_->read(first, count, positions, nullptr);
        if (colors && colors_)
            colors_->read(first, count, colors, nullptr);
    }

  private:
    // importObj's loop over the file's lines: vertex(xyz, rgb or null, line), face(polygon of
    // 0-based vertex ids, material, line), forward(positive 1-based index, line).
    template <typename Vertex, typename Face, typename Forward>
    void parse(Vertex&& vertex, Face&& face, Forward&& forward, uint64_t& pointOrLineRecords)
    {
        in_.seek(0);
        LineReader lines(in_);
        std::string record;
        std::vector<uint64_t> polygon;
        std::unordered_map<std::string, uint32_t> materialIndex;
        materials_.clear();
        mtlFiles_.clear();
        uint32_t currentMaterial = 0;
        uint64_t vertexCount = 0;
        std::string_view line;
        while (lines.next(line)) {
            const size_t firstLine = lines.line();
            TextCursor cursor{line.data(), line.data() + line.size()};
            cursor.skipBlanks();
            if (cursor.atEnd())
                continue;
            const char c = *cursor.p;
            const bool vertexRecord = c == 'v' && cursor.p + 1 < cursor.end && (cursor.p[1] == ' ' || cursor.p[1] == '\t');
            const bool faceRecord = c == 'f' && cursor.p + 1 < cursor.end && (cursor.p[1] == ' ' || cursor.p[1] == '\t');
            if ((vertexRecord || faceRecord) && continuesRecord(line)) {
                // A record continued with '\': the lines recordToken will read, joined by newlines.
                record.assign(line);
                std::string_view last = line;
                while (continuesRecord(last) && lines.next(last)) {
                    record += '\n';
                    record.append(last);
                }
                cursor = TextCursor{record.data(), record.data() + record.size()};
                cursor.skipBlanks();
            }
            cursor.line = firstLine;
            auto lineFail = [&](const std::string& problem) {
                fail(path_, "line " + std::to_string(cursor.line) + ": " + problem);
            };
            if (vertexRecord) {
                cursor.p += 2;
                float xyz[3], extra[4];
                const size_t extraCount = parseVertexRecord(cursor, lineFail, xyz, extra);
                float rgb[3];
                if (extraCount >= 3)
                    for (size_t k = extraCount - 3, j = 0; k < extraCount; ++k, ++j)
                        rgb[j] = std::isfinite(extra[k]) ? std::clamp(extra[k], 0.0f, 1.0f) : 0.0f;
                vertex(xyz, extraCount >= 3 ? rgb : nullptr, firstLine);
                ++vertexCount;
            } else if (faceRecord) {
                cursor.p += 2;
                polygon.clear();
                for (;;) {
                    std::string_view token = recordToken(cursor);
                    if (token.empty())
                        break;
                    int64_t index = 0;
                    if (!parseCorner(token, index))
                        lineFail("malformed face corner " + quoteToken(token));
                    if (index < 0) {
                        const int64_t resolved = int64_t(vertexCount) + index;
                        if (resolved < 0)
                            lineFail("face references vertex " + std::to_string(index) + " but only " +
                                     std::to_string(vertexCount) + " vertices precede it");
                        index = resolved;
                    } else if (index == 0) {
                        lineFail("face references vertex 0 (OBJ indices start at 1)");
                    } else {
                        if (index > UINT32_MAX)
                            lineFail("face references vertex " + std::to_string(index) + " (too large)");
                        forward(index, cursor.line);
                        index -= 1;
                    }
                    polygon.push_back(uint64_t(index));
                }
                face(polygon, currentMaterial, firstLine);
            } else if (isRecord(cursor, "usemtl")) {
                cursor.p += 6;
                const std::string name(cursor.token());
                if (materials_.empty())
                    materials_.push_back({glm::vec4(1.0f), "default"});
                auto [it, added] = materialIndex.emplace(name, uint32_t(materials_.size()));
                if (added)
                    materials_.push_back({glm::vec4(1.0f), name});
                currentMaterial = it->second;
            } else if (isRecord(cursor, "mtllib")) {
                cursor.p += 6;
                for (std::string_view token = cursor.token(); !token.empty(); token = cursor.token())
                    mtlFiles_.emplace_back(token);
            } else if ((c == 'l' || c == 'p') && cursor.p + 1 < cursor.end && (cursor.p[1] == ' ' || cursor.p[1] == '\t')) {
                ++pointOrLineRecords;
            }
        }
    }

    FileReader in_;
    ModelStreamOptions options_;
    std::unique_ptr<TemporaryVertexStore> positions_, colors_;
    std::vector<std::string> mtlFiles_;
    bool scanned_ = false;
};

} // namespace

std::unique_ptr<ModelStream> openObjStream(const std::string& path, const ModelStreamOptions& options)
{
    return std::make_unique<ObjStream>(path, options);
}

} // namespace penumbra::detail
