// The viewer's files: a model, scene or probe opened from the File panel's path field, by
// drag and drop or by script, loaded in the background (ui/scene_loader) with a progress bar
// while the old scene keeps rendering; the material edits of the loaded scene. Every error
// goes to the window's message line, naming the file.
#include <GLFW/glfw3.h>
#include <imgui.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <thread>

#include "renderer/core/error.h"
#include "renderer/core/fields.h"
#include "renderer/render/settings.h"
#include "ui/field_widgets.h"
#include "ui/viewer_app.h"

namespace kdt::ui {

namespace {

std::string shown(const std::string& path) {
    return path.empty() ? std::string("the default scene") : path;
}

// The message of a failed load, naming the file when the loader's own text does not.
std::string load_error(const LoadResult& r) {
    const std::string name = shown(r.what.path);
    if (r.error.find(r.what.path) != std::string::npos && !r.what.path.empty()) return r.error;
    return name + ": " + r.error;
}

// The progress bar's colour, distinct from ImGui's plots (tests find it in screenshots).
const ImVec4 kProgressColor(0.1f, 0.85f, 0.95f, 1.0f);

}  // namespace

void Viewer::open_file(const std::string& path) {
    const std::optional<LoadKind> kind = load_kind_of(path);
    if (!kind) {
        message_ = path +
                   ": not a file the viewer opens (models .ply .ply.gz .obj, scenes .json, "
                   "probes .hdr .exr .pfm)";
        return;
    }
    if (*kind == LoadKind::scene) {
        request_scene(path);
    } else {
        open_probe(path);
    }
}

void Viewer::request_scene(const std::string& path) {
    LoadRequest r;
    r.kind = LoadKind::scene;
    r.path = path;
    r.options = opts_;
    r.options.scene.scene_path = path;
    r.options.tree = tree_edit_;
    // The command line's camera and tree file belong to the command line's scene; another
    // scene has its own camera (and a tree file of another mesh would be refused).
    const SceneOptions& cli = vo_.options.scene;
    SceneOptions& s = r.options.scene;
    const bool cli_scene = path == cli.scene_path;
    s.camera = cli_scene ? cli.camera : std::nullopt;
    s.eye = cli_scene ? cli.eye : std::nullopt;
    s.target = cli_scene ? cli.target : std::nullopt;
    s.up = cli_scene ? cli.up : std::nullopt;
    s.vfov_degrees = cli_scene ? cli.vfov_degrees : std::nullopt;
    s.tree_file = cli_scene ? cli.tree_file : std::string();
    s.materials = cli_scene ? cli.materials : std::vector<MaterialDesc>();
    scene_requested_ = path;
    env_at_request_ = {opts_.scene.env_file, opts_.scene.env_rotation_degrees, env_intensity_};
    scene_loader_->request(std::move(r));
    scene_pending_ = true;
}

void Viewer::open_probe(const std::string& path) {
    EnvMapping mapping = EnvMapping::latlong;
    try {
        if (!opts_.scene.env_mapping.empty()) {
            mapping = EnvMapping(
                parse_name(kEnvMappingNames, opts_.scene.env_mapping, "scene.env_mapping"));
        }
    } catch (const Error& e) {
        message_ = e.what();
        return;
    }
    if (!worker_) {
        // No scene yet: the probe goes in as the scene's override, loaded with it.
        opts_.scene.env_file = path;
        request_scene(opts_.scene.scene_path);
        return;
    }
    LoadRequest r;
    r.kind = LoadKind::probe;
    r.path = path;
    // What apply_environment() will give the render thread once the probe has loaded.
    r.environment = prep_.scene.environment;
    r.environment.file = path;
    r.environment.mapping = mapping;
    r.environment.rotation_degrees += opts_.scene.env_rotation_degrees - env_rotation0_;
    r.environment.intensity = env_intensity_;
    probe_requested_ = path;
    probe_loader_->request(std::move(r));
    probe_pending_ = true;
}

void Viewer::poll_load() {
    if (std::optional<LoadResult> r = probe_loader_->take()) {
        probe_pending_ = false;
        for (const std::string& line : r->log) std::fprintf(stderr, "kdtrace: %s\n", line.c_str());
        if (!r->probe) {
            message_ = load_error(*r);
            std::fprintf(stderr, "kdtrace: view: %s\n", message_.c_str());
        } else if (worker_) {
            // The probe is known to load; the render thread builds its light again with the
            // rotation and intensity in force then.
            prep_.scene.environment.file = r->what.environment.file;
            prep_.scene.environment.mapping = r->what.environment.mapping;
            opts_.scene.env_file = r->what.path;
            apply_environment();
            message_.clear();
            status_ = "probe " + r->what.path;
        }
    }
    std::optional<LoadResult> r = scene_loader_->take();
    if (!r) return;
    scene_pending_ = false;
    for (const std::string& line : r->log) std::fprintf(stderr, "kdtrace: %s\n", line.c_str());
    if (!r->prepared) {
        message_ = load_error(*r);
        std::fprintf(stderr, "kdtrace: view: %s\n", message_.c_str());
        return;
    }
    // The environment edited while the scene loaded (by the user or a probe swapped in).
    const SceneOptions edited = opts_.scene;
    const EnvironmentDesc edited_env = prep_.scene.environment;
    const float edited_intensity = env_intensity_;
    prep_ = std::move(*r->prepared);
    opts_.scene = r->what.options.scene;
    opts_.tree = r->what.options.tree;
    env_rotation0_ = opts_.scene.env_rotation_degrees;
    env_intensity_ = prep_.scene.environment.intensity;
    bool env_edited = false;
    if (edited.env_file != env_at_request_.file) {
        opts_.scene.env_file = edited.env_file;
        prep_.scene.environment.file = edited_env.file;
        prep_.scene.environment.mapping = edited_env.mapping;
        env_edited = true;
    }
    if (edited.env_rotation_degrees != env_at_request_.rotation_degrees) {
        opts_.scene.env_rotation_degrees = edited.env_rotation_degrees;  // added to the scene's
        env_edited = true;
    }
    if (edited_intensity != env_at_request_.intensity) {
        env_intensity_ = edited_intensity;
        env_edited = true;
    }
    home_camera_ = camera_ = prep_.snapshot->camera_desc;
    tree_ = prep_.snapshot->scene->tree;
    materials_.clear();
    for (const MeshInstance& m : prep_.scene.meshes) materials_.push_back(m.material);
    material_instance_ = 0;
    materials_edited_ = false;
    message_.clear();
    char buf[512];
    std::snprintf(buf, sizeof buf, "%s: %zu triangles; read %.2f s, tree %.2f s%s",
                  shown(r->what.path).c_str(),
                  size_t(prep_.snapshot->scene->mesh->triangle_count()), prep_.load_seconds,
                  prep_.tree_seconds, tree_source_text(prep_, opts_.scene).c_str());
    status_ = buf;
    std::printf("view: loaded %s\n", status_.c_str());
    std::fflush(stdout);
    if (!worker_) {
        worker_ = std::make_unique<RenderWorker>(prep_.snapshot, opts_.trace, opts_.film, stop_,
                                                 vo_.preview_divisor);
        if (!vo_.session.empty()) load_session(vo_.session);  // a bad session ends the viewer
        return;
    }
    worker_->set_snapshot(prep_.snapshot);
    // Side B renders its own tree of the old mesh: it closes rather than show another scene.
    if (split_) {
        set_split(false);
        status_ += "; split view closed (a new scene)";
    }
    set_camera(camera_);
    // The render thread keeps a light set by apply_environment() across snapshots: give it
    // the new scene's (with the probe override, rotation and intensity in force).
    if (env_overridden_ || env_edited) apply_environment();
    // Tree parameters edited while the scene loaded apply to it.
    if (auto_rebuild_ && !same_fields(kd_tree_fields(), tree_edit_, opts_.tree)) request_rebuild();
}

void Viewer::finish_loading() {
    for (poll_load(); loading(); poll_load())
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
}

void Viewer::apply_materials() {
    if (!worker_) return;
    try {
        worker_->set_snapshot(with_materials(*worker_->snapshot(), materials_));
        if (split_) {  // side B keeps its own tree
            RenderWorker& b = split_->worker();
            b.set_snapshot(with_materials(*b.snapshot(), materials_));
        }
        materials_edited_ = true;
    } catch (const Error& e) {
        message_ = e.what();
    }
}

void Viewer::set_material(const std::string& name, const std::string& value) {
    if (materials_.empty()) throw Error("material: no scene is loaded");
    // A number in `range`, checked as the float the material holds: the scene file's ranges
    // (renderer/scene/scene.h), or the viewer's narrower ior range, so that a saved session
    // loads.
    const auto number = [&](const MaterialRange& range) {
        double v = 0.0;
        if (!detail::parse_number(value, v) || !range.contains_as_float(v)) {
            throw Error("material." + name + " must be a number in " + range.text() + " (got '" +
                        value + "')");
        }
        return float(v);
    };
    const auto colour = [&](const MaterialRange& range) {
        Vec3f c{0.0f};
        size_t at = 0;
        for (int i = 0; i < 3; ++i) {
            const size_t comma = i < 2 ? value.find(',', at) : value.size();
            double v = 0.0;
            if (comma == std::string::npos ||
                !detail::parse_number(value.substr(at, comma - at), v) ||
                !range.contains_as_float(v) || (i == 2 && value.find(',', at) != value.npos)) {
                throw Error("material." + name + " must be R,G,B with each in " + range.text() +
                            " (got '" + value + "')");
            }
            c[i] = float(v);
            at = comma + 1;
        }
        return c;
    };
    if (name == "instance") {
        double v = 0.0;
        const double last = double(materials_.size() - 1);
        if (!detail::parse_number(value, v) || !(v >= 0.0 && v <= last)) {
            throw Error("material.instance must be a number in [0, " + detail::number_text(last) +
                        "] (got '" + value + "')");
        }
        material_instance_ = int(v);
        return;
    }
    MaterialDesc& m = materials_[size_t(material_instance_)];
    if (name == "type") {
        m.type = MaterialType(parse_name(kMaterialTypeNames, value, "material.type"));
    } else if (name == "albedo") {
        m.albedo = colour(kAlbedoRange);
    } else if (name == "emission") {
        m.emission = colour(kEmissionRange);
    } else if (name == "ior") {
        m.ior = number(kIorEditRange);
    } else if (name == "roughness") {
        m.roughness = number(kRoughnessRange);
    } else {
        throw Error("no option material." + name +
                    " (material has instance, type, albedo, emission, ior and roughness)");
    }
    apply_materials();
}

void Viewer::draw_file_panel() {
    const LoadProgress sp = scene_loader_->progress(), pp = probe_loader_->progress();
    if (loading()) {
        // Over the image, which shows the old scene (if any) meanwhile, until poll_load()
        // takes the result.
        const LoadProgress& p = scene_pending_ ? sp : pp;
        const float s = content_scale_ > 0.0f ? content_scale_ : 1.0f;
        ImGui::SetNextWindowPos(ImVec2((float(image_x_) + float(image_w_) * 0.5f) / s,
                                       (float(image_y_) + float(image_h_) * 0.5f) / s),
                                ImGuiCond_Always, ImVec2(0.5f, 0.5f));
        ImGui::SetNextWindowSize(ImVec2(300.0f, 72.0f),
                                 ImGuiCond_Always);  // no auto-fit: shown at once
        ImGui::Begin("Loading", nullptr,
                     ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_NoInputs |
                         ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoFocusOnAppearing);
        // The file's name only: a long path would push the bar out of the fixed-size window.
        const std::string name =
            p.path.empty() ? shown(p.path) : std::filesystem::path(p.path).filename().string();
        ImGui::Text("loading %s", name.c_str());
        const char* stage = !p.busy     ? "done"
                            : p.started ? kPrepareStageNames[size_t(p.stage)]
                                        : "queued";
        char label[96];
        std::snprintf(label, sizeof label, "%s, %.1f s", stage, p.seconds);
        ImGui::PushStyleColor(ImGuiCol_PlotHistogram, kProgressColor);
        const float fraction = !p.busy ? 1.0f : p.started ? (float(p.stage) + 1.0f) / 4.0f : 0.05f;
        ImGui::ProgressBar(fraction, ImVec2(-1, 0), label);
        ImGui::PopStyleColor();
        ImGui::End();
    }
}

void Viewer::file_section() {
    static char path[1024] = "";
    ImGui::SetNextItemWidth(ImGui::GetContentRegionAvail().x - 60.0f);
    const bool enter =
        ImGui::InputText("##path", path, sizeof path, ImGuiInputTextFlags_EnterReturnsTrue);
    ImGui::SameLine();
    if ((ImGui::Button("Open") || enter) && path[0] != '\0') open_file(path);
    ImGui::TextDisabled("or drop a file on the window");
    if (!status_.empty()) ImGui::TextWrapped("%s", status_.c_str());
    if (!message_.empty()) {
        ImGui::PushStyleColor(ImGuiCol_Text, ImVec4(1, 0.4f, 0.3f, 1));
        ImGui::TextWrapped("%s", message_.c_str());
        ImGui::PopStyleColor();
    }
}

void Viewer::install_drop_callback(GLFWwindow* window) {
    glfwSetWindowUserPointer(window, this);
    glfwSetDropCallback(window, [](GLFWwindow* w, int count, const char** paths) {
        auto* v = static_cast<Viewer*>(glfwGetWindowUserPointer(w));
        for (int i = 0; v && i < count; ++i) v->open_file(paths[i]);
    });
}

}  // namespace kdt::ui
