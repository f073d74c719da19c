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
    draco::Decoder decoder;
    auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
    if (!decoded.ok())
        fail(path, prefix + "corrupt Draco data (" + decoded.status().error_msg_string() + ")");
    const draco::Mesh& mesh = *decoded.value();
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
