// Device faults injected through PENUMBRA_FAULT (runtime/src/device.h): out of
// device memory at the n-th allocation, device lost at the n-th submission, a
// fence wait that times out, and a real timeout (PENUMBRA_DEVICE_TIMEOUT). Each
// ends in one Error line; the renderer then refuses more work; and every
// Vulkan object is freed: the validation layer, on for every test, reports
// any object left when the device is destroyed, and the test environment
// (validation_environment.cpp) fails on any message. Each case below also
// checks the process's count itself, so a leak is pinned to its fault.
#include <cstdio>
#include <cstdlib>
#include <string>

#include <gtest/gtest.h>

#include "penumbra/penumbra.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

struct ScopedEnv {
    std::string name;
    ScopedEnv(const std::string& n, const std::string& value) : name(n) { setenv(name.c_str(), value.c_str(), 1); }
    ~ScopedEnv() { unsetenv(name.c_str()); }
};

const Mesh& scene()
{
    static const Mesh mesh = test::cubeOverFloor(0.3f);
    return mesh;
}

// A renderer, a model and `frames` frames of each method (srt: the most passes; afsm: its own).
void renderFrames(int frames)
{
    Renderer renderer;
    renderer.loadModel(scene());
    Camera camera;
    camera.position = {5, 6, 7};
    camera.target = {0, 1, 0};
    renderer.setCamera(camera);
    Light sun;
    sun.type = LightType::Directional;
    sun.direction = {-0.4f, -1.0f, -0.3f};
    renderer.setLights({sun});
    RenderSettings settings;
    settings.width = settings.height = 48;
    settings.shadowMapSize = 256;
    for (int i = 0; i < frames; ++i)
        for (ShadowMethod method : {ShadowMethod::Selective, ShadowMethod::AliasFree}) {
            settings.shadows = method;
            renderer.render(settings);
        }
}

struct Outcome {
    bool threw = false;
    std::string message;
};

// Runs the frames with one fault; the renderer (and its device) is destroyed inside.
Outcome withFault(const std::string& fault, int frames)
{
    ScopedEnv env("PENUMBRA_FAULT", fault);
    Outcome outcome;
    try {
        renderFrames(frames);
    } catch (const Error& e) {
        outcome.threw = true;
        outcome.message = e.what();
    }
    return outcome;
}

// Every n from 1 until the fault no longer fires (n beyond the calls the frames make).
void sweep(const std::string& kind, int frames, const std::string& expected, int& fired, std::string& allMessages)
{
    for (int n = 1; n < 400; ++n) {
        const uint32_t before = validationMessagesInProcess();
        Outcome outcome = withFault(kind + ":" + std::to_string(n), frames);
        EXPECT_EQ(validationMessagesInProcess(), before) << kind << ":" << n << " left Vulkan objects or misused the API (above)";
        if (!outcome.threw) {
            std::printf("%s: the fault fired at each of %d calls, then no more\n", kind.c_str(), fired);
            return;
        }
        ++fired;
        allMessages += outcome.message + "\n";
        EXPECT_EQ(outcome.message.find('\n'), std::string::npos) << outcome.message;
        EXPECT_NE(outcome.message.find(expected), std::string::npos) << kind << ":" << n << ": " << outcome.message;
    }
    ADD_FAILURE() << kind << " still fires after 400 calls";
}

TEST(DeviceFaults, OutOfDeviceMemoryAtEveryAllocation)
{
    int fired = 0;
    std::string messages;
    // The first frames allocate everything; later frames allocate nothing new.
    sweep("allocate", 1, "out of device memory (VK_ERROR_OUT_OF_DEVICE_MEMORY) allocating", fired, messages);
    EXPECT_GT(fired, 20) << "the device, its passes and the frame targets allocate more than this";
}

TEST(DeviceFaults, DeviceLostAtEverySubmission)
{
    int fired = 0;
    std::string messages;
    sweep("submit", 2, "device lost (VK_ERROR_DEVICE_LOST)", fired, messages);
    EXPECT_GE(fired, 4) << messages; // two frames, each with a mid-frame read-back
    // The lost submission is named by its passes.
    EXPECT_NE(messages.find("camera, view_fit"), std::string::npos) << messages;
    EXPECT_NE(messages.find("shade"), std::string::npos) << messages;
}

TEST(DeviceFaults, FenceWaitTimesOutAtEverySubmission)
{
    int fired = 0;
    std::string messages;
    sweep("wait", 2, "device did not finish ", fired, messages);
    EXPECT_GE(fired, 4) << messages;
    EXPECT_NE(messages.find("device did not finish camera, view_fit in 300 s"), std::string::npos) << messages;
    EXPECT_NE(messages.find("device did not finish shadow_map, thin_triangles, classify, compact, trace, shade, readback in 300 s"),
              std::string::npos)
        << messages;
    EXPECT_NE(messages.find("afsm_casters"), std::string::npos) << messages;
}

TEST(DeviceFaults, AFailedDeviceRefusesMoreWork)
{
    ScopedEnv env("PENUMBRA_FAULT", "wait:2");
    Renderer renderer;
    renderer.loadModel(scene());
    RenderSettings settings;
    settings.width = settings.height = 32;
    settings.shadowMapSize = 128;
    std::string first, second;
    for (std::string* message : {&first, &second})
        try {
            renderer.render(settings);
        } catch (const Error& e) {
            *message = e.what();
        }
    EXPECT_NE(first.find("device did not finish"), std::string::npos) << first;
    EXPECT_NE(second.find("the device failed earlier (device did not finish"), std::string::npos) << second;
    EXPECT_THROW(renderer.loadModel(scene()), Error);
}

TEST(DeviceFaults, RealTimeoutIsOneLineAndFreesEverything)
{
    // A microsecond: lavapipe cannot finish a submission in that time, so a real fence wait times out;
    // the renderer then waits for the work (at most 10 s) before it frees what the work uses.
    ScopedEnv env("PENUMBRA_DEVICE_TIMEOUT", "0.000001");
    Outcome outcome;
    try {
        renderFrames(1);
    } catch (const Error& e) {
        outcome.threw = true;
        outcome.message = e.what();
    }
    ASSERT_TRUE(outcome.threw);
    EXPECT_NE(outcome.message.find("device did not finish"), std::string::npos) << outcome.message;
    EXPECT_NE(outcome.message.find(" in 1e-06 s"), std::string::npos) << outcome.message;
    EXPECT_EQ(outcome.message.find('\n'), std::string::npos) << outcome.message;
}

TEST(DeviceFaults, BadFaultSpecIsAnError)
{
    ScopedEnv env("PENUMBRA_FAULT", "explode:1");
    EXPECT_THROW(Renderer{}, Error);
}

} // namespace
} // namespace penumbra
