#include "selective_choice.h"

#include <algorithm>

namespace penumbra {

bool SelectiveChoice::traceAll(uint64_t frameKey)
{
    if (!started || frameKey != key)
        *this = SelectiveChoice{};
    started = true;
    key = frameKey;
    ++frame;
    probe = frame > 2 && (otherMs < 0.0 ? settled || frame > kSettleFrames : sinceProbe >= interval);
    current = probe ? !all : all;
    return current;
}

void SelectiveChoice::record(double gpuMs)
{
    if (frame <= 1)
        return; // the key's first frame: warming up
    const double chosenCost = chosenCount ? *std::min_element(chosenMs.begin(), chosenMs.begin() + std::min<size_t>(chosenCount, chosenMs.size())) : gpuMs;
    if (!probe) {
        // Settled once a frame is no faster (by the margin) than the best before it.
        settled = settled || (chosenCount > 0 && gpuMs >= chosenCost * (1.0 - kMargin));
        chosenMs[chosenCount++ % chosenMs.size()] = gpuMs;
        ++sinceProbe;
        return;
    }
    // Not timed, and the next frame probes again: the first probe (its shaders may compile in it), and
    // the first frame of every probe of srt's own way (its light views' culling history is as old as
    // the frames that traced every pixel: a camera that moved meanwhile makes it draw more).
    if (!warmingUp && (otherMs < 0.0 || !current)) {
        warmingUp = true;
        return;
    }
    warmingUp = false;
    sinceProbe = 0;
    const bool firstProbe = otherMs < 0.0;
    if (gpuMs < chosenCost * (1.0 - kMargin)) {
        // The probe's way is cheaper: take it; the way left keeps its cost for comparison.
        all = current;
        otherMs = chosenCost;
        chosenMs = {gpuMs};
        chosenCount = 1;
        interval = kMinInterval;
    } else {
        otherMs = gpuMs;
        interval = firstProbe ? kMinInterval : std::min(interval * 2, kMaxInterval);
    }
}

} // namespace penumbra
