// In-memory triangle mesh and scene description shared by importers, generators and the runtime.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

namespace penumbra {

// A surface's material: its base colour (glTF baseColorFactor, OBJ mtl Kd,
// a PLY face colour). Textures are not read.
struct Material {
    glm::vec4 baseColor{1.0f}; // linear RGBA, each in [0, 1]
    std::string name;
};

// Indexed triangle list. positions holds xyz triples; indices holds three
// vertex indices per triangle, each < vertexCount(). Colours are optional:
// a triangle's albedo is its material's baseColor (white without materials)
// times the mean of its three vertex colours (1 without vertex colours).
struct Mesh {
    std::vector<float> positions;   // 3 floats per vertex, model units
    std::vector<uint32_t> indices;  // 3 per triangle, counter-clockwise front faces
    std::vector<float> colors;      // empty, or 3 floats per vertex: linear RGB in [0, 1]
    std::vector<Material> materials;          // empty, or the materials triangleMaterials names
    std::vector<uint32_t> triangleMaterials;  // empty (every triangle material 0), or one per triangle

    size_t vertexCount() const { return positions.size() / 3; }
    size_t triangleCount() const { return indices.size() / 3; }
    glm::vec3 position(size_t vertex) const
    {
        return {positions[vertex * 3 + 0], positions[vertex * 3 + 1], positions[vertex * 3 + 2]};
    }
    bool hasColors() const { return !colors.empty() || !materials.empty(); }
    // Linear RGB albedo of a triangle (see above).
    glm::vec3 triangleColor(size_t triangle) const;
};

struct Bounds {
    glm::vec3 min{1e30f};
    glm::vec3 max{-1e30f};
    bool empty() const { return min.x > max.x; }
    glm::vec3 center() const { return (min + max) * 0.5f; }
    glm::vec3 extent() const { return max - min; }
};

// Axis-aligned bounds of all vertices referenced or not.
Bounds computeBounds(const Mesh& mesh);

enum class Projection { Perspective, Orthographic };

// Pinhole (or orthographic) camera. The aspect ratio comes from the image.
struct Camera {
    glm::vec3 position{0.0f, 0.0f, 5.0f};
    glm::vec3 target{0.0f};
    glm::vec3 up{0.0f, 1.0f, 0.0f};
    Projection projection = Projection::Perspective;
    float yfovDegrees = 45.0f;     // perspective: vertical field of view
    float orthoHeight = 2.0f;      // orthographic: visible height in model units
    float nearPlane = 0.0f;        // 0: derived from the scene bounds
    float farPlane = 0.0f;         // 0: derived from the scene bounds
};

enum class LightType { Point, Spot, Directional, Rectangle, Disk, Sphere };

// Returns "point", "spot", ... ; parseLightType throws Error on unknown names.
const char* lightTypeName(LightType type);
LightType parseLightType(const std::string& name);

// A light source. Point-like lights use position; directional uses direction
// (the direction light travels). Area lights are centred at position, face
// along direction, and have a size: rectangle width x height (with up giving
// the height axis), disk and sphere radius.
struct Light {
    LightType type = LightType::Directional;
    glm::vec3 position{0.0f, 10.0f, 0.0f};
    glm::vec3 direction{0.0f, -1.0f, 0.0f};
    glm::vec3 up{0.0f, 0.0f, 1.0f};
    glm::vec3 color{1.0f};
    float intensity = 1.0f;
    float range = 0.0f;                 // 0: infinite
    float innerConeDegrees = 20.0f;     // spot
    float outerConeDegrees = 30.0f;     // spot: half angle of the cone
    float width = 1.0f;                 // rectangle
    float height = 1.0f;                // rectangle
    float radius = 0.5f;                // disk, sphere
};

// A model plus the cameras and lights that came with it (glTF) or that a
// generator suggests. Either list may be empty.
struct Scene {
    Mesh mesh;
    std::vector<Camera> cameras;
    std::vector<Light> lights;
};

} // namespace penumbra
