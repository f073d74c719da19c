#include "penumbra/scene_file.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include "io_internal.h"
#include "penumbra/error.h"

namespace penumbra {

namespace {

using Json = nlohmann::json;

float number(const Json& value, const std::string& subject, const char* key)
{
    if (!value.is_number())
        fail(subject, std::string("'") + key + "' must be a number");
    double v = value.get<double>();
    if (!std::isfinite(v))
        fail(subject, std::string("'") + key + "' must be finite");
    return float(v);
}

glm::vec3 vec3(const Json& value, const std::string& subject, const char* key)
{
    if (!value.is_array() || value.size() != 3)
        fail(subject, std::string("'") + key + "' must be an array of 3 numbers");
    return {number(value[0], subject, key), number(value[1], subject, key), number(value[2], subject, key)};
}

void rejectUnknownKeys(const Json& object, const std::set<std::string>& known, const std::string& subject)
{
    for (auto it = object.begin(); it != object.end(); ++it)
        if (!known.count(it.key()))
            fail(subject, "unknown key " + detail::quoteToken(it.key()));
}

// Applies one light property; false when key is not a light property.
LightType lightTypeIn(const std::string& name, const std::string& subject)
{
    try {
        return parseLightType(name);
    } catch (const Error& e) {
        fail(subject, e.what());
    }
}

bool setLightProperty(Light& light, const std::string& key, const Json& value, const std::string& subject)
{
    const char* k = key.c_str();
    if (key == "position") light.position = vec3(value, subject, k);
    else if (key == "direction") light.direction = vec3(value, subject, k);
    else if (key == "up") light.up = vec3(value, subject, k);
    else if (key == "color") light.color = vec3(value, subject, k);
    else if (key == "intensity") light.intensity = number(value, subject, k);
    else if (key == "range") light.range = number(value, subject, k);
    else if (key == "inner_cone") light.innerConeDegrees = number(value, subject, k);
    else if (key == "outer_cone") light.outerConeDegrees = number(value, subject, k);
    else if (key == "width") light.width = number(value, subject, k);
    else if (key == "height") light.height = number(value, subject, k);
    else if (key == "radius") light.radius = number(value, subject, k);
    else return false;
    return true;
}

} // namespace

bool isAreaLight(const Light& light)
{
    return light.type == LightType::Rectangle || light.type == LightType::Disk || light.type == LightType::Sphere;
}

void areaLightAxes(const Light& light, glm::vec3& u, glm::vec3& v)
{
    u = v = glm::vec3(0.0f);
    if (light.type == LightType::Sphere) {
        u = glm::vec3(light.radius, 0.0f, 0.0f);
        return;
    }
    if (light.type != LightType::Rectangle && light.type != LightType::Disk)
        return;
    glm::vec3 n = glm::normalize(light.direction);
    glm::vec3 up = light.up - glm::dot(light.up, n) * n;
    if (glm::length(up) < 1e-6f * std::max(glm::length(light.up), 1e-30f) || glm::length(up) == 0.0f) {
        glm::vec3 any = std::abs(n.y) < 0.9f ? glm::vec3(0, 1, 0) : glm::vec3(1, 0, 0);
        up = any - glm::dot(any, n) * n;
    }
    v = glm::normalize(up);
    u = glm::normalize(glm::cross(v, n));
    bool rectangle = light.type == LightType::Rectangle;
    u *= rectangle ? 0.5f * light.width : light.radius;
    v *= rectangle ? 0.5f * light.height : light.radius;
}

void validateLight(const Light& light, const std::string& subject)
{
    // The C++ and Python APIs take any floats (JSON and the command line cannot spell NaN or infinity): a
    // light at NaN would give NaN shadow-map matrices and a walk of the whole BVH for its nearest triangle.
    auto finite = [](glm::vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); };
    if (!finite(light.position) || !finite(light.direction) || !finite(light.up) || !finite(light.color) ||
        !std::isfinite(light.intensity) || !std::isfinite(light.range) || !std::isfinite(light.innerConeDegrees) ||
        !std::isfinite(light.outerConeDegrees) || !std::isfinite(light.width) || !std::isfinite(light.height) || !std::isfinite(light.radius))
        fail(subject, "its position, direction, up, colour and numbers must be finite");
    if (glm::length(light.direction) == 0.0f && light.type != LightType::Point && light.type != LightType::Sphere)
        fail(subject, "'direction' must not be zero");
    if (light.intensity < 0.0f || light.range < 0.0f || light.width <= 0.0f || light.height <= 0.0f || light.radius <= 0.0f)
        fail(subject, "intensity and range must be >= 0, width, height and radius > 0");
    if (light.type == LightType::Spot &&
        !(light.outerConeDegrees > 0.0f && light.outerConeDegrees < 90.0f && light.innerConeDegrees <= light.outerConeDegrees))
        fail(subject, "spot cones need 0 < inner_cone <= outer_cone < 90 degrees");
}

namespace {


Light parseLight(const Json& object, const std::string& subject)
{
    if (!object.is_object())
        fail(subject, "a light must be an object");
    Light light;
    if (!object.contains("type") || !object["type"].is_string())
        fail(subject, "a light needs a \"type\" string");
    light.type = lightTypeIn(object["type"].get<std::string>(), subject);
    for (auto it = object.begin(); it != object.end(); ++it)
        if (it.key() != "type" && !setLightProperty(light, it.key(), it.value(), subject))
            fail(subject, "unknown light key " + detail::quoteToken(it.key()));
    validateLight(light, subject);
    return light;
}

Camera parseCamera(const Json& object, const std::string& subject)
{
    if (!object.is_object())
        fail(subject, "'camera' must be an object");
    rejectUnknownKeys(object, {"position", "target", "up", "projection", "fov", "ortho_height", "near", "far"}, subject);
    Camera camera;
    if (object.contains("position")) camera.position = vec3(object["position"], subject, "position");
    if (object.contains("target")) camera.target = vec3(object["target"], subject, "target");
    if (object.contains("up")) camera.up = vec3(object["up"], subject, "up");
    if (object.contains("fov")) camera.yfovDegrees = number(object["fov"], subject, "fov");
    if (object.contains("ortho_height")) camera.orthoHeight = number(object["ortho_height"], subject, "ortho_height");
    if (object.contains("near")) camera.nearPlane = number(object["near"], subject, "near");
    if (object.contains("far")) camera.farPlane = number(object["far"], subject, "far");
    if (object.contains("projection")) {
        const Json& p = object["projection"];
        if (p == "perspective") camera.projection = Projection::Perspective;
        else if (p == "orthographic") camera.projection = Projection::Orthographic;
        else fail(subject, "'projection' must be \"perspective\" or \"orthographic\"");
    }
    if (camera.position == camera.target)
        fail(subject, "camera position and target must differ");
    if (!(camera.yfovDegrees > 0.0f && camera.yfovDegrees < 180.0f) || !(camera.orthoHeight > 0.0f))
        fail(subject, "fov must be in (0, 180) and ortho_height > 0");
    return camera;
}

Json parseJsonText(std::string_view text, const std::string& subject)
{
    try {
        return Json::parse(text.begin(), text.end());
    } catch (const Json::exception& e) { // parse_error, or out_of_range for a number like 1e400
        fail(subject, std::string("invalid JSON: ") + e.what());
    }
}

} // namespace

SceneDescription loadSceneDescription(const std::string& path)
{
    std::ifstream file(path, std::ios::binary);
    if (!file)
        fail(path, "cannot open scene file");
    std::stringstream text;
    text << file.rdbuf();
    return parseSceneDescription(text.str(), path);
}

SceneDescription parseSceneDescription(std::string_view text, const std::string& path)
{
    Json root = parseJsonText(text, path);
    if (!root.is_object())
        fail(path, "the scene must be a JSON object");
    rejectUnknownKeys(root, {"model", "camera", "lights"}, path);

    SceneDescription scene;
    if (root.contains("model")) {
        if (!root["model"].is_string())
            fail(path, "'model' must be a string");
        scene.model = root["model"].get<std::string>();
        size_t slash = path.find_last_of('/');
        if (!scene.model.empty() && scene.model[0] != '/' && slash != std::string::npos)
            scene.model = path.substr(0, slash + 1) + scene.model;
    }
    if (root.contains("camera"))
        scene.camera = parseCamera(root["camera"], path);
    if (root.contains("lights")) {
        if (!root["lights"].is_array())
            fail(path, "'lights' must be an array");
        for (const Json& light : root["lights"])
            scene.lights.push_back(parseLight(light, path));
    }
    return scene;
}

Light parseLightJson(const std::string& json, const std::string& subject)
{
    return parseLight(parseJsonText(json, subject), subject);
}

Camera parseCameraJson(const std::string& json, const std::string& subject)
{
    return parseCamera(parseJsonText(json, subject), subject);
}

glm::vec3 parseVec3(const std::string& text, const std::string& what)
{
    float v[3];
    size_t start = 0;
    for (int i = 0; i < 3; ++i) {
        size_t end = text.find(',', start);
        if ((i < 2) != (end != std::string::npos))
            fail(what, "expected three comma-separated numbers, got '" + text + "'");
        std::string part = text.substr(start, i < 2 ? end - start : std::string::npos);
        char* stop = nullptr;
        v[i] = std::strtof(part.c_str(), &stop);
        if (part.empty() || *stop != '\0' || !std::isfinite(v[i]))
            fail(what, "'" + part + "' is not a number");
        start = end + 1;
    }
    return {v[0], v[1], v[2]};
}

Light parseLightSpec(const std::string& spec)
{
    std::istringstream words(spec);
    std::string type;
    words >> type;
    std::string subject = "--light '" + spec + "'";
    if (type.empty())
        fail(subject, "empty light spec");
    Light light;
    light.type = lightTypeIn(type, subject);
    std::string word;
    while (words >> word) {
        size_t eq = word.find('=');
        if (eq == std::string::npos || eq == 0)
            fail(subject, "expected key=value, got '" + word + "'");
        std::string key = word.substr(0, eq), value = word.substr(eq + 1);
        Json json;
        if (value.find(',') != std::string::npos) {
            glm::vec3 v = parseVec3(value, subject);
            json = Json::array({v.x, v.y, v.z});
        } else {
            char* stop = nullptr;
            double number = std::strtod(value.c_str(), &stop);
            if (value.empty() || *stop != '\0')
                fail(subject, "'" + value + "' is not a number");
            json = number;
        }
        if (!setLightProperty(light, key, json, subject))
            fail(subject, "unknown light key '" + key + "'");
    }
    validateLight(light, subject);
    return light;
}

} // namespace penumbra
