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
