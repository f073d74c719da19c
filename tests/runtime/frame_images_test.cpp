// The frame's images stay the same when its code moves (issue 15: the frame
// as passes). A fixed set of cases (hard sm/srt/frt on city and the scan, a
// point light among the interior's geometry, a spot light beside a sun, soft
// shadows from a rectangle light with every method, the PIP debug image) is
// rendered and compared with the images recorded in tests/runtime/data/frames:
// colour (RGBA) and light 0's visibility, as 32-bit floats.
//
// On the device the images were recorded on, they must match bit for bit. On
// another device (a GPU, another LLVM) rasterization and floating point may
// round differently, so there the visibility may differ on at most 0.5% of the
// covered pixels: a regression in a pass still shows, rounding does not.
//
// Record again (only after an intended change of the images, and say why in
// the commit): PENUMBRA_UPDATE_FRAMES=1 build/runtime_tests --gtest_filter='FrameImages*'
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>

#include <OpenImageIO/imageio.h>
#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include "penumbra/generate.h"
#include "penumbra/penumbra.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

constexpr uint32_t kSize = 256;
constexpr int kChannels = 5; // R, G, B, A, visibility of light 0

std::string framePath(const std::string& name)
{
    return std::string(PENUMBRA_SOURCE_DIR) + "/tests/runtime/data/frames/" + name + ".exr";
}

struct Recorded {
    std::string device;
    std::vector<float> pixels; // kChannels per pixel
};

bool readRecorded(const std::string& path, Recorded& recorded)
{
    auto in = OIIO::ImageInput::open(path);
    if (!in)
        return false;
    const OIIO::ImageSpec& spec = in->spec();
    if (spec.width != int(kSize) || spec.height != int(kSize) || spec.nchannels != kChannels)
        return false;
    recorded.device = spec.get_string_attribute("penumbra:device");
    recorded.pixels.resize(size_t(kSize) * kSize * kChannels);
    bool ok = in->read_image(0, 0, 0, kChannels, OIIO::TypeDesc::FLOAT, recorded.pixels.data());
    in->close();
    return ok;
}

void writeRecorded(const std::string& path, const std::string& device, const std::vector<float>& pixels)
{
    std::filesystem::create_directories(std::filesystem::path(path).parent_path());
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out);
    OIIO::ImageSpec spec{int(kSize), int(kSize), kChannels, OIIO::TypeDesc::FLOAT};
    spec.channelnames = {"R", "G", "B", "A", "visibility"};
    spec.attribute("compression", "zip");
    spec.attribute("penumbra:device", device);
    ASSERT_TRUE(out->open(path, spec));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, pixels.data()));
    ASSERT_TRUE(out->close());
}

// Colour and light 0's visibility, interleaved as in the recorded files.
std::vector<float> framePixels(const Frame& frame)
{
    const size_t pixels = size_t(kSize) * kSize;
    std::vector<float> out(pixels * kChannels);
    for (size_t i = 0; i < pixels; ++i) {
        std::memcpy(&out[i * kChannels], &frame.color.rgba[i * 4], 4 * sizeof(float));
        out[i * kChannels + 4] = frame.visibility[i];
    }
    return out;
}

void checkFrame(const std::string& name, const Frame& frame)
{
    SCOPED_TRACE(name);
    ASSERT_EQ(frame.color.width, kSize);
    ASSERT_EQ(frame.visibility.size(), size_t(kSize) * kSize);
    const std::vector<float> pixels = framePixels(frame);
    const std::string path = framePath(name);
    const std::string device = frame.stats.device.name;
    if (std::getenv("PENUMBRA_UPDATE_FRAMES")) {
        writeRecorded(path, device, pixels);
        return;
    }
    Recorded recorded;
    ASSERT_TRUE(readRecorded(path, recorded)) << path << ": missing or unreadable (record it with PENUMBRA_UPDATE_FRAMES=1)";
    size_t covered = 0, colourDiffers = 0, visibilityDiffers = 0;
    float largest = 0.0f;
    for (size_t i = 0; i < size_t(kSize) * kSize; ++i) {
        const float* a = &pixels[i * kChannels];
        const float* b = &recorded.pixels[i * kChannels];
        covered += b[4] >= 0.0f;
        bool colour = std::memcmp(a, b, 4 * sizeof(float)) != 0;
        colourDiffers += colour;
        visibilityDiffers += std::memcmp(a + 4, b + 4, sizeof(float)) != 0;
        for (int c = 0; c < kChannels; ++c)
            largest = std::max(largest, std::fabs(a[c] - b[c]));
    }
    if (device == recorded.device) {
        EXPECT_EQ(colourDiffers, 0u) << "colour differs on " << colourDiffers << " pixels (largest difference " << largest << ")";
        EXPECT_EQ(visibilityDiffers, 0u) << "visibility differs on " << visibilityDiffers << " pixels";
    } else {
        EXPECT_LE(double(visibilityDiffers), 0.005 * double(covered))
            << "recorded on " << recorded.device << ", rendered on " << device << ": visibility differs on " << visibilityDiffers
            << " of " << covered << " covered pixels";
    }
}

Frame render(Renderer& renderer, ShadowMethod method, bool debugPip = false, bool floors = false)
{
    RenderSettings settings;
    settings.measureFloors = floors;
    settings.width = settings.height = kSize;
    settings.shadows = method;
    settings.readbackGBuffer = true;
    settings.debugPip = debugPip;
    settings.shadowMapSize = 1024;
    Frame frame = renderer.render(settings);
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
    return frame;
}

Scene generated(const char* name)
{
    GenerateOptions options;
    options.triangles = 60'000;
    return generateScene(name, options);
}

TEST(FrameImages, HardShadowsOnCityAndScan)
{
    for (const char* name : {"city", "scan"}) {
        Scene scene = generated(name);
        Renderer renderer;
        renderer.loadModel(scene.mesh);
        renderer.setCamera(scene.cameras[0]);
        renderer.setLights({scene.lights[0]});
        checkFrame(std::string(name) + "_sm", render(renderer, ShadowMethod::ShadowMap));
        checkFrame(std::string(name) + "_srt", render(renderer, ShadowMethod::Selective));
        checkFrame(std::string(name) + "_frt", render(renderer, ShadowMethod::FullRayTrace));
    }
}

TEST(FrameImages, PointLightAndSeveralLights)
{
    Scene scene = generated("interior");
    const Bounds bounds = computeBounds(scene.mesh);
    const Light point = test::pointLightAmong(bounds, 0.25f);
    Renderer renderer;
    renderer.loadModel(scene.mesh);
    renderer.setCamera(scene.cameras[0]);
    renderer.setLights({point});
    checkFrame("interior_point_sm", render(renderer, ShadowMethod::ShadowMap));
    Frame pointSrt = render(renderer, ShadowMethod::Selective);
    EXPECT_GT(pointSrt.stats.coveredPixels, kSize * kSize / 2);
    EXPECT_GT(pointSrt.stats.rays, 100u);
    checkFrame("interior_point_srt", pointSrt);

    // A spot light beside the sun: lights are shaded one after another into one colour.
    Light spot;
    spot.type = LightType::Spot;
    spot.position = point.position;
    spot.direction = glm::vec3(0.3f, -1.0f, 0.2f);
    spot.outerConeDegrees = 40.0f;
    spot.innerConeDegrees = 30.0f;
    spot.intensity = point.intensity;
    renderer.setLights({spot, scene.lights[0]});
    checkFrame("interior_spot_sun_srt", render(renderer, ShadowMethod::Selective));
}

// The recorded soft-shadow cases' light: a small rectangle above the scene, facing its centre.
Light rectangleOver(const Bounds& bounds)
{
    const float diagonal = glm::length(bounds.max - bounds.min);
    Light rectangle;
    rectangle.type = LightType::Rectangle;
    rectangle.position = bounds.center() + glm::vec3(0.2f, 0.6f, 0.3f) * diagonal;
    rectangle.direction = glm::normalize(bounds.center() - rectangle.position);
    rectangle.width = 0.03f * diagonal;
    rectangle.height = 0.015f * diagonal;
    rectangle.intensity = 0.5f * diagonal * diagonal;
    return rectangle;
}

TEST(FrameImages, SoftShadowsAndPipImage)
{
    Scene scene = generated("city");
    const Light rectangle = rectangleOver(computeBounds(scene.mesh));
    Renderer renderer;
    renderer.loadModel(scene.mesh);
    renderer.setCamera(scene.cameras[0]);
    renderer.setLights({rectangle});
    checkFrame("city_rectangle_sm", render(renderer, ShadowMethod::ShadowMap));
    for (ShadowMethod method : {ShadowMethod::Selective, ShadowMethod::FullRayTrace}) {
        Frame frame = render(renderer, method);
        EXPECT_GT(frame.stats.penumbraPixels, 500u) << "the case should have a penumbra";
        checkFrame(std::string("city_rectangle_") + shadowMethodName(method), frame);
    }

    // Each pass is timed with its own work (vk::writeTimestamp): the light's samples traced for every
    // listed pixel cost far more than listing them. On lavapipe the compaction's interval used to end
    // after the trace in some frames (these, reading no G-buffer back, among them).
    for (ShadowMethod method : {ShadowMethod::Selective, ShadowMethod::FullRayTrace}) {
        RenderSettings settings;
        settings.width = settings.height = kSize;
        settings.shadows = method;
        settings.shadowMapSize = 1024;
        settings.srtTraceAllWhenCheaper = false;
        const Frame frame = renderer.render(settings);
        auto passMs = [&frame](const char* name) {
            double ms = 0.0;
            for (const PassTiming& pass : frame.stats.passes)
                ms += pass.name == name ? pass.gpuMs : 0.0;
            return ms;
        };
        EXPECT_GT(passMs("compact"), 0.0) << shadowMethodName(method);
        EXPECT_GT(passMs("trace"), 3.0 * passMs("compact"))
            << shadowMethodName(method) << ": trace " << passMs("trace") << " ms, compact " << passMs("compact") << " ms";
    }

    renderer.setLights({scene.lights[0]});
    checkFrame("city_srt_pip", render(renderer, ShadowMethod::Selective, true));
}

// RenderSettings::measureFloors (penumbra bench's floor table) times null
// twins and uncompressed depth-only draws beside the passes: the recorded
// images stay exactly the same, and every floor of the frame's passes is timed.
TEST(FrameImages, FloorsLeaveTheFrameUnchanged)
{
    Scene scene = generated("city");
    const Light rectangle = rectangleOver(computeBounds(scene.mesh));
    Renderer renderer;
    renderer.loadModel(scene.mesh);
    renderer.setCamera(scene.cameras[0]);
    auto passNames = [](const Frame& frame) {
        std::vector<std::string> names;
        for (const PassTiming& pass : frame.stats.passes) {
            EXPECT_GE(pass.gpuMs, 0.0) << pass.name;
            names.push_back(pass.name);
        }
        return names;
    };
    auto has = [](const std::vector<std::string>& names, const char* name) {
        return std::find(names.begin(), names.end(), name) != names.end();
    };
    renderer.setLights({scene.lights[0]});
    checkFrame("city_sm", render(renderer, ShadowMethod::ShadowMap, false, true));
    Frame srt = render(renderer, ShadowMethod::Selective, false, true);
    checkFrame("city_srt", srt);
    for (const char* name : {"camera_floor", "view_fit_floor", "shadow_map_floor", "classify_floor", "compact_floor", "shade_floor",
                             "camera", "view_fit", "view_fit_readback", "classify", "compact", "trace", "shade"})
        EXPECT_TRUE(has(passNames(srt), name)) << name;
    renderer.setLights({rectangle});
    checkFrame("city_rectangle_sm", render(renderer, ShadowMethod::ShadowMap, false, true));
    checkFrame("city_rectangle_srt", render(renderer, ShadowMethod::Selective, false, true));
    // An ordinary frame after floor frames has no floors.
    Frame plain = render(renderer, ShadowMethod::Selective);
    EXPECT_FALSE(has(passNames(plain), "classify_floor"));
}

} // namespace
} // namespace penumbra

namespace penumbra {
namespace {

// RenderSettings::readbackLightLayers: light i's slice is the visibility that
// light alone gives (light 0's is Frame::visibility), and pip marks exactly
// the pixels some light traced.
TEST(FrameImages, EveryLightsVisibilityAndThePipMaskAreReadBack)
{
    Scene scene = generated("interior");
    const Bounds bounds = computeBounds(scene.mesh);
    Light spot;
    spot.type = LightType::Spot;
    spot.position = bounds.center() + glm::vec3(0.0f, 0.25f * (bounds.max.y - bounds.min.y), 0.0f);
    spot.direction = glm::vec3(0.3f, -1.0f, 0.2f);
    spot.outerConeDegrees = 40.0f;
    Renderer renderer;
    renderer.loadModel(scene.mesh);
    renderer.setCamera(scene.cameras[0]);
    RenderSettings settings;
    settings.width = settings.height = kSize;
    settings.shadows = ShadowMethod::Selective;
    settings.readbackGBuffer = true;
    settings.readbackLightLayers = true;
    renderer.setLights({scene.lights[0], spot});
    Frame both = renderer.render(settings);
    const size_t pixels = size_t(kSize) * kSize;
    ASSERT_EQ(both.lightVisibility.size(), 2 * pixels);
    ASSERT_EQ(both.pip.size(), pixels);
    EXPECT_TRUE(std::equal(both.visibility.begin(), both.visibility.end(), both.lightVisibility.begin()));
    renderer.setLights({spot});
    Frame spotAlone = renderer.render(settings);
    EXPECT_TRUE(std::equal(spotAlone.visibility.begin(), spotAlone.visibility.end(), both.lightVisibility.begin() + pixels))
        << "light 1's slice differs from the spot rendered alone";
    size_t marked = 0;
    for (float v : both.pip)
        marked += v != 0.0f;
    EXPECT_GT(marked, 0u);
    EXPECT_LE(marked, both.stats.pipPixels); // the union of the lights' marks, pipPixels their sum
    EXPECT_EQ(renderer.validationMessageCount(), 0u);
}

} // namespace
} // namespace penumbra
