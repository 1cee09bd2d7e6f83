// The split view: a second kd-tree configuration (B) renders the same camera, scene and
// parameters on its own RenderWorker, its tree built in the background by its own
// TreeRebuilder, and the display shows image A left of a draggable divider and image B right
// of it, so a user sees which tree is faster where (each side's rays/s and cost per ray).
// The Viewer owns one while the split is on; camera, render settings, environment, materials
// and debug layers go to both workers, and a new scene closes it (B would show the old one).
// Depends on the render worker, the tree rebuilder, the heat-map colours and GL (display).
#pragma once

#include <memory>
#include <optional>
#include <string>

#include "ui/display.h"
#include "ui/frame_pacer.h"
#include "ui/heat_map.h"
#include "ui/render_worker.h"
#include "ui/tree_rebuild.h"

namespace kdt::ui {

class SplitView {
public:
    /// Starts B's worker on `base` (A's snapshot: its scene, environment and tree) seen
    /// through `camera`, with the heat map and AOVs as given; when `tree` differs from the
    /// parameters of base's tree (`base_tree`), B's own tree is requested at once and B
    /// renders with A's tree until it is swapped in.
    SplitView(std::shared_ptr<const RenderSnapshot> base, const KdTreeParams& base_tree,
              const KdTreeParams& tree, const CameraDesc& camera, const TraceParams& trace,
              const FilmParams& film, const StopConditions& stop, int preview_divisor, bool heat,
              bool aov);

    RenderWorker& worker() { return *worker_; }
    const RenderWorker& worker() const { return *worker_; }
    /// Builds B's tree with tree_edit() in the background (a newer request supersedes it).
    void request_rebuild();
    /// Sets B's tree field `name` (a kd_tree_fields() name) to `value` and rebuilds. Throws
    /// kdt::Error naming the field when the value is invalid.
    void set_tree_option(const std::string& name, const std::string& value);
    /// Swaps in B's finished tree; returns the build's error ("" when none or still building).
    std::string poll_rebuild();
    /// Whether a rebuild is queued or building, or the swapped-in tree has no full pass yet.
    bool settling() const;
    /// Copies B's newest image (preview or full pass) and uploads it, coloured for `layer`
    /// (nullopt: radiance) on its scale widened to `a_scale` (side A's, so that both sides
    /// share one) -- GL context current; creates the texture at the first call.
    void update_image(std::optional<DebugLayer> layer, const HeatScale& a_scale);
    /// The texture of image B; null before the first update_image().
    const FilmDisplay* display() const { return display_.get(); }
    FilmDisplay* display() { return display_.get(); }
    /// Deletes the texture (GL context current), so that the rest can be destroyed on
    /// another thread.
    void release_display() { display_.reset(); }

    /// The mouse at u (its position across the image, 0 = left edge, 1 = right) with the
    /// left button `pressed`: a press within `grab` of the divider starts a drag that moves
    /// the divider until release. Returns whether the mouse is dragging it (the camera
    /// then ignores the mouse).
    bool drag(float u, float grab, bool pressed);

    KdTreeParams& tree_edit() { return tree_edit_; }
    const KdTreeParams& tree_params() const { return tree_params_; }  ///< of tree()
    const std::shared_ptr<const KdTree>& tree() const { return tree_; }
    const HeatScale& scale() const { return scale_; }
    const FilmImage& image() const { return image_; }
    /// Colours side B's image again at the next update_image() (a view mode changed).
    void recolour() { image_.version = 0; }
    /// Side B's tree builds finished since the start (TreeRebuilder::finished()).
    uint64_t rebuilds_finished() const { return rebuilder_.finished(); }
    float divider = 0.5f;  ///< share of the image width shown from A, in [0, 1]

private:
    std::unique_ptr<RenderWorker> worker_;
    TreeRebuilder rebuilder_;
    KdTreeParams tree_edit_, tree_params_, requested_;
    std::shared_ptr<const KdTree> tree_;
    uint64_t swap_restarts_ = 0;  ///< B's restart count when its tree was swapped in
    bool swapped_ = true;         ///< no tree swap waits for its first full pass
    std::unique_ptr<FilmDisplay> display_;
    FilmImage image_, preview_;
    ImageCopyPacer image_copies_;
    HeatScale scale_;
    bool dragging_ = false, was_pressed_ = false;
};

/// Draws texture a in the part of the viewport (x, y, w, h; framebuffer pixels, GL's
/// bottom-left origin) left of x + divider * w and texture b right of it (each stretched
/// over the whole viewport, so a pixel column shows the same image point on both sides),
/// with a 2-pixel light line at the divider. Leaves the scissor test off.
void draw_split(FilmDisplay& a, FilmDisplay& b, int x, int y, int w, int h, float divider,
                const ToneParams& tone, DisplayMode mode);

/// Uploads `layer` of `image` coloured (debug_colors: sets `scale`, widened to `also`) into
/// `display`, or its radiance when there is no layer or the image lacks it (a preview).
void upload_layer(FilmDisplay& display, const FilmImage& image, std::optional<DebugLayer> layer,
                  HeatScale& scale, const HeatScale* also);

}  // namespace kdt::ui
