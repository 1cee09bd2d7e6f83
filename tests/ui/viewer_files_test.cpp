// The viewer's files without a window: opening models, probes and broken files through the
// same calls as the File panel, the drop callback and the script, the swap of the loaded scene
// into the render thread, and the material edits (ui/viewer_files.cpp).
#include <sys/stat.h>

#include <chrono>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/io/image_io.h"
#include "renderer/render/render_options.h"
#include "tests/test_util.h"
#include "tests/ui/viewer_gui.h"
#include "ui/camera_control.h"
#include "ui/viewer_app.h"

namespace kdt::ui {
namespace {

ViewerOptions tiny_options() {
    ViewerOptions vo = test::small_viewer_options(48, 32);
    vo.options.scene.use_cache = false;
    return vo;
}

std::string write_tetra_ply(const std::filesystem::path& dir, const std::string& name) {
    const std::string path = (dir / name).string();
    std::ofstream f(path);
    f << "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
         "property float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n"
         "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
    return path;
}

/// tiny_options() on a tetrahedron written to dir/name.
ViewerOptions tetra_options(const std::filesystem::path& dir,
                            const std::string& name = "model.ply") {
    ViewerOptions vo = tiny_options();
    vo.options.scene.scene_path = write_tetra_ply(dir, name);
    return vo;
}

/// A viewer that has loaded its first scene (or failed to: see message_) once constructed.
struct LoadedViewer : Viewer {
    explicit LoadedViewer(const ViewerOptions& vo) : Viewer(vo) { finish_loading(); }
};

TEST(ViewerFiles, OpenSwapsTheSceneAndErrorsNameTheFile) {
    const auto dir = test::temp_dir("ui_open");
    ViewerOptions vo = tiny_options();
    vo.options.scene.eye = Vec3f(0.5f, 1.0f, 9.0f);  // the command line's, for its scene only
    Viewer v(vo);
    EXPECT_TRUE(v.loading());  // the constructor only asked for the default scene
    v.finish_loading();
    ASSERT_TRUE(v.worker_);
    EXPECT_EQ(v.camera_.eye, Vec3f(0.5f, 1.0f, 9.0f));
    const auto default_mesh = v.worker_->snapshot()->scene->mesh;
    EXPECT_GT(default_mesh->triangle_count(), 1000u);

    const std::string missing = (dir / "missing.obj").string();
    v.open_file(missing);
    v.finish_loading();
    EXPECT_NE(v.message_.find(missing), std::string::npos) << v.message_;
    EXPECT_EQ(v.worker_->snapshot()->scene->mesh, default_mesh);  // the old scene stays

    v.open_file((dir / "notes.txt").string());
    EXPECT_NE(v.message_.find("notes.txt: not a file the viewer opens"), std::string::npos);
    EXPECT_FALSE(v.loading());

    // Two requests in a row: the newer one is the one swapped in.
    const std::string a = write_tetra_ply(dir, "a.ply"), b = write_tetra_ply(dir, "b.ply");
    v.open_file(a);
    v.open_file(b);
    v.finish_loading();
    EXPECT_EQ(v.message_, "");
    EXPECT_EQ(v.opts_.scene.scene_path, b);
    EXPECT_EQ(v.worker_->snapshot()->scene->mesh->triangle_count(), 4u);
    EXPECT_EQ(v.tree_, v.worker_->snapshot()->scene->tree);
    EXPECT_EQ(v.camera_.eye, v.worker_->camera().eye);  // the new scene's camera
    EXPECT_NE(v.camera_.eye, Vec3f(0.5f, 1.0f, 9.0f));
    EXPECT_FALSE(v.opts_.scene.eye);
    ASSERT_EQ(v.materials_.size(), 1u);

    // A tree parameter edited while a scene loads applies to the new scene (the rebuild of the
    // old one it started is dropped).
    v.open_file(a);
    v.set_option("tree.max_depth", "5");
    v.finish_loading();
    for (int i = 0; i < 60000 && (v.rebuilder_->busy() || !v.awaiting_rebuild_image_); ++i) {
        v.poll_rebuild();
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    EXPECT_EQ(v.opts_.scene.scene_path, a);
    EXPECT_EQ(v.worker_->snapshot()->scene->mesh->triangle_count(), 4u);
    EXPECT_EQ(v.worker_->snapshot()->scene->tree->params().max_depth, 5);
}

TEST(ViewerFiles, ProbeAndMaterialEdits) {
    const auto dir = test::temp_dir("ui_probe_material");
    LoadedViewer v(tiny_options());
    ImageRGB sky(8, 4);
    for (float& c : sky.rgb) c = 0.5f;
    const std::string probe = (dir / "sky.pfm").string(), bad = (dir / "bad.exr").string();
    write_image(probe, sky);
    std::ofstream(bad) << "not an exr";
    v.open_file(bad);
    v.finish_loading();
    EXPECT_NE(v.message_.find(bad), std::string::npos) << v.message_;
    EXPECT_EQ(v.prep_.scene.environment.file, "");
    v.set_option("scene.env_file", probe);
    v.finish_loading();
    EXPECT_EQ(v.message_, "");
    EXPECT_EQ(v.prep_.scene.environment.file, probe);
    EXPECT_EQ(v.opts_.scene.env_file, probe);  // kept for the next scene and the session

    v.set_option("material.albedo", "0.9,0.1,0.2");
    const Material& m = v.worker_->snapshot()->scene->instances[0].material;
    EXPECT_EQ(m.albedo, Vec3f(0.9f, 0.1f, 0.2f));
    v.set_option("material.instance", "1");  // the default scene's ground
    v.set_option("material.type", "mirror");
    EXPECT_EQ(v.worker_->snapshot()->scene->instances[1].material.type, MaterialType::mirror);
    auto error = [&](const std::string& key, const std::string& value) {
        return test::error_of_call([&] { v.set_option(key, value); });
    };
    EXPECT_NE(error("material.albedo", "1,2").find("material.albedo must be R,G,B"),
              std::string::npos);
    EXPECT_NE(error("material.albedo", "1,2,3,4").find("material.albedo"), std::string::npos);
    EXPECT_NE(error("material.albedo", "-1,0,0").find("material.albedo"), std::string::npos);
    EXPECT_NE(error("material.type", "glass").find("material.type"), std::string::npos);
    // The scene file's limits, so that a saved session loads: albedo in [0, 1], roughness > 0.
    EXPECT_NE(error("material.albedo", "2,2,2")
                  .find("material.albedo must be R,G,B with each in "
                        "[0, 1] (got '2,2,2')"),
              std::string::npos);
    EXPECT_NE(error("material.albedo", "3e38,3e38,3e38").find("material.albedo"),
              std::string::npos);
    EXPECT_NE(error("material.roughness", "0")
                  .find("material.roughness must be a number in (0, "
                        "1] (got '0')"),
              std::string::npos);
    EXPECT_NE(error("material.ior", "0.5").find("material.ior must be a number in [1, 10]"),
              std::string::npos);
    EXPECT_EQ(error("material.emission", "5,5,5"), "");
    // Checked through the scene reader's ranges, on the float the material holds: 1e-50 is a
    // roughness of 0, which a saved session could not load; 1.00000001 an albedo of 1, which
    // it can; 4e38 an infinite emission.
    EXPECT_NE(error("material.roughness", "1e-50")
                  .find("material.roughness must be a number in (0, 1] (got '1e-50')"),
              std::string::npos);
    EXPECT_EQ(error("material.albedo", "1.00000001,0,0"), "");
    EXPECT_NE(error("material.emission", "4e38,0,0").find("material.emission must be R,G,B"),
              std::string::npos);
    EXPECT_NE(error("material.instance", "7").find("material.instance"), std::string::npos);
    EXPECT_NE(error("material.shine", "1").find("no option material.shine"), std::string::npos);

    // A tree requested before an edit comes with the edit (it was built from the old one).
    v.set_option("material.instance", "0");
    v.request_rebuild();
    v.set_option("material.albedo", "0.3,0.3,0.3");
    for (int i = 0; i < 60000 && (v.rebuilder_->busy() || !v.awaiting_rebuild_image_); ++i) {
        v.poll_rebuild();
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    EXPECT_TRUE(v.awaiting_rebuild_image_);
    EXPECT_EQ(v.worker_->snapshot()->scene->instances[0].material.albedo, Vec3f(0.3f));
    EXPECT_EQ(v.worker_->snapshot()->scene->instances[1].material.type, MaterialType::mirror);

    // The session keeps the probe; a viewer started from it loads the probe too.
    const std::string session = (dir / "s.json").string();
    v.save_session(session);
    ViewerOptions again = tiny_options();
    again.session = session;
    LoadedViewer w(again);
    EXPECT_EQ(w.message_, "");
    EXPECT_EQ(w.prep_.scene.environment.file, probe);
}

TEST(ViewerFiles, SessionsHoldAbsoluteFileNamesAndLoadFromAnywhere) {
    const auto dir = test::temp_dir("ui_session_paths");
    write_tetra_ply(dir, "model.ply");
    ImageRGB sky(8, 4);
    for (float& c : sky.rgb) c = 0.5f;
    write_image((dir / "sky.pfm").string(), sky);
    const std::filesystem::path cwd = std::filesystem::current_path();
    std::filesystem::current_path(dir);
    ViewerOptions vo = tiny_options();
    vo.options.scene.scene_path = "model.ply";  // as typed, relative to the working directory
    vo.options.scene.env_file = "sky.pfm";
    LoadedViewer v(vo);
    ASSERT_TRUE(v.worker_) << v.message_;
    v.save_session("s.json");
    const std::string text = [] {
        std::ifstream f("s.json");
        std::stringstream ss;
        ss << f.rdbuf();
        return ss.str();
    }();
    EXPECT_NE(text.find("\"scene_path\":\"" + (dir / "model.ply").string() + "\""),
              std::string::npos)
        << text;
    EXPECT_NE(text.find("\"env_file\":\"" + (dir / "sky.pfm").string() + "\""), std::string::npos)
        << text;
    // The viewer that saved it (model named relatively) takes it back.
    EXPECT_EQ(test::error_of_call([&] { v.load_session("s.json"); }), "");

    // A viewer started elsewhere finds the model and the probe.
    std::filesystem::current_path(dir.parent_path());
    ViewerOptions again = tiny_options();
    again.session = (dir / "s.json").string();
    options_from_session_file(again.session, again.options);  // as `kdtrace view --session`
    LoadedViewer w(again);
    std::filesystem::current_path(cwd);
    EXPECT_EQ(w.message_, "");
    ASSERT_TRUE(w.worker_);
    EXPECT_EQ(w.prep_.scene.environment.file, (dir / "sky.pfm").string());
    EXPECT_EQ(w.worker_->snapshot()->scene->mesh->triangle_count(), 4u);
}

TEST(ViewerFiles, ASessionsCameraPartsMoveTheCameraAsRenderTakesThem) {
    const auto dir = test::temp_dir("ui_session_camera");
    LoadedViewer v(tetra_options(dir));
    ASSERT_TRUE(v.worker_) << v.message_;
    const CameraDesc home = v.home_camera_;
    auto session = [&](const std::string& name, const Vec3f& eye) {
        const std::string path = (dir / name).string();
        std::ofstream(path) << std::setprecision(9) << "{\"scene\": {\"eye\": [" << eye.x << ", "
                            << eye.y << ", " << eye.z << "]}}";
        return path;
    };
    // An eye alone: the viewer's other parts stay.
    const Vec3f eye = home.eye + Vec3f(0.5f, 0.25f, 0.0f);
    EXPECT_EQ(test::error_of_call([&] { v.load_session(session("eye.json", eye)); }), "");
    EXPECT_EQ(v.camera_.eye, eye);
    EXPECT_EQ(v.camera_.target, home.target);
    EXPECT_EQ(v.camera_.up, home.up);
    // An eye on the target makes no camera: the session and its key are named, nothing moves.
    const std::string bad = session("on_target.json", home.target);
    const std::string e = test::error_of_call([&] { v.load_session(bad); });
    EXPECT_NE(e.find(bad + ": /scene/eye: eye and target coincide"), std::string::npos) << e;
    EXPECT_EQ(v.camera_.eye, eye);
}

std::string file_text(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    std::stringstream ss;
    ss << f.rdbuf();
    return ss.str();
}

TEST(ViewerFiles, OutputsNeverReplaceTheFilesViewedAndRefuseFifos) {
    const auto dir = test::temp_dir("ui_outputs");
    ViewerOptions vo = tetra_options(dir);
    ImageRGB sky(8, 4);
    for (float& c : sky.rgb) c = 0.5f;
    const std::string probe = (dir / "sky.pfm").string();
    write_image(probe, sky);
    vo.options.scene.env_file = probe;
    LoadedViewer v(vo);
    ASSERT_TRUE(v.worker_) << v.message_;
    const std::string session = (dir / "s.json").string();
    v.save_session(session);
    v.load_session(session);
    const std::string model = vo.options.scene.scene_path, model_text = file_text(model),
                      probe_text = file_text(probe), session_text = file_text(session);
    auto refused = [&](auto write, const std::string& input) {
        const std::string e = test::error_of_call(write);
        EXPECT_NE(e.find("it is the input " + input), std::string::npos) << e;
    };
    refused([&] { v.save_session(model); }, model);
    refused([&] { v.save_session(probe); }, probe);
    refused([&] { v.save_session(dir.string() + "/../" + dir.filename().string() + "/s.json"); },
            session);
    refused([&] { v.save_image(probe); }, probe);
    refused([&] { v.screenshot(model, 4, 4); }, model);
    EXPECT_EQ(file_text(model), model_text);
    EXPECT_EQ(file_text(probe), probe_text);
    EXPECT_EQ(file_text(session), session_text);
    // A base name writes .png and .exr: neither when one of them is an input.
    const std::string base = (dir / "sky").string();
    write_image(base + ".exr", sky);
    v.open_file(base + ".exr");
    v.finish_loading();
    refused([&] { v.save_image(base); }, base + ".exr");
    EXPECT_FALSE(std::filesystem::exists(base + ".png"));

    // A FIFO is refused at once (opening it to write would block until a reader comes).
    const std::string fifo = (dir / "fifo.json").string();
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    const std::string e = test::error_of_call([&] { v.save_session(fifo); });
    EXPECT_NE(e.find("FIFO"), std::string::npos) << e;
    // A script's output error fails the script, naming the command (a .png name: any other
    // is refused before the input is looked for).
    const std::string shot = (dir / "model_link.png").string();
    std::filesystem::create_symlink(model, shot);
    v.script_ = {"screenshot " + shot};
    v.script_next_ = 0;
    const std::string s = test::error_of_call([&] { v.script_step(); });
    EXPECT_NE(s.find("'screenshot " + shot + "'"), std::string::npos) << s;
    EXPECT_NE(s.find("it is the input"), std::string::npos) << s;
    EXPECT_TRUE(v.screenshot_requests_.empty());
}

TEST(ViewerFiles, CameraMovesThatWouldCollapseTheCameraAreRefused) {
    ViewerOptions vo = tetra_options(test::temp_dir("ui_camera"));
    vo.script = "fly 1e10 0 0; pan 1e10 1e10";
    for (int i = 0; i < 100; ++i) vo.script += "; zoom 0.35";
    LoadedViewer v(vo);
    ASSERT_TRUE(v.worker_) << v.message_;
    const CameraDesc home = v.camera_;
    EXPECT_FALSE(v.script_step());
    EXPECT_NE(v.message_.find("camera: move refused"), std::string::npos) << v.message_;
    EXPECT_EQ(v.worker_->camera().target, home.target);  // the pan and fly were not taken
    EXPECT_EQ(camera_problem(v.worker_->camera()), "");
    EXPECT_NEAR(glm::length(v.camera_.eye - v.camera_.target),
                kMinZoomDistance * glm::length(v.tree_->bounds().extent()), 1e-6f);
}

TEST(ViewerFiles, EnvironmentEditsWhileAModelLoadsApplyToIt) {
    const auto dir = test::temp_dir("ui_env_edits");
    LoadedViewer v(tetra_options(dir, "first.ply"));
    ASSERT_TRUE(v.worker_) << v.message_;
    ImageRGB sky(8, 4);
    for (float& c : sky.rgb) c = 0.5f;
    const std::string probe = (dir / "sky.pfm").string();
    write_image(probe, sky);

    // The model is requested first; the probe loads and swaps in before the model does (both
    // results wait until one poll takes the probe's, then the model's), and the rotation and
    // intensity are set meanwhile.
    v.open_file(write_tetra_ply(dir, "second.ply"));
    v.open_file(probe);
    v.set_option("scene.env_intensity", "0.25");
    v.set_option("scene.env_rotation_degrees", "45");
    for (int i = 0; i < 60000 && (v.scene_loader_->busy() || v.probe_loader_->busy()); ++i)
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    v.poll_load();
    ASSERT_FALSE(v.loading());
    EXPECT_EQ(v.opts_.scene.scene_path, (dir / "second.ply").string());
    EXPECT_EQ(v.message_, "");
    EXPECT_EQ(v.opts_.scene.env_file, probe);
    EXPECT_EQ(v.env_intensity_, 0.25f);
    EXPECT_EQ(v.opts_.scene.env_rotation_degrees, 45.0f);
    // The render thread has the new scene with the edited environment. It may first take the
    // probe with the old scene (the probe swaps in first), so wait for both.
    const auto taken = [&] {
        const auto snap = v.worker_->snapshot();
        return snap->environment.file == probe &&
               snap->scene->mesh == v.prep_.snapshot->scene->mesh;
    };
    for (int i = 0; i < 60000 && !taken(); ++i)
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    const EnvironmentDesc env = v.worker_->snapshot()->environment;
    EXPECT_EQ(env.file, probe);
    EXPECT_EQ(env.intensity, 0.25f);
    EXPECT_EQ(env.rotation_degrees, 45.0f);
    EXPECT_EQ(v.worker_->snapshot()->scene->mesh, v.prep_.snapshot->scene->mesh);
}

TEST(ViewerFiles, BadFirstSceneEndsAScriptedRunWithTheMessage) {
    ViewerOptions vo = tiny_options();
    vo.options.scene.scene_path = "/nonexistent/model.ply";
    vo.script = "orbit 10 0";
    LoadedViewer v(vo);
    EXPECT_FALSE(v.worker_);
    EXPECT_NE(v.message_.find("/nonexistent/model.ply"), std::string::npos) << v.message_;
    const std::string e = test::error_of_call([&] { v.script_step(); });
    EXPECT_NE(e.find("/nonexistent/model.ply"), std::string::npos) << e;
}

}  // namespace
}  // namespace kdt::ui
