#include "ui/frame_pacer.h"

#include <algorithm>

namespace kdt::ui {

bool FramePacer::due(const FrameSignals& s, Clock::time_point now) {
    const bool input = first_ || s.input_events != last_.input_events;
    const bool news = s.updates != last_.updates;
    if (input) last_input_ = now;
    // News shows in the frame that takes it; input and busy states settle over more frames.
    if (input || s.busy) settle_ = kSettleFrames + 1;  // this frame and kSettleFrames more
    const bool draw =
        news || settle_ > 0 || now - last_input_ < kRecentInput || now - last_drawn_ >= kMaxIdle;
    settle_ = std::max(settle_ - 1, 0);
    if (draw) last_drawn_ = now;
    first_ = false;
    last_ = s;
    return draw;
}

bool ImageCopyPacer::due(uint64_t completed_passes, bool force, Clock::time_point now) {
    if (!force && completed_passes == copied_passes_ && now - copied_at_ < kPartialImage)
        return false;
    copied_passes_ = completed_passes;
    copied_at_ = now;
    return true;
}

}  // namespace kdt::ui
