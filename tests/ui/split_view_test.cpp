// The split view: two workers whose exact kd-trees differ render the same image bitwise
// (trees change speed, not images) at their own costs; the composite shows A left of the
// divider and B right of it (read back from an offscreen OSMesa context); the panels and the
// debug views draw with the split on and no GL error; the divider's drag and the script's
// errors.
#include <imgui.h>
#include <imgui_internal.h>

#include <chrono>
#include <cstring>
#include <thread>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "tests/test_util.h"
#include "tests/ui/osmesa_context.h"
#include "tests/ui/viewer_gui.h"
#include "ui/camera_control.h"
#include "ui/viewer_app.h"

namespace kdt::ui {
namespace {

using Clock = std::chrono::steady_clock;

ViewerOptions split_options() {
    ViewerOptions vo = test::small_viewer_options(64, 48);
    static const std::string cache = test::temp_dir("split_tree_cache").string();
    vo.options.scene.cache_dir = cache;
    vo.options.stop.spp = 4;
    return vo;
}

TEST(SplitView, CompositeTakesLeftPixelsFromAAndRightPixelsFromB) {
    constexpr int kW = 200, kH = 100;
    test::OffscreenGL gl(kW, kH);
    ASSERT_TRUE(gl.ok()) << "OSMesa could not create a GL 3.3 core context";
    FilmDisplay a, b;
    a.init();
    b.init();
    // A is red and B is blue, each with a green ramp across its width: a column of the
    // composite must show its own column of the source image, not a squeezed copy.
    constexpr int kIw = 50, kIh = 10;
    std::vector<float> ra(kIw * kIh * 3), rb(kIw * kIh * 3);
    for (int y = 0; y < kIh; ++y) {
        for (int x = 0; x < kIw; ++x) {
            const size_t i = 3 * size_t(y * kIw + x);
            ra[i] = 1.0f;
            rb[i + 2] = 1.0f;
            ra[i + 1] = rb[i + 1] = float(x) / float(kIw - 1);
        }
    }
    a.upload(kIw, kIh, ra.data());
    b.upload(kIw, kIh, rb.data());
    glViewport(0, 0, kW, kH);
    glClearColor(0.0f, 0.0f, 0.0f, 1.0f);
    glClear(GL_COLOR_BUFFER_BIT);
    // The image in the viewport (20, 10, 160, 80); the divider at 30 % of it, x = 68.
    draw_split(a, b, 20, 10, 160, 80, 0.3f, ToneParams{}, DisplayMode::direct);
    glFinish();
    ASSERT_EQ(gl_errors("draw_split"), "");
    EXPECT_FALSE(glIsEnabled(GL_SCISSOR_TEST));
    const std::vector<uint8_t> px = gl.read_rgb();
    auto at = [&](int x, int y) { return &px[3 * (size_t(y) * kW + size_t(x))]; };
    const int row = kH / 2;
    for (int x = 21; x < 66; ++x) {
        EXPECT_GT(at(x, row)[0], 200) << x;
        EXPECT_LT(at(x, row)[2], 40) << x;
    }
    for (int x = 70; x < 179; ++x) {
        EXPECT_LT(at(x, row)[0], 40) << x;
        EXPECT_GT(at(x, row)[2], 200) << x;
    }
    // Green follows the image position on both sides of the divider.
    EXPECT_LT(at(22, row)[1], 40);
    EXPECT_NEAR(at(65, row)[1], at(71, row)[1], 25);
    EXPECT_GT(at(178, row)[1], 200);
    // The divider line, and nothing drawn outside the viewport.
    EXPECT_GT(at(67, row)[0], 200);
    EXPECT_GT(at(67, row)[1], 200);
    EXPECT_GT(at(67, row)[2], 200);
    EXPECT_EQ(at(10, row)[0] + at(10, row)[2], 0);
    EXPECT_EQ(at(190, row)[0] + at(190, row)[2], 0);
    EXPECT_EQ(at(100, 5)[0] + at(100, 5)[2], 0);
}

// Waits until both sides are done (stop: 4 spp) with B's own tree; false at the deadline.
bool wait_both_done(Viewer& v) {
    const auto deadline = Clock::now() + std::chrono::seconds(90);
    while (Clock::now() < deadline) {
        v.poll_rebuild();
        if (!v.split_->settling() && v.worker_->stats().done && v.split_->worker().stats().done)
            return true;
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return false;
}

TEST(SplitView, ExactTreesOfDifferentBuildersGiveTheSameImageAtTheirOwnCost) {
    Viewer v(split_options());
    v.finish_loading();
    v.set_split(true);
    ASSERT_TRUE(v.split_);
    EXPECT_EQ(v.split_->tree(), v.tree_);  // B starts with A's tree: same parameters
    v.split_->set_tree_option("builder", "thesis");
    v.split_->set_tree_option("q", "0.9");
    EXPECT_THROW(v.split_->set_tree_option("q", "2"), Error);
    EXPECT_THROW(v.split_->set_tree_option("no_such", "1"), Error);
    ASSERT_TRUE(wait_both_done(v)) << "the two sides did not finish within 90 s";
    ASSERT_NE(v.split_->tree(), v.tree_);
    EXPECT_EQ(v.split_->tree_params().builder, KdBuilder::thesis);
    EXPECT_EQ(v.split_->tree_params().q, 0.9f);
    EXPECT_NE(v.split_->tree()->stats().nodes, v.tree_->stats().nodes);
    FilmImage a, b;
    v.worker_->session().copy_image(a);
    v.split_->worker().session().copy_image(b);
    ASSERT_EQ(a.rgb.size(), size_t(64 * 48 * 3));
    ASSERT_EQ(a.rgb.size(), b.rgb.size());
    EXPECT_EQ(std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float)), 0);
    // The same rays at different costs: each side reports its own tree's traversal work.
    const WorkerStats sa = v.worker_->stats(), sb = v.split_->worker().stats();
    EXPECT_EQ(sa.spp, sb.spp);
    EXPECT_GT(sa.nodes_per_ray, 0.0);
    EXPECT_GT(sb.nodes_per_ray, 0.0);
    EXPECT_NE(sa.nodes_per_ray, sb.nodes_per_ray);
    // A camera change goes to both sides; turning the split off stops B's worker.
    v.set_camera(orbit(v.camera_, 20.0f, 0.0f));
    const CameraDesc b_camera = v.split_->worker().camera();
    EXPECT_EQ(std::memcmp(&b_camera, &v.camera_, sizeof(CameraDesc)), 0);
    v.set_split(false);
    EXPECT_FALSE(v.split_);
    // Off while B's tree builds: B is destroyed on another thread, the build finished there.
    v.set_split(true);
    v.split_->set_tree_option("n0", "3");
    ASSERT_TRUE(v.split_->settling());
    v.set_split(false);
    EXPECT_FALSE(v.split_);
    ASSERT_TRUE(v.split_retiring_.valid());
    v.split_retiring_.get();
}

TEST(SplitView, PanelsAndDebugViewsDrawWithNoGlErrorAndTheDividerWhereSet) {
    constexpr int kW = 1100, kH = 760;
    test::GuiViewer g(split_options(), kW, kH);
    ASSERT_TRUE(g.ok()) << "no OSMesa GL 3.3 core context or ImGui OpenGL3 backend";
    Viewer& v = g.viewer();
    test::ViewerGui& gui = g.gui();
    v.mouse_x_ = 600.0;  // right of the divider: the frames draw side B's inspector
    v.mouse_y_ = 20.0;
    v.script_ = {"split on", "split.set tree.n0 2", "divider 0.25", "wait_split", "check_gl"};
    auto frame = [&] { return gui.frame(false); };
    const auto deadline = Clock::now() + std::chrono::seconds(90);
    while (frame() && Clock::now() < deadline) {
        ASSERT_EQ(gl_errors("frame"), "");
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    ASSERT_LT(Clock::now(), deadline) << "the script (wait_split, check_gl) did not finish";
    ASSERT_TRUE(v.split_);
    EXPECT_EQ(v.split_->tree_params().n0, 2);
    for (ViewMode mode :
         {ViewMode::normals, ViewMode::depth, ViewMode::heat_nodes, ViewMode::radiance}) {
        v.set_view_mode(mode);
        v.have_image_ = false;
        // A debug view waits for a full pass with its layer: a preview before it shows
        // radiance and leaves the heat scale as it was.
        auto has_layer = [&] {
            const FilmImage& im = v.image_;
            if (mode == ViewMode::radiance) return true;
            const bool layer =
                mode == ViewMode::heat_nodes ? !im.heat_nodes.empty() : !im.aov_depth.empty();
            return layer && im.complete_passes > 0;
        };
        do {
            frame();
            ASSERT_EQ(gl_errors("frame"), "");
            std::this_thread::sleep_for(std::chrono::milliseconds(5));
        } while (!(v.have_image_ && v.split_->display() && has_layer()) && Clock::now() < deadline);
        ASSERT_TRUE(v.have_image_);
        ASSERT_TRUE(has_layer()) << "no full pass with the view's layer in time";
        frame();
        EXPECT_EQ(gl_errors("frame"), "");
        const ImGuiWindow* w = ImGui::FindWindowByName("Split view: A left, B right");
        ASSERT_NE(w, nullptr);
        EXPECT_TRUE(w->WasActive);
        if (mode == ViewMode::depth) {
            EXPECT_GT(v.heat_scale_.hi, v.heat_scale_.lo);
        }
    }
    // The divider line at a quarter of the image, in a row (from the top) below the split
    // panel in the top-left corner and above the File panel in the bottom-left one.
    const std::vector<uint8_t> px = g.gl().read_rgb();
    const uint8_t* line = &px[3 * (size_t(400) * kW + 159)];
    EXPECT_GT(line[0], 200);
    EXPECT_GT(line[1], 200);
    EXPECT_GT(line[2], 200);
    v.set_split(false);
}

TEST(SplitView, DividerDragStartsOnlyNearIt) {
    Viewer v(split_options());
    v.finish_loading();
    v.set_split(true);
    SplitView& s = *v.split_;
    EXPECT_FALSE(s.drag(0.8f, 0.01f, true));  // a press away from it: the camera's
    EXPECT_FALSE(s.drag(0.5f, 0.01f, true));  // held across it: still the camera's
    EXPECT_EQ(s.divider, 0.5f);
    EXPECT_FALSE(s.drag(0.5f, 0.01f, false));
    EXPECT_TRUE(s.drag(0.505f, 0.01f, true));  // a press on it
    EXPECT_TRUE(s.drag(0.7f, 0.01f, true));    // drags it
    EXPECT_EQ(s.divider, 0.7f);
    EXPECT_TRUE(s.drag(1.5f, 0.01f, true));
    EXPECT_EQ(s.divider, 1.0f);  // clamped to the image
    EXPECT_FALSE(s.drag(0.2f, 0.01f, false));
    EXPECT_EQ(s.divider, 1.0f);
}

TEST(SplitView, ScriptErrorsNameTheProblem) {
    auto fails = [](const std::string& cmd, const char* why) {
        ViewerOptions vo = split_options();
        Viewer v(vo);
        v.finish_loading();
        v.script_ = {cmd};
        try {
            v.script_step();
            ADD_FAILURE() << cmd << ": no error";
        } catch (const Error& e) {
            EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
        }
    };
    fails("split.set tree.q 0.9", "split view is off");
    fails("divider 0.5", "split view is off");
    fails("divider 2", "[0, 1]");
    fails("split maybe", "on or off");
    fails("mode shiny", "normals or depth");
    fails("screenshot shot.exr", "the screenshot is written as PNG; give a .png name");
}

}  // namespace
}  // namespace kdt::ui
