// Streamed model files (model_stream.h): the buffered text cursors, the
// temporary vertex store, format dispatch and readModelStream. The format
// readers live beside their importers (ply.cpp, obj.cpp, stl.cpp, gltf.cpp)
// and share their parsing helpers.
#include <algorithm>
#include <cstring>

#include "io_internal.h"

namespace penumbra {
namespace detail {

namespace {

bool isBlank(char c)
{
    return c == ' ' || c == '\t' || c == '\r';
}

bool isSpace(char c)
{
    return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v';
}

} // namespace

void StreamCursor::skipBlanks()
{
    while (in_.ensure(1)) {
        const char* p = reinterpret_cast<const char*>(in_.data());
        const size_t n = in_.available();
        size_t i = 0;
        while (i < n && isBlank(p[i]))
            ++i;
        in_.advance(i);
        if (i < n)
            return;
    }
}

void StreamCursor::skipWhitespace()
{
    while (in_.ensure(1)) {
        const char* p = reinterpret_cast<const char*>(in_.data());
        const size_t n = in_.available();
        size_t i = 0;
        for (; i < n; ++i) {
            if (p[i] == '\n')
                ++line;
            else if (!isSpace(p[i]))
                break;
        }
        in_.advance(i);
        if (i < n)
            return;
    }
}

void StreamCursor::skipLine()
{
    while (in_.ensure(1)) {
        const char* p = reinterpret_cast<const char*>(in_.data());
        const size_t n = in_.available();
        const void* nl = std::memchr(p, '\n', n);
        if (nl) {
            in_.advance(size_t(static_cast<const char*>(nl) - p) + 1);
            ++line;
            return;
        }
        in_.advance(n);
    }
}

std::string_view StreamCursor::token()
{
    skipBlanks();
    size_t length = 0;
    for (;;) {
        const char* p = reinterpret_cast<const char*>(in_.data());
        const size_t n = in_.available();
        while (length < n && !isSpace(p[length]))
            ++length;
        if (length == n && n + 1 > in_.bufferSize())
            fail(in_.path(), "line " + std::to_string(line) + ": a token longer than " +
                                 std::to_string(in_.bufferSize()) + " bytes");
        if (length < n || !in_.ensure(n + 1)) {
            // The token ends inside the buffer, or the file ends with it.
            p = reinterpret_cast<const char*>(in_.data());
            in_.advance(length);
            return {p, length};
        }
    }
}

bool LineReader::next(std::string_view& line)
{
    in_.advance(pending_);
    pending_ = 0;
    if (!in_.ensure(1))
        return false;
    size_t searched = 0;
    for (;;) {
        const char* p = reinterpret_cast<const char*>(in_.data());
        const size_t n = in_.available();
        const void* nl = std::memchr(p + searched, '\n', n - searched);
        if (nl) {
            const size_t length = size_t(static_cast<const char*>(nl) - p);
            line = {p, length};
            pending_ = length + 1;
            ++line_;
            return true;
        }
        searched = n;
        if (n + 1 > in_.bufferSize())
            fail(in_.path(), "line " + std::to_string(line_ + 1) + " is longer than " + std::to_string(in_.bufferSize()) +
                                 " bytes");
        if (!in_.ensure(n + 1)) {
            // The last line has no newline.
            p = reinterpret_cast<const char*>(in_.data());
            line = {p, in_.available()};
            pending_ = in_.available();
            ++line_;
            return true;
        }
    }
}

TemporaryVertexStore::TemporaryVertexStore(const std::string& directory, const std::string& purpose, bool colors)
    : file_(directory, purpose, size_t(1) << 20), colors_(colors)
{
}

void TemporaryVertexStore::append(const float* xyz, const float* rgb)
{
    float record[6] = {xyz[0], xyz[1], xyz[2], 1.0f, 1.0f, 1.0f};
    if (colors_ && rgb) {
        record[3] = rgb[0];
        record[4] = rgb[1];
        record[5] = rgb[2];
    }
    file_.append(record, colors_ ? 24 : 12);
    ++count_;
}

void TemporaryVertexStore::read(uint64_t first, uint64_t count, float* positions, float* colors)
{
    if (first > count_ || count > count_ - first)
        fail(file_.name(), "internal error: vertices " + std::to_string(first) + "+" + std::to_string(count) +
                               " outside the " + std::to_string(count_) + " stored");
    if (!colors_) {
        file_.readAt(first * 12, positions, size_t(count) * 12);
        return;
    }
    const size_t floats = 6;
    scratch_.resize(size_t(count) * floats);
    file_.readAt(first * floats * 4, scratch_.data(), scratch_.size() * 4);
    for (uint64_t v = 0; v < count; ++v) {
        std::memcpy(positions + 3 * v, &scratch_[v * floats], 12);
        if (colors)
            std::memcpy(colors + 3 * v, &scratch_[v * floats + 3], 12);
    }
}

std::string temporaryDirectory(const std::string& path, const ModelStreamOptions& options)
{
    if (!options.tempDirectory.empty())
        return options.tempDirectory;
    const size_t slash = path.find_last_of('/');
    return slash == std::string::npos ? std::string(".") : slash == 0 ? std::string("/") : path.substr(0, slash);
}

} // namespace detail

std::unique_ptr<ModelStream> openModelStream(const std::string& path, const ModelStreamOptions& options)
{
    switch (formatFromPath(path)) {
    case ModelFormat::Ply:
        return detail::openPlyStream(path, options);
    case ModelFormat::Obj:
        return detail::openObjStream(path, options);
    case ModelFormat::Stl:
        return detail::openStlStream(path, options);
    case ModelFormat::Gltf:
        return detail::openGltfStream(path, options, false);
    case ModelFormat::Glb:
        return detail::openGltfStream(path, options, true);
    case ModelFormat::Draco:
        break;
    }
    fail(path, "a Draco file is one compressed mesh and cannot be streamed; preprocess it without --memory-limit "
               "or convert it, e.g. to PLY");
}

Scene readModelStream(ModelStream& stream)
{
    Scene scene;
    Mesh& mesh = scene.mesh;
    stream.scan([](const float*, size_t) {});
    const bool materials = !stream.materials().empty();
    mesh.materials = stream.materials();
    if (stream.indexed()) {
        const uint64_t count = stream.vertexCount();
        mesh.positions.resize(size_t(count) * 3);
        if (stream.vertexColors())
            mesh.colors.resize(size_t(count) * 3);
        const uint64_t block = 1 << 16;
        for (uint64_t first = 0; first < count; first += block) {
            const uint64_t n = std::min(block, count - first);
            stream.readVertices(first, n, mesh.positions.data() + 3 * first,
                                stream.vertexColors() ? mesh.colors.data() + 3 * first : nullptr);
        }
    }
    std::vector<float> corners;
    stream.triangles([&](const StreamTriangles& batch) {
        for (size_t t = 0; t < batch.count; ++t) {
            if (batch.vertices)
                for (int k = 0; k < 3; ++k)
                    mesh.indices.push_back(uint32_t(batch.vertices[3 * t + size_t(k)]));
            else
                corners.insert(corners.end(), batch.corners + 9 * t, batch.corners + 9 * t + 9);
            if (materials)
                mesh.triangleMaterials.push_back(batch.materials ? batch.materials[t] : 0);
        }
    });
    if (!stream.indexed())
        detail::weldTriangles(corners, mesh);
    scene.cameras = stream.cameras();
    scene.lights = stream.lights();
    return scene;
}

} // namespace penumbra
