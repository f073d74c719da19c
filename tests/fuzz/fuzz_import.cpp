// libFuzzer target for one model importer, fed from memory (importSceneMemory).
// The format is fixed at build time by PENUMBRA_FUZZ_FORMAT: "obj", "ply"
// (ASCII and binary), "stl" (ASCII and binary), "gltf" (an input starting with
// the GLB magic is read as .glb, anything else as .gltf; Draco primitives
// included) or "drc".
// Bad input must throw penumbra::Error whose message is one line starting with
// the input's name; an accepted scene must keep the importer's promises (at
// least one triangle, every index in range, finite positions), which are
// checked by reading all of it so AddressSanitizer sees any bad access.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>

#include "penumbra/error.h"
#include "penumbra/io.h"

#ifndef PENUMBRA_FUZZ_FORMAT
#error "define PENUMBRA_FUZZ_FORMAT"
#endif

namespace {

// A directory that does not exist, so glTF external buffer URIs never resolve
// to real files (path resolution stops at the missing component).
const std::string kDirectory = "/nonexistent-penumbra-fuzz/";

void check(bool condition)
{
    if (!condition)
        std::abort();
}

std::string inputName(const uint8_t* data, size_t size)
{
    std::string extension = PENUMBRA_FUZZ_FORMAT;
    if (extension == "gltf" && size >= 4 && std::memcmp(data, "glTF", 4) == 0)
        extension = "glb";
    return kDirectory + "input." + extension;
}

void ignoreWarning(const std::string&) {}

} // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***)
{
    penumbra::setWarningSink(ignoreWarning);
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    const std::string name = inputName(data, size);
    try {
        penumbra::Scene scene = penumbra::importSceneMemory({data, size}, name);
        const penumbra::Mesh& mesh = scene.mesh;
        check(mesh.triangleCount() > 0 && mesh.indices.size() % 3 == 0 && mesh.positions.size() % 3 == 0);
        for (uint32_t index : mesh.indices)
            check(index < mesh.vertexCount());
        for (float value : mesh.positions)
            check(std::isfinite(value));
    } catch (const penumbra::Error& e) {
        const std::string message = e.what();
        check(message.rfind(name + ": ", 0) == 0);
        check(message.find('\n') == std::string::npos && message.find('\r') == std::string::npos);
    }
    return 0;
}
