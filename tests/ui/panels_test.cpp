// One ImGui frame with every panel open (kd-tree, stats, view with the heat-map legend and the
// inspector, render, files), drawn by the real OpenGL3 backend in an offscreen OSMesa context
// with no GL error; and the script and option errors of the viewer.
#include <imgui.h>
#include <imgui_internal.h>

#include <algorithm>
#include <chrono>
#include <thread>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/io/image_io.h"
#include "tests/test_util.h"
#include "tests/ui/osmesa_context.h"
#include "tests/ui/viewer_gui.h"
#include "ui/viewer_app.h"

namespace kdt::ui {
namespace {

ViewerOptions small_options() {
    ViewerOptions vo = test::small_viewer_options(64, 48);
    // One tree build for all the viewers of these tests, cached in a directory of their own.
    static const std::string cache = test::temp_dir("ui_tree_cache").string();
    vo.options.scene.cache_dir = cache;
    return vo;
}

TEST(ViewerPanels, EveryPanelDrawsWithNoGlError) {
    constexpr int kW = 1100, kH = 760;
    test::GuiViewer g(small_options(), kW, kH);
    ASSERT_TRUE(g.ok()) << "no OSMesa GL 3.3 core context or ImGui OpenGL3 backend";
    Viewer& v = g.viewer();
    test::ViewerGui& gui = g.gui();
    v.mouse_x_ = 20.0;  // over the image: the inspector shows a pixel
    v.mouse_y_ = 20.0;
    auto frame = [&] { gui.frame(true); };
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    for (ViewMode mode : {ViewMode::radiance, ViewMode::heat_nodes, ViewMode::heat_triangles}) {
        v.set_view_mode(mode);
        v.have_image_ = false;
        // A heat view waits for an image with heat counts: a preview before it shows radiance
        // and leaves the heat scale as it was.
        const bool heat = mode != ViewMode::radiance;
        auto shown = [&] {
            return v.have_image_ &&
                   (!heat || (!v.image_.heat_nodes.empty() && v.image_.complete_passes > 0));
        };
        do {
            frame();
            ASSERT_EQ(gl_errors("frame"), "");
            std::this_thread::sleep_for(std::chrono::milliseconds(5));
        } while (!shown() && std::chrono::steady_clock::now() < deadline);
        ASSERT_TRUE(v.have_image_) << "no image within a minute";
        ASSERT_TRUE(shown()) << "no heat counts within a minute";
        frame();  // the panels with the image's statistics
        EXPECT_EQ(gl_errors("frame"), "");
        const ImGuiWindow* sidebar = ImGui::FindWindowByName(kSidebarName);
        ASSERT_NE(sidebar, nullptr);
        EXPECT_TRUE(sidebar->WasActive);
        // The sidebar spans the window's height and its five open sections overflow it.
        EXPECT_FLOAT_EQ(sidebar->Size.y, float(kH) - 12.0f);
        EXPECT_GT(sidebar->ContentSize.y, float(kH));
        EXPECT_GT(ImGui::GetDrawData()->TotalVtxCount, 2000);
    }
    EXPECT_GT(v.heat_scale_.hi, v.heat_scale_.lo);  // the heat map had a range to show
    // A file being opened: the progress bar over the image until the load is taken.
    v.open_file("/nonexistent/model.ply");
    frame();
    frame();
    EXPECT_EQ(gl_errors("loading"), "");
    const ImGuiWindow* loading = ImGui::FindWindowByName("Loading");
    ASSERT_NE(loading, nullptr);
    EXPECT_TRUE(loading->WasActive);
    v.finish_loading();
    EXPECT_NE(v.message_.find("/nonexistent/model.ply"), std::string::npos) << v.message_;
    // The display shows the panels over the image: pixels differ from the clear colour.
    const std::vector<uint8_t> px = g.gl().read_rgb();
    size_t lit = 0;
    for (uint8_t c : px) lit += c > 40;
    EXPECT_GT(lit, px.size() / 10);
}

TEST(ViewerScript, BadCommandsAndOptionsNameTheProblem) {
    auto error_of = [](const std::string& script) -> std::string {
        ViewerOptions vo = small_options();
        vo.script = script;
        try {
            Viewer v(vo);
            v.finish_loading();
            while (v.script_step()) {
            }
        } catch (const Error& e) {
            return e.what();
        }
        return "";
    };
    EXPECT_NE(error_of("orbit x").find("'orbit x': expected yaw degrees"), std::string::npos);
    EXPECT_NE(error_of("fly 1 2").find("expected forward"), std::string::npos);
    EXPECT_NE(error_of("jump").find("'jump': unknown command"), std::string::npos);
    // An unknown command fails when the viewer starts, before the commands before it run.
    ViewerOptions typo = small_options();
    typo.script = "orbit 10 0; wiat 5";
    EXPECT_THROW(Viewer bad(typo), Error);
    EXPECT_NE(error_of("set tree.q 2").find("tree.q must be in (0, 1]"), std::string::npos);
    EXPECT_NE(error_of("set trace.nothing 1").find("no option trace.nothing"), std::string::npos);
    EXPECT_NE(error_of("heat hot").find("expected nodes, triangles or off"), std::string::npos);
    EXPECT_NE(error_of("view Z").find("Z"), std::string::npos);
    EXPECT_NE(error_of("exposure 200").find("'exposure 200': film.exposure must be in [-64, 64]"),
              std::string::npos);
    EXPECT_NE(error_of("set scene.env_intensity -1").find("scene.env_intensity"),
              std::string::npos);
    EXPECT_EQ(error_of("orbit 10 5; zoom 0.9; set trace.max_depth 4; set film.exposure 1; "
                       "set scene.env_rotation_degrees 90; set scene.env_intensity 2"),
              "");
}

TEST(ViewerScript, EveryWaitEndsOrFailsTheScript) {
    test::GuiViewer g(small_options(), 900, 600);
    ASSERT_TRUE(g.ok()) << "no OSMesa GL 3.3 core context or ImGui OpenGL3 backend";
    Viewer& v = g.viewer();
    // Runs `script` frame by frame to its end; "" or the script's error. A wait that never
    // ended is reported as such after a minute.
    auto run = [&](std::vector<std::string> script) -> std::string {
        v.script_ = std::move(script);
        v.script_next_ = 0;
        v.waiting_.clear();
        const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
        try {
            while (g.gui().frame(false)) {
                if (std::chrono::steady_clock::now() > deadline) return "never ended";
                std::this_thread::sleep_for(std::chrono::milliseconds(2));
            }
        } catch (const Error& e) {
            ImGui::EndFrame();  // the frame the error left open
            return e.what();
        }
        return "";
    };
    // The render stops at 1 pass: wait_passes 5 ends with it.
    EXPECT_EQ(run({"set stop.spp 1", "wait_passes 5"}), "");
    EXPECT_TRUE(v.worker_->stats().done);
    EXPECT_EQ(run({"set stop.spp 100000", "wait_rebuild", "wait_split"}), "");  // nothing pending
    // Paused before the change, so that neither the rebuilt tree's first image nor the split
    // view's first pass can come in before the wait (on a slow machine a frame takes long
    // enough for both).
    for (const char* wait : {"wait_passes 1000", "wait_done", "wait_rebuild"}) {
        const std::vector<std::string> script = {"pause", "set tree.max_depth 12", wait};
        const std::string e = run(script);
        EXPECT_NE(e.find("'" + std::string(wait) + "': cannot end while the render is paused"),
                  std::string::npos)
            << e;
        // The last rebuild is waited for too: its swap clears the window's message, which on
        // a slow machine could land after the refused intensity's below.
        EXPECT_EQ(run({"resume", "wait_rebuild", "set tree.max_depth 0", "wait_rebuild"}), "");
    }
    const std::string e = run({"pause", "split on", "wait_split"});
    EXPECT_NE(e.find("'wait_split': cannot end while the render is paused"), std::string::npos)
        << e;
    EXPECT_EQ(run({"resume", "wait_split", "split off", "wait_passes 1"}), "");
    EXPECT_NE(run({"wait_passes -1"}).find("expected a count >= 0"), std::string::npos);
    // An intensity in the option's range that the render thread refuses (the radiance would
    // overflow) is the window's message, not dropped out of sight.
    v.message_.clear();
    EXPECT_EQ(run({"set scene.env_intensity 1e38", "wait_passes 1", "wait 2"}), "");
    // The render thread takes the change at its next pass, which on a busy machine may come
    // long after the pass the wait saw end: frames until it does, for up to a minute.
    const auto refused_by = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (v.message_.find("above the limit") == std::string::npos &&
           std::chrono::steady_clock::now() < refused_by)
        EXPECT_EQ(run({"wait 5"}), "");
    EXPECT_NE(v.message_.find("above the limit 1e+30"), std::string::npos) << v.message_;
    EXPECT_EQ(run({"set scene.env_intensity 3e38", "set tree.traversal_cost 3e38"}), "");
}

TEST(ViewerFiles, SessionRoundTripAndSavedImageMetadata) {
    const auto dir = test::temp_dir("ui_session");
    const std::string session = (dir / "s.json").string(), base = (dir / "shot").string();
    ViewerOptions vo = small_options();
    vo.script = "orbit 20 5; set trace.max_depth 5; set film.exposure 1.5; save_session " +
                session + "; exposure 2.5; set scene.env_intensity 0.5; " +
                "set material.albedo 0.2,0.6,0.2; wait_passes 1; save " + base;
    CameraDesc saved;
    {
        Viewer v(vo);
        v.finish_loading();
        const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
        // wait_passes needs an image on screen: stand in for the frame loop's upload.
        while (v.script_step() && std::chrono::steady_clock::now() < deadline) {
            if (v.worker_->stats().full_passes >= 1) v.have_image_ = true;
            std::this_thread::sleep_for(std::chrono::milliseconds(2));
        }
        saved = v.camera_;
        EXPECT_NE(saved.eye, v.home_camera_.eye);
    }
    // The PNG and the EXR of the image with the options (the camera in scene.camera).
    const ImageMetadata meta = read_exr_metadata(base + ".exr");
    bool has_params = false;
    for (const auto& [key, value] : meta) {
        if (key != "kdtrace:params") continue;
        has_params = true;
        RenderOptions o;
        options_from_json(value, o);
        ASSERT_TRUE(o.scene.camera);
        EXPECT_EQ(o.scene.camera->eye, saved.eye);
        EXPECT_EQ(o.trace.max_depth, 5);
        // What is on screen: the exposure command's, the intensity, the edited material.
        EXPECT_EQ(o.film.exposure, 2.5f);
        ASSERT_TRUE(o.scene.env_intensity);
        EXPECT_EQ(*o.scene.env_intensity, 0.5f);
        ASSERT_FALSE(o.scene.materials.empty());
        EXPECT_EQ(o.scene.materials[0].albedo, Vec3f(0.2f, 0.6f, 0.2f));
    }
    std::vector<std::string> keys;
    for (const auto& kv : meta) keys.push_back(kv.first);
    for (const char* key : {"kdtrace:scene", "kdtrace:scene_json", "kdtrace:camera", "kdtrace:seed",
                            "kdtrace:spp", "kdtrace:passes"}) {
        EXPECT_NE(std::find(keys.begin(), keys.end(), key), keys.end()) << key;
    }
    EXPECT_TRUE(has_params);
    EXPECT_EQ(load_image(base + ".png").width, 64);

    // A new viewer from the session file starts where the first one was.
    ViewerOptions again = small_options();
    again.session = session;
    Viewer v(again);
    v.finish_loading();
    EXPECT_EQ(v.camera_.eye, saved.eye);
    EXPECT_EQ(v.opts_.trace.max_depth, 5);
    EXPECT_EQ(v.tone_.exposure, 1.5f);

    // A session of another image size is refused with the file's name.
    ViewerOptions other = small_options();
    other.options.scene.width = 32;
    other.session = session;
    try {
        Viewer bad(other);
        bad.finish_loading();
        ADD_FAILURE() << "a session of another size was accepted";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("s.json"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace kdt::ui
