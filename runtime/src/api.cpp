// Small public helpers: names, defaults, image output, stats formatting.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <unistd.h>

#include <OpenImageIO/imageio.h>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include "penumbra/penumbra.h"

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
    Light light;
    light.type = LightType::Directional;
    light.direction = glm::normalize(glm::vec3(-0.45f, -1.0f, -0.3f));
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

void checkImagePath(const std::string& path)
{
    size_t dot = path.find_last_of('.');
    if (dot == std::string::npos || path.find('/', dot) != std::string::npos)
        fail(path, "no file extension (use .png or .exr)");
    if (!OIIO::ImageOutput::create(path))
        fail(path, "unsupported image format '" + path.substr(dot) + "'");
}

void writeImage(const Image& image, const std::string& path)
{
    checkImagePath(path);
    if (image.width == 0 || image.height == 0 || image.rgba.size() != size_t(image.width) * image.height * 4)
        fail(path, "image is empty or inconsistent");
    std::string extension = path.substr(path.find_last_of('.')); // checkImagePath: there is one
    for (char& c : extension)
        c = char(std::tolower(static_cast<unsigned char>(c)));
    bool floating = extension == ".exr" || extension == ".hdr" || extension == ".tif" || extension == ".tiff";

    // OpenImageIO picks the format from the extension, so the temporary name keeps it.
    size_t slash = path.find_last_of('/');
    std::string directory = slash == std::string::npos ? "" : path.substr(0, slash + 1);
    std::string base = slash == std::string::npos ? path : path.substr(slash + 1);
    std::string temporary = directory + ".tmp-" + std::to_string(::getpid()) + "-" + base;

    auto out = OIIO::ImageOutput::create(path);
    if (!out)
        fail(path, "unsupported image format '" + extension + "'");
    OIIO::ImageSpec spec(int(image.width), int(image.height), 4, floating ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::UINT8);
    bool ok = out->open(temporary, spec);
    if (ok) {
        if (floating) {
            ok = out->write_image(OIIO::TypeDesc::FLOAT, image.rgba.data());
        } else {
            std::vector<uint8_t> bytes(image.rgba.size());
            for (size_t i = 0; i < image.rgba.size(); ++i) {
                float v = (i % 4 == 3) ? std::fmin(std::fmax(image.rgba[i], 0.0f), 1.0f) : linearToSrgb(image.rgba[i]);
                bytes[i] = uint8_t(std::lround(v * 255.0f));
            }
            ok = out->write_image(OIIO::TypeDesc::UINT8, bytes.data());
        }
        ok = out->close() && ok;
    }
    if (!ok) {
        std::string message = out->geterror();
        std::remove(temporary.c_str());
        fail(path, "cannot write image: " + (message.empty() ? std::string("unknown error") : message.substr(0, message.find('\n'))));
    }
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
    if (stats.shadows != ShadowMethod::ShadowMap) {
        std::snprintf(buffer, sizeof(buffer), " | PIP %.2f%% | rays %llu | nodes %llu", stats.pipFraction * 100.0,
                      (unsigned long long)stats.rays, (unsigned long long)stats.nodesVisited);
        line += buffer;
    }
    if (stats.lightSamples) {
        std::snprintf(buffer, sizeof(buffer), " | samples %u | penumbra %.2f%%", stats.lightSamples, stats.penumbraFraction * 100.0);
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
    json["rays"] = stats.rays;
    json["bvh_nodes_visited"] = stats.nodesVisited;
    json["leaves_visited"] = stats.leavesVisited;
    json["triangle_tests"] = stats.triangleTests;
    json["light_samples"] = stats.lightSamples;
    json["penumbra_pixels"] = stats.penumbraPixels;
    json["penumbra_fraction"] = stats.penumbraFraction;
    json["ray_offset"] = stats.rayOffset;
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
