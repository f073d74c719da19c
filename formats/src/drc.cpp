// Draco (.drc) import and export, and the Draco encode/decode shared with the
// glTF KHR_draco_mesh_compression path. Uses Google's Draco library
// (edgebreaker connectivity coding, quantized positions).
#include <draco/compression/decode.h>
#include <draco/compression/encode.h>
#include <draco/core/decoder_buffer.h>
#include <draco/core/encoder_buffer.h>
#include <draco/mesh/mesh.h>

#include "io_internal.h"

namespace penumbra::detail {
namespace {

// Reads a Draco varint (7 bits a byte, low first) or a little-endian uint32.
bool readCount(const uint8_t*& p, const uint8_t* end, bool varint, uint64_t& value)
{
    value = 0;
    if (!varint) {
        if (end - p < 4)
            return false;
        value = uint64_t(p[0]) | uint64_t(p[1]) << 8 | uint64_t(p[2]) << 16 | uint64_t(p[3]) << 24;
        p += 4;
        return true;
    }
    for (int shift = 0; shift < 35; shift += 7) {
        if (p >= end)
            return false;
        uint8_t byte = *p++;
        value |= uint64_t(byte & 0x7f) << shift;
        if (!(byte & 0x80))
            return true;
    }
    return false;
}

// Moves p past a Draco metadata block (bitstream 1.3 and later): attribute
// metadata and the file's, each a tree of elements {entries (name, varint size,
// bytes), named sub-elements}. False when it runs past the end.
bool skipDracoMetadata(const uint8_t*& p, const uint8_t* end)
{
    auto skipName = [&] {
        if (p >= end || size_t(end - p) < size_t(1) + *p)
            return false;
        p += 1 + *p;
        return true;
    };
    auto skipTree = [&] {
        uint64_t pending = 1; // elements still to read; all but the root are preceded by a name
        for (bool root = true; pending > 0; root = false) {
            --pending;
            uint64_t entries = 0, subs = 0;
            if ((!root && !skipName()) || !readCount(p, end, true, entries))
                return false;
            for (uint64_t e = 0; e < entries; ++e) {
                uint64_t size = 0;
                if (!skipName() || !readCount(p, end, true, size) || size > uint64_t(end - p))
                    return false;
                p += size;
            }
            if (!readCount(p, end, true, subs) || subs > uint64_t(end - p))
                return false;
            pending += subs;
        }
        return true;
    };
    uint64_t attributes = 0, id = 0;
    if (!readCount(p, end, true, attributes) || attributes > uint64_t(end - p))
        return false;
    for (uint64_t a = 0; a < attributes; ++a)
        if (!readCount(p, end, true, id) || !skipTree())
            return false;
    return skipTree();
}

// libdraco sizes its tables from the face and vertex counts in the
// connectivity header before it reads the data, so a few hostile bytes can
// make it allocate gigabytes (a 44-byte .drc asked for 3.2 GB). This reads
// those counts as the decoder does (bitstream 1.x uses fixed uint32 counts,
// 2.x varints; edgebreaker before 2.2 has an extra new-vertex count) and
// rejects counts no encoder could fit in the data: more than 2^20 + 1024 per
// byte. Metadata (header flag 0x8000, read from bitstream 1.3) is skipped first.
void checkDracoCounts(const std::string& path, const std::string& prefix, const uint8_t* data, size_t size)
{
    if (size < 11 || std::memcmp(data, "DRACO", 5) != 0)
        return; // the decoder reports it
    const int version = data[5] * 256 + data[6];
    const bool mesh = data[7] == 1;
    const int method = data[8];
    const uint16_t flags = uint16_t(data[9] | data[10] << 8);
    if (!mesh || method > 1)
        return;
    const uint8_t* p = data + 11;
    const uint8_t* end = data + size;
    if ((flags & 0x8000) && version >= 0x103 && !skipDracoMetadata(p, end))
        return; // the decoder reports it
    const bool varint = version >= 0x200;
    uint64_t faces = 0, vertices = 0, unused = 0;
    bool ok;
    if (method == 0) { // sequential: faces, points; varints from 2.2
        const bool v22 = version >= 0x202;
        ok = readCount(p, end, v22, faces) && readCount(p, end, v22, vertices);
    } else { // edgebreaker: traversal type, [new vertices before 2.2], encoded vertices, faces
        ok = p < end;
        ++p;
        if (ok && version < 0x202)
            ok = readCount(p, end, varint, unused);
        ok = ok && readCount(p, end, varint, vertices) && readCount(p, end, varint, faces);
    }
    if (!ok)
        return; // truncated: the decoder reports it
    const uint64_t limit = (uint64_t(1) << 20) + uint64_t(size) * 1024;
    if (faces > limit || vertices > limit)
        fail(path, prefix + "corrupt Draco data (claims " + std::to_string(faces) + " faces and " +
                       std::to_string(vertices) + " vertices in " + std::to_string(size) + " bytes)");
}

} // namespace

DecodedDraco decodeDraco(const std::string& path, const std::string& what, const uint8_t* data, size_t size,
                         int64_t positionUniqueId)
{
    const std::string prefix = what.empty() ? std::string() : what + ": ";
    draco::DecoderBuffer buffer;
    buffer.Init(reinterpret_cast<const char*>(data), size);
    auto type = draco::Decoder::GetEncodedGeometryType(&buffer);
    if (!type.ok())
        fail(path, prefix + "not Draco data (" + type.status().error_msg_string() + ")");
    if (type.value() == draco::POINT_CLOUD)
        fail(path, prefix + "no triangles (Draco point cloud)");
    if (type.value() != draco::TRIANGULAR_MESH)
        fail(path, prefix + "unsupported Draco geometry type");
    checkDracoCounts(path, prefix, data, size);
    draco::Decoder decoder;
    std::unique_ptr<draco::Mesh> decodedMesh;
    try {
        auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
        if (!decoded.ok())
            fail(path, prefix + "corrupt Draco data (" + decoded.status().error_msg_string() + ")");
        decodedMesh = std::move(decoded).value();
    } catch (const std::bad_alloc&) {
        fail(path, prefix + "corrupt Draco data (the decoder ran out of memory)");
    }
    const draco::Mesh& mesh = *decodedMesh;
    const draco::PointAttribute* position = positionUniqueId >= 0
                                                ? mesh.GetAttributeByUniqueId(uint32_t(positionUniqueId))
                                                : mesh.GetNamedAttribute(draco::GeometryAttribute::POSITION);
    if (!position)
        fail(path, prefix + "Draco mesh has no position attribute" +
                       (positionUniqueId >= 0 ? " with id " + std::to_string(positionUniqueId) : std::string()));
    if (position->num_components() < 3)
        fail(path, prefix + "Draco position attribute has " + std::to_string(int(position->num_components())) +
                       " components, expected 3");
    DecodedDraco out;
    const size_t points = mesh.num_points();
    if (points > UINT32_MAX)
        fail(path, prefix + "too many Draco points");
    out.positions.resize(points * 3);
    for (size_t i = 0; i < points; ++i) {
        draco::AttributeValueIndex value = position->mapped_index(draco::PointIndex(uint32_t(i)));
        if (!position->ConvertValue<float>(value, 3, &out.positions[i * 3]))
            fail(path, prefix + "Draco position attribute cannot be read as floats");
    }
    const size_t faces = mesh.num_faces();
    out.indices.resize(faces * 3);
    for (size_t f = 0; f < faces; ++f) {
        const draco::Mesh::Face& face = mesh.face(draco::FaceIndex(uint32_t(f)));
        for (int k = 0; k < 3; ++k) {
            uint32_t index = face[k].value();
            if (index >= points)
                fail(path, prefix + "Draco face " + std::to_string(f) + " references point " + std::to_string(index) +
                               " but there are " + std::to_string(points) + " points");
            out.indices[f * 3 + size_t(k)] = index;
        }
    }
    return out;
}

std::vector<char> encodeDracoMesh(const std::string& path, const Mesh& mesh, const ExportOptions& options,
                                  uint32_t* positionId, size_t* encodedPoints, size_t* encodedFaces)
{
    const size_t vertexCount = mesh.vertexCount();
    const size_t triangleCount = mesh.triangleCount();
    if (vertexCount > INT32_MAX || triangleCount > INT32_MAX)
        fail(path, "mesh too large for Draco");
    draco::Mesh dracoMesh;
    dracoMesh.set_num_points(uint32_t(vertexCount));
    draco::GeometryAttribute attribute;
    attribute.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_FLOAT32, false, sizeof(float) * 3, 0);
    int attributeId = dracoMesh.AddAttribute(attribute, true, uint32_t(vertexCount));
    draco::PointAttribute* position = dracoMesh.attribute(attributeId);
    position->buffer()->Write(0, mesh.positions.data(), vertexCount * sizeof(float) * 3);
    dracoMesh.SetNumFaces(triangleCount);
    for (size_t t = 0; t < triangleCount; ++t) {
        draco::Mesh::Face face;
        for (int k = 0; k < 3; ++k)
            face[k] = draco::PointIndex(mesh.indices[t * 3 + size_t(k)]);
        dracoMesh.SetFace(draco::FaceIndex(uint32_t(t)), face);
    }

    draco::Encoder encoder;
    encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, options.dracoPositionBits);
    int speed = std::clamp(options.dracoSpeed, 0, 10);
    encoder.SetSpeedOptions(speed, speed);
    encoder.SetEncodingMethod(draco::MESH_EDGEBREAKER_ENCODING);
    encoder.SetTrackEncodedProperties(true);
    draco::EncoderBuffer buffer;
    draco::Status status = encoder.EncodeMeshToBuffer(dracoMesh, &buffer);
    if (!status.ok())
        fail(path, "Draco encoding failed: " + status.error_msg_string());
    if (positionId)
        *positionId = position->unique_id();
    if (encodedPoints)
        *encodedPoints = encoder.num_encoded_points();
    if (encodedFaces)
        *encodedFaces = encoder.num_encoded_faces();
    return std::vector<char>(buffer.data(), buffer.data() + buffer.size());
}

Scene importDraco(const std::string& path, const MappedFile& file)
{
    DecodedDraco decoded = decodeDraco(path, "", file.data(), file.size(), -1);
    Scene scene;
    scene.mesh.positions = std::move(decoded.positions);
    scene.mesh.indices = std::move(decoded.indices);
    return scene;
}

void exportDraco(const Scene& scene, const std::string& path, AtomicFileWriter& out, const ExportOptions& options)
{
    std::vector<char> encoded = encodeDracoMesh(path, scene.mesh, options, nullptr, nullptr, nullptr);
    out.write(encoded.data(), encoded.size());
}

} // namespace penumbra::detail
