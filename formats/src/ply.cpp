// PLY (Stanford polygon format) import and export: ASCII, binary little- and
// big-endian. Reference: Greg Turk, "The PLY Polygon File Format" (1994).
// Binary vertex and face records are parsed in place from the mapped file;
// the common layout (float x,y,z ... / list uchar int vertex_indices) has a
// dedicated loop. Every count is checked against the bytes left before any
// allocation.
#include <algorithm>
#include <bit>
#include <cmath>
#include <unordered_map>
#include <cinttypes>
#include <cstdio>
#include <optional>

#include <glm/vec3.hpp>

#include "io_internal.h"

namespace penumbra::detail {
namespace {

enum class PlyType : uint8_t { Int8, Uint8, Int16, Uint16, Int32, Uint32, Float32, Float64 };

std::optional<PlyType> parsePlyType(std::string_view name)
{
    if (name == "char" || name == "int8")
        return PlyType::Int8;
    if (name == "uchar" || name == "uint8")
        return PlyType::Uint8;
    if (name == "short" || name == "int16")
        return PlyType::Int16;
    if (name == "ushort" || name == "uint16")
        return PlyType::Uint16;
    if (name == "int" || name == "int32")
        return PlyType::Int32;
    if (name == "uint" || name == "uint32")
        return PlyType::Uint32;
    if (name == "float" || name == "float32")
        return PlyType::Float32;
    if (name == "double" || name == "float64")
        return PlyType::Float64;
    return std::nullopt;
}

size_t plyTypeSize(PlyType type)
{
    switch (type) {
    case PlyType::Int8:
    case PlyType::Uint8:
        return 1;
    case PlyType::Int16:
    case PlyType::Uint16:
        return 2;
    case PlyType::Int32:
    case PlyType::Uint32:
    case PlyType::Float32:
        return 4;
    case PlyType::Float64:
        return 8;
    }
    return 1;
}

bool isIntegerType(PlyType type)
{
    return type != PlyType::Float32 && type != PlyType::Float64;
}

struct PlyProperty {
    std::string name;
    PlyType type = PlyType::Float32; // value type (item type for lists)
    bool isList = false;
    PlyType countType = PlyType::Uint8; // lists only
};

struct PlyElement {
    std::string name;
    uint64_t count = 0;
    std::vector<PlyProperty> properties;
    // Byte size of one record when it has no list properties, else 0.
    size_t fixedStride() const
    {
        size_t stride = 0;
        for (const PlyProperty& p : properties) {
            if (p.isList)
                return 0;
            stride += plyTypeSize(p.type);
        }
        return stride;
    }
    // Smallest possible record size (lists empty).
    size_t minimumStride() const
    {
        size_t stride = 0;
        for (const PlyProperty& p : properties)
            stride += plyTypeSize(p.isList ? p.countType : p.type);
        return stride;
    }
    int find(std::string_view name) const
    {
        for (size_t i = 0; i < properties.size(); ++i)
            if (properties[i].name == name)
                return int(i);
        return -1;
    }
};

enum class PlyEncoding { Ascii, BinaryLittle, BinaryBig };

struct PlyHeader {
    PlyEncoding encoding = PlyEncoding::Ascii;
    std::vector<PlyElement> elements;
    size_t dataOffset = 0;
};

PlyHeader parseHeader(const std::string& path, const MappedFile& file)
{
    TextCursor cursor{reinterpret_cast<const char*>(file.data()),
                      reinterpret_cast<const char*>(file.data()) + file.size()};
    auto headerFail = [&](const std::string& problem) {
        fail(path, "header line " + std::to_string(cursor.line) + ": " + problem);
    };

    if (cursor.token() != "ply")
        fail(path, "not a PLY file (missing 'ply' magic)");
    if (!cursor.token().empty())
        headerFail("unexpected text after 'ply'");
    cursor.skipLine();

    PlyHeader header;
    bool haveFormat = false;
    for (;;) {
        if (cursor.atEnd())
            fail(path, "truncated header (no end_header line)");
        std::string_view keyword = cursor.token();
        if (keyword == "end_header") {
            if (!cursor.token().empty())
                headerFail("unexpected text after end_header");
            cursor.skipLine();
            break;
        }
        if (keyword.empty() || keyword == "comment" || keyword == "obj_info") {
            cursor.skipLine();
            continue;
        }
        if (keyword == "format") {
            std::string_view encoding = cursor.token();
            std::string_view version = cursor.token();
            if (encoding == "ascii")
                header.encoding = PlyEncoding::Ascii;
            else if (encoding == "binary_little_endian")
                header.encoding = PlyEncoding::BinaryLittle;
            else if (encoding == "binary_big_endian")
                header.encoding = PlyEncoding::BinaryBig;
            else
                headerFail("unknown format " + quoteToken(encoding));
            if (version != "1.0")
                headerFail("unsupported PLY version " + quoteToken(version));
            haveFormat = true;
        } else if (keyword == "element") {
            PlyElement element;
            element.name = std::string(cursor.token());
            std::string_view countText = cursor.token();
            int64_t count = 0;
            if (element.name.empty() || !parseInt(countText, count) || count < 0)
                headerFail("malformed element line (expected 'element <name> <count>')");
            element.count = uint64_t(count);
            header.elements.push_back(std::move(element));
        } else if (keyword == "property") {
            if (header.elements.empty())
                headerFail("property before any element");
            PlyProperty property;
            std::string_view typeName = cursor.token();
            if (typeName == "list") {
                property.isList = true;
                std::string_view countTypeName = cursor.token();
                std::string_view itemTypeName = cursor.token();
                auto countType = parsePlyType(countTypeName);
                auto itemType = parsePlyType(itemTypeName);
                if (!countType || !isIntegerType(*countType))
                    headerFail("bad list count type " + quoteToken(countTypeName));
                if (!itemType)
                    headerFail("unknown property type " + quoteToken(itemTypeName));
                property.countType = *countType;
                property.type = *itemType;
            } else {
                auto type = parsePlyType(typeName);
                if (!type)
                    headerFail("unknown property type " + quoteToken(typeName));
                property.type = *type;
            }
            property.name = std::string(cursor.token());
            if (property.name.empty())
                headerFail("property without a name");
            header.elements.back().properties.push_back(std::move(property));
        } else {
            headerFail("unknown keyword " + quoteToken(keyword));
        }
        if (!cursor.token().empty())
            headerFail("unexpected text at end of line");
        cursor.skipLine();
    }
    if (!haveFormat)
        fail(path, "header has no format line");
    header.dataOffset = size_t(cursor.p - reinterpret_cast<const char*>(file.data()));
    return header;
}

// ---- binary ----

template <typename T> T loadSwapped(const uint8_t* p, bool swap)
{
    T value;
    std::memcpy(&value, p, sizeof(T));
    if (swap) {
        if constexpr (sizeof(T) == 2) {
            uint16_t u;
            std::memcpy(&u, &value, 2);
            u = __builtin_bswap16(u);
            std::memcpy(&value, &u, 2);
        } else if constexpr (sizeof(T) == 4) {
            uint32_t u;
            std::memcpy(&u, &value, 4);
            u = __builtin_bswap32(u);
            std::memcpy(&value, &u, 4);
        } else if constexpr (sizeof(T) == 8) {
            uint64_t u;
            std::memcpy(&u, &value, 8);
            u = __builtin_bswap64(u);
            std::memcpy(&value, &u, 8);
        }
    }
    return value;
}

double loadNumber(const uint8_t* p, PlyType type, bool swap)
{
    switch (type) {
    case PlyType::Int8:
        return double(int8_t(*p));
    case PlyType::Uint8:
        return double(*p);
    case PlyType::Int16:
        return double(loadSwapped<int16_t>(p, swap));
    case PlyType::Uint16:
        return double(loadSwapped<uint16_t>(p, swap));
    case PlyType::Int32:
        return double(loadSwapped<int32_t>(p, swap));
    case PlyType::Uint32:
        return double(loadSwapped<uint32_t>(p, swap));
    case PlyType::Float32:
        return double(loadSwapped<float>(p, swap));
    case PlyType::Float64:
        return loadSwapped<double>(p, swap);
    }
    return 0.0;
}

int64_t loadInteger(const uint8_t* p, PlyType type, bool swap)
{
    switch (type) {
    case PlyType::Int8:
        return int8_t(*p);
    case PlyType::Uint8:
        return *p;
    case PlyType::Int16:
        return loadSwapped<int16_t>(p, swap);
    case PlyType::Uint16:
        return loadSwapped<uint16_t>(p, swap);
    case PlyType::Int32:
        return loadSwapped<int32_t>(p, swap);
    case PlyType::Uint32:
        return loadSwapped<uint32_t>(p, swap);
    default:
        return 0;
    }
}

[[noreturn]] void failIndex(const std::string& path, uint64_t face, int64_t index, uint64_t vertexCount)
{
    fail(path, "face " + std::to_string(face) + " references vertex " + std::to_string(index) + " but there are " +
                   std::to_string(vertexCount) + " vertices");
}

// Colour properties of an element: red, green, blue (or diffuse_red, ...).
struct ColorProperties {
    int index[3] = {-1, -1, -1};
    bool present() const { return index[0] >= 0 && index[1] >= 0 && index[2] >= 0; }
    // Channel of property i, or -1.
    int channel(size_t i) const { return int(i) == index[0] ? 0 : int(i) == index[1] ? 1 : int(i) == index[2] ? 2 : -1; }
};

ColorProperties findColors(const PlyElement& element)
{
    ColorProperties colors;
    const char* names[3][2] = {{"red", "diffuse_red"}, {"green", "diffuse_green"}, {"blue", "diffuse_blue"}};
    for (int c = 0; c < 3; ++c) {
        colors.index[c] = element.find(names[c][0]);
        if (colors.index[c] < 0)
            colors.index[c] = element.find(names[c][1]);
        if (colors.index[c] >= 0 && element.properties[size_t(colors.index[c])].isList)
            colors.index[c] = -1;
    }
    return colors;
}

// A colour value in [0, 1]: integers over their type's maximum (uchar 255, ushort 65535), floats as they are.
float colorValue(double value, PlyType type)
{
    double scale = 1.0;
    switch (type) {
    case PlyType::Int8: scale = 127.0; break;
    case PlyType::Uint8: scale = 255.0; break;
    case PlyType::Int16: scale = 32767.0; break;
    case PlyType::Uint16: scale = 65535.0; break;
    case PlyType::Int32: scale = 2147483647.0; break;
    case PlyType::Uint32: scale = 4294967295.0; break;
    default: break;
    }
    double v = value / scale;
    return std::isfinite(v) ? float(std::clamp(v, 0.0, 1.0)) : 0.0f;
}

// Face colours to materials: one per distinct colour (8 bits per channel).
void faceColorsToMaterials(const std::vector<glm::vec3>& triangleColors, Mesh& mesh)
{
    if (triangleColors.empty())
        return;
    std::unordered_map<uint32_t, uint32_t> byColor;
    mesh.triangleMaterials.resize(triangleColors.size());
    for (size_t t = 0; t < triangleColors.size(); ++t) {
        const glm::vec3 c = triangleColors[t];
        const uint32_t key = uint32_t(std::lround(c.r * 255.0f)) | uint32_t(std::lround(c.g * 255.0f)) << 8 |
                             uint32_t(std::lround(c.b * 255.0f)) << 16;
        auto [it, added] = byColor.emplace(key, uint32_t(mesh.materials.size()));
        if (added)
            mesh.materials.push_back({glm::vec4(float(key & 255) / 255.0f, float(key >> 8 & 255) / 255.0f,
                                                float(key >> 16) / 255.0f, 1.0f),
                                      ""});
        mesh.triangleMaterials[t] = it->second;
    }
}

// Growable index output written through a raw cursor (no per-push capacity checks).
struct IndexOutput {
    std::vector<uint32_t>& indices;
    size_t used = 0;
    void ensure(size_t extra)
    {
        if (used + extra > indices.size())
            indices.resize(std::max(indices.size() * 2, used + extra));
    }
};

struct FaceStats {
    uint64_t degenerate = 0; // faces with fewer than 3 corners
};

class BinaryPlyReader {
  public:
    BinaryPlyReader(const std::string& path, const MappedFile& file, const PlyHeader& header)
        : path_(path), data_(file.data()), size_(file.size()), offset_(header.dataOffset),
          swap_((header.encoding == PlyEncoding::BinaryBig) == (std::endian::native == std::endian::little))
    {
    }

    size_t remaining() const { return size_ - offset_; }

    void checkFixed(const PlyElement& element, size_t stride, const char* noun)
    {
        if (stride != 0 && element.count > remaining() / stride)
            fail(path_, "truncated: header claims " + std::to_string(element.count) + " " + noun + " (" +
                            std::to_string(element.count) + " x " + std::to_string(stride) + " bytes) but only " +
                            std::to_string(remaining()) + " bytes of data follow");
    }

    void skipElement(const PlyElement& element)
    {
        size_t stride = element.fixedStride();
        if (stride != 0 || element.properties.empty()) {
            checkFixed(element, stride, ("'" + element.name + "' records").c_str());
            offset_ += size_t(element.count) * stride;
            return;
        }
        checkFixed(element, element.minimumStride(), ("'" + element.name + "' records").c_str());
        for (uint64_t r = 0; r < element.count; ++r)
            for (const PlyProperty& property : element.properties)
                skipProperty(element, r, property);
    }

    void readVertices(const PlyElement& element, Mesh& mesh)
    {
        int ix = element.find("x"), iy = element.find("y"), iz = element.find("z");
        if (ix < 0 || iy < 0 || iz < 0)
            fail(path_, "vertex element has no x, y and z properties");
        for (int i : {ix, iy, iz})
            if (element.properties[size_t(i)].isList)
                fail(path_, "vertex property '" + element.properties[size_t(i)].name + "' is a list");
        size_t stride = element.fixedStride();
        checkFixed(element, stride == 0 ? element.minimumStride() : stride, "vertices");
        if (element.count > UINT32_MAX)
            fail(path_, "too many vertices (" + std::to_string(element.count) + ", limit 4294967295)");
        if (stride == 0) {
            readVerticesGeneric(element, mesh, ix, iy, iz);
            return;
        }
        size_t offsets[3] = {0, 0, 0}, colorOffsets[3] = {0, 0, 0};
        const ColorProperties colors = findColors(element);
        size_t running = 0;
        for (size_t i = 0; i < element.properties.size(); ++i) {
            if (int(i) == ix)
                offsets[0] = running;
            if (int(i) == iy)
                offsets[1] = running;
            if (int(i) == iz)
                offsets[2] = running;
            if (colors.channel(i) >= 0)
                colorOffsets[colors.channel(i)] = running;
            running += plyTypeSize(element.properties[i].type);
        }
        const size_t count = size_t(element.count);
        if (colors.present()) {
            mesh.colors.resize(count * 3);
            for (size_t v = 0; v < count; ++v)
                for (int c = 0; c < 3; ++c) {
                    const PlyType type = element.properties[size_t(colors.index[c])].type;
                    mesh.colors[v * 3 + size_t(c)] =
                        colorValue(loadNumber(data_ + offset_ + v * stride + colorOffsets[c], type, swap_), type);
                }
        }
        mesh.positions.resize(count * 3);
        float* out = mesh.positions.data();
        const uint8_t* base = data_ + offset_;
        const bool allFloat = element.properties[size_t(ix)].type == PlyType::Float32 &&
                              element.properties[size_t(iy)].type == PlyType::Float32 &&
                              element.properties[size_t(iz)].type == PlyType::Float32;
        if (allFloat && !swap_ && offsets[1] == offsets[0] + 4 && offsets[2] == offsets[0] + 8) {
            if (stride == 12) {
                if (count > 0) // out is null for an empty vertex element
                    std::memcpy(out, base, count * 12);
            } else {
                for (size_t v = 0; v < count; ++v)
                    std::memcpy(out + v * 3, base + v * stride + offsets[0], 12);
            }
        } else {
            const PlyType types[3] = {element.properties[size_t(ix)].type, element.properties[size_t(iy)].type,
                                      element.properties[size_t(iz)].type};
            for (size_t v = 0; v < count; ++v)
                for (int c = 0; c < 3; ++c)
                    out[v * 3 + size_t(c)] = float(loadNumber(base + v * stride + offsets[c], types[c], swap_));
        }
        offset_ += count * stride;
    }

    void readFaces(const PlyElement& element, int listIndex, uint64_t vertexCount, Mesh& mesh, FaceStats& stats)
    {
        const PlyProperty& list = element.properties[size_t(listIndex)];
        if (!isIntegerType(list.type))
            fail(path_, "face property '" + list.name + "' has non-integer type");
        checkFixed(element, element.minimumStride(), "faces");
        // Each face needs at least minimumStride bytes, so this reservation is bounded by the file size.
        IndexOutput out{mesh.indices};
        size_t guess = size_t(std::min<uint64_t>(
            element.count, remaining() / std::max<size_t>(element.minimumStride() + 3 * plyTypeSize(list.type), 1)));
        mesh.indices.resize(guess * 3);

        const bool fast = element.properties.size() == 1 && list.countType == PlyType::Uint8 &&
                          (list.type == PlyType::Int32 || list.type == PlyType::Uint32) && !swap_;
        if (fast)
            readFacesFast(element.count, vertexCount, out, stats);
        else
            readFacesGeneric(element, listIndex, vertexCount, out, stats);
        mesh.indices.resize(out.used);
    }

  private:
    [[noreturn]] void truncated(const char* what, uint64_t record)
    {
        fail(path_, std::string("truncated: file ends inside ") + what + " " + std::to_string(record));
    }

    void skipProperty(const PlyElement& element, uint64_t record, const PlyProperty& property)
    {
        if (!property.isList) {
            size_t size = plyTypeSize(property.type);
            if (remaining() < size)
                truncated(("'" + element.name + "' record").c_str(), record);
            offset_ += size;
            return;
        }
        size_t countSize = plyTypeSize(property.countType);
        if (remaining() < countSize)
            truncated(("'" + element.name + "' record").c_str(), record);
        int64_t n = loadInteger(data_ + offset_, property.countType, swap_);
        offset_ += countSize;
        if (n < 0)
            fail(path_, "'" + element.name + "' record " + std::to_string(record) + " has a negative list length");
        size_t itemSize = plyTypeSize(property.type);
        if (uint64_t(n) > remaining() / itemSize)
            truncated(("'" + element.name + "' record").c_str(), record);
        offset_ += size_t(n) * itemSize;
    }

    void readVerticesGeneric(const PlyElement& element, Mesh& mesh, int ix, int iy, int iz)
    {
        checkFixed(element, element.minimumStride(), "vertices");
        mesh.positions.resize(size_t(element.count) * 3);
        for (uint64_t v = 0; v < element.count; ++v) {
            for (size_t i = 0; i < element.properties.size(); ++i) {
                const PlyProperty& property = element.properties[i];
                if (!property.isList && (int(i) == ix || int(i) == iy || int(i) == iz)) {
                    if (remaining() < plyTypeSize(property.type))
                        truncated("vertex", v);
                    int c = int(i) == ix ? 0 : int(i) == iy ? 1 : 2;
                    mesh.positions[size_t(v) * 3 + size_t(c)] =
                        float(loadNumber(data_ + offset_, property.type, swap_));
                    offset_ += plyTypeSize(property.type);
                } else {
                    skipProperty(element, v, property);
                }
            }
        }
    }

    void readFacesFast(uint64_t faceCount, uint64_t vertexCount, IndexOutput& out, FaceStats& stats)
    {
        const uint8_t* p = data_ + offset_;
        const uint8_t* end = data_ + size_;
        const uint32_t limit = uint32_t(std::min<uint64_t>(vertexCount, UINT32_MAX));
        uint32_t* dst = out.indices.data();
        size_t used = out.used;
        size_t capacity = out.indices.size();
        for (uint64_t f = 0; f < faceCount; ++f) {
            if (p >= end)
                truncated("face", f);
            uint32_t n = *p++;
            if (size_t(end - p) < size_t(n) * 4)
                truncated("face", f);
            if (n == 3) {
                uint32_t a, b, c;
                std::memcpy(&a, p, 4);
                std::memcpy(&b, p + 4, 4);
                std::memcpy(&c, p + 8, 4);
                p += 12;
                if ((a >= limit) | (b >= limit) | (c >= limit)) {
                    uint32_t bad = a >= limit ? a : b >= limit ? b : c;
                    failIndex(path_, f, badIndexValue(bad), vertexCount);
                }
                if (used + 3 > capacity) {
                    out.used = used;
                    out.ensure(3);
                    dst = out.indices.data();
                    capacity = out.indices.size();
                }
                dst[used] = a;
                dst[used + 1] = b;
                dst[used + 2] = c;
                used += 3;
                continue;
            }
            if (n < 3) {
                ++stats.degenerate;
                p += size_t(n) * 4;
                continue;
            }
            size_t needed = size_t(n - 2) * 3;
            if (used + needed > capacity) {
                out.used = used;
                out.ensure(needed);
                dst = out.indices.data();
                capacity = out.indices.size();
            }
            uint32_t corner[3];
            for (uint32_t k = 0; k < n; ++k) {
                uint32_t index;
                std::memcpy(&index, p + size_t(k) * 4, 4);
                if (index >= limit)
                    failIndex(path_, f, badIndexValue(index), vertexCount);
                if (k == 0)
                    corner[0] = index;
                else if (k == 1)
                    corner[2] = index;
                else {
                    corner[1] = corner[2];
                    corner[2] = index;
                    dst[used] = corner[0];
                    dst[used + 1] = corner[1];
                    dst[used + 2] = corner[2];
                    used += 3;
                }
            }
            p += size_t(n) * 4;
        }
        out.used = used;
        offset_ = size_t(p - data_);
    }

    // Signed index types show negative values as such in messages.
    int64_t badIndexValue(uint32_t raw) const { return faceIndexSigned_ ? int64_t(int32_t(raw)) : int64_t(raw); }

    void readFacesGeneric(const PlyElement& element, int listIndex, uint64_t vertexCount, IndexOutput& out,
                          FaceStats& stats)
    {
        const PlyProperty& list = element.properties[size_t(listIndex)];
        const size_t countSize = plyTypeSize(list.countType);
        const size_t itemSize = plyTypeSize(list.type);
        const ColorProperties colors = findColors(element);
        for (uint64_t f = 0; f < element.count; ++f) {
            glm::vec3 color(1.0f);
            for (size_t i = 0; i < element.properties.size(); ++i) {
                if (int(i) != listIndex) {
                    if (colors.present() && colors.channel(i) >= 0 && remaining() >= plyTypeSize(element.properties[i].type))
                        color[colors.channel(i)] = colorValue(loadNumber(data_ + offset_, element.properties[i].type, swap_),
                                                              element.properties[i].type);
                    skipProperty(element, f, element.properties[i]);
                    continue;
                }
                if (remaining() < countSize)
                    truncated("face", f);
                int64_t n = loadInteger(data_ + offset_, list.countType, swap_);
                offset_ += countSize;
                if (n < 0)
                    fail(path_, "face " + std::to_string(f) + " has a negative vertex count");
                if (uint64_t(n) > remaining() / itemSize)
                    truncated("face", f);
                if (n < 3) {
                    ++stats.degenerate;
                    offset_ += size_t(n) * itemSize;
                    continue;
                }
                out.ensure(size_t(n - 2) * 3);
                uint32_t first = 0, previous = 0;
                for (int64_t k = 0; k < n; ++k) {
                    int64_t index = loadInteger(data_ + offset_, list.type, swap_);
                    offset_ += itemSize;
                    if (index < 0 || uint64_t(index) >= vertexCount)
                        failIndex(path_, f, index, vertexCount);
                    if (k == 0)
                        first = uint32_t(index);
                    else if (k >= 2) {
                        out.indices[out.used++] = first;
                        out.indices[out.used++] = previous;
                        out.indices[out.used++] = uint32_t(index);
                    }
                    previous = uint32_t(index);
                }
            }
            if (colors.present())
                triangleColors.resize((out.used) / 3, color);
        }
    }

  public:
    std::vector<glm::vec3> triangleColors; // per triangle, from the face colours (empty without)
    bool faceIndexSigned_ = true;

  private:
    const std::string& path_;
    const uint8_t* data_;
    size_t size_;
    size_t offset_;
    bool swap_;
};

// ---- ASCII ----

class AsciiPlyReader {
  public:
    AsciiPlyReader(const std::string& path, const MappedFile& file, const PlyHeader& header)
        : path_(path), cursor_{reinterpret_cast<const char*>(file.data()) + header.dataOffset,
                               reinterpret_cast<const char*>(file.data()) + file.size()}
    {
        // Header lines were counted by the header parser; recount for messages.
        for (size_t i = 0; i < header.dataOffset; ++i)
            if (file.data()[i] == '\n')
                ++cursor_.line;
    }

    size_t remaining() const { return size_t(cursor_.end - cursor_.p); }

    void readElement(const PlyElement& element, Mesh* vertices, int listIndex, uint64_t vertexCount, Mesh* faces,
                     FaceStats& stats)
    {
        int ix = element.find("x"), iy = element.find("y"), iz = element.find("z");
        if (vertices) {
            if (ix < 0 || iy < 0 || iz < 0)
                fail(path_, "vertex element has no x, y and z properties");
        }
        // Every value takes at least two bytes ("0 "), so larger counts cannot fit.
        size_t minimumBytes = std::max<size_t>(element.properties.size(), 1) * 2;
        if (element.count > remaining() / minimumBytes + 1)
            fail(path_, "truncated: header claims " + std::to_string(element.count) + " '" + element.name +
                            "' records but only " + std::to_string(remaining()) + " bytes of data follow");
        if (vertices && element.count > UINT32_MAX)
            fail(path_, "too many vertices (" + std::to_string(element.count) + ", limit 4294967295)");
        if (vertices)
            vertices->positions.resize(size_t(element.count) * 3);
        const ColorProperties colors = vertices || faces ? findColors(element) : ColorProperties{};
        if (vertices && colors.present())
            vertices->colors.resize(size_t(element.count) * 3);
        for (uint64_t r = 0; r < element.count; ++r) {
            glm::vec3 faceColor(1.0f);
            for (size_t i = 0; i < element.properties.size(); ++i) {
                const PlyProperty& property = element.properties[i];
                if (!property.isList) {
                    std::string_view token = next(element, r);
                    if (vertices && (int(i) == ix || int(i) == iy || int(i) == iz)) {
                        float value;
                        if (!parseFloat(token, value))
                            malformed(token);
                        int c = int(i) == ix ? 0 : int(i) == iy ? 1 : 2;
                        vertices->positions[size_t(r) * 3 + size_t(c)] = value;
                    } else if (colors.present() && colors.channel(i) >= 0) {
                        float value;
                        if (!parseFloat(token, value))
                            malformed(token);
                        const float c = colorValue(value, property.type);
                        if (vertices)
                            vertices->colors[size_t(r) * 3 + size_t(colors.channel(i))] = c;
                        else
                            faceColor[colors.channel(i)] = c;
                    }
                    continue;
                }
                int64_t n = 0;
                std::string_view countToken = next(element, r);
                if (!parseInt(countToken, n) || n < 0)
                    malformed(countToken);
                if (!faces || int(i) != listIndex) {
                    for (int64_t k = 0; k < n; ++k)
                        next(element, r);
                    continue;
                }
                if (n < 3)
                    ++stats.degenerate;
                uint32_t first = 0, previous = 0;
                for (int64_t k = 0; k < n; ++k) {
                    std::string_view token = next(element, r);
                    int64_t index = 0;
                    if (!parseInt(token, index))
                        malformed(token);
                    if (index < 0 || uint64_t(index) >= vertexCount)
                        failIndex(path_, r, index, vertexCount);
                    if (k == 0)
                        first = uint32_t(index);
                    else if (k >= 2) {
                        faces->indices.push_back(first);
                        faces->indices.push_back(previous);
                        faces->indices.push_back(uint32_t(index));
                    }
                    previous = uint32_t(index);
                }
            }
            if (faces && colors.present())
                triangleColors.resize(faces->indices.size() / 3, faceColor);
        }
    }

    std::vector<glm::vec3> triangleColors; // per triangle, from the face colours (empty without)

  private:
    std::string_view next(const PlyElement& element, uint64_t record)
    {
        cursor_.skipWhitespace();
        std::string_view token = cursor_.token();
        if (token.empty())
            fail(path_, "truncated: file ends inside '" + element.name + "' record " + std::to_string(record) + " of " +
                            std::to_string(element.count));
        return token;
    }
    [[noreturn]] void malformed(std::string_view token)
    {
        fail(path_, "line " + std::to_string(cursor_.line) + ": malformed number " + quoteToken(token));
    }

    const std::string& path_;
    TextCursor cursor_;
};

// The mesh's elements of a header: the first "vertex", the first "face" and
// its vertex_indices (or vertex_index) list property; fails on a point cloud
// or a face element without the list.
struct MeshElements {
    const PlyElement* vertex = nullptr;
    const PlyElement* face = nullptr;
    int listIndex = -1;
};

MeshElements findMeshElements(const std::string& path, const PlyHeader& header)
{
    MeshElements found;
    for (const PlyElement& element : header.elements) {
        if (element.name == "vertex" && !found.vertex)
            found.vertex = &element;
        if (element.name == "face" && !found.face) {
            found.face = &element;
            found.listIndex = element.find("vertex_indices");
            if (found.listIndex < 0)
                found.listIndex = element.find("vertex_index");
            if (found.listIndex < 0 || !element.properties[size_t(found.listIndex)].isList)
                fail(path, "face element has no vertex_indices list property");
        }
    }
    if (!found.vertex)
        fail(path, "no vertex element");
    if (!found.face || found.face->count == 0)
        fail(path, "no triangles (point cloud: no faces)");
    return found;
}

} // namespace

Scene importPly(const std::string& path, const MappedFile& file)
{
    PlyHeader header = parseHeader(path, file);
    Scene scene;
    Mesh& mesh = scene.mesh;

    const MeshElements elements = findMeshElements(path, header);
    const PlyElement* vertexElement = elements.vertex;
    const PlyElement* faceElement = elements.face;
    const int listIndex = elements.listIndex;
    const uint64_t vertexCount = vertexElement->count;

    FaceStats stats;
    if (header.encoding == PlyEncoding::Ascii) {
        AsciiPlyReader reader(path, file, header);
        for (const PlyElement& element : header.elements) {
            bool isVertex = &element == vertexElement;
            bool isFace = &element == faceElement;
            reader.readElement(element, isVertex ? &mesh : nullptr, isFace ? listIndex : -1, vertexCount,
                               isFace ? &mesh : nullptr, stats);
        }
        faceColorsToMaterials(reader.triangleColors, mesh);
    } else {
        BinaryPlyReader reader(path, file, header);
        reader.faceIndexSigned_ = faceElement->properties[size_t(listIndex)].type == PlyType::Int32 ||
                                  faceElement->properties[size_t(listIndex)].type == PlyType::Int16 ||
                                  faceElement->properties[size_t(listIndex)].type == PlyType::Int8;
        for (const PlyElement& element : header.elements) {
            if (&element == vertexElement)
                reader.readVertices(element, mesh);
            else if (&element == faceElement)
                reader.readFaces(element, listIndex, vertexCount, mesh, stats);
            else
                reader.skipElement(element);
        }
        faceColorsToMaterials(reader.triangleColors, mesh);
    }
    if (mesh.indices.empty())
        fail(path, "no triangles (all " + std::to_string(faceElement->count) + " faces have fewer than 3 vertices)");
    if (stats.degenerate > 0)
        importWarning(path, "ply-degenerate",
                      "skipped " + std::to_string(stats.degenerate) + " faces with fewer than 3 vertices");
    std::string skipped;
    for (const PlyElement& element : header.elements)
        if (&element != vertexElement && &element != faceElement && element.count > 0)
            skipped += (skipped.empty() ? "'" : ", '") + element.name + "' (" + std::to_string(element.count) + ")";
    if (!skipped.empty())
        importWarning(path, "ply-elements", "skipped elements " + skipped);
    return scene;
}

void exportPly(const Scene& scene, AtomicFileWriter& out, bool binary)
{
    const Mesh& mesh = scene.mesh;
    std::string header = "ply\nformat ";
    header +=
        binary ? (std::endian::native == std::endian::little ? "binary_little_endian" : "binary_big_endian") : "ascii";
    header += " 1.0\ncomment written by penumbra\nelement vertex " + std::to_string(mesh.vertexCount()) +
              "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
              std::to_string(mesh.triangleCount()) + "\nproperty list uchar uint vertex_indices\nend_header\n";
    out.write(header);
    const size_t triangles = mesh.triangleCount();
    if (binary) {
        out.write(mesh.positions.data(), mesh.positions.size() * sizeof(float));
        for (size_t t = 0; t < triangles; ++t) {
            char* p = out.reserve(13);
            p[0] = 3;
            std::memcpy(p + 1, &mesh.indices[t * 3], 12);
            out.advance(13);
        }
        return;
    }
    for (size_t v = 0; v < mesh.vertexCount(); ++v) {
        char* start = out.reserve(128);
        char* p = formatFloat(start, mesh.positions[v * 3], ' ');
        p = formatFloat(p, mesh.positions[v * 3 + 1], ' ');
        p = formatFloat(p, mesh.positions[v * 3 + 2], '\n');
        out.advance(size_t(p - start));
    }
    for (size_t t = 0; t < triangles; ++t) {
        char* start = out.reserve(128);
        char* p = start;
        *p++ = '3';
        *p++ = ' ';
        p = formatUint(p, mesh.indices[t * 3], ' ');
        p = formatUint(p, mesh.indices[t * 3 + 1], ' ');
        p = formatUint(p, mesh.indices[t * 3 + 2], '\n');
        out.advance(size_t(p - start));
    }
}

// ---- streaming (model_stream.h) ----

namespace {

// The header of a PLY file read through `in` (from offset 0): the bytes up to
// the end_header line, at most 1 MiB, parsed as importPly does.
PlyHeader readStreamHeader(const std::string& path, FileReader& in, size_t& headerLines)
{
    if (in.size() == 0)
        fail(path, "empty file");
    const size_t limit = std::min<size_t>(size_t(1) << 20, in.bufferSize());
    size_t want = std::min<size_t>(4096, limit);
    for (;;) {
        const bool complete = in.ensure(want);
        const char* text = reinterpret_cast<const char*>(in.data());
        const std::string_view view(text, in.available());
        size_t at = 0;
        while ((at = view.find("end_header", at)) != std::string_view::npos) {
            const bool lineStart = at > 0 && view[at - 1] == '\n';
            const size_t newline = view.find('\n', at);
            if (lineStart && newline != std::string_view::npos) {
                MappedFile head(path, in.data(), newline + 1);
                headerLines = size_t(std::count(view.begin(), view.begin() + long(newline + 1), '\n'));
                return parseHeader(path, head);
            }
            if (lineStart)
                break; // end_header without its newline yet: read more
            at += 10;
        }
        if (!complete || in.available() >= limit) {
            MappedFile head(path, in.data(), in.available());
            parseHeader(path, head); // fails: no end_header line
            fail(path, "header longer than " + std::to_string(limit) + " bytes");
        }
        want = std::min<size_t>(want * 4, limit);
    }
}

// Positions (and colours) of fixed-size binary vertex records.
struct VertexLayout {
    size_t stride = 0;
    size_t offsets[3] = {0, 0, 0};
    PlyType types[3] = {PlyType::Float32, PlyType::Float32, PlyType::Float32};
    bool colors = false;
    size_t colorOffsets[3] = {0, 0, 0};
    PlyType colorTypes[3] = {PlyType::Uint8, PlyType::Uint8, PlyType::Uint8};
    bool swap = false;
    bool plainFloats = false; // float x, y, z in order, native byte order

    void decode(const uint8_t* record, float* xyz, float* rgb) const
    {
        if (plainFloats)
            std::memcpy(xyz, record + offsets[0], 12);
        else
            for (int c = 0; c < 3; ++c)
                xyz[c] = float(loadNumber(record + offsets[c], types[c], swap));
        if (colors && rgb)
            for (int c = 0; c < 3; ++c)
                rgb[c] = colorValue(loadNumber(record + colorOffsets[c], colorTypes[c], swap), colorTypes[c]);
    }
};

// The vertex store of a binary PLY: its own vertex records, read in place.
class PlyInPlaceStore : public VertexStore {
  public:
    PlyInPlaceStore(const std::string& path, uint64_t offset, uint64_t count, const VertexLayout& layout)
        : reader_(path, 4096), offset_(offset), count_(count), layout_(layout)
    {
    }
    void read(uint64_t first, uint64_t count, float* positions, float* colors) override
    {
        if (first > count_ || count > count_ - first)
            fail(reader_.path(), "internal error: vertices " + std::to_string(first) + "+" + std::to_string(count) +
                                     " outside the " + std::to_string(count_) + " stored");
        scratch_.resize(size_t(count) * layout_.stride);
        reader_.readAt(offset_ + first * layout_.stride, scratch_.data(), scratch_.size());
        for (uint64_t v = 0; v < count; ++v)
            layout_.decode(scratch_.data() + v * layout_.stride, positions + 3 * v, colors ? colors + 3 * v : nullptr);
    }

  private:
    FileReader reader_;
    uint64_t offset_, count_;
    VertexLayout layout_;
    std::vector<uint8_t> scratch_;
};

[[noreturn]] void failNonFinite(const std::string& path, uint64_t v, const float* p)
{
    char text[160];
    std::snprintf(text, sizeof(text), "vertex %llu has a non-finite position (%g, %g, %g)", (unsigned long long)v,
                  double(p[0]), double(p[1]), double(p[2]));
    fail(path, text);
}

class PlyStream : public ModelStream {
  public:
    PlyStream(const std::string& path, const ModelStreamOptions& options) : in_(path, options.bufferBytes), options_(options)
    {
        path_ = path;
    }

    void scan(const std::function<void(const float*, size_t)>& onVertices) override
    {
        size_t headerLines = 0;
        header_ = readStreamHeader(path_, in_, headerLines);
        const MeshElements elements = findMeshElements(path_, header_);
        vertexElement_ = elements.vertex;
        faceElement_ = elements.face;
        listIndex_ = elements.listIndex;
        swap_ = header_.encoding != PlyEncoding::Ascii &&
                (header_.encoding == PlyEncoding::BinaryBig) == (std::endian::native == std::endian::little);
        vertexCount_ = vertexElement_->count;
        faceColors_ = findColors(*faceElement_).present();
        const PlyProperty& list = faceElement_->properties[size_t(listIndex_)];
        if (header_.encoding != PlyEncoding::Ascii && !isIntegerType(list.type))
            fail(path_, "face property '" + list.name + "' has non-integer type");
        faceIndexSigned_ = list.type == PlyType::Int32 || list.type == PlyType::Int16 || list.type == PlyType::Int8;

        in_.seek(header_.dataOffset);
        StreamCursor cursor(in_, 1 + headerLines); // line numbers count the header's lines, as importPly's
        for (const PlyElement& element : header_.elements) {
            if (&element == vertexElement_) {
                if (header_.encoding == PlyEncoding::Ascii)
                    readAsciiVertices(element, cursor, onVertices);
                else
                    readBinaryVertices(element, onVertices);
            } else if (&element == faceElement_) {
                faceOffset_ = in_.offset();
                faceLine_ = cursor.line;
                readFaces(element, cursor, nullptr);
            } else if (header_.encoding == PlyEncoding::Ascii) {
                readAsciiOther(element, cursor);
            } else {
                skipBinary(element);
            }
        }
        if (triangleCount_ == 0)
            fail(path_, "no triangles (all " + std::to_string(faceElement_->count) + " faces have fewer than 3 vertices)");
        if (degenerate_ > 0)
            warn(path_, "skipped " + std::to_string(degenerate_) + " faces with fewer than 3 vertices");
        std::string skipped;
        for (const PlyElement& element : header_.elements)
            if (&element != vertexElement_ && &element != faceElement_ && element.count > 0)
                skipped += (skipped.empty() ? "'" : ", '") + element.name + "' (" + std::to_string(element.count) + ")";
        if (!skipped.empty())
            warn(path_, "skipped elements " + skipped);
        scanned_ = true;
    }

    void triangles(const std::function<void(const StreamTriangles&)>& onTriangles) override
    {
        if (!scanned_)
            fail(path_, "internal error: triangles() before scan()");
        in_.seek(faceOffset_);
        StreamCursor cursor(in_, faceLine_);
        TriangleBatcher batcher{onTriangles};
        batcher.withMaterials = faceColors_;
        readFaces(*faceElement_, cursor, &batcher);
        batcher.flush();
    }

    void readVertices(uint64_t first, uint64_t count, float* positions, float* colors) override
    {
        if (!store_)
            fail(path_, "internal error: readVertices() before scan()");
        store_->read(first, count, positions, vertexColors_ ? colors : nullptr);
    }

  private:
    // ---- vertices ----

    void readBinaryVertices(const PlyElement& element, const std::function<void(const float*, size_t)>& onVertices)
    {
        const int ix = element.find("x"), iy = element.find("y"), iz = element.find("z");
        if (ix < 0 || iy < 0 || iz < 0)
            fail(path_, "vertex element has no x, y and z properties");
        for (int i : {ix, iy, iz})
            if (element.properties[size_t(i)].isList)
                fail(path_, "vertex property '" + element.properties[size_t(i)].name + "' is a list");
        const ColorProperties colors = findColors(element);
        vertexColors_ = colors.present();
        const size_t stride = element.fixedStride();
        std::vector<float> batch;
        const size_t batchVertices = 1 << 14;
        batch.reserve(batchVertices * 3);
        uint64_t v = 0;
        auto deliver = [&](const float* xyz) {
            if (!std::isfinite(xyz[0]) || !std::isfinite(xyz[1]) || !std::isfinite(xyz[2]))
                failNonFinite(path_, v, xyz);
            batch.insert(batch.end(), xyz, xyz + 3);
            if (batch.size() == batchVertices * 3) {
                onVertices(batch.data(), batchVertices);
                batch.clear();
            }
            ++v;
        };
        if (stride > in_.bufferSize() / 2)
            fail(path_, "vertex records of " + std::to_string(stride) + " bytes are larger than the read buffer");
        if (stride != 0) {
            // Fixed-size records: the vertex store is the file itself.
            VertexLayout layout;
            layout.stride = stride;
            layout.swap = swap_;
            layout.colors = vertexColors_;
            size_t running = 0;
            for (size_t i = 0; i < element.properties.size(); ++i) {
                const PlyType type = element.properties[i].type;
                for (int c = 0; c < 3; ++c)
                    if (int(i) == (c == 0 ? ix : c == 1 ? iy : iz)) {
                        layout.offsets[c] = running;
                        layout.types[c] = type;
                    }
                if (colors.channel(i) >= 0) {
                    layout.colorOffsets[colors.channel(i)] = running;
                    layout.colorTypes[colors.channel(i)] = type;
                }
                running += plyTypeSize(type);
            }
            layout.plainFloats = !swap_ && layout.types[0] == PlyType::Float32 && layout.types[1] == PlyType::Float32 &&
                                 layout.types[2] == PlyType::Float32 && layout.offsets[1] == layout.offsets[0] + 4 &&
                                 layout.offsets[2] == layout.offsets[0] + 8;
            const uint64_t start = in_.offset();
            if (element.count > (in_.size() - std::min(in_.size(), start)) / stride)
                fail(path_, "truncated: header claims " + std::to_string(element.count) + " vertices (" +
                                std::to_string(element.count) + " x " + std::to_string(stride) + " bytes) but only " +
                                std::to_string(in_.size() - std::min(in_.size(), start)) + " bytes of data follow");
            const size_t perRead = std::max<size_t>(1, in_.bufferSize() / stride / 2);
            float xyz[3];
            for (uint64_t done = 0; done < element.count;) {
                const size_t n = size_t(std::min<uint64_t>(perRead, element.count - done));
                if (!in_.ensure(n * stride))
                    fail(path_, "truncated: file ends inside vertex " + std::to_string(done));
                const uint8_t* p = in_.data();
                for (size_t r = 0; r < n; ++r) {
                    layout.decode(p + r * stride, xyz, nullptr);
                    deliver(xyz);
                }
                in_.advance(n * stride);
                done += n;
            }
            store_ = std::make_unique<PlyInPlaceStore>(path_, start, element.count, layout);
        } else {
            // Records with lists: parsed one by one into a temporary store.
            auto temporary = std::make_unique<TemporaryVertexStore>(temporaryDirectory(path_, options_),
                                                                    "the vertices of " + path_, vertexColors_);
            BinaryRecord record{in_, path_, swap_};
            for (uint64_t r = 0; r < element.count; ++r) {
                float xyz[3] = {0, 0, 0}, rgb[3] = {1, 1, 1};
                for (size_t i = 0; i < element.properties.size(); ++i) {
                    const PlyProperty& property = element.properties[i];
                    const int c = int(i) == ix ? 0 : int(i) == iy ? 1 : int(i) == iz ? 2 : -1;
                    if (!property.isList && (c >= 0 || colors.channel(i) >= 0)) {
                        const double value = record.number(property.type, "vertex", r);
                        if (c >= 0)
                            xyz[c] = float(value);
                        else
                            rgb[colors.channel(i)] = colorValue(value, property.type);
                    } else {
                        record.skip(element, r, property);
                    }
                }
                deliver(xyz);
                temporary->append(xyz, rgb);
            }
            temporary->finish();
            store_ = std::move(temporary);
        }
        if (!batch.empty())
            onVertices(batch.data(), batch.size() / 3);
    }

    void readAsciiVertices(const PlyElement& element, StreamCursor& cursor,
                           const std::function<void(const float*, size_t)>& onVertices)
    {
        const int ix = element.find("x"), iy = element.find("y"), iz = element.find("z");
        if (ix < 0 || iy < 0 || iz < 0)
            fail(path_, "vertex element has no x, y and z properties");
        const ColorProperties colors = findColors(element);
        vertexColors_ = colors.present();
        auto temporary = std::make_unique<TemporaryVertexStore>(temporaryDirectory(path_, options_),
                                                                "the vertices of " + path_, vertexColors_);
        std::vector<float> batch;
        const size_t batchVertices = 1 << 14;
        for (uint64_t r = 0; r < element.count; ++r) {
            float xyz[3] = {0, 0, 0}, rgb[3] = {1, 1, 1};
            for (size_t i = 0; i < element.properties.size(); ++i) {
                const PlyProperty& property = element.properties[i];
                if (!property.isList) {
                    std::string_view token = next(cursor, element, r);
                    const int c = int(i) == ix ? 0 : int(i) == iy ? 1 : int(i) == iz ? 2 : -1;
                    if (c >= 0 || colors.channel(i) >= 0) {
                        float value;
                        if (!parseFloat(token, value))
                            malformed(cursor, token);
                        if (c >= 0)
                            xyz[c] = value;
                        else
                            rgb[colors.channel(i)] = colorValue(value, property.type);
                    }
                    continue;
                }
                int64_t n = 0;
                std::string_view countToken = next(cursor, element, r);
                if (!parseInt(countToken, n) || n < 0)
                    malformed(cursor, countToken);
                for (int64_t k = 0; k < n; ++k)
                    next(cursor, element, r);
            }
            if (!std::isfinite(xyz[0]) || !std::isfinite(xyz[1]) || !std::isfinite(xyz[2]))
                failNonFinite(path_, r, xyz);
            temporary->append(xyz, rgb);
            batch.insert(batch.end(), xyz, xyz + 3);
            if (batch.size() == batchVertices * 3) {
                onVertices(batch.data(), batchVertices);
                batch.clear();
            }
        }
        if (!batch.empty())
            onVertices(batch.data(), batch.size() / 3);
        temporary->finish();
        store_ = std::move(temporary);
    }

    // ---- other elements ----

    void readAsciiOther(const PlyElement& element, StreamCursor& cursor)
    {
        for (uint64_t r = 0; r < element.count; ++r)
            for (const PlyProperty& property : element.properties) {
                if (!property.isList) {
                    next(cursor, element, r);
                    continue;
                }
                int64_t n = 0;
                std::string_view countToken = next(cursor, element, r);
                if (!parseInt(countToken, n) || n < 0)
                    malformed(cursor, countToken);
                for (int64_t k = 0; k < n; ++k)
                    next(cursor, element, r);
            }
    }

    void skipBinary(const PlyElement& element)
    {
        const size_t stride = element.fixedStride();
        if (stride != 0 || element.properties.empty()) {
            const uint64_t start = in_.offset();
            const uint64_t left = in_.size() - std::min(in_.size(), start);
            if (stride != 0 && element.count > left / stride)
                fail(path_, "truncated: header claims " + std::to_string(element.count) + " '" + element.name +
                                "' records records (" + std::to_string(element.count) + " x " + std::to_string(stride) +
                                " bytes) but only " + std::to_string(left) + " bytes of data follow");
            in_.seek(start + element.count * stride);
            return;
        }
        BinaryRecord record{in_, path_, swap_};
        for (uint64_t r = 0; r < element.count; ++r)
            for (const PlyProperty& property : element.properties)
                record.skip(element, r, property);
    }

    // ---- faces ----

    // Parses the face element at the reader's position: counts and checks (out null, the scan) or
    // hands on the triangles (out set).
    void readFaces(const PlyElement& element, StreamCursor& cursor, TriangleBatcher* out)
    {
        const PlyProperty& list = element.properties[size_t(listIndex_)];
        const ColorProperties colors = findColors(element);
        uint64_t triangles = 0;
        auto emit = [&](uint64_t a, uint64_t b, uint64_t c, const glm::vec3& color) {
            ++triangles;
            uint32_t material = 0;
            if (faceColors_) {
                const uint32_t key = uint32_t(std::lround(color.r * 255.0f)) | uint32_t(std::lround(color.g * 255.0f)) << 8 |
                                     uint32_t(std::lround(color.b * 255.0f)) << 16;
                auto [it, added] = colorMaterials_.emplace(key, uint32_t(materials_.size()));
                if (added)
                    materials_.push_back({glm::vec4(float(key & 255) / 255.0f, float(key >> 8 & 255) / 255.0f,
                                                    float(key >> 16) / 255.0f, 1.0f),
                                          ""});
                material = it->second;
            }
            if (out)
                out->add(a, b, c, material);
        };
        const uint64_t vertexCount = vertexCount_;
        auto checkIndex = [&](uint64_t face, int64_t index) {
            if (index < 0 || uint64_t(index) >= vertexCount)
                failIndex(path_, face, index, vertexCount);
        };
        if (header_.encoding == PlyEncoding::Ascii) {
            for (uint64_t r = 0; r < element.count; ++r) {
                glm::vec3 color(1.0f);
                bool polygon = false;
                std::vector<uint64_t>& corners = corners_;
                corners.clear();
                for (size_t i = 0; i < element.properties.size(); ++i) {
                    const PlyProperty& property = element.properties[i];
                    if (!property.isList) {
                        std::string_view token = next(cursor, element, r);
                        if (colors.present() && colors.channel(i) >= 0) {
                            float value;
                            if (!parseFloat(token, value))
                                malformed(cursor, token);
                            color[colors.channel(i)] = colorValue(value, property.type);
                        }
                        continue;
                    }
                    int64_t n = 0;
                    std::string_view countToken = next(cursor, element, r);
                    if (!parseInt(countToken, n) || n < 0)
                        malformed(cursor, countToken);
                    if (int(i) != listIndex_) {
                        for (int64_t k = 0; k < n; ++k)
                            next(cursor, element, r);
                        continue;
                    }
                    if (n < 3 && !out)
                        ++degenerate_;
                    for (int64_t k = 0; k < n; ++k) {
                        std::string_view token = next(cursor, element, r);
                        int64_t index = 0;
                        if (!parseInt(token, index))
                            malformed(cursor, token);
                        checkIndex(r, index);
                        corners.push_back(uint64_t(index));
                    }
                    polygon = true;
                }
                // The colour may follow the list, so the triangles go out at the end of the record.
                if (polygon)
                    for (size_t k = 2; k < corners.size(); ++k)
                        emit(corners[0], corners[k - 1], corners[k], color);
            }
        } else {
            BinaryRecord record{in_, path_, swap_};
            const size_t countSize = plyTypeSize(list.countType);
            const size_t itemSize = plyTypeSize(list.type);
            const bool fast = element.properties.size() == 1 && list.countType == PlyType::Uint8 &&
                              (list.type == PlyType::Int32 || list.type == PlyType::Uint32) && !swap_;
            for (uint64_t f = 0; f < element.count; ++f) {
                if (fast && in_.ensure(1 + 12) && in_.data()[0] == 3) {
                    uint32_t v[3];
                    std::memcpy(v, in_.data() + 1, 12);
                    for (uint32_t index : v)
                        if (uint64_t(index) >= vertexCount)
                            failIndex(path_, f, badIndexValue(index), vertexCount);
                    in_.advance(13);
                    emit(v[0], v[1], v[2], glm::vec3(1.0f));
                    continue;
                }
                glm::vec3 color(1.0f);
                corners_.clear();
                bool polygon = false;
                for (size_t i = 0; i < element.properties.size(); ++i) {
                    const PlyProperty& property = element.properties[i];
                    if (int(i) != listIndex_) {
                        if (colors.present() && colors.channel(i) >= 0 && !property.isList)
                            color[colors.channel(i)] = colorValue(record.number(property.type, "face", f), property.type);
                        else
                            record.skip(element, f, property);
                        continue;
                    }
                    if (!in_.ensure(countSize))
                        record.truncated("face", f);
                    const int64_t n = loadInteger(in_.data(), list.countType, swap_);
                    in_.advance(countSize);
                    if (n < 0)
                        fail(path_, "face " + std::to_string(f) + " has a negative vertex count");
                    if (n < 3 && !out)
                        ++degenerate_;
                    for (int64_t k = 0; k < n; ++k) {
                        if (!in_.ensure(itemSize))
                            record.truncated("face", f);
                        int64_t index = loadInteger(in_.data(), list.type, swap_);
                        in_.advance(itemSize);
                        if (index < 0 || uint64_t(index) >= vertexCount)
                            failIndex(path_, f, index, vertexCount);
                        corners_.push_back(uint64_t(index));
                    }
                    polygon = true;
                }
                if (polygon)
                    for (size_t k = 2; k < corners_.size(); ++k)
                        emit(corners_[0], corners_[k - 1], corners_[k], color);
            }
        }
        if (!out)
            triangleCount_ = triangles;
    }

    int64_t badIndexValue(uint32_t raw) const { return faceIndexSigned_ ? int64_t(int32_t(raw)) : int64_t(raw); }

    // ---- records ----

    struct BinaryRecord {
        FileReader& in;
        const std::string& path;
        bool swap;
        [[noreturn]] void truncated(const char* what, uint64_t record)
        {
            fail(path, std::string("truncated: file ends inside ") + what + " " + std::to_string(record));
        }
        double number(PlyType type, const char* what, uint64_t record)
        {
            const size_t size = plyTypeSize(type);
            if (!in.ensure(size))
                truncated(what, record);
            const double value = loadNumber(in.data(), type, swap);
            in.advance(size);
            return value;
        }
        void skip(const PlyElement& element, uint64_t record, const PlyProperty& property)
        {
            const std::string what = "'" + element.name + "' record";
            if (!property.isList) {
                const size_t size = plyTypeSize(property.type);
                if (!in.ensure(size))
                    truncated(what.c_str(), record);
                in.advance(size);
                return;
            }
            const size_t countSize = plyTypeSize(property.countType);
            if (!in.ensure(countSize))
                truncated(what.c_str(), record);
            const int64_t n = loadInteger(in.data(), property.countType, swap);
            in.advance(countSize);
            if (n < 0)
                fail(path, "'" + element.name + "' record " + std::to_string(record) + " has a negative list length");
            const uint64_t bytes = uint64_t(n) * plyTypeSize(property.type);
            if (bytes > in.size() - std::min(in.size(), in.offset()))
                truncated(what.c_str(), record);
            in.seek(in.offset() + bytes);
        }
    };

    std::string_view next(StreamCursor& cursor, const PlyElement& element, uint64_t record)
    {
        cursor.skipWhitespace();
        std::string_view token = cursor.token();
        if (token.empty())
            fail(path_, "truncated: file ends inside '" + element.name + "' record " + std::to_string(record) + " of " +
                            std::to_string(element.count));
        return token;
    }
    [[noreturn]] void malformed(const StreamCursor& cursor, std::string_view token)
    {
        fail(path_, "line " + std::to_string(cursor.line) + ": malformed number " + quoteToken(token));
    }

    FileReader in_;
    ModelStreamOptions options_;
    PlyHeader header_;
    const PlyElement* vertexElement_ = nullptr;
    const PlyElement* faceElement_ = nullptr;
    int listIndex_ = -1;
    bool swap_ = false;
    bool faceColors_ = false;
    bool faceIndexSigned_ = true;
    bool scanned_ = false;
    uint64_t faceOffset_ = 0;
    size_t faceLine_ = 1;
    uint64_t degenerate_ = 0;
    std::unique_ptr<VertexStore> store_;
    std::unordered_map<uint32_t, uint32_t> colorMaterials_;
    std::vector<uint64_t> corners_;
};

} // namespace

std::unique_ptr<ModelStream> openPlyStream(const std::string& path, const ModelStreamOptions& options)
{
    return std::make_unique<PlyStream>(path, options);
}

} // namespace penumbra::detail
