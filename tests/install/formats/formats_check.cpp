// Built against Penumbra::formats alone (no Vulkan), with CMake and with
// `pkg-config --cflags --libs penumbra-formats`:
// writes a triangle to a PLY file and reads it back.
#include <cstdio>

#include <penumbra/io.h>

int main(int, char** argv)
{
    penumbra::Scene scene;
    scene.mesh.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    scene.mesh.indices = {0, 1, 2};
    penumbra::exportScene(scene, argv[1]);
    size_t triangles = penumbra::importScene(argv[1]).mesh.triangleCount();
    std::printf("%s: %zu triangle(s)\n", argv[1], triangles);
    return triangles == 1 ? 0 : 1;
}
