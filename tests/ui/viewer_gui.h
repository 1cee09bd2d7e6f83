// The viewer's tests' shared setup: small fast options, and the viewer's ImGui frame drawn by
// the real OpenGL3 backend in the current (offscreen OSMesa) GL context.
#pragma once

#include "ui/viewer_app.h"

namespace kdt::test {

/// A width x height image rendered and built with one thread each.
ui::ViewerOptions small_viewer_options(int width, int height);

/// An ImGui context and its OpenGL3 backend for one viewer in a width x height framebuffer,
/// the viewer's image at (0, 0) 640 x 480; ok() says whether the backend started. Destroyed
/// before the viewer and the GL context.
class ViewerGui {
public:
    ViewerGui(ui::Viewer& viewer, int width, int height);
    ~ViewerGui();
    ViewerGui(const ViewerGui&) = delete;
    ViewerGui& operator=(const ViewerGui&) = delete;
    bool ok() const { return ok_; }
    /// One frame as the viewer's loop draws it (without the window's input, the load's poll
    /// and the screenshots), the File panel when file_panel; returns script_step()'s result.
    bool frame(bool file_panel);

private:
    ui::Viewer& v_;
    int width_, height_;
    bool ok_ = false;
};

}  // namespace kdt::test
