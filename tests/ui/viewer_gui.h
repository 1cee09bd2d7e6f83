// The viewer's tests' shared setup: small fast options, and the viewer's ImGui frame drawn by
// the real OpenGL3 backend in the current (offscreen OSMesa) GL context.
#pragma once

#include <optional>

#include "tests/ui/osmesa_context.h"
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

/// The panel tests' setup: a width x height offscreen GL context, a viewer of `options` with
/// its scene loaded, and its ViewerGui; ok() says whether GL and the backend started (the
/// viewer and its GUI exist only then). Destroyed GUI first, then viewer, then context.
class GuiViewer {
public:
    GuiViewer(const ui::ViewerOptions& options, int width, int height);
    bool ok() const { return gui_ && gui_->ok(); }
    OffscreenGL& gl() { return gl_; }
    ui::Viewer& viewer() { return *viewer_; }
    ViewerGui& gui() { return *gui_; }

private:
    OffscreenGL gl_;
    std::optional<ui::Viewer> viewer_;
    std::optional<ViewerGui> gui_;
};

}  // namespace kdt::test
