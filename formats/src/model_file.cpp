// Writing and mapping .penumbra model files (layout: formats/README.md,
// section ".penumbra model file"). The checks a reader applies live in
// model_validate.cpp so that the fuzzer can build them without the importers.
#include <xxhash.h>

#include <cstring>
#include <limits>
#include <vector>

#include "io_internal.h"
#include "penumbra/error.h"
#include "penumbra/model_format.h"

namespace penumbra {
namespace {

using namespace model;

uint64_t alignUp(uint64_t value)
{
    return (value + kSectionAlignment - 1) / kSectionAlignment * kSectionAlignment;
}

void writeZeros(detail::AtomicFileWriter& out, uint64_t count)
{
    static constexpr char kZeros[kSectionAlignment] = {};
    out.write(kZeros, size_t(count));
}

} // namespace

namespace detail {

uint64_t writeModelImage(const CompressedModel& model, AtomicFileWriter& out, const std::string& path)
{
    if (model.clusters.size() > std::numeric_limits<uint32_t>::max() ||
        model.nodes.size() > std::numeric_limits<uint32_t>::max())
        fail(path, "too many clusters or nodes for the format (limit 4294967295 each)");

    // Header: counts from the spans, everything else from model.header.
    FileHeader header = model.header;
    std::memcpy(header.magic, kMagic, sizeof(kMagic));
    header.version = kVersion;
    header.headerSize = sizeof(FileHeader);
    header.clusterCount = uint32_t(model.clusters.size());
    header.nodeCount = uint32_t(model.nodes.size());
    header.vertexCount = model.vertices.size();
    header.indexBytes = model.indices.size();
    if (model.materials.size() > kMaxMaterials || model.cameras.size() > kMaxCameras || model.lights.size() > kMaxLights)
        fail(path, "too many materials, cameras or lights for the format");
    header.materialCount = uint32_t(model.materials.size());
    header.cameraCount = uint32_t(model.cameras.size());
    header.lightCount = uint32_t(model.lights.size());

    // Never write a file the reader would reject.
    CompressedModel checked = model;
    checked.header = header;
    validateModel(checked, path + ": refusing to write an invalid model");

    // Sections in the order Clusters, Nodes, Vertices, Indices, Materials, then Cameras and Lights
    // when there are any, each 64-byte aligned; the remaining table entries stay zero.
    struct Payload {
        SectionType type;
        uint32_t elementSize;
        const void* data;
        uint64_t size;
    };
    std::vector<Payload> payloads = {
        {SectionType::Clusters, sizeof(ClusterRecord), model.clusters.data(), model.clusters.size_bytes()},
        {SectionType::Nodes, sizeof(Node), model.nodes.data(), model.nodes.size_bytes()},
        {SectionType::Vertices, sizeof(QuantizedVertex), model.vertices.data(), model.vertices.size_bytes()},
        {SectionType::Indices, 1, model.indices.data(), model.indices.size_bytes()},
        {SectionType::Materials, sizeof(MaterialRecord), model.materials.data(), model.materials.size_bytes()},
    };
    if (!model.cameras.empty())
        payloads.push_back({SectionType::Cameras, sizeof(CameraRecord), model.cameras.data(), model.cameras.size_bytes()});
    if (!model.lights.empty())
        payloads.push_back({SectionType::Lights, sizeof(LightRecord), model.lights.data(), model.lights.size_bytes()});
    std::memset(header.sections, 0, sizeof(header.sections));
    uint64_t end = sizeof(FileHeader);
    for (uint32_t i = 0; i < payloads.size(); ++i) {
        SectionEntry& entry = header.sections[i];
        entry.type = uint32_t(payloads[i].type);
        entry.elementSize = payloads[i].elementSize;
        entry.offset = alignUp(end);
        entry.size = payloads[i].size;
        entry.checksum = XXH64(payloads[i].data, size_t(payloads[i].size), 0);
        end = entry.offset + entry.size;
    }
    header.fileSize = alignUp(end);
    header.headerChecksum = 0;
    header.headerChecksum = XXH64(&header, sizeof(header), 0);

    // Payloads go straight from the caller's memory to write(2).
    out.write(&header, sizeof(header));
    uint64_t written = sizeof(header);
    for (uint32_t i = 0; i < payloads.size(); ++i) {
        writeZeros(out, header.sections[i].offset - written);
        out.write(payloads[i].data, size_t(payloads[i].size));
        written = header.sections[i].offset + header.sections[i].size;
    }
    writeZeros(out, header.fileSize - written);
    return header.fileSize;
}

} // namespace detail

void writeModelFile(const CompressedModel& model, const std::string& path)
{
    detail::AtomicFileWriter out(path);
    detail::writeModelImage(model, out, path);
    out.commit(detail::AtomicFileWriter::Durability::Synced);
}

CompressedModel withScene(const CompressedModel& model, const std::vector<Camera>& cameras, const std::vector<Light>& lights,
                          const std::string& subject)
{
    struct Storage {
        std::shared_ptr<const void> base;
        std::vector<model::CameraRecord> cameras;
        std::vector<model::LightRecord> lights;
    };
    auto storage = std::make_shared<Storage>();
    storage->base = model.storage;
    for (size_t i = 0; i < cameras.size() && storage->cameras.size() < model::kMaxCameras; ++i) {
        const model::CameraRecord record = cameraRecord(cameras[i]);
        try {
            validateCameraRecord(record, "camera " + std::to_string(i));
            storage->cameras.push_back(record);
        } catch (const Error& e) {
            warn(subject, std::string(e.what()) + " (not stored)");
        }
    }
    for (size_t i = 0; i < lights.size() && storage->lights.size() < model::kMaxLights; ++i) {
        const model::LightRecord record = lightRecord(lights[i]);
        try {
            validateLightRecord(record, "light " + std::to_string(i));
            storage->lights.push_back(record);
        } catch (const Error& e) {
            warn(subject, std::string(e.what()) + " (not stored)");
        }
    }
    CompressedModel result = model;
    result.cameras = storage->cameras;
    result.lights = storage->lights;
    result.header.cameraCount = uint32_t(storage->cameras.size());
    result.header.lightCount = uint32_t(storage->lights.size());
    result.storage = std::move(storage);
    return result;
}

CompressedModel openModelFile(const std::string& path)
{
    auto file = std::make_shared<detail::MappedFile>(path);
    std::span<const uint8_t> bytes(file->data(), file->size());
    CompressedModel model = openModelMemory(bytes, file, path);
    file->release(); // validated: what a renderer reads from here on is mapped again where it reads
    return model;
}

} // namespace penumbra
