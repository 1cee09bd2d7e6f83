#include "tests/ui/osmesa_context.h"

#include <GL/osmesa.h>

#include <algorithm>
#include <cstddef>

#include "ui/gl.h"

namespace kdt::test {

OffscreenGL::OffscreenGL(int width, int height)
    : width_(width), height_(height), buffer_(size_t(width) * size_t(height) * 4) {
    const int attribs[] = {OSMESA_FORMAT,
                           OSMESA_RGBA,
                           OSMESA_DEPTH_BITS,
                           0,
                           OSMESA_PROFILE,
                           OSMESA_CORE_PROFILE,
                           OSMESA_CONTEXT_MAJOR_VERSION,
                           3,
                           OSMESA_CONTEXT_MINOR_VERSION,
                           3,
                           0};
    OSMesaContext ctx = OSMesaCreateContextAttribs(attribs, nullptr);
    if (!ctx) return;
    if (!OSMesaMakeCurrent(ctx, buffer_.data(), GL_UNSIGNED_BYTE, width, height)) {
        OSMesaDestroyContext(ctx);
        return;
    }
    context_ = ctx;
}

OffscreenGL::~OffscreenGL() {
    if (context_) OSMesaDestroyContext(static_cast<OSMesaContext>(context_));
}

std::vector<uint8_t> OffscreenGL::read_rgb() const {
    std::vector<uint8_t> px(size_t(width_) * size_t(height_) * 3), out(px.size());
    glFinish();
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, width_, height_, GL_RGB, GL_UNSIGNED_BYTE, px.data());
    const size_t row = size_t(width_) * 3;
    for (int y = 0; y < height_; ++y) {
        std::copy_n(px.data() + size_t(height_ - 1 - y) * row, row, out.data() + size_t(y) * row);
    }
    return out;
}

}  // namespace kdt::test
