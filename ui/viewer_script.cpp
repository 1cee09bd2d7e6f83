// Scripted input for tests and measurements (`kdtrace view --script "orbit 30 0; rebuild"`):
// each command does what a user's input would, through the same Viewer calls. Commands:
//   orbit YAW PITCH | pan DX DY | zoom F | fly R U F | frame | reset | view NAME
//   set GROUP.NAME VALUE | rebuild | heat nodes|triangles|off | exposure STOPS
//   pause | resume | panels on|off | screenshot FILE | save BASE | save_session FILE
//   load_session FILE | wait FRAMES | wait_passes N | wait_done | wait_rebuild
//   (wait_passes also ends when the render is done; a wait for rendering fails the script
//   while the render is paused or after it failed)
//   stats LABEL (prints the frame times since the previous stats command, and with the split
//   view on, both sides' rays/s and cost per ray)
//   mode radiance|nodes|triangles|normals|depth (the view)
//   split on|off | split.set tree.NAME VALUE (side B's tree) | divider U (0 = left, 1 = right)
//   wait_split (until B's tree is built and B has a full pass with it)
//   check_gl (fails the script when OpenGL reported an error since the last check)
//   open PATH | drop PATH... (as dropped on the window) | wait_loaded (the requests so far
//   are swapped in or failed) | message (prints the window's message line)
// The script starts once the first scene has loaded. `set` also takes material.NAME
// (instance, type, albedo R,G,B, emission R,G,B, ior, roughness) and scene.env_file PATH.
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <iterator>
#include <sstream>

#include "renderer/core/error.h"
#include "renderer/scene/views.h"
#include "ui/camera_control.h"
#include "ui/field_widgets.h"
#include "ui/viewer_app.h"

namespace kdt::ui {

namespace {

Error script_error(const std::string& cmd, const std::string& why) {
    return Error("view --script: '" + cmd + "': " + why);
}

}  // namespace

void Viewer::set_option(const std::string& key, const std::string& value) {
    const size_t dot = key.find('.');
    const std::string group = key.substr(0, dot), name = dot == key.npos ? "" : key.substr(dot + 1);
    if (group == "material") {
        set_material(name, value);
        return;
    }
    if (key == "scene.env_file") {
        open_probe(value);
        return;
    }
    if (group == "tree" && set_field(kd_tree_fields(), tree_edit_, group, name, value)) {
        if (auto_rebuild_) request_rebuild();
        return;
    }
    if (group == "scene" && name == "env_rotation_degrees") {
        set_field(scene_fields(), opts_.scene, group, name, value);
        apply_environment();
        return;
    }
    if (group == "scene" && name == "env_intensity") {
        // An optional override without a table entry: its range is the scene file's.
        double v = 0.0;
        if (!detail::parse_number(value, v) || !(v >= 0.0 && v <= 3e38))
            throw Error("scene.env_intensity must be in [0, 3e38] (got '" + value + "')");
        env_intensity_ = float(v);
        apply_environment();
        return;
    }
    if (group == "film" && name == "exposure") {
        set_field(film_fields(), opts_.film, group, name, value);
        tone_.exposure = opts_.film.exposure;
        return;
    }
    if ((group == "trace" && set_field(trace_fields(), opts_.trace, group, name, value)) ||
        (group == "film" && set_field(film_fields(), opts_.film, group, name, value)) ||
        (group == "stop" && set_field(stop_fields(), stop_, group, name, value))) {
        apply_params();
        if (!message_.empty()) throw Error(message_);
        return;
    }
    throw Error("no option " + key +
                " (the groups are tree, trace, film, stop and material; scene has "
                "env_rotation_degrees, env_intensity and env_file)");
}

void Viewer::check_script() const {
    static const char* const kCommands[] = {
        "orbit",  "pan",         "zoom",       "fly",          "frame",        "reset",
        "view",   "set",         "rebuild",    "heat",         "exposure",     "pause",
        "resume", "panels",      "screenshot", "save",         "save_session", "load_session",
        "wait",   "wait_passes", "wait_done",  "wait_rebuild", "stats",        "mode",
        "split",  "split.set",   "divider",    "wait_split",   "check_gl",     "open",
        "drop",   "wait_loaded", "message"};
    for (const std::string& cmd : script_) {
        std::istringstream in(cmd);
        std::string op;
        in >> op;
        if (std::find(std::begin(kCommands), std::end(kCommands), op) == std::end(kCommands))
            throw script_error(cmd, "unknown command");
    }
}

bool Viewer::script_step() {
    if (!worker_) {
        if (loading()) return true;  // the first scene is loading
        // The first scene failed: a script or a test run has nothing to drive.
        if (!script_.empty() || vo_.frames > 0) throw Error(message_);
        return false;
    }
    // A wait in force holds the script until its condition.
    // Every wait ends: at its condition, at once when what it waits for cannot come (a render
    // already done ends wait_passes; nothing pending ends wait_rebuild and wait_split), or
    // with an error when rendering it needs is paused or failed.
    if (!waiting_.empty()) {
        const std::string& cmd = script_[script_next_ - 1];  // the wait command
        const WorkerStats s = worker_->stats();
        const bool shown_done = s.done && image_.complete_passes > 0;
        // wait and wait_loaded end without the render; the others need it running.
        const bool renders = waiting_ != "wait" && waiting_ != "wait_loaded";
        bool over = false;
        if (waiting_ == "wait") over = --wait_count_ <= 0;
        if (waiting_ == "wait_passes")
            over = (s.full_passes >= wait_count_ && have_image_) || shown_done;
        if (waiting_ == "wait_done") over = shown_done;
        if (waiting_ == "wait_rebuild") over = !rebuilder_->busy() && !awaiting_rebuild_image_;
        std::string failed = s.render_error;
        if (waiting_ == "wait_split") {
            over = !split_ || (!split_->settling() && split_->worker().stats().full_passes >= 1 &&
                               split_->image().complete_passes > 0);
            if (split_ && failed.empty()) failed = split_->worker().stats().render_error;
        }
        if (waiting_ == "wait_loaded") over = !loading();
        if (!over && renders && !failed.empty())
            throw script_error(cmd, "cannot end: the render failed: " + failed);
        if (!over && renders && paused_)
            throw script_error(cmd, "cannot end while the render is paused (resume first)");
        if (!over) return true;
        waiting_.clear();
    }
    while (script_next_ < script_.size()) {
        const std::string& cmd = script_[script_next_++];
        std::istringstream in(cmd);
        std::string op;
        in >> op;
        auto number = [&](const char* what) {
            float v = 0.0f;
            if (!(in >> v)) throw script_error(cmd, std::string("expected ") + what);
            return v;
        };
        auto word = [&](const char* what) {
            std::string w;
            if (!(in >> w)) throw script_error(cmd, std::string("expected ") + what);
            return w;
        };
        auto rest = [&](const char* what) {  // the rest of the command: a path with spaces
            std::string w;
            std::getline(in >> std::ws, w);
            if (w.empty()) throw script_error(cmd, std::string("expected ") + what);
            return w;
        };
        try {
            if (op == "orbit") {
                const float yaw = number("yaw degrees");
                move_camera(orbit(camera_, yaw, number("pitch degrees")));
            } else if (op == "pan") {
                const float dx = number("dx");
                move_camera(pan(camera_, dx, number("dy")));
            } else if (op == "zoom") {
                move_camera(zoom(camera_, number("factor"), tree_->bounds()));
            } else if (op == "fly") {
                const float r = number("right"), u = number("up");
                move_camera(fly(camera_, r, u, number("forward")));
            } else if (op == "frame") {
                move_camera(frame(camera_, tree_->bounds()));
            } else if (op == "reset") {
                set_camera(home_camera_);
            } else if (op == "view") {
                move_camera(find_view(vo_.views, word("view name")));
            } else if (op == "set") {
                const std::string key = word("group.name");
                set_option(key, word("value"));
            } else if (op == "rebuild") {
                request_rebuild();
            } else if (op == "heat") {
                const std::string w = word("nodes, triangles or off");
                if (w != "nodes" && w != "triangles" && w != "off")
                    throw script_error(cmd, "expected nodes, triangles or off");
                set_view_mode(w == "nodes"       ? ViewMode::heat_nodes
                              : w == "triangles" ? ViewMode::heat_triangles
                                                 : ViewMode::radiance);
            } else if (op == "mode") {
                static const char* const kModes[] = {"radiance", "nodes", "triangles", "normals",
                                                     "depth"};
                const std::string w = word("a view mode");
                const auto* m = std::find(std::begin(kModes), std::end(kModes), w);
                if (m == std::end(kModes))
                    throw script_error(cmd,
                                       "expected radiance, nodes, triangles, normals or depth");
                set_view_mode(ViewMode(m - std::begin(kModes)));
            } else if (op == "split") {
                const std::string w = word("on or off");
                if (w != "on" && w != "off") throw script_error(cmd, "expected on or off");
                set_split(w == "on");
            } else if (op == "split.set") {
                const std::string key = word("tree.name"), value = word("value");
                if (!split_) throw script_error(cmd, "the split view is off (split on)");
                if (key.rfind("tree.", 0) != 0)
                    throw script_error(cmd, "side B differs in tree options only (tree.NAME)");
                split_->set_tree_option(key.substr(5), value);
            } else if (op == "divider") {
                const float u = number("a position in [0, 1]");
                if (!(u >= 0.0f && u <= 1.0f))
                    throw script_error(cmd, "expected a value in [0, 1]");
                if (!split_) throw script_error(cmd, "the split view is off (split on)");
                split_->divider = u;
            } else if (op == "check_gl") {
                if (std::string e = gl_errors("the frames before"); !e.empty())
                    throw script_error(cmd, e);
            } else if (op == "wait_split") {
                waiting_ = op;
                return true;
            } else if (op == "exposure") {
                FilmParams f = opts_.film;  // film.exposure's range
                set_field(film_fields(), f, "film", "exposure", word("stops"));
                tone_.exposure = f.exposure;
            } else if (op == "pause" || op == "resume") {
                paused_ = op == "pause";
                worker_->set_paused(paused_);
                if (split_) split_->worker().set_paused(paused_);
            } else if (op == "panels") {
                panels_ = word("on or off") == "on";
            } else if (op == "screenshot") {
                const std::string file = word("file");
                std::string ext = std::filesystem::path(file).extension().string();
                for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
                if (ext != ".png")
                    throw script_error(cmd, "the screenshot is written as PNG; give a .png name");
                check_viewer_output(file, "the screenshot");  // a script error, not the exit's
                screenshot_requests_.push_back(file);
                return true;  // taken at the end of this frame, before any later command
            } else if (op == "save") {
                save_image(word("file"));
            } else if (op == "save_session") {
                save_session(word("file"));
            } else if (op == "load_session") {
                load_session(word("file"));
            } else if (op == "stats") {
                const std::string label = word("label");
                std::printf("%s\n", frame_stats(label).c_str());
                if (split_) {
                    const WorkerStats a = worker_->stats(), b = split_->worker().stats();
                    std::printf(
                        "view split %s: A %.1f spp %.3f Mrays/s %.2f nodes %.2f triangles per ray; "
                        "B %.1f spp %.3f Mrays/s %.2f nodes %.2f triangles per ray\n",
                        label.c_str(), a.spp, a.mrays_per_second, a.nodes_per_ray,
                        a.triangles_per_ray, b.spp, b.mrays_per_second, b.nodes_per_ray,
                        b.triangles_per_ray);
                }
                std::fflush(stdout);
            } else if (op == "wait" || op == "wait_passes") {
                const float n = number("count");
                if (!(n >= 0.0f && n <= 1e9f)) throw script_error(cmd, "expected a count >= 0");
                waiting_ = op;
                wait_count_ = int(n);
                return true;
            } else if (op == "open") {
                open_file(rest("a file"));
            } else if (op == "drop") {
                for (std::string w = word("files"); !w.empty(); w.clear(), in >> w) open_file(w);
            } else if (op == "message") {
                std::printf("view message: %s\n", message_.c_str());
                std::fflush(stdout);
            } else if (op == "wait_done" || op == "wait_rebuild" || op == "wait_loaded") {
                waiting_ = op;
                return true;
            } else {
                throw script_error(cmd, "unknown command");
            }
        } catch (const Error& e) {
            const std::string what = e.what();
            if (what.rfind("view --script", 0) == 0) throw;
            throw script_error(cmd, what);
        }
    }
    return false;
}

}  // namespace kdt::ui
