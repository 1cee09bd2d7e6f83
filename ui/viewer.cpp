#include "ui/viewer.h"

#include <GLFW/glfw3.h>
#include <imgui.h>
#include <imgui_impl_glfw.h>
#include <imgui_impl_opengl3.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <sstream>
#include <thread>

#include "renderer/core/error.h"
#include "renderer/core/open_file.h"
#include "renderer/core/output_path.h"
#include "renderer/core/shell_word.h"
#include "renderer/core/temp_file.h"
#include "renderer/io/image_io.h"
#include "renderer/render/prepare.h"
#include "renderer/render/settings.h"
#include "renderer/scene/views.h"
#include "ui/camera_control.h"
#include "ui/frame_pacer.h"
#include "ui/viewer_app.h"

namespace kdt::ui {

namespace {

double ms_since(Viewer::Clock::time_point t) {
    return std::chrono::duration<double, std::milli>(Viewer::Clock::now() - t).count();
}

double percentile(std::vector<double> v, double p) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    return v[std::min(v.size() - 1, size_t(p * double(v.size() - 1) + 0.5))];
}

}  // namespace

Viewer::Viewer(const ViewerOptions& options) : vo_(options) {
    stop_ = options.options.stop;
    opts_ = resolve(options.options);
    validate(opts_);
    validate(stop_);
    tree_edit_ = opts_.tree;
    env_rotation0_ = opts_.scene.env_rotation_degrees;
    rebuilder_ = std::make_unique<TreeRebuilder>();
    tone_.exposure = opts_.film.exposure;
    std::stringstream ss(options.script);
    for (std::string cmd; std::getline(ss, cmd, ';');) {
        const size_t a = cmd.find_first_not_of(" \t\n"), b = cmd.find_last_not_of(" \t\n");
        if (a != std::string::npos) script_.push_back(cmd.substr(a, b - a + 1));
    }
    check_script();  // a typo fails before any window opens
    if (!vo_.screenshot.empty()) check_viewer_output(vo_.screenshot, "the screenshot");
    // The scene loads while the window opens; poll_load() starts the render thread with it
    // and then loads the session (which needs the scene's worker).
    scene_loader_ = std::make_unique<SceneLoader>();
    probe_loader_ = std::make_unique<SceneLoader>();
    request_scene(opts_.scene.scene_path);
}

void Viewer::set_camera(const CameraDesc& camera) {
    camera_ = camera;
    worker_->set_camera(camera);
    if (split_) split_->worker().set_camera(camera);
    camera_changed_at_ = Clock::now();
    camera_restart_ = worker_->stats().restarts;
    awaiting_preview_ = true;
}

void Viewer::move_camera(const CameraDesc& camera) {
    if (const std::string problem = camera_problem(camera); !problem.empty()) {
        message_ = "camera: move refused (" + problem + "); R resets the camera";
        return;
    }
    set_camera(camera);
}

void Viewer::request_rebuild() {
    rebuilder_->request(worker_->snapshot(), tree_edit_);
    rebuild_requested_at_ = Clock::now();
    awaiting_rebuild_image_ = false;
}

void Viewer::apply_params() {
    try {
        worker_->set_params(opts_.trace, opts_.film, stop_);
        if (split_) split_->worker().set_params(opts_.trace, opts_.film, stop_);
        message_.clear();
    } catch (const Error& e) {
        message_ = e.what();
    }
}

void Viewer::apply_environment() {
    env_overridden_ = true;
    EnvironmentDesc d = prep_.scene.environment;  // with the command line's overrides
    d.rotation_degrees += opts_.scene.env_rotation_degrees - env_rotation0_;
    d.intensity = env_intensity_;
    worker_->set_environment(d);
    if (split_) split_->worker().set_environment(d);
}

void Viewer::set_view_mode(ViewMode mode) {
    if (mode == view_) return;
    const bool heat = is_heat(debug_layer(mode)), aov = is_aov(debug_layer(mode));
    if (heat != is_heat(debug_layer(view_))) {
        opts_.trace.count_traversal = heat || resolve(vo_.options).trace.count_traversal;
        apply_params();
        worker_->set_heat_map(heat);
        if (split_) split_->worker().set_heat_map(heat);
    }
    if (aov != is_aov(debug_layer(view_))) {
        worker_->set_aov(aov);
        if (split_) split_->worker().set_aov(aov);
    }
    view_ = mode;
    image_.version = 0;  // recolour at the next frame
    if (split_) split_->recolour();
}

void Viewer::poll_rebuild() {
    if (split_) {
        if (std::string error = split_->poll_rebuild(); !error.empty()) message_ = error;
    }
    std::optional<RebuildResult> r = rebuilder_->take();
    if (!r || !worker_) return;
    if (!r->snapshot) {
        message_ = r->error;
        return;
    }
    // A tree of a scene replaced meanwhile is dropped; one requested before a material edit
    // gets the edit.
    if (r->snapshot->scene->mesh != worker_->snapshot()->scene->mesh) return;
    if (materials_edited_) {
        try {
            r->snapshot = with_materials(*r->snapshot, materials_);
        } catch (const Error& e) {
            message_ = e.what();
            return;
        }
    }
    message_.clear();
    tree_ = r->snapshot->scene->tree;
    opts_.tree = tree_edit_;
    lat_.build_seconds.push_back(r->seconds);
    worker_->set_snapshot(r->snapshot);
    swapped_at_ = Clock::now();
    rebuild_restarts_ = worker_->stats().restarts;
    awaiting_rebuild_image_ = true;
}

void Viewer::upload(const FilmImage& img) {
    upload_layer(display_, img, debug_layer(view_), heat_scale_,
                 split_ ? &split_->scale() : nullptr);
    have_image_ = true;
}

void Viewer::update_image() {
    if (!worker_) return;
    if (const uint64_t failures = worker_->failures(); failures != render_failures_seen_) {
        render_failures_seen_ = failures;
        message_ = "render: " + worker_->stats().render_error;
        std::fprintf(stderr, "kdtrace: view: %s\n", message_.c_str());
    }
    // An environment the render thread refused (its light cannot be built: the old one stays)
    // is the window's message too, not only a line in the Render section.
    if (const uint64_t u = worker_->updates(); u != worker_updates_seen_) {
        worker_updates_seen_ = u;
        if (std::string e = worker_->stats().error; e != env_error_) {
            env_error_ = std::move(e);
            if (!env_error_.empty()) {
                message_ = env_error_;
                std::fprintf(stderr, "kdtrace: view: %s\n", message_.c_str());
            }
        }
    }
    if (split_) split_->update_image(debug_layer(view_), heat_scale_);
    // The preview of a change is shown until a full-resolution pass of the change is complete
    // (the session's image of the pass in flight still shows the previous state).
    if (worker_->copy_preview(preview_)) {
        upload(preview_);
        if (awaiting_preview_ && preview_.generation >= camera_restart_) {
            lat_.preview_ms.push_back(ms_since(camera_changed_at_));
            awaiting_preview_ = false;
        }
    }
    // Copied at once: a new pass, a recolour (version 0), a debug view still showing radiance.
    const std::optional<DebugLayer> layer = debug_layer(view_);
    const bool force = image_.version == 0 || (layer && !has_layer(*layer, image_));
    if (!image_copies_.due(worker_->completed_passes(), force, Clock::now())) return;
    if (!worker_->session().copy_image(image_, layer.has_value())) return;
    if (image_.complete_passes == 0) return;
    upload(image_);
    if (awaiting_rebuild_image_) {
        const WorkerStats s = worker_->stats();
        if (s.restarts == rebuild_restarts_ && s.full_passes >= 1) {
            lat_.rebuild_ms.push_back(ms_since(rebuild_requested_at_));
            lat_.swap_ms.push_back(ms_since(swapped_at_));
            awaiting_rebuild_image_ = false;
        }
    }
}

void Viewer::draw_image(int fb_height) {
    const DisplayMode mode =
        view_ == ViewMode::radiance ? DisplayMode::radiance : DisplayMode::direct;
    // image_y_ counts from the top; GL's viewport from the bottom.
    if (split_ && split_->display()) {
        draw_split(display_, *split_->display(), image_x_, fb_height - image_y_ - image_h_,
                   image_w_, image_h_, split_->divider, tone_, mode);
    } else {
        display_.draw(image_x_, fb_height - image_y_ - image_h_, image_w_, image_h_, tone_, mode);
    }
}

void Viewer::handle_input(GLFWwindow* window, double dt) {
    if (!worker_) return;  // no scene yet
    const ImGuiIO& io = ImGui::GetIO();
    double mx = 0.0, my = 0.0;
    glfwGetCursorPos(window, &mx, &my);
    const double dx = mx - mouse_x_, dy = my - mouse_y_;
    mouse_x_ = mx;
    mouse_y_ = my;
    CameraDesc c = camera_;
    // A press near the split view's divider drags it instead of the camera.
    const bool dragging =
        split_ && !io.WantCaptureMouse && image_w_ > 0 &&
        split_->drag(float((mx * content_scale_ - image_x_) / image_w_),
                     6.0f * content_scale_ / float(image_w_),
                     glfwGetMouseButton(window, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS);
    if (!io.WantCaptureMouse && !dragging) {
        const bool left = glfwGetMouseButton(window, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
        const bool right = glfwGetMouseButton(window, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS ||
                           glfwGetMouseButton(window, GLFW_MOUSE_BUTTON_MIDDLE) == GLFW_PRESS;
        const bool shift = glfwGetKey(window, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS;
        if ((dx != 0.0 || dy != 0.0) && left && !shift) {
            c = orbit(c, float(dx) * 0.3f, float(dy) * 0.3f);
        } else if ((dx != 0.0 || dy != 0.0) && (right || (left && shift))) {
            const float h = float(std::max(image_h_, 1)) / content_scale_;
            c = pan(c, -float(dx) / h, float(dy) / h);
        }
        if (io.MouseWheel != 0.0f) c = zoom(c, std::pow(0.9f, io.MouseWheel), tree_->bounds());
    }
    if (!io.WantCaptureKeyboard) {
        const float step = float(dt) * 0.5f;  // half the target distance per second
        auto down = [&](int key) { return glfwGetKey(window, key) == GLFW_PRESS; };
        const float r = (down(GLFW_KEY_D) ? step : 0.0f) - (down(GLFW_KEY_A) ? step : 0.0f);
        const float u = (down(GLFW_KEY_E) ? step : 0.0f) - (down(GLFW_KEY_Q) ? step : 0.0f);
        const float f = (down(GLFW_KEY_W) ? step : 0.0f) - (down(GLFW_KEY_S) ? step : 0.0f);
        if (r != 0.0f || u != 0.0f || f != 0.0f) c = fly(c, r, u, f);
        if (ImGui::IsKeyPressed(GLFW_KEY_F)) c = frame(c, tree_->bounds());
        if (ImGui::IsKeyPressed(GLFW_KEY_R)) c = home_camera_;
        for (int k = 0; k < 4; ++k) {
            if (!ImGui::IsKeyPressed(GLFW_KEY_1 + k)) continue;
            try {
                c = find_view(vo_.views, std::string(1, char('A' + k)));
            } catch (const Error& e) {
                message_ = e.what();
            }
        }
        if (ImGui::IsKeyPressed(GLFW_KEY_TAB)) panels_ = !panels_;
        if (ImGui::IsKeyPressed(GLFW_KEY_F12)) {
            try {
                save_image("kdtrace-view");
            } catch (const Error& e) {
                message_ = e.what();
            }
        }
    }
    if (std::memcmp(&c, &camera_, sizeof c) != 0) move_camera(c);
}

std::vector<std::string> Viewer::input_files() const {
    const SceneOptions& cli = vo_.options.scene;
    std::vector<std::string> files = {opts_.scene.scene_path,
                                      opts_.scene.env_file,
                                      opts_.scene.tree_file,
                                      cli.scene_path,
                                      cli.env_file,
                                      cli.tree_file,
                                      scene_requested_,
                                      probe_requested_,
                                      vo_.session,
                                      vo_.views};
    const std::vector<std::string> scene = scene_input_files(prep_.scene);
    files.insert(files.end(), scene.begin(), scene.end());
    files.insert(files.end(), sessions_read_.begin(), sessions_read_.end());
    return files;
}

void Viewer::check_viewer_output(const std::string& path, const char* what) const {
    check_output(path, input_files(), what);
}

void Viewer::screenshot(const std::string& path, int fb_width, int fb_height) const {
    check_viewer_output(path, "the screenshot");
    std::vector<uint8_t> px(size_t(fb_width) * size_t(fb_height) * 3);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadBuffer(GL_BACK);
    glReadPixels(0, 0, fb_width, fb_height, GL_RGB, GL_UNSIGNED_BYTE, px.data());
    // The PNG writer encodes linear values; sRGB codes decoded to linear encode back to the
    // same codes (tests/ui checks all 256).
    ImageRGB img(fb_width, fb_height);
    for (int y = 0; y < fb_height; ++y) {
        const uint8_t* row = px.data() + size_t(fb_height - 1 - y) * size_t(fb_width) * 3;
        for (int i = 0; i < fb_width * 3; ++i) {
            img.rgb[size_t(y) * size_t(fb_width) * 3 + size_t(i)] =
                srgb_to_linear(float(row[i]) / 255.0f);
        }
    }
    write_png(path, img);
}

RenderOptions Viewer::shown_options(bool tree_in_use) const {
    RenderOptions o = opts_;
    o.tree = tree_in_use ? worker_->snapshot()->tree_params : tree_edit_;
    o.scene.camera = camera_;
    o.scene.env_intensity = env_intensity_;
    o.stop = stop_;
    o.scene.materials = materials_;  // as on screen, edited or not
    o.film.exposure = tone_.exposure;
    o.film.tonemap = tone_.curve;
    return o;
}

RenderOptions Viewer::session_options(bool tree_in_use) const {
    RenderOptions o = shown_options(tree_in_use);
    make_file_names_absolute(o.scene);
    return o;
}

void Viewer::save_image(const std::string& base) const {
    FilmImage img;
    worker_->session().copy_image(img);
    ImageRGB out(img.width, img.height);
    out.rgb = img.rgb;
    const RenderOptions o = session_options(true);
    const std::shared_ptr<const RenderSnapshot> snap = worker_->snapshot();
    // The scene as rendered: its environment as the render thread has it, the materials as
    // edited.
    Scene scene = prep_.scene;
    scene.environment = snap->environment;
    for (size_t i = 0; i < scene.meshes.size() && i < materials_.size(); ++i)
        scene.meshes[i].material = materials_[i];
    const WorkerStats s = worker_->stats();
    // The keys of `kdtrace render`'s images (app/cmd_render.cpp), but for its command line.
    ImageMetadata meta;
    meta.emplace_back("Software", "kdtrace 0.1.0 view");
    const std::string& path = o.scene.scene_path;
    meta.emplace_back("kdtrace:scene", path.empty() ? std::string("builtin:default") : path);
    meta.emplace_back("kdtrace:scene_json", scene_to_json(scene));
    meta.emplace_back("kdtrace:camera",
                      camera_to_json(make_camera(camera_, worker_->width(), worker_->height())));
    meta.emplace_back("kdtrace:params", options_to_json(o));
    meta.emplace_back("kdtrace:seed", std::to_string(o.trace.seed));
    meta.emplace_back("kdtrace:spp", std::to_string(s.spp));
    meta.emplace_back("kdtrace:passes", std::to_string(s.full_passes));
    // The command that renders the image again: the image is its own session (its
    // kdtrace:params, with absolute file names), at the samples it has.
    const auto write = [&](const std::string& file) {
        ImageMetadata m = meta;
        m.emplace_back("kdtrace:command", "kdtrace render --session " +
                                              shell_word(absolute_file_name(file)) + " --spp " +
                                              std::to_string(std::max(1L, std::lround(s.spp))));
        write_image(file, out, tone_, m);
    };
    const auto ends = [&](const char* ext) {
        return base.size() > 4 && base.compare(base.size() - 4, 4, ext) == 0;
    };
    if (ends(".png") || ends(".exr") || ends(".pfm")) {
        check_viewer_output(base, "the image");
        write(base);
        return;
    }
    // Both checked before either is written.
    check_viewer_output(base + ".png", "the image");
    check_viewer_output(base + ".exr", "the image");
    write(base + ".png");
    write(base + ".exr");
}

void Viewer::save_session(const std::string& path) const {
    const RenderOptions o = session_options(false);
    check_viewer_output(path, "the session file");
    const std::string text = options_to_json(o) + "\n";
    write_file_atomically(path, text.data(), text.size());
}

void Viewer::load_session(const std::string& path) {
    RenderOptions o = opts_;
    o.stop = stop_;
    options_from_session_file(path, o);  // validates
    if (std::find(sessions_read_.begin(), sessions_read_.end(), path) == sessions_read_.end())
        sessions_read_.push_back(path);
    if (!same_file(o.scene.scene_path, opts_.scene.scene_path) ||
        o.scene.width != opts_.scene.width || o.scene.height != opts_.scene.height) {
        throw Error(ErrorLocation{path, "scene", -1},
                    "the session is of another scene or image size; open it with kdtrace view");
    }
    if (!o.scene.materials.empty() && o.scene.materials.size() != materials_.size()) {
        throw Error(ErrorLocation{path, "/scene/materials", -1},
                    std::to_string(o.scene.materials.size()) + " materials for a scene of " +
                        std::to_string(materials_.size()) + " mesh instances");
    }
    // The session's camera parts over the camera the viewer started with, as `render
    // --session` puts them over the scene's: a part alone (an "eye") counts too, and one that
    // makes no camera is an error naming the session and its key, before anything changes.
    std::optional<CameraDesc> camera = o.scene.camera;
    if (!o.scene.session_camera.file.empty()) {
        check_session_camera(home_camera_, o.scene);
        camera = with_camera_overrides(home_camera_, o.scene);
        if (const std::string problem = camera_problem(*camera); !problem.empty())
            throw Error(ErrorLocation{path, "/scene", -1}, "camera: " + problem);
    }
    opts_.trace = o.trace;
    opts_.film = o.film;
    // A probe opened in the session's viewer: loaded in the background like any other.
    if (!o.scene.env_file.empty() && !same_file(o.scene.env_file, opts_.scene.env_file))
        open_probe(o.scene.env_file);
    if (o.scene.env_rotation_degrees != opts_.scene.env_rotation_degrees ||
        (o.scene.env_intensity && *o.scene.env_intensity != env_intensity_)) {
        opts_.scene.env_rotation_degrees = o.scene.env_rotation_degrees;
        if (o.scene.env_intensity) env_intensity_ = *o.scene.env_intensity;
        apply_environment();
    }
    stop_ = o.stop;
    tone_.exposure = o.film.exposure;
    if (!o.scene.materials.empty() && o.scene.materials != materials_) {
        materials_ = o.scene.materials;
        apply_materials();
    }
    apply_params();
    if (options_to_json(o) !=
        options_to_json(RenderOptions{o.scene, tree_edit_, o.trace, o.film, o.stop})) {
        tree_edit_ = o.tree;
        request_rebuild();
    }
    if (camera) set_camera(*camera);
}

std::string Viewer::summary() const {
    const WorkerStats s = worker_ ? worker_->stats() : WorkerStats{};
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "view: %zu frames (%zu unchanged, not drawn), frame ms median %.2f p99 %.2f; "
                  "preview ms median %.1f (%zu); "
                  "rebuild to full image ms median %.1f (%zu), build s median %.3f, swap to full "
                  "image ms median %.1f; "
                  "%.1f spp, %d passes, %.3f Mrays/s, error %.4f",
                  lat_.frame_ms.size(), frames_unchanged_, percentile(lat_.frame_ms, 0.5),
                  percentile(lat_.frame_ms, 0.99), percentile(lat_.preview_ms, 0.5),
                  lat_.preview_ms.size(), percentile(lat_.rebuild_ms, 0.5), lat_.rebuild_ms.size(),
                  percentile(lat_.build_seconds, 0.5), percentile(lat_.swap_ms, 0.5), s.spp,
                  s.full_passes, s.mrays_per_second, s.mean_error);
    return buf;
}

std::string Viewer::frame_stats(const std::string& label) {
    const std::vector<double> f(lat_.frame_ms.begin() + ptrdiff_t(stats_from_),
                                lat_.frame_ms.end());
    stats_from_ = lat_.frame_ms.size();
    const WorkerStats s = worker_->stats();
    char buf[256];
    std::snprintf(buf, sizeof buf,
                  "view stats %s: %zu frames, median %.2f ms, p99 %.2f ms; %.1f spp, %.3f Mrays/s",
                  label.c_str(), f.size(), percentile(f, 0.5), percentile(f, 0.99), s.spp,
                  s.mrays_per_second);
    return buf;
}

namespace {

void glfw_error(int code, const char* text) {
    std::fprintf(stderr, "kdtrace: GLFW error 0x%x: %s\n", code, text);
}

// Letterboxes the image into the area left of the panels (top-left origin).
void layout(Viewer& v, int fb_w, int fb_h) {
    const int panel = v.panels_ ? int((kSidebarWidth + 10.0f) * v.content_scale_) : 0;
    const int area_w = std::max(fb_w - panel, 1);
    const double aspect = double(v.opts_.scene.width) / double(v.opts_.scene.height);
    int w = area_w, h = int(double(area_w) / aspect + 0.5);
    if (h > fb_h) {
        h = fb_h;
        w = int(double(fb_h) * aspect + 0.5);
    }
    v.image_w_ = w;
    v.image_h_ = h;
    v.image_x_ = (area_w - w) / 2;
    v.image_y_ = (fb_h - h) / 2;
}

constexpr auto kFramePeriod = std::chrono::microseconds(16667);

// Input events seen by GLFW's callbacks (all on the UI thread, in glfwPollEvents).
uint64_t g_input_events = 0;

void count_input_events(GLFWwindow* window) {
    glfwSetCursorPosCallback(window, [](GLFWwindow*, double, double) { ++g_input_events; });
    glfwSetMouseButtonCallback(window, [](GLFWwindow*, int, int, int) { ++g_input_events; });
    glfwSetScrollCallback(window, [](GLFWwindow*, double, double) { ++g_input_events; });
    glfwSetKeyCallback(window, [](GLFWwindow*, int, int, int, int) { ++g_input_events; });
    glfwSetCharCallback(window, [](GLFWwindow*, unsigned) { ++g_input_events; });
    glfwSetCursorEnterCallback(window, [](GLFWwindow*, int) { ++g_input_events; });
    glfwSetWindowFocusCallback(window, [](GLFWwindow*, int) { ++g_input_events; });
    glfwSetWindowSizeCallback(window, [](GLFWwindow*, int, int) { ++g_input_events; });
    glfwSetWindowRefreshCallback(window, [](GLFWwindow*) { ++g_input_events; });
}

// What the frame pacer needs to know about the viewer before a tick.
FrameSignals observe(Viewer& v) {
    FrameSignals s;
    s.input_events = g_input_events;
    // Both counters only grow: their sum changes when either does. A build in flight draws
    // nothing new until it finishes, so the builder gets the UI's time meanwhile.
    s.updates = (v.worker_ ? v.worker_->updates() : 0) + v.rebuilder_->finished();
    if (v.split_) s.updates += v.split_->worker().updates() + v.split_->rebuilds_finished();
    // An image still to come, a load in flight (its progress bar moves at display rate), a
    // script command to run now or a wait that counts frames.
    s.busy = !v.have_image_ || v.loading() ||
             (v.waiting_.empty() && v.script_next_ < v.script_.size()) || v.waiting_ == "wait";
    return s;
}

}  // namespace

void run_viewer(const ViewerOptions& options) {
    Viewer v(options);
    glfwSetErrorCallback(glfw_error);
    if (!glfwInit()) throw Error("view: cannot open a window (no display? GLFW failed to start)");
    struct GlfwGuard {
        ~GlfwGuard() { glfwTerminate(); }
    } glfw_guard;
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    const int win_w = v.opts_.scene.width + int(kSidebarWidth) + 10,
              win_h = std::max(v.opts_.scene.height, 720);
    GLFWwindow* window = glfwCreateWindow(win_w, win_h, "kdtrace view", nullptr, nullptr);
    if (!window) throw Error("view: cannot create an OpenGL 3.3 core window");
    glfwMakeContextCurrent(window);
    glfwSwapInterval(1);

    IMGUI_CHECKVERSION();
    ImGui::CreateContext();
    ImGui::GetIO().IniFilename = nullptr;  // no imgui.ini next to the user's files
    ImGui::StyleColorsDark();
    count_input_events(window);  // before the ImGui backend, which chains to these
    ImGui_ImplGlfw_InitForOpenGL(window, true);
    ImGui_ImplOpenGL3_Init("#version 330 core");
    struct ImGuiGuard {
        ~ImGuiGuard() {
            ImGui_ImplOpenGL3_Shutdown();
            ImGui_ImplGlfw_Shutdown();
            ImGui::DestroyContext();
        }
    } imgui_guard;
    v.display_.init();
    v.install_drop_callback(window);

    int frames_after_script = 0;
    FramePacer pacer;
    auto last = Viewer::Clock::now();
    while (!glfwWindowShouldClose(window)) {
        const auto start = Viewer::Clock::now();
        glfwPollEvents();
        if (!pacer.due(observe(v), start)) {
            ++v.frames_unchanged_;
            std::this_thread::sleep_until(start + kFramePeriod);
            continue;
        }
        // Capped: after an idle spell the first frame's fly step is not the whole pause.
        const double dt = std::min(std::chrono::duration<double>(start - last).count(), 0.05);
        last = start;
        int fb_w = 0, fb_h = 0;
        glfwGetFramebufferSize(window, &fb_w, &fb_h);
        int ww = 0, wh = 0;
        glfwGetWindowSize(window, &ww, &wh);
        v.content_scale_ = ww > 0 ? float(fb_w) / float(ww) : 1.0f;
        layout(v, fb_w, fb_h);

        ImGui_ImplOpenGL3_NewFrame();
        ImGui_ImplGlfw_NewFrame();
        ImGui::NewFrame();
        v.handle_input(window, dt);
        v.poll_load();     // before the script, whose wait_loaded then sees the swap
        v.poll_rebuild();  // before the script, whose wait_rebuild then sees the swap
        bool script_running = false;
        try {
            script_running = v.script_step();
        } catch (const Error& e) {
            v.message_ = e.what();
            glfwSetWindowShouldClose(window, GLFW_TRUE);
            throw;
        }
        v.update_image();
        if (v.panels_ || !v.worker_) v.draw_panels();
        v.draw_file_panel();
        ImGui::Render();

        glViewport(0, 0, fb_w, fb_h);
        glClearColor(0.08f, 0.08f, 0.09f, 1.0f);
        glClear(GL_COLOR_BUFFER_BIT);
        v.draw_image(fb_h);
        glViewport(0, 0, fb_w, fb_h);
        ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
        for (const std::string& path : v.screenshot_requests_) v.screenshot(path, fb_w, fb_h);
        v.screenshot_requests_.clear();
        const bool last_frame =
            !script_running && options.frames > 0 && ++frames_after_script >= options.frames;
        if (last_frame && !options.screenshot.empty()) v.screenshot(options.screenshot, fb_w, fb_h);
        glfwSwapBuffers(window);
        v.lat_.frame_ms.push_back(ms_since(start));
        if (last_frame) break;
        // At most 60 frames a second where the swap does not wait for the display (Xvfb,
        // vsync off): the render threads get the time a spinning UI would take.
        std::this_thread::sleep_until(start + kFramePeriod);
    }
    glfwDestroyWindow(window);
    std::printf("%s\n", v.summary().c_str());
}

}  // namespace kdt::ui
