// `kdtrace view`: the interactive viewer (ui/viewer.h) with every render option, plus hooks
// for tests and measurements (--frames, --screenshot, --script).
#include "app/commands.h"
#include "app/options_cli.h"
#include "renderer/core/error.h"

#ifdef KDT_HAVE_VIEWER
#include "ui/viewer.h"
#endif

namespace kdt::app {

void add_view_command(CLI::App& parent) {
#ifdef KDT_HAVE_VIEWER
    static ui::ViewerOptions vo;
    auto* sub = parent.add_subcommand(
        "view", "Open a scene, a model or the built-in default scene in the interactive viewer");
    add_render_options(*sub, vo.options);
    sub->add_option("--frames", vo.frames,
                    "Exit after N frames once the script has run (tests; 0 = until closed)")
        ->check(in_range(0, 2147483647));
    file_extension(non_empty_file_name(sub->add_option("--screenshot", vo.screenshot,
                                                       "PNG of the window at exit (with --frames)"),
                                       "--screenshot"),
                   "--screenshot", ".png", "the screenshot is written as PNG");
    sub->add_option("--script", vo.script,
                    "Commands separated by ';', e.g. \"orbit 30 0; set tree.q 0.9; rebuild\"");
    sub->add_option("--preview-divisor", vo.preview_divisor,
                    "Resolution divisor of the preview pass after a change (1 = none)")
        ->check(in_range(1, 64));
    sub->callback([sub] {
        warn_unused_tree_flags(*sub, vo.options.tree, !vo.options.scene.tree_file.empty());
        warn_unused_render_flags(*sub, vo.options);
        check_views_file(*sub);
        // The screenshot is taken in the last frame of a --frames run; a window the user
        // closes would exit without it.
        if (!vo.screenshot.empty() && vo.frames == 0)
            throw Error("--screenshot needs --frames N (it is taken N frames after the script)");
        // The viewer's film is render's and more: one that cannot fit is refused before the
        // window opens and the scene loads, naming the flags, as render refuses it.
        check_image_memory(vo.options.scene.width, vo.options.scene.height);
        try {
            ui::run_viewer(vo);
        } catch (const Error& e) {
            // A script error quotes the command as typed: flags are named in its reason only.
            const std::string m = e.what(), script = "view --script: '";
            const size_t quoted = m.rfind(script, 0) == 0 ? m.find("': ", script.size()) : m.npos;
            if (quoted != m.npos)
                throw Error(m.substr(0, quoted + 3) + with_flags(m.substr(quoted + 3)));
            throw Error(with_camera_flags(*sub, with_flags(m), vo.options.scene));
        }
    });
#else
    parent.add_subcommand("view", "The interactive viewer (not built: KDT_WITH_VIEWER=OFF)")
        ->callback([] { throw Error("view: kdtrace was built without the viewer"); });
#endif
}

}  // namespace kdt::app
