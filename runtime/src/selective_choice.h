// srt's choice, frame by frame, between its own sequence (shadow map, thin
// triangles, classification, rays for the pixels the map may get wrong) and a
// ray for every light-facing pixel (frt's sequence: no map, no classification).
//
// Selective ray tracing pays for the map and the classification to save rays.
// Where the map leaves many pixels in doubt (a plant's gratings and pipes: 43%
// of the pixels at 1024^2) or the tracer is fast for this view, tracing every
// pixel is the cheaper way to the same exact shadows: its image is the oracle's,
// srt's differs from it on a few pixels more. Which way is cheaper is measured,
// not guessed: once srt's own frames have settled (after the first frame that
// is not 5% faster than the best before it: the light views' occlusion
// culling learns over the first frames; at the latest the 17th), two frames
// trace every pixel (probes; the first is not timed: lavapipe compiles the
// shaders a sequence uses in its first frame), and from then on the frames take the way whose
// measured GPU time is lower, probing the other way again now and then (8
// frames after a probe; after a probe that lost, other than the first, twice as
// many frames as before, at most 256). A probe of srt's own way also takes two
// frames, the first not timed: its light views' culling history is as old as the
// frames that traced every pixel.
// The costs are per settings, lights and model (key); the camera may move.
//
// No Vulkan here: the renderer asks traceAll before a frame and reports the
// frame's GPU time after it (renderer.cpp).
#pragma once

#include <array>
#include <cstdint>

namespace penumbra {

class SelectiveChoice {
  public:
    static constexpr uint32_t kSettleFrames = 16; // frames of srt's own way at most before the first probe
    static constexpr uint32_t kMinInterval = 8;    // frames between probes of the way not taken
    static constexpr uint32_t kMaxInterval = 256;  // ... doubled after each probe that lost
    static constexpr double kMargin = 0.05;        // the other way must be this much cheaper to switch

    // Whether the next frame with this key traces every light-facing pixel. A
    // new key starts over (its first frame is not timed: the culling and the
    // caches are still warming up, and lavapipe compiles shaders on first use).
    bool traceAll(uint64_t key);
    // The frame that traceAll was just asked about took gpuMs.
    void record(double gpuMs);

    // The way the frames take now (between probes); whether the last frame was a
    // probe; whether both ways were measured (the choice is made).
    bool tracingAll() const { return all; }
    bool lastWasProbe() const { return probe; }
    bool chosen() const { return otherMs >= 0.0; }
    uint32_t probeInterval() const { return interval; }

  private:
    uint64_t key = 0;
    bool started = false;
    uint32_t frame = 0;           // frames of this key so far, counting the one being rendered
    bool all = false;             // the chosen way
    bool current = false;         // the way of the frame being rendered
    bool probe = false;           // ... and whether it is a probe of the way not chosen
    uint32_t sinceProbe = 0;      // frames since the last probe
    uint32_t interval = kMinInterval;
    // GPU ms: the chosen way's last frames (the lowest is its cost: other work on the
    // machine only adds time), the other way's last probe.
    std::array<double, 4> chosenMs{};
    uint32_t chosenCount = 0;
    bool settled = false; // the chosen way's frames no longer get faster (before the first probe)
    bool warmingUp = false; // the last frame was a probe's untimed first frame
    double otherMs = -1.0;
};

} // namespace penumbra
