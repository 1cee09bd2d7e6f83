// The viewer's ImGui panels: kd-tree, render, view, stats and the pixel inspector. Every
// parameter widget comes from a range table (field_widgets); this file lays them out.
#include <imgui.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "renderer/core/error.h"
#include "ui/field_widgets.h"
#include "ui/viewer_app.h"

namespace kdt::ui {

namespace {

bool section(const char* name) {
    return ImGui::CollapsingHeader(name, ImGuiTreeNodeFlags_DefaultOpen);
}

// The kd-tree widgets; those the chosen builder does not read are shown but disabled.
bool tree_widgets(const char* group, KdTreeParams& p, std::string* error) {
    bool changed = false;
    for (const Field<KdTreeParams>& f : kd_tree_fields()) {
        const bool applies = kd_tree_field_applies(p, f.name);
        ImGui::BeginDisabled(!applies);
        changed |= field_widget(group, p, f, error);
        ImGui::EndDisabled();
    }
    return changed;
}

void tree_panel(Viewer& v) {
    std::string error;
    if (tree_widgets("tree", v.tree_edit_, &error) && v.auto_rebuild_) v.request_rebuild();
    if (!error.empty()) v.message_ = error;
    ImGui::Checkbox("auto-rebuild", &v.auto_rebuild_);
    ImGui::SameLine();
    if (ImGui::Button("Rebuild")) v.request_rebuild();
    if (v.rebuilder_->busy()) {
        ImGui::SameLine();
        ImGui::TextUnformatted("building...");
    }
}

void render_panel(Viewer& v) {
    std::string error;
    const FilmParams film_before = v.opts_.film;
    bool changed = field_widgets("trace", v.opts_.trace, trace_fields(), &error);
    if (field_widgets("film", v.opts_.film, film_fields(), &error)) {
        // Exposure is applied by the display shader: it alone restarts nothing.
        FilmParams f = film_before;
        f.exposure = v.opts_.film.exposure;
        v.tone_.exposure = v.opts_.film.exposure;
        changed |= !same_fields(film_fields(), f, v.opts_.film);
    }
    changed |= field_widgets("stop", v.stop_, stop_fields(), &error);
    if (!error.empty()) v.message_ = error;
    if (changed) v.apply_params();
    if (ImGui::Button(v.paused_ ? "Resume" : "Pause")) {
        v.paused_ = !v.paused_;
        v.worker_->set_paused(v.paused_);
        if (v.split_) v.split_->worker().set_paused(v.paused_);
    }
}

void environment_panel(Viewer& v) {
    std::string error;
    bool changed = false;
    if (const Field<SceneOptions>* rot = find_field(scene_fields(), "env_rotation_degrees"))
        changed |= field_widget("scene", v.opts_.scene, *rot, &error);
    float intensity = v.env_intensity_;
    // The intensity override has no table entry; its range is the scene file's, [0, 3e38].
    if (ImGui::DragFloat("env_intensity##scene", &intensity, 0.01f, 0.0f, 3e38f, "%.4g") &&
        std::isfinite(intensity) && intensity >= 0.0f) {
        v.env_intensity_ = intensity;
        changed = true;
    }
    if (!error.empty()) v.message_ = error;
    if (changed) v.apply_environment();
    // The probe: loaded in the background, then it replaces the environment.
    static char probe[1024] = "";
    const bool enter =
        ImGui::InputText("##probe", probe, sizeof probe, ImGuiInputTextFlags_EnterReturnsTrue);
    ImGui::SameLine();
    if ((ImGui::Button("Load probe") || enter) && probe[0] != '\0') v.open_probe(probe);
    ImGui::TextDisabled("environment: %s", v.prep_.scene.environment.file.empty()
                                               ? "constant colour"
                                               : v.prep_.scene.environment.file.c_str());
    const std::string failed = v.worker_->stats().error;
    if (!failed.empty()) {  // wrapped: the whole reason, however long
        ImGui::PushStyleColor(ImGuiCol_Text, ImVec4(1, 0.4f, 0.3f, 1));
        ImGui::TextWrapped("%s", failed.c_str());
        ImGui::PopStyleColor();
    }
}

// A colour ramp as a bar the width of the panel, from ramp(0) on the left to ramp(1).
template <class Ramp>
ImVec2 legend_bar(Ramp ramp) {
    ImDrawList* dl = ImGui::GetWindowDrawList();
    const ImVec2 p = ImGui::GetCursorScreenPos();
    const float w = ImGui::GetContentRegionAvail().x, h = 14.0f;
    constexpr int kSteps = 32;
    for (int i = 0; i < kSteps; ++i) {
        const Vec3f a = ramp(float(i) / kSteps), b = ramp(float(i + 1) / kSteps);
        dl->AddRectFilledMultiColor(ImVec2(p.x + w * float(i) / kSteps, p.y),
                                    ImVec2(p.x + w * float(i + 1) / kSteps, p.y + h),
                                    ImColor(a.x, a.y, a.z), ImColor(b.x, b.y, b.z),
                                    ImColor(b.x, b.y, b.z), ImColor(a.x, a.y, a.z));
    }
    ImGui::Dummy(ImVec2(w, h + 2.0f));
    return ImVec2(p.x, w);
}

// The legend of the debug view on screen: its colour scale with the frame's range (in a
// split view, both sides' range, which both are coloured with).
void legend(const Viewer& v) {
    const HeatScale s = v.split_ ? widen(v.heat_scale_, v.split_->scale()) : v.heat_scale_;
    switch (v.view_) {
        case ViewMode::radiance:
            return;
        case ViewMode::heat_nodes:
        case ViewMode::heat_triangles: {
            const ImVec2 at = legend_bar([](float t) { return heat_ramp(0.05f + 0.95f * t); });
            // The frame's mean as a green mark on the bar (side B's in cyan).
            const float y = ImGui::GetCursorScreenPos().y - 18.0f;
            auto mark = [&](double mean, ImU32 colour) {
                const float x = at.x + at.y * heat_position(float(mean), s);
                ImGui::GetWindowDrawList()->AddLine(ImVec2(x, y - 2.0f), ImVec2(x, y + 16.0f),
                                                    colour, 2.0f);
            };
            mark(s.mean, IM_COL32(0, 255, 0, 255));
            if (v.split_) {
                mark(v.split_->scale().mean, IM_COL32(0, 220, 255, 255));
                ImGui::Text("%.1f (log scale) %.1f; mean A %.2f (green), B %.2f (cyan)", s.lo, s.hi,
                            s.mean, v.split_->scale().mean);
            } else {
                ImGui::Text("%.1f (log scale) %.1f; mean %.2f (green)", s.lo, s.hi, s.mean);
            }
            return;
        }
        case ViewMode::normals:
            ImGui::TextUnformatted("rgb = n * 0.5 + 0.5 (world x, y, z); grey checks: sky");
            ImGui::Text("sky %.1f %% of the pixels", 100.0 * s.sky_fraction);
            return;
        case ViewMode::depth:
            legend_bar(depth_ramp);
            ImGui::Text("%.4g (log scale) %.4g, mean %.4g; sky %.1f %% (grey checks)", s.lo, s.hi,
                        s.mean, 100.0 * s.sky_fraction);
            return;
    }
}

// The split view's side B: its kd-tree widgets (from kd_tree_fields(), as the kd-tree panel)
// and both sides' parameters and speed, so the faster configuration is read off directly.
void split_panel(Viewer& v) {
    SplitView& sv = *v.split_;
    std::string error;
    if (ImGui::TreeNode("tree B parameters")) {
        if (tree_widgets("treeB", sv.tree_edit(), &error)) sv.request_rebuild();
        ImGui::TreePop();
    }
    if (!error.empty()) v.message_ = error;
    ImGui::SliderFloat("divider", &sv.divider, 0.0f, 1.0f, "%.2f");
    if (sv.settling()) ImGui::TextUnformatted("B: building its tree...");
    const WorkerStats a = v.worker_->stats(), b = sv.worker().stats();
    if (!ImGui::BeginTable("split", 3, ImGuiTableFlags_Borders | ImGuiTableFlags_SizingFixedFit))
        return;
    ImGui::TableSetupColumn("");
    ImGui::TableSetupColumn("A (left)");
    ImGui::TableSetupColumn("B (right)");
    ImGui::TableHeadersRow();
    auto row = [](const char* name, const std::string& left, const std::string& right) {
        ImGui::TableNextRow();
        ImGui::TableNextColumn();
        ImGui::TextUnformatted(name);
        ImGui::TableNextColumn();
        ImGui::TextUnformatted(left.c_str());
        ImGui::TableNextColumn();
        ImGui::TextUnformatted(right.c_str());
    };
    // The parameters of the trees rendering now: builder, q, n0 and depth always, any other
    // field where they differ.
    for (const Field<KdTreeParams>& f : kd_tree_fields()) {
        const std::string l = field_text(f, v.opts_.tree), r = field_text(f, sv.tree_params());
        const std::string name = f.name;
        if (l != r || name == "builder" || name == "q" || name == "n0" || name == "max_depth")
            row(f.name, l, r);
    }
    auto num = [](const char* fmt, double x) {
        char buf[32];
        std::snprintf(buf, sizeof buf, fmt, x);
        return std::string(buf);
    };
    row("tree depth", num("%.0f", double(v.tree_->stats().max_depth_reached)),
        num("%.0f", double(sv.tree()->stats().max_depth_reached)));
    row("nodes", num("%.0f", double(v.tree_->stats().nodes)),
        num("%.0f", double(sv.tree()->stats().nodes)));
    row("Mrays/s", num("%.3f", a.mrays_per_second), num("%.3f", b.mrays_per_second));
    row("nodes/ray", num("%.2f", a.nodes_per_ray), num("%.2f", b.nodes_per_ray));
    row("tris/ray", num("%.2f", a.triangles_per_ray), num("%.2f", b.triangles_per_ray));
    row("spp", num("%.1f", a.spp), num("%.1f", b.spp));
    ImGui::EndTable();
}

// The material of one instance (the model's, for a model file), applied live.
void material_panel(Viewer& v) {
    if (v.materials_.empty()) return;
    const int n = int(v.materials_.size());
    if (n > 1) ImGui::SliderInt("instance", &v.material_instance_, 0, n - 1);
    v.material_instance_ = std::clamp(v.material_instance_, 0, n - 1);
    MaterialDesc& m = v.materials_[size_t(v.material_instance_)];
    bool changed = false;
    int type = int(m.type);
    if (ImGui::Combo("material", &type, kMaterialTypeNames.data(),
                     int(kMaterialTypeNames.size()))) {
        m.type = MaterialType(type);
        changed = true;
    }
    // The fields the type uses: the others would change nothing (and are not saved).
    if (material_uses(m.type, MaterialField::albedo))
        changed |= ImGui::ColorEdit3("albedo", &m.albedo.x, ImGuiColorEditFlags_Float);
    if (material_uses(m.type, MaterialField::ior))
        changed |=
            ImGui::DragFloat("ior", &m.ior, 0.005f, kIorEditRange.lo, kIorEditRange.hi, "%.3f");
    if (material_uses(m.type, MaterialField::roughness))
        changed |= ImGui::DragFloat("roughness", &m.roughness, 0.005f, kMinRoughness,
                                    kRoughnessRange.hi, "%.3f", ImGuiSliderFlags_AlwaysClamp);
    if (material_uses(m.type, MaterialField::emission)) {
        changed |= ImGui::ColorEdit3("emission", &m.emission.x,
                                     ImGuiColorEditFlags_Float | ImGuiColorEditFlags_HDR);
    }
    if (changed) {
        // The scene file's ranges (renderer/scene/scene.h; typed values may be outside).
        m.albedo = glm::clamp(m.albedo, Vec3f(kAlbedoRange.lo), Vec3f(kAlbedoRange.hi));
        if (!kRoughnessRange.contains(m.roughness))
            m.roughness = m.roughness > kRoughnessRange.hi ? kRoughnessRange.hi : kMinRoughness;
        m.emission = glm::clamp(m.emission, Vec3f(kEmissionRange.lo), Vec3f(kEmissionRange.hi));
        v.apply_materials();
    }
}

void view_panel(Viewer& v) {
    int mode = int(v.view_);
    ImGui::RadioButton("radiance", &mode, 0);
    ImGui::SameLine();
    ImGui::RadioButton("nodes/sample", &mode, 1);
    ImGui::SameLine();
    ImGui::RadioButton("triangles/sample", &mode, 2);
    ImGui::RadioButton("normals", &mode, 3);
    ImGui::SameLine();
    ImGui::RadioButton("depth", &mode, 4);
    ImGui::SameLine();
    bool split = v.split_ != nullptr;
    if (ImGui::Checkbox("split view", &split)) v.set_split(split);
    if (mode != int(v.view_)) v.set_view_mode(ViewMode(mode));
    int curve = int(v.tone_.curve);
    if (ImGui::Combo("tone curve", &curve, kToneCurveNames.data(), int(kToneCurveNames.size())))
        v.tone_.curve = ToneCurve(curve);
    legend(v);
}

void stats_panel(Viewer& v) {
    const WorkerStats s = v.worker_->stats();
    const KdTreeStats& t = v.tree_->stats();
    ImGui::Text("tree: %llu nodes, %llu leaves (%llu empty)", (unsigned long long)t.nodes,
                (unsigned long long)t.leaves, (unsigned long long)t.empty_leaves);
    ImGui::Text("built in %.3f s", t.build_seconds);
    ImGui::Text("depth %u, %.2f refs/tri, %.1f bytes/tri", t.max_depth_reached, t.refs_per_triangle,
                t.bytes_per_triangle);
    ImGui::Text("leaf size: mean %.2f, max %u", t.mean_leaf_size, t.max_leaf_size);
    ImGui::Text("splits: median %llu, centre %llu, cut-off %llu, SAH %llu",
                (unsigned long long)t.median_splits, (unsigned long long)t.center_splits,
                (unsigned long long)t.cutoff_splits, (unsigned long long)t.sah_splits);
    std::vector<float> hist(t.depth_histogram.begin(), t.depth_histogram.end());
    if (!hist.empty()) {
        ImGui::TextUnformatted("leaves by depth, 0 to the deepest:");
        ImGui::PlotHistogram("##leaves by depth", hist.data(), int(hist.size()), 0, nullptr, 0.0f,
                             FLT_MAX, ImVec2(ImGui::GetContentRegionAvail().x, 50));
    }
    ImGui::Separator();
    ImGui::Text("%.2f Mrays/s, %.1f spp, %d passes%s%s", s.mrays_per_second, s.spp, s.full_passes,
                s.done ? " (done)" : "", s.paused ? " (paused)" : "");
    ImGui::Text("%.1f nodes, %.1f triangles per ray", s.nodes_per_ray, s.triangles_per_ray);
    ImGui::Text("estimated relative error %.4f", s.mean_error);
    if (!s.error_curve.empty()) {
        std::vector<float> e;
        for (const auto& [sec, err] : s.error_curve) e.push_back(float(err));
        ImGui::Text("error over the first %.1f s:", s.error_curve.back().first);
        ImGui::PlotLines("##error curve", e.data(), int(e.size()), 0, nullptr, 0.0f, FLT_MAX,
                         ImVec2(ImGui::GetContentRegionAvail().x, 60));
    }
    if (!v.lat_.frame_ms.empty()) ImGui::Text("UI frame %.2f ms", v.lat_.frame_ms.back());
}

void inspector(Viewer& v) {
    const double sx = v.mouse_x_ * v.content_scale_ - v.image_x_;
    const double sy = v.mouse_y_ * v.content_scale_ - v.image_y_;
    if (v.image_w_ <= 0 || sx < 0 || sy < 0 || sx >= v.image_w_ || sy >= v.image_h_) {
        ImGui::TextUnformatted("(mouse over the image)");
        return;
    }
    // In the pixels of the image the session publishes now (the preview's while it shows).
    const int w = v.image_.width > 0 ? v.image_.width : v.worker_->width();
    const int h = v.image_.height > 0 ? v.image_.height : v.worker_->height();
    const int x = int(sx / v.image_w_ * w), y = int(sy / v.image_h_ * h);
    // Right of a split view's divider, side B's pixel.
    const bool b = v.split_ && sx >= v.split_->divider * v.image_w_;
    const std::optional<PixelInfo> p =
        (b ? v.split_->worker() : *v.worker_).session().inspect(x, y);
    if (v.split_) ImGui::TextUnformatted(b ? "side B (right)" : "side A (left)");
    if (!p) {
        ImGui::Text("pixel %d %d: preview", x, y);
        return;
    }
    ImGui::Text("pixel %d %d: rgb %.4g %.4g %.4g", x, y, p->rgb.x, p->rgb.y, p->rgb.z);
    ImGui::Text("%u samples, rel. error %.4g", p->samples, p->relative_error);
    ImGui::Text("%.1f nodes, %.1f triangles per sample", p->nodes_per_sample,
                p->triangles_per_sample);
    if (p->depth != 0.0f) {
        ImGui::Text("normal %.3f %.3f %.3f, depth %.4g", p->normal.x, p->normal.y, p->normal.z,
                    p->depth);
    }
}

void files_panel(Viewer& v) {
    static char path[512] = "kdtrace-session.json";
    ImGui::InputText("file", path, sizeof path);
    auto guarded = [&](auto f) {
        try {
            f();
            v.message_.clear();
        } catch (const Error& e) {
            v.message_ = e.what();
        }
    };
    if (ImGui::Button("Save session")) guarded([&] { v.save_session(path); });
    ImGui::SameLine();
    if (ImGui::Button("Load session")) guarded([&] { v.load_session(path); });
    ImGui::SameLine();
    if (ImGui::Button("Save image (F12)")) guarded([&] { v.save_image("kdtrace-view"); });
}

}  // namespace

void Viewer::draw_panels() {
    const ImVec2 display = ImGui::GetIO().DisplaySize;
    ImGui::SetNextWindowPos(ImVec2(display.x - kSidebarWidth - 6.0f, 6.0f), ImGuiCond_Always);
    ImGui::SetNextWindowSize(ImVec2(kSidebarWidth, std::max(display.y - 12.0f, 100.0f)),
                             ImGuiCond_Always);
    ImGui::Begin(kSidebarName, nullptr,
                 ImGuiWindowFlags_NoTitleBar | ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize |
                     ImGuiWindowFlags_NoCollapse);
    if (section("File")) file_section();
    if (worker_) {  // no scene yet: the File section only
        if (section("kd-tree")) tree_panel(*this);
        if (section("Stats")) stats_panel(*this);
        if (section("View")) {
            view_panel(*this);
            inspector(*this);
        }
        if (section("Render")) {
            render_panel(*this);
            environment_panel(*this);
            material_panel(*this);
            files_panel(*this);
        }
    }
    ImGui::End();
    if (split_) {
        // In the top-left corner, as small as its contents; the user may drag it elsewhere.
        ImGui::SetNextWindowPos(ImVec2(6.0f, 6.0f), ImGuiCond_FirstUseEver);
        ImGui::Begin("Split view: A left, B right", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
        split_panel(*this);
        ImGui::End();
    }
}

}  // namespace kdt::ui
