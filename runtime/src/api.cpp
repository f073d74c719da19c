// Small public helpers: names, defaults, image output, stats formatting.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <unistd.h>

#if PENUMBRA_WITH_OPENIMAGEIO
#include <OpenImageIO/imageio.h>
#endif
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include "penumbra/file_io.h"
#include "penumbra/penumbra.h"
#include "png_writer.h"

namespace penumbra {

const char* cullModeName(CullMode mode)
{
    switch (mode) {
    case CullMode::None: return "none";
    case CullMode::Frustum: return "frustum";
    case CullMode::All: return "all";
    }
    return "unknown";
}

CullMode parseCullMode(const std::string& name)
{
    if (name == "none")
        return CullMode::None;
    if (name == "frustum")
        return CullMode::Frustum;
    if (name == "all")
        return CullMode::All;
    fail("--cull " + name, "unknown mode (expected none, frustum or all)");
}

const char* rasterIndicesName(RasterIndices indices)
{
    switch (indices) {
    case RasterIndices::Auto: return "auto";
    case RasterIndices::Strips: return "strips";
    case RasterIndices::Triangles: return "triangles";
    }
    return "unknown";
}

RasterIndices parseRasterIndices(const std::string& name)
{
    if (name == "auto")
        return RasterIndices::Auto;
    if (name == "strips")
        return RasterIndices::Strips;
    if (name == "triangles")
        return RasterIndices::Triangles;
    fail("--raster-indices " + name, "unknown form (expected auto, strips or triangles)");
}

float shadowRayOffset(const Bounds& bounds, float maxPositionError)
{
    return std::max(1e-5f * glm::length(bounds.extent()), 4.0f * maxPositionError);
}

Camera defaultCamera(const Bounds& bounds)
{
    Camera camera;
    glm::vec3 center = bounds.center();
    float radius = std::max(glm::length(bounds.extent()) * 0.5f, 1e-3f);
    camera.target = center;
    camera.position = center + glm::normalize(glm::vec3(0.9f, 0.75f, 1.3f)) * radius * 2.2f;
    camera.yfovDegrees = 45.0f;
    return camera;
}

Light defaultLight()
{
    // defaultCamera looks along -(0.9, 0.75, 1.3); its left is (-0.82, 0, 0.57)
    // in the ground plane. The sun sits up, left and a little in front of the
    // camera (about 50 degrees above the horizon), so cast shadows fall to the
    // right of and behind what they fall from, in view.
    Light light;
    light.type = LightType::Directional;
    light.direction = glm::normalize(glm::vec3(0.4f, -1.0f, -0.7f));
    light.intensity = 2.5f;
    return light;
}

namespace {

float linearToSrgb(float v)
{
    v = std::fmin(std::fmax(v, 0.0f), 1.0f);
    return v <= 0.0031308f ? v * 12.92f : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

} // namespace

const char* toneMapName(ToneMap curve)
{
    return curve == ToneMap::Filmic ? "filmic" : "none";
}

ToneMap parseToneMap(const std::string& name)
{
    if (name == "filmic")
        return ToneMap::Filmic;
    if (name == "none")
        return ToneMap::None;
    fail("--tonemap " + name, "unknown curve (expected filmic or none)");
}

float applyToneMap(float value, ToneMap curve)
{
    float x = std::fmax(value, 0.0f);
    if (curve == ToneMap::Filmic) // Narkowicz 2015, ACES fitted
        x = (x * (2.51f * x + 0.03f)) / (x * (2.43f * x + 0.59f) + 0.14f);
    return std::fmin(x, 1.0f);
}

namespace {

// The x >= 0 with applyToneMap(x) == y, 0 < y < 1.
double inverseToneMap(double y, ToneMap curve)
{
    if (curve == ToneMap::None)
        return y;
    // y (2.43 x^2 + 0.59 x + 0.14) = 2.51 x^2 + 0.03 x, the positive root.
    double a = 2.43 * y - 2.51, b = 0.59 * y - 0.03, c = 0.14 * y;
    return (-b - std::sqrt(b * b - 4.0 * a * c)) / (2.0 * a);
}

} // namespace

float autoExposure(const Image& image, ToneMap curve, const float background[3])
{
    constexpr double kPercentile = 0.95, kTarget = 0.8;
    std::vector<float> luminance;
    for (size_t i = 0; i + 3 < image.rgba.size(); i += 4) {
        const float* p = &image.rgba[i];
        if (p[0] == background[0] && p[1] == background[1] && p[2] == background[2])
            continue;
        luminance.push_back(0.2126f * p[0] + 0.7152f * p[1] + 0.0722f * p[2]);
    }
    if (luminance.empty())
        return 1.0f;
    auto at = luminance.begin() + ptrdiff_t(double(luminance.size() - 1) * kPercentile);
    std::nth_element(luminance.begin(), at, luminance.end());
    if (!(*at > 0.0f) || !std::isfinite(*at))
        return 1.0f;
    return float(inverseToneMap(kTarget, curve) / double(*at));
}

std::vector<float> pipMask(const Image& plain, const Image& tinted)
{
    if (plain.rgba.size() != tinted.rgba.size())
        fail("pipMask", "the two images differ in size");
    std::vector<float> mask(plain.rgba.size() / 4, 0.0f);
    for (size_t i = 0; i < mask.size(); ++i)
        for (size_t c = 0; c < 3; ++c)
            if (plain.rgba[i * 4 + c] != tinted.rgba[i * 4 + c])
                mask[i] = 1.0f;
    return mask;
}

std::vector<ImageLayer> frameLayers(const Frame& frame, const Camera& camera, const std::vector<float>& pip)
{
    size_t pixels = size_t(frame.color.width) * frame.color.height;
    if (frame.visibility.size() != pixels || frame.positions.size() != pixels * 4)
        fail("frameLayers", "the frame was rendered without readbackGBuffer");
    std::vector<ImageLayer> layers;
    if (!frame.lightVisibility.empty() && frame.lightVisibility.size() % pixels == 0) {
        for (size_t light = 0; light < frame.lightVisibility.size() / pixels; ++light)
            layers.push_back({"visibility.light" + std::to_string(light),
                              std::vector<float>(frame.lightVisibility.begin() + light * pixels,
                                                 frame.lightVisibility.begin() + (light + 1) * pixels)});
    } else {
        layers.push_back({"visibility.light0", frame.visibility});
    }
    const std::vector<float>& mask = pip.empty() ? frame.pip : pip;
    if (!mask.empty()) {
        if (mask.size() != pixels)
            fail("frameLayers", "the pip mask differs in size from the frame");
        layers.push_back({"pip", mask});
    }
    ImageLayer depth{"Z", std::vector<float>(pixels, std::numeric_limits<float>::infinity())};
    glm::vec3 forward = glm::normalize(camera.target - camera.position);
    for (size_t i = 0; i < pixels; ++i) {
        const float* p = &frame.positions[i * 4];
        if (p[3] != 0.0f)
            depth.values[i] = glm::dot(glm::vec3(p[0], p[1], p[2]) - camera.position, forward);
    }
    layers.push_back(std::move(depth));
    return layers;
}

bool wantsGround(const Mesh& mesh)
{
    Bounds bounds = computeBounds(mesh);
    if (bounds.empty())
        return false;
    glm::vec3 e = bounds.extent();
    if (e.y < 0.25f * std::max(e.x, e.z))
        return false; // wide and flat: a scene
    float slab = bounds.min.y + 0.02f * e.y;
    Bounds upper;
    for (size_t v = 0; v < mesh.vertexCount(); ++v) {
        glm::vec3 p = mesh.position(v);
        if (p.y > slab) {
            upper.min = glm::min(upper.min, p);
            upper.max = glm::max(upper.max, p);
        }
    }
    glm::vec3 u = upper.extent();
    return !upper.empty() && double(u.x) * u.z >= 0.5 * double(e.x) * e.z;
}

float groundHeight(const Bounds& modelBounds)
{
    return modelBounds.min.y - 0.002f * glm::length(modelBounds.extent());
}

void addGround(Mesh& mesh, const Bounds& modelBounds, float y)
{
    constexpr uint32_t kQuads = 8;
    glm::vec3 e = modelBounds.extent();
    float reach = std::max(std::max(e.x, e.z), 1e-3f) + 3.0f * std::max(e.y, 0.0f);
    glm::vec3 c = modelBounds.center();
    float x0 = c.x - 0.5f * e.x - reach, x1 = c.x + 0.5f * e.x + reach;
    float z0 = c.z - 0.5f * e.z - reach, z1 = c.z + 0.5f * e.z + reach;
    uint32_t first = uint32_t(mesh.vertexCount());
    for (uint32_t j = 0; j <= kQuads; ++j)
        for (uint32_t i = 0; i <= kQuads; ++i) {
            float u = float(i) / kQuads, v = float(j) / kQuads;
            mesh.positions.insert(mesh.positions.end(), {x0 + (x1 - x0) * u, y, z0 + (z1 - z0) * v});
        }
    for (uint32_t j = 0; j < kQuads; ++j)
        for (uint32_t i = 0; i < kQuads; ++i) {
            uint32_t a = first + j * (kQuads + 1) + i, b = a + 1, d = a + kQuads + 1, c2 = d + 1;
            // Counter-clockwise seen from +y: x grows to the right, z toward the viewer.
            mesh.indices.insert(mesh.indices.end(), {a, d, b, b, d, c2});
        }
    // The ground is white: a material of its own when the model has materials, white vertices when it has colours.
    if (!mesh.colors.empty())
        mesh.colors.resize(mesh.positions.size(), 1.0f);
    if (!mesh.materials.empty()) {
        if (mesh.triangleMaterials.empty())
            mesh.triangleMaterials.assign(mesh.triangleCount() - 2 * kQuads * kQuads, 0);
        mesh.triangleMaterials.resize(mesh.triangleCount(), uint32_t(mesh.materials.size()));
        mesh.materials.push_back({glm::vec4(1.0f), "ground"});
    }
}

Ground parseGround(const std::string& text)
{
    if (text == "auto") return {Ground::Kind::Auto};
    if (text == "below") return {Ground::Kind::Below};
    if (text == "off") return {Ground::Kind::Off};
    if (text.rfind("y=", 0) == 0) {
        char* stop = nullptr;
        float y = std::strtof(text.c_str() + 2, &stop);
        if (text.size() > 2 && *stop == '\0' && std::isfinite(y))
            return {Ground::Kind::At, y};
    }
    fail("--ground " + text, "expected auto, below, off or y=VALUE");
}

bool applyGround(const Ground& ground, const Bounds& modelBounds, Mesh& mesh, CompressedModel& compressed)
{
    bool add = ground.kind == Ground::Kind::Below || ground.kind == Ground::Kind::At ||
               (ground.kind == Ground::Kind::Auto && compressed.clusters.empty() && wantsGround(mesh));
    if (!add)
        return false;
    if (!compressed.clusters.empty()) {
        mesh = decodeMesh(compressed);
        compressed = CompressedModel{};
    }
    addGround(mesh, modelBounds, ground.kind == Ground::Kind::At ? ground.y : groundHeight(modelBounds));
    return true;
}

Mesh decodeMesh(const CompressedModel& model)
{
    Mesh mesh;
    mesh.positions.reserve(model.vertices.size() * 3);
    mesh.indices.reserve(model.header.triangleCount * 3);
    for (const model::ClusterRecord& cluster : model.clusters) {
        uint32_t first = uint32_t(mesh.vertexCount());
        for (uint32_t v = 0; v < cluster.vertexCount; ++v) {
            glm::vec3 p = decodePosition(cluster, model.vertices[cluster.firstVertex + v]);
            mesh.positions.insert(mesh.positions.end(), {p.x, p.y, p.z});
        }
        const uint8_t* strips = model.indices.data() + cluster.firstIndex;
        forEachStripTriangle(strips, strips + cluster.indexBytes, [&](uint32_t a, uint32_t b, uint32_t c) {
            mesh.indices.insert(mesh.indices.end(), {first + a, first + b, first + c});
            mesh.triangleMaterials.push_back(cluster.material);
        });
    }
    // Materials: the table as stored (one white material means none).
    const bool plain = model.materials.size() == 1 && model.materials[0].baseColor[0] == 1.0f &&
                       model.materials[0].baseColor[1] == 1.0f && model.materials[0].baseColor[2] == 1.0f &&
                       model.materials[0].baseColor[3] == 1.0f;
    if (plain)
        mesh.triangleMaterials.clear();
    else
        for (const model::MaterialRecord& m : model.materials)
            mesh.materials.push_back({glm::vec4(m.baseColor[0], m.baseColor[1], m.baseColor[2], m.baseColor[3]), ""});
    return mesh;
}

namespace {

// The extension of a path that has one (checkImagePath), in lower case: ".png".
std::string lowerExtension(const std::string& path)
{
    std::string extension = path.substr(path.find_last_of('.'));
    for (char& c : extension)
        c = char(std::tolower(static_cast<unsigned char>(c)));
    return extension;
}

} // namespace

void checkImagePath(const std::string& path)
{
    size_t dot = path.find_last_of('.');
    if (dot == std::string::npos || path.find('/', dot) != std::string::npos)
        fail(path, "no file extension (use .png or .exr)");
#if PENUMBRA_WITH_OPENIMAGEIO
    if (!OIIO::ImageOutput::create(path))
        fail(path, "unsupported image format '" + path.substr(dot) + "'");
#else
    if (lowerExtension(path) != ".png")
        fail(path, "unsupported image format '" + path.substr(dot) + "' (this build has no OpenImageIO: .png only)");
#endif
}

void writeImage(const Image& image, const std::string& path)
{
    writeImage(image, path, ImageOptions{});
}

void writeImage(const Image& image, const std::string& path, const ImageOptions& options)
{
    checkImagePath(path);
    if (image.width == 0 || image.height == 0 || image.rgba.size() != size_t(image.width) * image.height * 4)
        fail(path, "image is empty or inconsistent");
    const std::string extension = lowerExtension(path); // checkImagePath: there is one
    bool floating = extension == ".exr" || extension == ".hdr" || extension == ".tif" || extension == ".tiff";

    // OpenImageIO picks the format from the extension, so the temporary name keeps it.
    size_t slash = path.find_last_of('/');
    std::string directory = slash == std::string::npos ? "" : path.substr(0, slash + 1);
    std::string base = slash == std::string::npos ? path : path.substr(slash + 1);
    std::string temporary = directory + ".tmp-" + std::to_string(::getpid()) + "-" + base;
    const TrackedTemporary tracked(temporary); // removed if the process is interrupted

    size_t pixels = size_t(image.width) * image.height;
    if (!options.layers.empty() && extension != ".exr")
        fail(path, "extra channels (layers) need an .exr output");
    for (const ImageLayer& layer : options.layers)
        if (layer.values.size() != pixels || layer.name.empty())
            fail(path, "layer '" + layer.name + "' is unnamed or differs in size from the image");
    // Exposure 1 and no curve: exactly the plain sRGB encoding of the linear values.
    auto encode8 = [&] {
        const bool plain = options.exposure == 1.0f && options.tonemap == ToneMap::None;
        std::vector<uint8_t> bytes(image.rgba.size());
        for (size_t i = 0; i < image.rgba.size(); ++i) {
            float v = image.rgba[i];
            if (i % 4 == 3)
                v = std::fmin(std::fmax(v, 0.0f), 1.0f);
            else
                v = linearToSrgb(plain ? v : applyToneMap(v * options.exposure, options.tonemap));
            bytes[i] = uint8_t(std::lround(v * 255.0f));
        }
        return bytes;
    };
#if PENUMBRA_WITH_OPENIMAGEIO
    auto out = OIIO::ImageOutput::create(path);
    if (!out)
        fail(path, "unsupported image format '" + extension + "'");
    OIIO::ImageSpec spec(int(image.width), int(image.height), 4, floating ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::UINT8);
    if (!options.layers.empty()) {
        // R, G, B, A stay half; the layers are full float.
        spec.nchannels = int(4 + options.layers.size());
        spec.channelformats.assign(4, OIIO::TypeDesc::HALF);
        for (const ImageLayer& layer : options.layers) {
            spec.channelnames.push_back(layer.name);
            spec.channelformats.push_back(OIIO::TypeDesc::FLOAT);
        }
        spec.z_channel = -1;
        for (size_t i = 0; i < options.layers.size(); ++i)
            if (options.layers[i].name == "Z")
                spec.z_channel = int(4 + i);
    }
    bool ok = out->open(temporary, spec);
    if (ok) {
        if (floating && !options.layers.empty()) {
            size_t channels = 4 + options.layers.size();
            std::vector<float> interleaved(pixels * channels);
            for (size_t p = 0; p < pixels; ++p) {
                std::copy_n(&image.rgba[p * 4], 4, &interleaved[p * channels]);
                for (size_t l = 0; l < options.layers.size(); ++l)
                    interleaved[p * channels + 4 + l] = options.layers[l].values[p];
            }
            ok = out->write_image(OIIO::TypeDesc::FLOAT, interleaved.data());
        } else if (floating) {
            ok = out->write_image(OIIO::TypeDesc::FLOAT, image.rgba.data());
        } else {
            const std::vector<uint8_t> bytes = encode8();
            ok = out->write_image(OIIO::TypeDesc::UINT8, bytes.data());
        }
        ok = out->close() && ok;
    }
    if (!ok) {
        std::string message = out->geterror();
        std::remove(temporary.c_str());
        fail(path, "cannot write image: " + (message.empty() ? std::string("unknown error") : message.substr(0, message.find('\n'))));
    }
#else
    (void)floating; // checkImagePath: .png, 8 bits
    const std::vector<uint8_t> bytes = encode8();
    if (!writePngRgba8(temporary, image.width, image.height, bytes.data())) {
        std::remove(temporary.c_str());
        fail(path, "cannot write image: cannot create or fill the file");
    }
#endif
    if (std::rename(temporary.c_str(), path.c_str()) != 0) {
        std::remove(temporary.c_str());
        fail(path, "cannot rename the finished image into place");
    }
}

std::string summaryLine(const FrameStats& stats)
{
    char buffer[256];
    std::string line = "triangles " + std::to_string(stats.triangles) + " | " + std::to_string(stats.width) + "x" +
                       std::to_string(stats.height) + " | " + stats.device.name + " | lights " + std::to_string(stats.lights) +
                       " | shadows " + shadowMethodName(stats.shadows);
    if (stats.srtTracedAll)
        line += stats.srtProbe ? " (every pixel traced: a probe)" : " (every pixel traced: measured cheaper)";
    else if (stats.srtProbe)
        line += " (selective: a probe)";
    if (stats.shadows != ShadowMethod::ShadowMap) {
        std::snprintf(buffer, sizeof(buffer), " | PIP %.2f%% | rays %llu | nodes %llu", stats.pipFraction * 100.0,
                      (unsigned long long)stats.rays, (unsigned long long)stats.nodesVisited);
        line += buffer;
    }
    if (stats.shadows == ShadowMethod::RayHierarchy) {
        std::snprintf(buffer, sizeof(buffer), " | casters %llu | ray tests %llu | batches %u | rounds %u | peak pairs %.1f MiB",
                      (unsigned long long)stats.rhCasters, (unsigned long long)stats.triangleTests, stats.rhBatches, stats.rhRounds,
                      double(stats.rhPeakPairBytes) / double(1 << 20));
        line += buffer;
    }
    if (stats.lightSamples) {
        std::snprintf(buffer, sizeof(buffer), " | samples %u | penumbra %.2f%%", stats.lightSamples, stats.penumbraFraction * 100.0);
        line += buffer;
    }
    if (stats.shadows == ShadowMethod::AliasFree)
        line += " | closed clusters " + std::to_string(stats.afsmClosedClusters) + ": " + stats.afsmClosedCasting + " | most samples in a cell " + std::to_string(stats.afsmCellMost) + ", slice draws " + std::to_string(stats.afsmSliceDraws) + ", compute path " + (stats.afsmComputePath ? "on" : "off") + ", row-wise casters " + std::to_string(stats.afsmWideCasters) + " (raster path in " + std::to_string(stats.afsmWideRasterLayers) + " layers), two passes in " + std::to_string(stats.afsmTwoPassLayers) + " layers (" + std::to_string(stats.afsmRefreshedLayers) + " refreshed)";
    if (stats.geometryBudgetBytes) {
        std::snprintf(buffer, sizeof(buffer),
                      " | budget %.1f of %.1f MiB | model on device %.1f MiB | resident peak %.1f MiB | pages uploaded %llu | streamed %.1f MiB | parking rounds %u",
                      double(stats.geometryBudgetBytes) / 1048576.0, double(stats.geometryBytes) / 1048576.0,
                      double(stats.modelDeviceBytes) / 1048576.0,
                      double(stats.residentPeakBytes) / 1048576.0, (unsigned long long)stats.pagesUploaded,
                      double(stats.bytesStreamed) / 1048576.0, stats.parkingRounds);
        line += buffer;
    }
    for (const PassTiming& pass : stats.passes) {
        std::snprintf(buffer, sizeof(buffer), " | %s %.2f ms", pass.name.c_str(), pass.gpuMs);
        line += buffer;
    }
    line += std::string(" | cull ") + cullModeName(stats.cull);
    for (const ViewCullStats& view : stats.views) {
        uint64_t total = view.trianglesDrawn + view.trianglesCulled;
        std::snprintf(buffer, sizeof(buffer), " | %s %.2f ms, %.1f%% tris culled, %llu queries", view.name.c_str(), view.gpuMs,
                      total ? 100.0 * double(view.trianglesCulled) / double(total) : 0.0, (unsigned long long)view.queriesIssued);
        line += buffer;
    }
    std::snprintf(buffer, sizeof(buffer), " | gpu %.2f ms | frame %.2f ms", stats.gpuMs, stats.cpuMs);
    return line + buffer;
}

std::string statsJson(const FrameStats& stats)
{
    nlohmann::ordered_json json;
    json["device"] = {{"name", stats.device.name}, {"type", stats.device.type}, {"driver", stats.device.driver},
                      {"api_version", stats.device.apiVersion}};
    json["triangles"] = stats.triangles;
    json["width"] = stats.width;
    json["height"] = stats.height;
    json["lights"] = stats.lights;
    json["shadows"] = shadowMethodName(stats.shadows);
    json["covered_pixels"] = stats.coveredPixels;
    json["pip_pixels"] = stats.pipPixels;
    json["pip_fraction"] = stats.pipFraction;
    if (stats.shadows == ShadowMethod::Selective) {
        json["srt_traced_all"] = stats.srtTracedAll;
        json["srt_probe"] = stats.srtProbe;
        json["srt_chosen"] = stats.srtChosen;
    }
    json["rays"] = stats.rays;
    json["bvh_nodes_visited"] = stats.nodesVisited;
    json["leaves_visited"] = stats.leavesVisited;
    json["triangle_tests"] = stats.triangleTests;
    json["light_samples"] = stats.lightSamples;
    json["penumbra_pixels"] = stats.penumbraPixels;
    json["penumbra_fraction"] = stats.penumbraFraction;
    json["ray_offset"] = stats.rayOffset;
    if (stats.shadows == ShadowMethod::RayHierarchy)
        json["rh"] = {{"casters", stats.rhCasters}, {"cone_tests", stats.nodesVisited}, {"ray_tests", stats.triangleTests},
                      {"batches", stats.rhBatches}, {"rounds", stats.rhRounds}, {"peak_pair_bytes", stats.rhPeakPairBytes}};
    if (stats.shadows == ShadowMethod::AliasFree)
        json["afsm"] = {{"closed_clusters", stats.afsmClosedClusters}, {"closed_casting", stats.afsmClosedCasting}, {"cell_most", stats.afsmCellMost}, {"slice_draws", stats.afsmSliceDraws}, {"compute_path", stats.afsmComputePath}, {"row_casters", stats.afsmWideCasters}, {"raster_layers", stats.afsmWideRasterLayers}, {"two_pass_layers", stats.afsmTwoPassLayers}, {"refreshed_layers", stats.afsmRefreshedLayers}};
    if (stats.geometryBudgetBytes)
        json["geometry_budget"] = {{"budget_bytes", stats.geometryBudgetBytes},     {"geometry_bytes", stats.geometryBytes},
                                   {"resident_peak_bytes", stats.residentPeakBytes}, {"pages_uploaded", stats.pagesUploaded},
                                   {"bytes_streamed", stats.bytesStreamed},          {"parking_rounds", stats.parkingRounds},
                                   {"parked_rays", stats.parkedRays},                {"model_device_bytes", stats.modelDeviceBytes}};
    nlohmann::ordered_json passes = nlohmann::ordered_json::object();
    for (const PassTiming& pass : stats.passes)
        passes[pass.name + "_ms"] = pass.gpuMs;
    json["passes"] = passes;
    json["cull"] = cullModeName(stats.cull);
    nlohmann::ordered_json views = nlohmann::ordered_json::array();
    for (const ViewCullStats& view : stats.views)
        views.push_back({{"name", view.name},
                         {"nodes_tested", view.nodesTested},
                         {"clusters_drawn", view.clustersDrawn},
                         {"clusters_culled", view.clustersCulled},
                         {"clusters_occluded", view.clustersOccluded},
                         {"clusters_beside_receivers", view.clustersBesideReceivers},
                         {"triangles_drawn", view.trianglesDrawn},
                         {"triangles_culled", view.trianglesCulled},
                         {"queries_issued", view.queriesIssued},
                         {"cull_cpu_ms", view.cpuMs},
                         {"gpu_ms", view.gpuMs}});
    json["views"] = views;
    json["gpu_ms"] = stats.gpuMs;
    json["frame_ms"] = stats.cpuMs;
    return json.dump(2);
}

} // namespace penumbra
