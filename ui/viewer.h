// `kdtrace view`: the interactive viewer. A GLFW window with an OpenGL 3.3 core context shows
// the progressive path-traced image (RenderWorker on its own thread), ImGui panels generated
// from the options' range tables, kd-tree rebuilds in the background and heat maps of the
// tree's cost per pixel. Depends on renderer, GLFW, OpenGL and Dear ImGui.
#pragma once

#include <string>

#include "renderer/render/render_options.h"

namespace kdt::ui {

struct ViewerOptions {
    RenderOptions options;  ///< as given (resolve() is the viewer's; no stop = render on)
    /// Exit after this many frames once the script has run (0 = run until the window closes).
    int frames = 0;
    std::string screenshot;  ///< PNG of the whole window written at exit (with --frames)
    /// Commands separated by ';' run one per frame (see viewer_script.cpp): orbit, pan, zoom,
    /// fly, frame, reset, view, set, rebuild, heat, exposure, pause, resume, wait, wait_passes,
    /// wait_done, wait_rebuild, screenshot, save, save_session, load_session, panels, open,
    /// drop, wait_loaded, message.
    std::string script;
    std::string session;      ///< a session file (save_session) to start from
    std::string views;        ///< views file of keys 1-4 (empty: the dragon's views)
    int preview_divisor = 4;  ///< resolution divisor of the preview pass after a change
};

/// Opens the window at once and loads the scene in the background, then runs until the
/// window closes (or --frames). Prints a summary (frame times, preview and rebuild latencies,
/// throughput) to stdout at exit. A file that fails to load is shown in the window; throws
/// kdt::Error for bad options or scripts, when no window can be opened, and when the first
/// scene fails in a scripted run (--script or --frames).
void run_viewer(const ViewerOptions& options);

}  // namespace kdt::ui
