// The viewer's frame pacing: a frame is drawn at a tick only when it may differ from the last
// one (input, news from other threads, busy, settling frames), and at least every kMaxIdle.
#include "ui/frame_pacer.h"

#include <gtest/gtest.h>

#include <cmath>

namespace kdt::ui {
namespace {

using Clock = FramePacer::Clock;
constexpr auto kTick = std::chrono::microseconds(16667);

// Ticks from `t` with the same signals until `count` ticks passed; returns frames drawn.
int run(FramePacer& p, const FrameSignals& s, Clock::time_point& t, int count) {
    int drawn = 0;
    for (int i = 0; i < count; ++i) {
        drawn += p.due(s, t);
        t += kTick;
    }
    return drawn;
}

TEST(FramePacer, IdleTicksSkipFramesButNotForLongerThanMaxIdle) {
    FramePacer p;
    FrameSignals s;
    Clock::time_point t{};
    EXPECT_TRUE(p.due(s, t));  // the first frame
    t += kTick;
    // Within kRecentInput of the first frame everything is drawn (it counts as input).
    EXPECT_EQ(run(p, s, t, 29), 29);
    // Two idle seconds: a frame every kMaxIdle (the first tick at or past it), not 120.
    const int ticks_per_frame = int(std::ceil(std::chrono::duration<double>(FramePacer::kMaxIdle) /
                                              std::chrono::duration<double>(kTick)));
    ASSERT_GT(ticks_per_frame, 2);  // an idle viewer skips most ticks
    const int idle = run(p, s, t, 120);
    EXPECT_GE(idle, 120 / ticks_per_frame - 2);
    EXPECT_LE(idle, 120 / ticks_per_frame + 1);
}

TEST(FramePacer, InputWorkerNewsAndBusyDrawAtOnceAndSettle) {
    FramePacer p;
    FrameSignals s;
    Clock::time_point t{};
    run(p, s, t, 120);  // past the first frame's recent-input spell, into idle
    // News (a pass, a build): this tick only, then idle again.
    s.updates = 1;
    EXPECT_TRUE(p.due(s, t));
    t += kTick;
    EXPECT_LE(run(p, s, t, 5), 1);
    // Busy (a script step): every tick.
    s.busy = true;
    EXPECT_EQ(run(p, s, t, 60), 60);
    s.busy = false;
    EXPECT_EQ(run(p, s, t, FramePacer::kSettleFrames), FramePacer::kSettleFrames);
    run(p, s, t, 60);
    // One input event: drawn for kRecentInput (30 ticks), then idle.
    s.input_events = 7;
    EXPECT_EQ(run(p, s, t, 30), 30);
    run(p, s, t, 2);
    EXPECT_LE(run(p, s, t, 5), 1);
}

TEST(ImageCopyPacer, CopiesAtANewPassWhenForcedOrAfterThePartialInterval) {
    ImageCopyPacer p;
    const auto t0 = ImageCopyPacer::Clock::now();
    const auto ms = [](int n) { return std::chrono::milliseconds(n); };
    EXPECT_TRUE(p.due(0, false, t0));             // the first time
    EXPECT_FALSE(p.due(0, false, t0 + ms(100)));  // tiles of the same pass, too soon
    EXPECT_TRUE(p.due(1, false, t0 + ms(110)));   // a pass completed
    EXPECT_FALSE(p.due(1, false, t0 + ms(200)));
    EXPECT_TRUE(p.due(1, true, t0 + ms(210)));  // forced (a recolour)
    EXPECT_FALSE(p.due(1, false, t0 + ms(210) + ImageCopyPacer::kPartialImage - ms(1)));
    EXPECT_TRUE(p.due(1, false, t0 + ms(210) + ImageCopyPacer::kPartialImage));
}

}  // namespace
}  // namespace kdt::ui
