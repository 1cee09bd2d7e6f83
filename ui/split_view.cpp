#include "ui/split_view.h"

#include <algorithm>
#include <cmath>
#include <future>
#include <vector>

#include "renderer/core/error.h"
#include "ui/field_widgets.h"
#include "ui/viewer_app.h"

namespace kdt::ui {

SplitView::SplitView(std::shared_ptr<const RenderSnapshot> base, const KdTreeParams& base_tree,
                     const KdTreeParams& tree, const CameraDesc& camera, const TraceParams& trace,
                     const FilmParams& film, const StopConditions& stop, int preview_divisor,
                     bool heat, bool aov)
    : tree_edit_(tree), tree_params_(base_tree), requested_(base_tree), tree_(base->scene->tree) {
    worker_ = std::make_unique<RenderWorker>(base, trace, film, stop, preview_divisor);
    worker_->set_camera(camera);
    if (heat) worker_->set_heat_map(true);
    if (aov) worker_->set_aov(true);
    if (!same_fields(kd_tree_fields(), tree, base_tree)) request_rebuild();
}

void SplitView::request_rebuild() {
    requested_ = tree_edit_;
    rebuilder_.request(worker_->snapshot(), tree_edit_);
}

void SplitView::set_tree_option(const std::string& name, const std::string& value) {
    if (!set_field(kd_tree_fields(), tree_edit_, "tree", name, value))
        throw Error("no kd-tree option " + name);
    request_rebuild();
}

std::string SplitView::poll_rebuild() {
    std::optional<RebuildResult> r = rebuilder_.take();
    if (!r) return "";
    if (!r->snapshot) return r->error;
    tree_ = r->snapshot->scene->tree;
    tree_params_ = requested_;
    worker_->set_snapshot(r->snapshot);
    swap_restarts_ = worker_->stats().restarts;
    swapped_ = false;
    return "";
}

bool SplitView::settling() const {
    if (rebuilder_.busy()) return true;
    if (swapped_) return false;
    const WorkerStats s = worker_->stats();
    return s.restarts == swap_restarts_ && s.full_passes < 1;
}

void SplitView::update_image(std::optional<DebugLayer> layer, const HeatScale& a_scale) {
    if (!display_) {
        display_ = std::make_unique<FilmDisplay>();
        display_->init();
    }
    // As Viewer::update_image: a change's preview shows until its first full pass is complete,
    // and the session's image is copied as ImageCopyPacer says.
    const FilmImage* show = nullptr;
    if (worker_->copy_preview(preview_)) show = &preview_;
    const bool force = image_.version == 0 || (layer && !has_layer(*layer, image_));
    if (image_copies_.due(worker_->completed_passes(), force, ImageCopyPacer::Clock::now())) {
        if (!swapped_) {
            const WorkerStats s = worker_->stats();
            swapped_ = s.restarts != swap_restarts_ || s.full_passes >= 1;
        }
        if (worker_->session().copy_image(image_, layer.has_value()) && image_.complete_passes > 0)
            show = &image_;
    }
    if (show) upload_layer(*display_, *show, layer, scale_, &a_scale);
}

bool SplitView::drag(float u, float grab, bool pressed) {
    if (!pressed) {
        dragging_ = was_pressed_ = false;
        return false;
    }
    if (!was_pressed_ && std::abs(u - divider) <= grab) dragging_ = true;
    was_pressed_ = true;
    if (dragging_) divider = std::clamp(u, 0.0f, 1.0f);
    return dragging_;
}

void draw_split(FilmDisplay& a, FilmDisplay& b, int x, int y, int w, int h, float divider,
                const ToneParams& tone, DisplayMode mode) {
    const int split = x + int(std::lround(std::clamp(divider, 0.0f, 1.0f) * float(w)));
    glEnable(GL_SCISSOR_TEST);
    glScissor(x, y, split - x, h);
    a.draw(x, y, w, h, tone, mode);
    glScissor(split, y, x + w - split, h);
    b.draw(x, y, w, h, tone, mode);
    // The divider: a light line 2 pixels wide, centred on the split, drawn by a clear.
    glScissor(std::max(split - 1, x), y, 2, h);
    glClearColor(0.9f, 0.9f, 0.9f, 1.0f);
    glClear(GL_COLOR_BUFFER_BIT);
    glDisable(GL_SCISSOR_TEST);
}

void upload_layer(FilmDisplay& display, const FilmImage& image, std::optional<DebugLayer> layer,
                  HeatScale& scale, const HeatScale* also) {
    std::vector<float> rgb;
    if (layer && debug_colors(*layer, image, rgb, scale, also)) {
        display.upload(image.width, image.height, rgb.data());
    } else {
        display.upload(image.width, image.height, image.rgb.data());
    }
}

std::optional<DebugLayer> debug_layer(ViewMode mode) {
    switch (mode) {
        case ViewMode::radiance:
            return std::nullopt;
        case ViewMode::heat_nodes:
            return DebugLayer::nodes;
        case ViewMode::heat_triangles:
            return DebugLayer::triangles;
        case ViewMode::normals:
            return DebugLayer::normals;
        case ViewMode::depth:
            return DebugLayer::depth;
    }
    return std::nullopt;
}

void Viewer::set_split(bool on) {
    if (!on) {
        if (!split_) return;
        // B's destructor waits for a tree build in flight (builds have no cancel point): on
        // another thread, so the UI keeps drawing; Viewer's destructor waits for it.
        split_->release_display();
        split_retiring_ =
            std::async(std::launch::async, [s = std::move(split_)]() mutable { s.reset(); });
        return;
    }
    if (split_) return;
    const std::optional<DebugLayer> layer = debug_layer(view_);
    split_ = std::make_unique<SplitView>(worker_->snapshot(), opts_.tree, tree_edit_, camera_,
                                         opts_.trace, opts_.film, stop_, vo_.preview_divisor,
                                         is_heat(layer), is_aov(layer));
    if (paused_) split_->worker().set_paused(true);
}

}  // namespace kdt::ui
