#include "penumbra/mesh.h"

#include <glm/common.hpp>

#include "io_internal.h"
#include "penumbra/error.h"

namespace penumbra {

Bounds computeBounds(const Mesh& mesh)
{
    Bounds bounds;
    for (size_t i = 0; i < mesh.vertexCount(); ++i) {
        glm::vec3 p = mesh.position(i);
        bounds.min = glm::min(bounds.min, p);
        bounds.max = glm::max(bounds.max, p);
    }
    return bounds;
}

glm::vec3 Mesh::triangleColor(size_t triangle) const
{
    glm::vec3 color(1.0f);
    if (!materials.empty())
        color = glm::vec3(materials[triangleMaterials.empty() ? 0 : triangleMaterials[triangle]].baseColor);
    if (!colors.empty()) {
        glm::vec3 sum(0.0f);
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = indices[triangle * 3 + k];
            sum += glm::vec3(colors[v * 3], colors[v * 3 + 1], colors[v * 3 + 2]);
        }
        color *= sum / 3.0f;
    }
    return color;
}

const char* lightTypeName(LightType type)
{
    switch (type) {
    case LightType::Point: return "point";
    case LightType::Spot: return "spot";
    case LightType::Directional: return "directional";
    case LightType::Rectangle: return "rectangle";
    case LightType::Disk: return "disk";
    case LightType::Sphere: return "sphere";
    }
    return "unknown";
}

LightType parseLightType(const std::string& name)
{
    for (LightType type : {LightType::Point, LightType::Spot, LightType::Directional, LightType::Rectangle,
                           LightType::Disk, LightType::Sphere})
        if (name == lightTypeName(type))
            return type;
    fail("light type " + detail::quoteToken(name), "unknown (expected point, spot, directional, rectangle, disk or sphere)");
}

} // namespace penumbra
