// Helpers shared by the formats tests: temp paths, file writing, small meshes.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstring>

#include <fstream>
#include <functional>
#include <glm/geometric.hpp>
#include <string>
#include <vector>

#include "penumbra/error.h"
#include "penumbra/mesh.h"

namespace penumbra::test {

inline std::string tempPath(const std::string& name)
{
    return std::string(PENUMBRA_TEST_TMP) + "/" + name;
}

inline std::string writeFile(const std::string& name, const std::string& bytes)
{
    std::string path = tempPath(name);
    std::ofstream file(path, std::ios::binary | std::ios::trunc);
    file.write(bytes.data(), std::streamsize(bytes.size()));
    return path;
}

inline std::string readFile(const std::string& path)
{
    std::ifstream file(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>());
}

template <typename T> void append(std::string& bytes, T value)
{
    bytes.append(reinterpret_cast<const char*>(&value), sizeof(T));
}

// n x n quads in the xz plane spanning [0, n] (2 n^2 triangles), with a little height.
inline Mesh makeGrid(int n)
{
    Mesh mesh;
    for (int z = 0; z <= n; ++z)
        for (int x = 0; x <= n; ++x) {
            mesh.positions.push_back(float(x));
            mesh.positions.push_back(0.25f * float((x * 7 + z * 3) % 5));
            mesh.positions.push_back(float(z));
        }
    auto at = [n](int x, int z) { return uint32_t(z * (n + 1) + x); };
    for (int z = 0; z < n; ++z)
        for (int x = 0; x < n; ++x) {
            mesh.indices.insert(mesh.indices.end(), {at(x, z), at(x, z + 1), at(x + 1, z)});
            mesh.indices.insert(mesh.indices.end(), {at(x + 1, z), at(x, z + 1), at(x + 1, z + 1)});
        }
    return mesh;
}

// Runs fn, expects penumbra::Error whose message contains every fragment.
inline void expectError(const std::function<void()>& fn, const std::vector<std::string>& fragments)
{
    try {
        fn();
        ADD_FAILURE() << "expected penumbra::Error containing '" << (fragments.empty() ? "" : fragments[0]) << "'";
    } catch (const Error& e) {
        std::string message = e.what();
        for (const std::string& fragment : fragments)
            EXPECT_NE(message.find(fragment), std::string::npos) << "message: " << message << "\nmissing: " << fragment;
        EXPECT_EQ(message.find('\n'), std::string::npos) << "message is not one line: " << message;
    } catch (const std::exception& e) {
        ADD_FAILURE() << "expected penumbra::Error, got std::exception: " << e.what();
    }
}

// Triangle corner positions of a mesh, each triangle rotated so its smallest
// corner comes first and the list sorted: equal for meshes with the same
// triangles regardless of vertex or triangle order.
inline std::vector<std::array<float, 9>> canonicalTriangles(const Mesh& mesh)
{
    std::vector<std::array<float, 9>> out;
    for (size_t t = 0; t < mesh.triangleCount(); ++t) {
        std::array<std::array<float, 3>, 3> c;
        for (int k = 0; k < 3; ++k)
            for (int a = 0; a < 3; ++a)
                c[size_t(k)][size_t(a)] = mesh.positions[size_t(mesh.indices[t * 3 + size_t(k)]) * 3 + size_t(a)];
        size_t first = 0;
        for (size_t k = 1; k < 3; ++k)
            if (c[k] < c[first])
                first = k;
        std::array<float, 9> tri;
        for (size_t k = 0; k < 3; ++k)
            for (size_t a = 0; a < 3; ++a)
                tri[k * 3 + a] = c[(first + k) % 3][a];
        out.push_back(tri);
    }
    std::sort(out.begin(), out.end());
    return out;
}

// Builds a GLB from JSON text and a binary payload (no BIN chunk when bin is empty).
inline std::string makeGlb(std::string jsonText, std::string bin)
{
    while (jsonText.size() % 4)
        jsonText += ' ';
    while (bin.size() % 4)
        bin += '\0';
    std::string out;
    append(out, uint32_t(0x46546C67));
    append(out, uint32_t(2));
    append(out, uint32_t(12 + 8 + jsonText.size() + (bin.empty() ? 0 : 8 + bin.size())));
    append(out, uint32_t(jsonText.size()));
    append(out, uint32_t(0x4E4F534A));
    out += jsonText;
    if (!bin.empty()) {
        append(out, uint32_t(bin.size()));
        append(out, uint32_t(0x004E4942));
        out += bin;
    }
    return out;
}

} // namespace penumbra::test
