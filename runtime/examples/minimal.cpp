// Minimal use of the Penumbra C++ API: load a model, set camera and light,
// render with shadow mapping, save the image and print per-pass timings.
//   example_minimal MODEL OUTPUT.png
#include <cstdio>

#include "penumbra/penumbra.h"

int main(int argc, char** argv)
{
    if (argc != 3) {
        std::fprintf(stderr, "usage: example_minimal MODEL OUTPUT.png\n");
        return 2;
    }
    try {
        penumbra::Scene scene = penumbra::importScene(argv[1]);

        penumbra::Renderer renderer;                 // picks a GPU, else lavapipe
        renderer.loadModel(scene.mesh);

        penumbra::Camera camera = penumbra::defaultCamera(penumbra::computeBounds(scene.mesh));
        renderer.setCamera(camera);

        penumbra::Light sun;
        sun.type = penumbra::LightType::Directional;
        sun.direction = {-0.4f, -1.0f, -0.2f};
        sun.intensity = 1.0f;
        renderer.setLights({sun});

        penumbra::RenderSettings settings;
        settings.width = settings.height = 1024;
        settings.shadows = penumbra::ShadowMethod::ShadowMap;
        penumbra::Frame frame = renderer.render(settings);

        penumbra::writeImage(frame.color, argv[2]);
        for (const penumbra::PassTiming& pass : frame.stats.passes)
            std::printf("%-10s %8.2f ms\n", pass.name.c_str(), pass.gpuMs);
    } catch (const penumbra::Error& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        return 1;
    }
    return 0;
}
