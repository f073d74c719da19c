// libFuzzer target for the JSON scene description reader (parseSceneDescription).
// Bad input must throw penumbra::Error whose message is one line naming the file;
// accepted lights must pass validateLight.
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "penumbra/error.h"
#include "penumbra/scene_file.h"

namespace {

void check(bool condition)
{
    if (!condition)
        std::abort();
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    const std::string name = "/nonexistent-penumbra-fuzz/scene.json";
    try {
        penumbra::SceneDescription scene =
            penumbra::parseSceneDescription({reinterpret_cast<const char*>(data), size}, name);
        for (const penumbra::Light& light : scene.lights)
            penumbra::validateLight(light, "accepted light");
    } catch (const penumbra::Error& e) {
        const std::string message = e.what();
        check(message.rfind(name + ": ", 0) == 0);
        check(message.find('\n') == std::string::npos && message.find('\r') == std::string::npos);
    }
    return 0;
}
