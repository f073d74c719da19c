// Renders a small generated city with hard ray-traced shadows to a PNG.
#include <penumbra/generate.h>
#include <penumbra/penumbra.h>

int main(int argc, char** argv)
{
    penumbra::Scene city = penumbra::generateScene("city", {.triangles = 20'000});
    penumbra::Renderer renderer;                 // picks a GPU, else lavapipe
    renderer.loadModel(city.mesh);
    renderer.setCamera(city.cameras.at(0));
    renderer.setLights(city.lights);
    penumbra::RenderSettings settings{.width = 320, .height = 240, .shadows = penumbra::ShadowMethod::Selective};
    penumbra::writeImage(renderer.render(settings).color, argc > 1 ? argv[1] : "city.png");
    return renderer.validationMessageCount() == 0 ? 0 : 1;
}
