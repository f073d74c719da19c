// One-line progress bar on stderr for the CLI's long commands (preprocess,
// bench): redrawn at most ~10 times a second, silent when stderr is not a
// terminal.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>

#include <unistd.h>

namespace penumbra {

class ProgressBar {
  public:
    explicit ProgressBar(bool enabled) : enabled(enabled && isatty(STDERR_FILENO)) {}
    ~ProgressBar() { finish(); }
    ProgressBar(const ProgressBar&) = delete;
    ProgressBar& operator=(const ProgressBar&) = delete;

    // Draws "label [####....]  42%"; fraction in [0, 1].
    void update(const std::string& label, double fraction)
    {
        if (!enabled)
            return;
        auto now = std::chrono::steady_clock::now();
        if (label == lastLabel && now - lastDraw < std::chrono::milliseconds(100) && fraction < 1.0)
            return;
        lastDraw = now;
        lastLabel = label;
        int filled = int(std::lround(std::clamp(fraction, 0.0, 1.0) * kWidth));
        std::fprintf(stderr, "\r%-24.24s [%s%s] %3d%%", label.c_str(), std::string(size_t(filled), '#').c_str(),
                     std::string(size_t(kWidth - filled), '.').c_str(), int(std::lround(fraction * 100.0)));
        std::fflush(stderr);
        drawn = true;
    }

    // Erases the bar so that the next line prints cleanly.
    void finish()
    {
        if (drawn)
            std::fprintf(stderr, "\r%*s\r", kWidth + 34, "");
        drawn = false;
    }

  private:
    static constexpr int kWidth = 40;
    bool enabled;
    bool drawn = false;
    std::string lastLabel;
    std::chrono::steady_clock::time_point lastDraw{};
};

} // namespace penumbra
