// An offscreen OpenGL 3.3 core context in memory (OSMesa, Mesa's software rasteriser) for the
// display tests: no GPU and no display needed.
#pragma once

#include <cstdint>
#include <vector>

namespace kdt::test {

class OffscreenGL {
public:
    /// Creates and makes current a width x height RGBA context; ok() says whether it worked.
    OffscreenGL(int width, int height);
    ~OffscreenGL();
    OffscreenGL(const OffscreenGL&) = delete;
    OffscreenGL& operator=(const OffscreenGL&) = delete;
    bool ok() const { return context_ != nullptr; }
    /// The framebuffer as RGB bytes, top row first.
    std::vector<uint8_t> read_rgb() const;

private:
    void* context_ = nullptr;
    int width_, height_;
    std::vector<uint8_t> buffer_;
};

}  // namespace kdt::test
