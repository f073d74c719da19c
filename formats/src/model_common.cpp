// Pieces of the .penumbra model shared by the writer, reader, preprocessor,
// runtime and tests: owning views, the scalar position decoder, node boxes.
#include <cstring>

#include <glm/common.hpp>

#include "penumbra/model_format.h"

// The decoder must match the vertex shader bit for bit: no fused multiply-add.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC optimize("fp-contract=off")
#endif
#if defined(__clang__)
#pragma clang fp contract(off)
#endif

namespace penumbra {

CompressedModel makeCompressedModel(std::shared_ptr<CompressedModelData> data)
{
    CompressedModel model;
    model.header = data->header;
    model.clusters = data->clusters;
    model.nodes = data->nodes;
    model.vertices = data->vertices;
    model.indices = data->indices;
    model.materials = data->materials;
    model.cameras = data->cameras;
    model.lights = data->lights;
    model.storage = std::move(data);
    return model;
}

namespace {

void put3(float* out, const glm::vec3& v)
{
    out[0] = v.x;
    out[1] = v.y;
    out[2] = v.z;
}

glm::vec3 get3(const float* v)
{
    return {v[0], v[1], v[2]};
}

} // namespace

model::CameraRecord cameraRecord(const Camera& camera)
{
    model::CameraRecord r{};
    put3(r.position, camera.position);
    put3(r.target, camera.target);
    put3(r.up, camera.up);
    r.projection = camera.projection == Projection::Orthographic ? 1u : 0u;
    r.yfovDegrees = camera.yfovDegrees;
    r.orthoHeight = camera.orthoHeight;
    r.nearPlane = camera.nearPlane;
    r.farPlane = camera.farPlane;
    return r;
}

Camera cameraFromRecord(const model::CameraRecord& r)
{
    Camera camera;
    camera.position = get3(r.position);
    camera.target = get3(r.target);
    camera.up = get3(r.up);
    camera.projection = r.projection == 1 ? Projection::Orthographic : Projection::Perspective;
    camera.yfovDegrees = r.yfovDegrees;
    camera.orthoHeight = r.orthoHeight;
    camera.nearPlane = r.nearPlane;
    camera.farPlane = r.farPlane;
    return camera;
}

model::LightRecord lightRecord(const Light& light)
{
    model::LightRecord r{};
    r.type = uint32_t(light.type);
    put3(r.position, light.position);
    put3(r.direction, light.direction);
    put3(r.up, light.up);
    put3(r.color, light.color);
    r.intensity = light.intensity;
    r.range = light.range;
    r.innerConeDegrees = light.innerConeDegrees;
    r.outerConeDegrees = light.outerConeDegrees;
    r.width = light.width;
    r.height = light.height;
    r.radius = light.radius;
    return r;
}

Light lightFromRecord(const model::LightRecord& r)
{
    Light light;
    light.type = LightType(r.type);
    light.position = get3(r.position);
    light.direction = get3(r.direction);
    light.up = get3(r.up);
    light.color = get3(r.color);
    light.intensity = r.intensity;
    light.range = r.range;
    light.innerConeDegrees = r.innerConeDegrees;
    light.outerConeDegrees = r.outerConeDegrees;
    light.width = r.width;
    light.height = r.height;
    light.radius = r.radius;
    return light;
}

std::vector<Camera> modelCameras(const CompressedModel& model)
{
    std::vector<Camera> cameras;
    for (const model::CameraRecord& r : model.cameras)
        cameras.push_back(cameraFromRecord(r));
    return cameras;
}

std::vector<Light> modelLights(const CompressedModel& model)
{
    std::vector<Light> lights;
    for (const model::LightRecord& r : model.lights)
        lights.push_back(lightFromRecord(r));
    return lights;
}


glm::vec3 decodePosition(const model::ClusterRecord& cluster, const model::QuantizedVertex& vertex)
{
    volatile float x = float(vertex.x) * cluster.step[0];
    volatile float y = float(vertex.y) * cluster.step[1];
    volatile float z = float(vertex.z) * cluster.step[2];
    return {cluster.boxMin[0] + x, cluster.boxMin[1] + y, cluster.boxMin[2] + z};
}

float nodeStep(uint8_t exponent)
{
    const uint32_t bits = uint32_t(exponent) << 23;
    float step;
    std::memcpy(&step, &bits, sizeof(step));
    return step;
}

void decodeChildBox(const model::Node& node, uint32_t c, glm::vec3& min, glm::vec3& max)
{
    // q * 2^k is exact: one rounding, in the add (an FMA gives the same result).
    for (int axis = 0; axis < 3; ++axis) {
        const float step = nodeStep(node.exponent[axis]);
        min[axis] = node.origin[axis] + float(node.lo[axis][c]) * step;
        max[axis] = node.origin[axis] + float(node.hi[axis][c]) * step;
    }
}

} // namespace penumbra
