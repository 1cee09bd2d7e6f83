// The viewer's state and its parts, shared by viewer.cpp (window, frame loop, input, files),
// viewer_panels.cpp (ImGui panels) and viewer_script.cpp (scripted input). Internal to ui/.
#pragma once

#include <chrono>
#include <future>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "renderer/core/color.h"
#include "renderer/render/prepare.h"
#include "ui/display.h"
#include "ui/frame_pacer.h"
#include "ui/heat_map.h"
#include "ui/render_worker.h"
#include "ui/scene_loader.h"
#include "ui/split_view.h"
#include "ui/tree_rebuild.h"
#include "ui/viewer.h"

struct GLFWwindow;

namespace kdt::ui {

/// The sidebar window (Viewer::draw_panels()) and its width in ImGui units; the image is
/// letterboxed into the area left of it, 10 units apart.
inline constexpr const char* kSidebarName = "kdtrace##sidebar";
inline constexpr float kSidebarWidth = 370.0f;

/// The ior the viewer edits (its slider and `set material.ior`): glasses and crystals, inside
/// what scene files accept (kIorRange), so that a saved session loads. Other material fields
/// are edited in the scene file's ranges themselves (kAlbedoRange, ...).
inline constexpr MaterialRange kIorEditRange{1.0f, 10.0f};
static_assert(kIorRange.contains(kIorEditRange.lo) && kIorRange.contains(kIorEditRange.hi));
/// The roughness slider's lower end (scene files require roughness > 0).
inline constexpr float kMinRoughness = 0.001f;
static_assert(kRoughnessRange.contains(kMinRoughness));

enum class ViewMode : int { radiance, heat_nodes, heat_triangles, normals, depth };

/// The debug layer a view mode shows; nullopt for radiance.
std::optional<DebugLayer> debug_layer(ViewMode mode);

/// Latencies the viewer measures for its summary, in milliseconds.
struct Latencies {
    std::vector<double> frame_ms;       ///< work per frame, input to buffer swap
    std::vector<double> preview_ms;     ///< camera change to the first preview on screen
    std::vector<double> rebuild_ms;     ///< tree request to the first full image with it
    std::vector<double> swap_ms;        ///< of rebuild_ms, the new tree's swap to that image
    std::vector<double> build_seconds;  ///< the rebuilds' build times
};

class Viewer {
public:
    using Clock = std::chrono::steady_clock;

    /// Checks the options and the script and starts loading the scene in the background
    /// (poll_load() starts the render thread once it is loaded); no window yet.
    explicit Viewer(const ViewerOptions& options);

    // ---- changes (any thread-safe order; each restarts the image with a preview)
    void set_camera(const CameraDesc& camera);
    /// set_camera() for a user's move (mouse, keys, script): a camera that camera_problem()
    /// refuses is not taken (the message says why) and the old one stays.
    void move_camera(const CameraDesc& camera);
    void request_rebuild();
    /// Applies opts_.trace / film / stop_ to the render thread; an error goes to message_.
    void apply_params();
    void set_view_mode(ViewMode mode);
    /// Starts (with B's tree parameters equal to A's) or stops the split view (split_view.cpp).
    void set_split(bool on);
    /// Applies opts_.scene.env_rotation_degrees and env_intensity_ to the environment.
    void apply_environment();
    /// Sets "group.name" to `value` through the range tables (tree fields rebuild when
    /// auto-rebuild is on). Throws kdt::Error naming the field.
    void set_option(const std::string& name, const std::string& value);

    // ---- per frame
    void poll_rebuild();
    /// Copies the published image when it changed and uploads it (GL context current).
    void update_image();
    void upload(const FilmImage& image);
    /// Draws the image in its rectangle of a framebuffer fb_height pixels high.
    void draw_image(int fb_height);
    /// The sidebar at the window's right edge, its full height: File, kd-tree, Stats, View
    /// and Render sections (File only before a scene is loaded); it scrolls when taller.
    void draw_panels();
    /// Throws kdt::Error naming the first command of the script that does not exist.
    void check_script() const;
    /// Runs script commands until one waits; false once the script is done.
    bool script_step();
    void handle_input(GLFWwindow* window, double dt);

    // ---- files
    /// The whole window as a PNG (GL context current).
    void screenshot(const std::string& path, int fb_width, int fb_height) const;
    /// The image on screen: base + ".png" (tone-mapped) and base + ".exr" (linear), with the
    /// render metadata; a base ending in .png, .exr or .pfm writes that one file.
    void save_image(const std::string& base) const;
    /// The options of what is on screen: opts_ with the camera, the stop conditions, the
    /// environment's intensity, the materials as edited and the display's exposure and tone
    /// curve; the tree parameters are tree_edit_ (the session's) or those of the tree
    /// rendering now (`tree_in_use`, the image's).
    RenderOptions shown_options(bool tree_in_use) const;
    /// shown_options() with absolute file names: what sessions and saved images hold, since
    /// they are read from any directory.
    RenderOptions session_options(bool tree_in_use) const;
    /// The session (session_options(false) as JSON) through a temporary file.
    void save_session(const std::string& path) const;
    void load_session(const std::string& path);
    /// The files the viewer reads or is loading: the model or scene file and its meshes, the
    /// probe, a --tree file, the views file and the session files it was started from or loaded.
    std::vector<std::string> input_files() const;
    /// check_output() of a viewer output against input_files(): throws kdt::Error naming
    /// `path` when writing it would replace an input, or it is a FIFO, device or directory
    /// (checked without opening it), or it may not be replaced.
    void check_viewer_output(const std::string& path, const char* what) const;

    // ---- opening files in the background (viewer_files.cpp); errors go to message_
    /// A model or scene (.ply, .ply.gz, .obj, .json: replaces the scene once loaded, the old
    /// one rendering meanwhile) or a probe (.hdr, .exr, .pfm: replaces the environment).
    void open_file(const std::string& path);
    /// Loads `path` ("" = the built-in default scene) with the current options and tree
    /// parameters, the camera of the new scene; a newer request cancels this one.
    void request_scene(const std::string& path);
    void open_probe(const std::string& path);
    /// Takes finished loads: swaps in the scene (starting the render thread at the first) or
    /// the environment, or shows the error naming the file.
    void poll_load();
    /// Blocks until loading() is false, polling the loads (tests and headless callers; throws
    /// as poll_load() does).
    void finish_loading();
    /// A scene or probe request is not yet swapped in (or failed).
    bool loading() const { return scene_pending_ || probe_pending_; }
    /// While a file loads, its progress bar over the image.
    void draw_file_panel();
    /// The sidebar's File section: path field, Open, what is loaded, the last error.
    void file_section();
    /// Applies materials_ to the scene rendering now (restarts the image).
    void apply_materials();
    /// material.NAME for the script: instance N (which one the others edit), type NAME,
    /// albedo R,G,B, emission R,G,B, ior X, roughness X. Throws kdt::Error naming the field.
    void set_material(const std::string& name, const std::string& value);
    /// Registers the GLFW drop callback: dropped files go to open_file().
    void install_drop_callback(GLFWwindow* window);

    std::string summary() const;
    /// "view stats LABEL: N frames, median M ms, p99 P ms" over the frames since the last call.
    std::string frame_stats(const std::string& label);

    ViewerOptions vo_;
    RenderOptions opts_;   ///< resolved; the panels edit trace, film and tree_edit_
    StopConditions stop_;  ///< the viewer's own: no condition renders on
    Prepared prep_;
    CameraDesc home_camera_, camera_;
    std::unique_ptr<RenderWorker> worker_;
    std::unique_ptr<TreeRebuilder> rebuilder_;
    KdTreeParams tree_edit_;
    float env_rotation0_ = 0.0f;          ///< opts_.scene.env_rotation_degrees as loaded
    float env_intensity_ = 1.0f;          ///< the environment's intensity now
    std::shared_ptr<const KdTree> tree_;  ///< the tree rendering now (for its stats)

    // Loading (viewer_files.cpp). worker_ and tree_ are null until the first scene loaded.
    std::unique_ptr<SceneLoader> scene_loader_, probe_loader_;
    bool scene_pending_ = false, probe_pending_ = false;
    std::string scene_requested_, probe_requested_;  ///< the last requests' files
    std::vector<std::string> sessions_read_;         ///< session files loaded
    /// The environment as the last scene request took it: edits made while that scene loads
    /// (a probe, rotation, intensity) differ from it and are applied to the scene swapped in.
    struct EnvAtRequest {
        std::string file;
        float rotation_degrees = 0.0f, intensity = 1.0f;
    } env_at_request_;
    bool env_overridden_ = false;  ///< apply_environment() was called: the worker keeps its light
    std::string status_;           ///< what is loaded, shown in the File panel
    std::vector<MaterialDesc> materials_;  ///< per instance, as edited
    int material_instance_ = 0;            ///< the instance the Render panel edits
    bool materials_edited_ = false;

    FilmDisplay display_;
    FilmImage image_, preview_;
    bool have_image_ = false;
    ToneParams tone_;
    ViewMode view_ = ViewMode::radiance;
    HeatScale heat_scale_;
    std::unique_ptr<SplitView> split_;  ///< the split view's side B while it is on
    std::future<void> split_retiring_;  ///< destroys a split view turned off (split_view.cpp)
    bool auto_rebuild_ = true, panels_ = true, paused_ = false;
    std::string message_;  ///< last error, shown in the window
    int image_x_ = 0, image_y_ = 0, image_w_ = 0, image_h_ = 0;  ///< framebuffer rectangle
    double mouse_x_ = 0.0, mouse_y_ = 0.0;
    float content_scale_ = 1.0f;

    ImageCopyPacer image_copies_;  ///< when the session's image is copied and uploaded

    // Frame pacing (run_viewer draws a frame only when it may differ from the last one).
    size_t frames_unchanged_ = 0;  ///< ticks with no frame drawn

    // Latency bookkeeping.
    Latencies lat_;
    Clock::time_point camera_changed_at_{};
    bool awaiting_preview_ = false;
    uint64_t camera_restart_ = 0;        ///< the worker's restart count after the camera change
    uint64_t render_failures_seen_ = 0;  ///< RenderWorker::failures() shown in message_
    uint64_t worker_updates_seen_ = 0;   ///< RenderWorker::updates() when env_error_ was read
    std::string env_error_;              ///< the render thread's refusal of the environment
    Clock::time_point rebuild_requested_at_{};
    uint64_t rebuild_restarts_ = 0;   ///< worker restarts when the new tree was swapped in
    Clock::time_point swapped_at_{};  ///< when the new tree was given to the worker
    bool awaiting_rebuild_image_ = false;

    // Script state.
    std::vector<std::string> script_;
    size_t script_next_ = 0;
    int wait_frames_ = 0;
    std::string waiting_;  ///< the wait command in force ("" = none)
    int wait_count_ = 0;
    std::vector<std::string> screenshot_requests_;
    size_t stats_from_ = 0;  ///< first frame of the next frame_stats()
};

}  // namespace kdt::ui
