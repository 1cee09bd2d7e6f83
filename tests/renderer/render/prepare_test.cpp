// The camera a session file's parts make with the scene's: an error names the session, its
// keys and where the other parts came from, unless a flag or a view replaced the session's.
#include "renderer/render/prepare.h"

#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "tests/test_util.h"

#include "renderer/core/error.h"

namespace kdt {
namespace {

struct SessionCameraTest : ::testing::Test {
    std::filesystem::path dir = test::temp_dir("prepare_session_camera");
    std::string file = (dir / "s.json").string();
    CameraDesc scene;  // the scene file's camera: from (0, 0, 5) at the origin, +y up

    // The options of the session `text` (a file, as --session reads it), of scene x.json.
    SceneOptions session(const std::string& text) {
        const std::string json = "{\"scene\": " + text + "}";
        test::write_bytes(file, std::vector<unsigned char>(json.begin(), json.end()));
        RenderOptions o;
        options_from_session_file(file, o);
        o.scene.scene_path = "x.json";
        return o.scene;
    }
    std::string error(const SceneOptions& o) {
        return test::error_of_call([&] { check_session_camera(scene, o); });
    }
};

TEST_F(SessionCameraTest, NamesTheSessionItsKeysAndTheScenesParts) {
    EXPECT_EQ(error(session(R"({"eye": [0, 0, 0]})")),
              file + ": /scene/eye: eye and target coincide (target from the scene file x.json)");
    EXPECT_EQ(error(session(R"({"up": [0, 0, -2]})")),
              file +
                  ": /scene/up: up vector is parallel to the viewing direction (eye and target "
                  "from the scene file x.json)");
    SceneOptions builtin = session(R"({"target": [0, 0, 5]})");
    builtin.scene_path.clear();
    EXPECT_EQ(error(builtin),
              file + ": /scene/target: eye and target coincide (eye from the built-in scene)");
    // The session's parts alone: every key, nothing from the scene.
    EXPECT_EQ(error(session(R"({"camera": {"eye": [0, 5, 0], "target": [0, 0, 0],
        "up": [0, 0, 1]}, "up": [0, 1, 0]})")),
              file +
                  ": /scene/camera/eye, /scene/camera/target, /scene/up: up vector is parallel "
                  "to the viewing direction");
    EXPECT_EQ(error(session(R"({"eye": [1, 2, 3]})")), "");
}

TEST_F(SessionCameraTest, ASecondSessionWithoutCameraPartsBlamesNone) {
    // Options that read one session and then another, as the viewer's Load session does:
    // the first one's parts are no longer a session's, so its file is not named.
    const std::string first = (dir / "first.json").string();
    const std::string text = R"({"scene": {"eye": [0, 0, 0]}})";
    test::write_bytes(first, std::vector<unsigned char>(text.begin(), text.end()));
    RenderOptions o;
    options_from_session_file(first, o);
    EXPECT_EQ(o.scene.session_camera.file, first);
    const std::string second = R"({"trace": {"seed": 3}})";
    test::write_bytes(file, std::vector<unsigned char>(second.begin(), second.end()));
    options_from_session_file(file, o);
    EXPECT_EQ(o.scene.session_camera.file, "");
    EXPECT_EQ(error(o.scene), "");
}

TEST_F(SessionCameraTest, PartsAFlagOrAViewReplacedAreNotTheSessions) {
    // --eye replaced the session's eye: the problem is the flag's, reported by make_camera().
    SceneOptions flag = session(R"({"eye": [1, 1, 1]})");
    flag.eye = Vec3f(0.0f);
    EXPECT_EQ(error(flag), "");
    SceneOptions target = session(R"({"eye": [1, 2, 3]})");
    target.target = Vec3f(1.0f, 2.0f, 3.0f);
    EXPECT_EQ(error(target), file + ": /scene/eye: eye and target coincide (target from --target)");
    SceneOptions view = session(R"({"camera": {"eye": [0, 0, 5], "target": [0, 0, 0],
        "up": [0, 1, 0]}, "up": [0, 1, 0]})");
    view.camera = CameraDesc{{0.0f, 5.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 40.0f};
    EXPECT_EQ(error(view),
              file +
                  ": /scene/up: up vector is parallel to the viewing direction (eye and target "
                  "from the view)");
    // A part the session's camera object leaves out is the object's default.
    SceneOptions up = session(R"({"camera": {"eye": [0, 0, 1], "up": [1, 0, 0]}})");
    up.up = Vec3f(0.0f, 0.0f, 1.0f);
    EXPECT_EQ(error(up), file +
                             ": /scene/camera/eye, /scene/camera: up vector is parallel to the "
                             "viewing direction (up from --up)");
}

// Options read otherwise (rank 0's, a scene's own camera) name no session: make_camera()
// reports the problem later.
TEST_F(SessionCameraTest, OnlySessionFilesAreNamed) {
    RenderOptions o;
    options_from_json(R"({"scene": {"eye": [0, 0, 0]}})", o, "rank 0's options");
    EXPECT_EQ(error(o.scene), "");
}

// Each part's source, blamed or not: what a flag's camera error names for the other parts.
TEST_F(SessionCameraTest, EachPartsSource) {
    auto sources = [](const SceneOptions& o) {
        std::string s;
        for (size_t i = 0; i < 3; ++i) {
            const CameraPartSource p = camera_part_source(o, i);
            s += (s.empty() ? "" : "; ") + (p.key.empty() ? p.other : p.key);
        }
        return s;
    };
    SceneOptions o = session(R"({"target": [1, 2, 3], "camera": {"eye": [0, 0, 1]}})");
    o.up = Vec3f(0.0f);  // --up 0,0,0
    EXPECT_EQ(sources(o), "/scene/camera/eye; /scene/target; --up");
    o.camera = CameraDesc{{0.0f, 5.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 40.0f};
    o.target = Vec3f(3.0f, 2.0f, 1.0f);
    EXPECT_EQ(sources(o), "the view; --target; --up");
    SceneOptions flags;  // no session: every override is a flag's
    flags.scene_path = "x.json";
    flags.eye = Vec3f(1.0f);
    EXPECT_EQ(sources(flags), "--eye; the scene file x.json; the scene file x.json");
    flags.scene_path.clear();
    EXPECT_EQ(sources(flags), "--eye; the built-in scene; the built-in scene");
}

// load_scene_with_overrides() checks before it applies the session's parts.
TEST_F(SessionCameraTest, LoadingTheSceneChecks) {
    SceneOptions o = session(R"({"eye": [0, 0.85, 0]})");
    o.scene_path.clear();  // the built-in scene, which looks at (0, 0.85, 0)
    EXPECT_EQ(test::error_of_call([&] { load_scene_with_overrides(o, [](const std::string&) {}); }),
              file + ": /scene/eye: eye and target coincide (target from the built-in scene)");
}

}  // namespace
}  // namespace kdt

namespace kdt {
namespace {

// A constant environment whose colour times intensity overflows the radiance bound names
// where the intensity came from: the option (--env-intensity or a session's), else the scene.
TEST(PrepareEnvironment, ConstantRadianceErrorsNameTheirSource) {
    const auto dir = test::temp_dir("prepare_env_radiance");
    const std::string scene = (dir / "bright.json").string();
    const std::string json = R"({"meshes": [{"file": "builtin:icosphere"}],
        "environment": {"color": [1, 1, 1], "intensity": 1e31}})";
    test::write_bytes(scene, std::vector<unsigned char>(json.begin(), json.end()));
    const auto quiet = [](const std::string&) {};
    RenderOptions o;
    o.scene.scene_path = scene;
    o.scene.width = 8;
    o.scene.height = 8;
    EXPECT_EQ(
        test::error_of_call([&] { prepare_render(o, quiet); })
            .rfind(scene + ": environment: environment colour channel 1 times intensity 1e+31 is "
                           "radiance 1e+31, above the limit 1e+30",
                   0),
        0u);
    // An intensity option that brings it within the bound is used instead of the file's.
    o.scene.env_intensity = 1.0f;
    o.scene.use_cache = false;
    EXPECT_EQ(test::error_of_call([&] { prepare_render(o, quiet); }), "");
    o.scene.env_intensity = 3e38f;
    o.scene.scene_path.clear();  // the built-in scene
    EXPECT_EQ(test::error_of_call([&] { prepare_render(o, quiet); })
                  .rfind("scene.env_intensity: environment colour channel 1 times intensity "
                         "3e+38 is radiance 3e+38, above the limit 1e+30",
                         0),
              0u);
}

}  // namespace
}  // namespace kdt
