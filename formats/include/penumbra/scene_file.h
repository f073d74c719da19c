// Scene description files (JSON) and command-line light/camera specs.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "penumbra/mesh.h"

namespace penumbra {

struct SceneDescription {
    std::string model;                 // model path, relative to the JSON file; may be empty
    std::optional<Camera> camera;
    std::vector<Light> lights;
};

// Reads a JSON scene description:
// { "model": "city.glb",
//   "camera": {"position": [x,y,z], "target": [x,y,z], "up": [0,1,0],
//              "projection": "perspective"|"orthographic", "fov": 45, "ortho_height": 10,
//              "near": 0.1, "far": 1000},
//   "lights": [{"type": "directional"|"point"|"spot"|"rectangle"|"disk"|"sphere",
//               "position": [..], "direction": [..], "up": [..], "color": [r,g,b],
//               "intensity": 1, "range": 0, "inner_cone": 20, "outer_cone": 30,
//               "width": 1, "height": 1, "radius": 0.5}] }
// Every key is optional. Throws Error("<path>: <problem>") on bad JSON, unknown
// keys or types, or wrong value shapes.
SceneDescription loadSceneDescription(const std::string& path);

// One light or the camera as JSON object text with the keys above (the Python
// module's dicts). Throws Error("<subject>: <problem>") as loadSceneDescription does.
Light parseLightJson(const std::string& json, const std::string& subject);
Camera parseCameraJson(const std::string& json, const std::string& subject);
// loadSceneDescription on JSON text in memory; path names it in messages and
// anchors the relative model path.
SceneDescription parseSceneDescription(std::string_view text, const std::string& path);

// Parses a light from "TYPE key=value ...", e.g.
// "spot position=0,5,0 direction=0,-1,0 outer_cone=30 intensity=50".
// Keys as in the JSON file; vectors comma-separated. Throws Error naming the spec.
Light parseLightSpec(const std::string& spec);

// Checks a light's values (non-zero direction where one is needed, positive
// sizes, spot cones within 0..90 degrees). Throws Error("<subject>: <problem>").
void validateLight(const Light& light, const std::string& subject);

// Area lights (rectangle, disk, sphere): true for those types.
bool isAreaLight(const Light& light);

// Half-extent vectors of an area light as penumbra/light_sampling.h takes
// them. Rectangle and disk face along direction; V is the part of up across
// that direction (height axis), U = V x direction (width axis). Rectangle:
// |U| = width / 2, |V| = height / 2; disk: both the radius; sphere:
// U = (radius, 0, 0), V = 0. Point-like lights: both zero.
void areaLightAxes(const Light& light, glm::vec3& u, glm::vec3& v);

// Parses "x,y,z". Throws Error naming what.
glm::vec3 parseVec3(const std::string& text, const std::string& what);

} // namespace penumbra
