// Images a person wants to look at (issue 21, parts 3, 5, 7): exposure and
// the filmic curve of 8-bit outputs, the ground plane, the default sun, the
// sm | srt | pip comparison strip and the EXR layers. The plain path
// (--exposure 1 --tonemap none --ground off, explicit lights) must write
// exactly the bytes the linear frame always gave.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <string>

#include <OpenImageIO/imageio.h>
#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include "cli_run.h"
#include "penumbra/penumbra.h"
#include "png_writer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

std::string tmp(const std::string& name)
{
    return test::scratchPath("image_", name);
}

using test::runCli;

struct ReadImage {
    int width = 0, height = 0;
    std::vector<std::string> channels;
    std::vector<OIIO::TypeDesc> formats;
    std::vector<float> values; // interleaved, as float
    std::vector<uint8_t> bytes; // 8-bit files: the stored bytes
};

ReadImage readImage(const std::string& path)
{
    ReadImage image;
    auto in = OIIO::ImageInput::open(path);
    EXPECT_TRUE(in) << path;
    if (!in)
        return image;
    const OIIO::ImageSpec& spec = in->spec();
    image.width = spec.width;
    image.height = spec.height;
    image.channels = spec.channelnames;
    for (int c = 0; c < spec.nchannels; ++c)
        image.formats.push_back(spec.channelformat(c));
    image.values.resize(size_t(spec.width) * spec.height * spec.nchannels);
    EXPECT_TRUE(in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, image.values.data()));
    if (spec.format == OIIO::TypeDesc::UINT8) {
        image.bytes.resize(image.values.size());
        EXPECT_TRUE(in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::UINT8, image.bytes.data()));
    }
    return image;
}

// What writeImage wrote for PNGs before exposure and tone curves existed.
std::vector<uint8_t> legacyPngBytes(const Image& image)
{
    std::vector<uint8_t> bytes(image.rgba.size());
    for (size_t i = 0; i < image.rgba.size(); ++i) {
        float v = std::fmin(std::fmax(image.rgba[i], 0.0f), 1.0f);
        if (i % 4 != 3)
            v = v <= 0.0031308f ? v * 12.92f : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
        bytes[i] = uint8_t(std::lround(v * 255.0f));
    }
    return bytes;
}

// The built-in writer of builds without OpenImageIO (PENUMBRA_WITH_OPENIMAGEIO=OFF):
// OpenImageIO reads its files back byte for byte, with rows longer than one
// stored deflate block (65,535 bytes) and odd sizes; a path it cannot create
// is reported. OpenImageIO premultiplies a PNG's colours by its alpha when it
// reads them, so the colours are compared where the alpha is opaque (every
// pixel of the first pass) and the alpha everywhere.
TEST(ImageOutput, BuiltInPngWriterRoundTrips)
{
    for (bool opaque : {true, false})
        for (const auto& [width, height] : {std::pair<uint32_t, uint32_t>{1, 1}, {3, 2}, {16411, 3}, {257, 129}}) {
            std::vector<uint8_t> rgba(size_t(width) * height * 4);
            for (size_t i = 0; i < rgba.size(); ++i)
                rgba[i] = opaque && i % 4 == 3 ? 255 : uint8_t((i * 2654435761u) >> 13);
            const std::string path = tmp("builtin_" + std::to_string(width) + "x" + std::to_string(height) + ".png");
            ASSERT_TRUE(writePngRgba8(path, width, height, rgba.data())) << path;
            ReadImage read = readImage(path);
            EXPECT_EQ(read.width, int(width));
            EXPECT_EQ(read.height, int(height));
            ASSERT_EQ(read.bytes.size(), rgba.size()) << path;
            size_t differing = 0;
            for (size_t i = 0; i < rgba.size(); ++i)
                differing += (opaque || i % 4 == 3) && read.bytes[i] != rgba[i] ? 1 : 0;
            EXPECT_EQ(differing, 0u) << path << (opaque ? " (opaque)" : " (alpha)");
        }
    const uint8_t pixel[4] = {1, 2, 3, 4};
    EXPECT_FALSE(writePngRgba8(tmp("no_such_folder/x.png"), 1, 1, pixel));
}

TEST(ImageOutput, FilmicCurveAndAutomaticExposure)
{
    EXPECT_EQ(applyToneMap(0.0f, ToneMap::Filmic), 0.0f);
    EXPECT_NEAR(applyToneMap(1.0f, ToneMap::Filmic), 0.80f, 0.01f); // Narkowicz: 2.54 / 3.16
    EXPECT_LT(applyToneMap(100.0f, ToneMap::Filmic), 1.0f + 1e-6f);
    EXPECT_GT(applyToneMap(100.0f, ToneMap::Filmic), 0.99f);
    float last = 0.0f;
    for (float x = 0.01f; x < 8.0f; x *= 1.3f) { // increasing (it reaches 1 near x = 11)
        EXPECT_GT(applyToneMap(x, ToneMap::Filmic), last) << x;
        last = applyToneMap(x, ToneMap::Filmic);
    }
    EXPECT_EQ(applyToneMap(1.7f, ToneMap::None), 1.0f);
    EXPECT_EQ(applyToneMap(0.3f, ToneMap::None), 0.3f);
    EXPECT_EQ(parseToneMap("filmic"), ToneMap::Filmic);
    EXPECT_THROW(parseToneMap("reinhard"), Error);

    // 100 background pixels, then covered pixels of luminance 0.01 .. 1.00:
    // the 95th percentile of the covered ones (0.95) lands on 0.8 after the curve.
    const float background[3] = {0.06f, 0.07f, 0.09f};
    Image image;
    image.width = 200;
    image.height = 1;
    for (int i = 0; i < 100; ++i)
        image.rgba.insert(image.rgba.end(), {background[0], background[1], background[2], 1.0f});
    for (int i = 1; i <= 100; ++i)
        image.rgba.insert(image.rgba.end(), {0.01f * i, 0.01f * i, 0.01f * i, 1.0f});
    for (ToneMap curve : {ToneMap::Filmic, ToneMap::None}) {
        float exposure = autoExposure(image, curve, background);
        EXPECT_NEAR(applyToneMap(0.95f * exposure, curve), 0.8f, 2e-3f) << toneMapName(curve);
    }
    Image empty = image;
    empty.rgba.resize(400);
    empty.width = 100;
    EXPECT_EQ(autoExposure(empty, ToneMap::Filmic, background), 1.0f);
}

TEST(ImageOutput, GroundRuleAndGeometry)
{
    Bounds statue{{-1, 0, -1}, {1, 3, 1}};
    auto box = [](glm::vec3 lo, glm::vec3 hi) {
        Mesh mesh;
        test::addBox(mesh, lo, hi);
        return mesh;
    };
    EXPECT_TRUE(wantsGround(box(statue.min, statue.max)));    // a single object
    EXPECT_TRUE(wantsGround(box({0, 0, 0}, {4, 1.2f, 3})));   // a flat part, still an object
    EXPECT_FALSE(wantsGround(box({-50, 0, -50}, {50, 8, 50}))); // wide and flat: a scene
    Mesh onPlate = box({-0.5f, 0.01f, -0.5f}, {0.5f, 2.0f, 0.5f});
    test::addQuad(onPlate, {-3, 0, -3}, {-3, 0, 3}, {3, 0, 3}, {3, 0, -3});
    EXPECT_FALSE(wantsGround(onPlate));                        // stands on its own floor
    EXPECT_FALSE(wantsGround(Mesh{}));
    EXPECT_LT(groundHeight(statue), 0.0f);
    EXPECT_GT(groundHeight(statue), -0.02f);

    Mesh mesh;
    test::addBox(mesh, statue.min, statue.max);
    size_t before = mesh.triangleCount();
    addGround(mesh, statue, -0.5f);
    ASSERT_EQ(mesh.triangleCount(), before + 128);
    Bounds all = computeBounds(mesh);
    EXPECT_EQ(all.min.y, -0.5f);
    EXPECT_LE(all.min.x, statue.min.x - 3.0f * 3.0f); // reaches a low sun's shadow
    EXPECT_GE(all.max.z, statue.max.z + 3.0f * 3.0f);
    for (size_t t = before; t < mesh.triangleCount(); ++t) { // every ground triangle faces up
        glm::vec3 a = mesh.position(mesh.indices[t * 3]), b = mesh.position(mesh.indices[t * 3 + 1]),
                  c = mesh.position(mesh.indices[t * 3 + 2]);
        EXPECT_GT(glm::cross(b - a, c - a).y, 0.0f) << t;
    }
}

// The default sun, seen from the default camera, casts a shadow of a box onto
// the automatic ground that the camera sees.
TEST(ImageOutput, DefaultSunShowsTheCastShadowOnTheGround)
{
    Mesh mesh;
    test::addBox(mesh, {-0.5f, 0.0f, -0.5f}, {0.5f, 1.5f, 0.5f});
    Bounds bounds = computeBounds(mesh);
    ASSERT_TRUE(wantsGround(mesh));
    addGround(mesh, bounds, groundHeight(bounds));
    Renderer renderer;
    renderer.loadModel(mesh);
    Camera camera = defaultCamera(bounds);
    renderer.setCamera(camera);
    RenderSettings settings;
    settings.width = settings.height = 128;
    settings.readbackGBuffer = true;
    Frame frame = renderer.render(settings);
    size_t groundShadowed = 0, groundLit = 0;
    for (size_t i = 0; i < frame.visibility.size(); ++i) {
        bool ground = frame.positions[i * 4 + 3] != 0.0f && frame.positions[i * 4 + 1] < 0.0f;
        if (ground && frame.visibility[i] == 0.0f)
            ++groundShadowed;
        if (ground && frame.visibility[i] == 1.0f)
            ++groundLit;
    }
    EXPECT_GT(groundShadowed, 200u); // a shadow the size of the box's side, in view
    EXPECT_GT(groundLit, groundShadowed);
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
}

// --exposure 1 --tonemap none --ground off --colors off with an explicit light:
// the CLI's PNG holds exactly the old encoding of the renderer's linear frame.
TEST(ImageOutput, PlainPathIsBitIdentical)
{
    std::string model = tmp("scan.ply"), image = tmp("plain.png");
    ASSERT_EQ(runCli("generate scan --triangles 20000 -o " + model), 0);
    const std::string light = "directional direction=-0.45,-1,-0.3 intensity=2.5";
    std::string output;
    ASSERT_EQ(runCli("render " + model + " -o " + image + " --size 96x80 --shadows srt --exposure 1 --tonemap none --ground off --colors off " +
                         "--camera-position 3,2,4 --camera-target 0,0.5,0 --light '" + light + "'",
                     &output),
              0)
        << output;

    Renderer renderer;
    renderer.loadModel(importScene(model).mesh);
    Camera camera;
    camera.position = {3, 2, 4};
    camera.target = {0, 0.5f, 0};
    renderer.setCamera(camera);
    renderer.setLights({parseLightSpec(light)});
    RenderSettings settings;
    settings.width = 96;
    settings.height = 80;
    settings.shadows = ShadowMethod::Selective;
    Frame frame = renderer.render(settings);

    ReadImage written = readImage(image);
    ASSERT_EQ(written.width, 96);
    ASSERT_EQ(written.height, 80);
    std::vector<uint8_t> expected = legacyPngBytes(frame.color);
    ASSERT_EQ(written.bytes.size(), expected.size());
    size_t differing = 0;
    for (size_t i = 0; i < expected.size(); ++i)
        differing += written.bytes[i] != expected[i];
    EXPECT_EQ(differing, 0u);

    // The API's plain writeImage too; the filmic default differs.
    std::string api = tmp("plain_api.png"), filmic = tmp("filmic_api.png");
    writeImage(frame.color, api);
    EXPECT_EQ(readImage(api).bytes, expected);
    ImageOptions options;
    options.tonemap = ToneMap::Filmic;
    options.exposure = autoExposure(frame.color, options.tonemap, settings.background);
    writeImage(frame.color, filmic, options);
    EXPECT_NE(readImage(filmic).bytes, expected);
}

// A .penumbra model is drawn as stored under --ground auto; --ground below
// decodes it and adds the ground's 128 triangles.
TEST(ImageOutput, GroundUnderAPreprocessedModel)
{
    std::string source = tmp("ground_part.obj"), model = tmp("ground_part.penumbra"), output;
    Mesh part;
    test::addBox(part, {0, 0, 0}, {1, 2, 1});
    exportScene(Scene{part, {}, {}}, source);
    ASSERT_EQ(runCli("preprocess " + source + " -o " + model + " --quiet", &output), 0) << output;
    ASSERT_EQ(runCli("render " + model + " -o " + tmp("ground_part.png") + " --size 32 --validation", &output), 0) << output;
    EXPECT_NE(output.find("triangles 12 |"), std::string::npos) << output;
    ASSERT_EQ(runCli("render " + model + " -o " + tmp("ground_part.png") + " --size 32 --validation --ground below", &output), 0)
        << output;
    EXPECT_NE(output.find("triangles 140 |"), std::string::npos) << output;
    ASSERT_EQ(runCli("render " + source + " -o " + tmp("ground_part.png") + " --size 32 --validation", &output), 0) << output;
    EXPECT_NE(output.find("triangles 140 |"), std::string::npos) << output; // auto: a single object
}

// An .exr with --exr-layers carries light 0's visibility, the PIP mask and the
// depth as named float channels; --compare writes sm | srt | pip.
TEST(ImageOutput, ExrLayersAndCompareStrip)
{
    std::string model = tmp("scan_layers.ply"), exr = tmp("layers.exr"), strip = tmp("compare.png");
    ASSERT_EQ(runCli("generate scan --triangles 20000 -o " + model), 0);
    std::string output;
    ASSERT_EQ(runCli("render " + model + " -o " + exr + " --size 64 --shadows srt --exr-layers --validation --compare " + strip,
                     &output),
              0)
        << output;
    EXPECT_NE(output.find("compare: sm | srt | pip"), std::string::npos) << output;

    // OpenEXR keeps channels in name order: find them by name.
    ReadImage layers = readImage(exr);
    ASSERT_EQ(layers.channels.size(), 7u);
    auto channel = [&](const std::string& name) {
        size_t c = size_t(std::find(layers.channels.begin(), layers.channels.end(), name) - layers.channels.begin());
        EXPECT_LT(c, layers.channels.size()) << name;
        return c;
    };
    for (const char* name : {"R", "G", "B", "A"})
        EXPECT_EQ(layers.formats[channel(name)], OIIO::TypeDesc::HALF) << name;
    const size_t v = channel("visibility.light0"), m = channel("pip"), d = channel("Z");
    for (size_t c : {v, m, d})
        ASSERT_EQ(layers.formats[c], OIIO::TypeDesc::FLOAT) << layers.channels[c];
    size_t covered = 0, shadowed = 0, traced = 0;
    for (size_t p = 0; p < size_t(layers.width) * layers.height; ++p) {
        float visibility = layers.values[p * 7 + v], pip = layers.values[p * 7 + m], z = layers.values[p * 7 + d];
        EXPECT_TRUE(pip == 0.0f || pip == 1.0f) << p;
        if (visibility == -1.0f) {
            EXPECT_TRUE(std::isinf(z)) << p;
            EXPECT_EQ(pip, 0.0f) << p;
            continue;
        }
        EXPECT_GE(visibility, 0.0f);
        EXPECT_LE(visibility, 1.0f);
        EXPECT_TRUE(std::isfinite(z) && z > 0.0f) << p << " " << z;
        ++covered;
        shadowed += visibility == 0.0f;
        traced += pip == 1.0f;
    }
    EXPECT_GT(covered, 1000u);
    EXPECT_GT(shadowed, 20u);
    EXPECT_GT(traced, 10u);
    EXPECT_LT(traced, covered / 2);

    // The shadow map alone gives no pixel rays.
    ASSERT_EQ(runCli("render " + model + " -o " + exr + " --size 64 --shadows sm --exr-layers", &output), 0) << output;
    ReadImage smLayers = readImage(exr);
    ASSERT_EQ(smLayers.channels, layers.channels);
    for (size_t p = 0; p < size_t(smLayers.width) * smLayers.height; ++p)
        ASSERT_EQ(smLayers.values[p * 7 + m], 0.0f) << p;

    ReadImage compare = readImage(strip);
    EXPECT_EQ(compare.width, 3 * 64);
    EXPECT_EQ(compare.height, 64);

    EXPECT_NE(runCli("render " + model + " -o " + tmp("layers.png") + " --exr-layers --size 16", &output), 0);
    EXPECT_NE(output.find(".exr"), std::string::npos) << output;
    EXPECT_NE(runCli("render " + model + " -o " + tmp("x.png") + " --ground sideways --size 16", &output), 0);
    EXPECT_NE(output.find("--ground"), std::string::npos) << output;
    EXPECT_NE(runCli("render " + model + " -o " + tmp("x.png") + " --exposure -2 --size 16", &output), 0);
    EXPECT_NE(output.find("--exposure"), std::string::npos) << output;
}

} // namespace
} // namespace penumbra
