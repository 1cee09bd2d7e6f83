// When the viewer draws a frame: at the 60 Hz tick only if the frame may differ from the one
// on screen. Under software GL a frame costs milliseconds of CPU (mostly rasterising the
// panels) that a repeated frame would take from the render threads. Pure logic: the frame
// loop (ui/viewer.cpp) feeds it what it observed. Depends on the standard library only.
#pragma once

#include <chrono>
#include <cstdint>

namespace kdt::ui {

/// What the frame loop saw before a tick.
struct FrameSignals {
    uint64_t input_events = 0;  ///< a count that grows with every window input event
    uint64_t updates = 0;       ///< a count that grows with news from other threads
    bool busy = false;          ///< something moves on its own (a script step)
};

/// Draws at a tick after any input (and for kRecentInput after it: ImGui's hover states,
/// held keys that send no events), after any news (a render pass, a finished tree build: it
/// shows in the frame that takes it), while busy and for kSettleFrames after (a script's
/// command often shows only in the frame after the one that ran it), and at least every
/// kMaxIdle (states the loop cannot see).
class FramePacer {
public:
    using Clock = std::chrono::steady_clock;
    static constexpr int kSettleFrames = 1;
    static constexpr std::chrono::milliseconds kRecentInput{500};
    static constexpr std::chrono::milliseconds kMaxIdle{250};

    /// Whether to draw at `now`; the first call always draws.
    bool due(const FrameSignals& s, Clock::time_point now);

private:
    bool first_ = true;
    FrameSignals last_;
    Clock::time_point last_input_{}, last_drawn_{};
    int settle_ = 0;
};

/// When to copy a render's image for display: at once when a pass has completed since the
/// last copy (or when forced: a recolour, a layer the image still lacks), and while a pass is
/// in flight, its finished tiles at most every kPartialImage: a copy and an upload a frame
/// would cost the render threads more than the tiles show.
class ImageCopyPacer {
public:
    using Clock = std::chrono::steady_clock;
    static constexpr std::chrono::milliseconds kPartialImage{250};

    /// Whether to copy at `now`, given the worker's completed passes; records the copy.
    bool due(uint64_t completed_passes, bool force, Clock::time_point now);

private:
    uint64_t copied_passes_ = 0;
    Clock::time_point copied_at_{};
};

}  // namespace kdt::ui
