// The option structs as data: every table's defaults are valid, its ranges are enforced with
// the field's name, the JSON of all options reads back to the same options, and the rules of
// resolve() hold.
#include "renderer/render/render_options.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "tests/test_util.h"

#include "renderer/core/error.h"
#include "renderer/io/image_io.h"
#include "renderer/render/prepare.h"

namespace kdt {
namespace {

// The tree option named `name` (its JSON key); null when there is none.
const Field<KdTreeParams>* tree_field(const std::string& name) {
    for (const Field<KdTreeParams>& f : kd_tree_fields())
        if (f.name == name) return &f;
    return nullptr;
}

// Every field of a table: the default is valid, a value past either end of its range is
// refused by parse_field with a reason, and the range's ends are accepted.
template <class S>
void check_table(std::span<const Field<S>> fields, const char* group) {
    ASSERT_FALSE(fields.empty()) << group;
    for (const Field<S>& f : fields) {
        SCOPED_TRACE(std::string(group) + "." + f.name);
        S s{};
        EXPECT_EQ(check_field(f, s), "");
        const FieldRef r = f.at(s);
        if (std::holds_alternative<bool*>(r)) {
            EXPECT_EQ(parse_field(f, s, "maybe").empty(), false);
            EXPECT_EQ(parse_field(f, s, "true"), "");
            EXPECT_TRUE(*std::get<bool*>(r));
            continue;
        }
        if (std::holds_alternative<ChoiceRef>(r)) {
            ASSERT_FALSE(f.choices.empty());
            for (const char* name : f.choices) {
                EXPECT_EQ(parse_field(f, s, name), "");
                EXPECT_EQ(field_text(f, s), name);
            }
            EXPECT_NE(parse_field(f, s, "no-such-name"), "");
            continue;
        }
        if (std::holds_alternative<uint64_t*>(r)) {
            EXPECT_EQ(parse_field(f, s, "18446744073709551615"), "");
            EXPECT_EQ(*std::get<uint64_t*>(r), ~uint64_t(0));
            EXPECT_NE(parse_field(f, s, "18446744073709551616"), "");
            EXPECT_NE(parse_field(f, s, "-1"), "");
            EXPECT_EQ(*std::get<uint64_t*>(r), ~uint64_t(0));  // unchanged by a refusal
            continue;
        }
        const bool integral = field_is_integral(r);
        const double below = f.min_open ? f.min : f.min - (integral ? 1.0 : std::fabs(f.min) + 1.0);
        const double before = field_number(r);
        EXPECT_NE(parse_field(f, s, detail::number_text(below)), "");
        EXPECT_EQ(field_number(r), before);
        EXPECT_NE(parse_field(f, s, "nan"), "");
        EXPECT_NE(parse_field(f, s, "inf"), "");
        EXPECT_NE(parse_field(f, s, "12abc"), "");
        if (f.max < 1e30) {
            EXPECT_NE(parse_field(f, s, detail::number_text(f.max * 2.0 + 1.0)), "");
        }
        EXPECT_EQ(parse_field(f, s, detail::number_text(f.max)), "") << f.max;
        if (std::holds_alternative<float*>(r) && f.min_open) {
            // Above an open minimum as a double, on it as a float: 1e-50 would be stored as 0.
            const double inside = f.min == 0.0 ? 1e-50 : f.min * (1.0 + 1e-12);
            const double kept = field_number(r);
            EXPECT_NE(parse_field(f, s, detail::number_text(inside)), "") << inside;
            EXPECT_EQ(field_number(r), kept);
        }
        if (integral) {
            EXPECT_NE(parse_field(f, s, "1.5"), "");
        }
    }
}

TEST(RenderOptions, EveryTableHasValidDefaultsAndEnforcedRanges) {
    check_table(scene_fields(), "scene");
    check_table(kd_tree_fields(), "tree");
    check_table(trace_fields(), "trace");
    check_table(film_fields(), "film");
    check_table(stop_fields(), "stop");
    EXPECT_NO_THROW(validate(RenderOptions{}));
}

TEST(RenderOptions, ErrorsNameTheField) {
    RenderOptions o;
    o.trace.max_depth = -1;
    EXPECT_EQ(test::error_of_call([&] { validate(o); }),
              "trace.max_depth must be in [0, 1024] (got -1)");
    o = RenderOptions{};
    o.trace.max_depth = 100000;  // a whole number in digits, not 1e+05
    EXPECT_EQ(test::error_of_call([&] { validate(o); }),
              "trace.max_depth must be in [0, 1024] (got 100000)");
    o = RenderOptions{};
    o.stop.max_spp = 100000;
    for (const Field<StopConditions>& f : stop_fields()) {
        if (std::string(f.name) == "max_spp") {
            EXPECT_EQ(field_text(f, o.stop), "100000");
        }
    }
    o = RenderOptions{};
    o.tree.q = 1.5f;
    EXPECT_EQ(test::error_of_call([&] { validate(o); }), "tree.q must be in (0, 1] (got 1.5)");
    o = RenderOptions{};
    o.film.adaptive_threshold = std::nanf("");
    EXPECT_NE(test::error_of_call([&] { validate(o); }).find("film.adaptive_threshold"),
              std::string::npos);
    o = RenderOptions{};
    o.stop.seconds = -1.0;
    EXPECT_NE(test::error_of_call([&] { validate(o); }).find("stop.seconds"), std::string::npos);
    o = RenderOptions{};
    o.scene.width = 0;
    EXPECT_NE(test::error_of_call([&] { validate(o); }).find("scene.width"), std::string::npos);
    o = RenderOptions{};
    o.scene.env_intensity = -2.0f;
    EXPECT_NE(test::error_of_call([&] { validate(o); }).find("scene.env_intensity"),
              std::string::npos);
    o = RenderOptions{};
    o.trace.filter = PixelFilter(9);
    EXPECT_NE(
        test::error_of_call([&] { validate(o); }).find("trace.filter must be one of: box, tent"),
        std::string::npos);
}

TEST(RenderOptions, TheStatedMaximumOfAFloatFieldIsAccepted) {
    // 3e38 as a float is 3.0000000055e38: still the range's maximum, as stated.
    RenderOptions o;
    o.scene.env_intensity = float(3e38);
    o.tree.traversal_cost = float(3e38);
    o.tree.intersect_cost = float(3e38);
    EXPECT_NO_THROW(validate(o));
    KdTreeParams p;
    const Field<KdTreeParams>* cost = tree_field("traversal_cost");
    ASSERT_TRUE(cost);
    EXPECT_EQ(parse_field(*cost, p, "3e38"), "");
    EXPECT_EQ(check_field(*cost, p), "");
    // Beyond it is still refused.
    o.scene.env_intensity = 3.1e38f;
    EXPECT_THROW(validate(o), Error);
    EXPECT_EQ(parse_field(*cost, p, "3.1e38"), "must be in (0, 3e+38] (got 3.1e+38)");
}

// A value within a float field's range as typed that its float is not: refused with both,
// not stored as 0 (which --error and --time read as off) or refused later without the flag.
TEST(RenderOptions, AValueThatRoundsOutOfAFloatFieldsRangeIsRefused) {
    KdTreeParams p;
    const Field<KdTreeParams>* q = tree_field("q");
    ASSERT_TRUE(q);
    EXPECT_EQ(parse_field(*q, p, "1e-50"), "must be in (0, 1] (got 1e-50, which is 0 as a float)");
    EXPECT_EQ(p.q, KdTreeParams{}.q);
    EXPECT_EQ(parse_field(*q, p, "1e-30"), "");
    EXPECT_EQ(p.q, 1e-30f);
}

TEST(RenderOptions, ResolveHoldsTheRules) {
    RenderOptions o;
    RenderOptions r = resolve(o);
    EXPECT_EQ(r.stop.spp, kDefaultSpp);  // no stop condition
    EXPECT_FALSE(r.film.adaptive);
    o.stop.error = 0.05f;
    o.trace.threads = 3;
    r = resolve(o);
    EXPECT_EQ(r.stop.spp, 0);  // the error target is a stop condition
    EXPECT_TRUE(r.film.adaptive);
    EXPECT_EQ(r.film.adaptive_threshold, 0.05f);
    EXPECT_EQ(r.tree.threads, 3);
    o.tree.threads = 1;
    EXPECT_EQ(resolve(o).tree.threads, 1);  // a tree's own threads stay
}

TEST(RenderOptions, JsonReadsBackTheSameOptions) {
    RenderOptions o;
    o.scene.scene_path = "models/dragon.ply";
    o.scene.env_file = "probes/grace.hdr";
    o.scene.env_intensity = 2.6f;
    o.scene.width = 123;
    o.scene.eye = Vec3f(0.1f, 2.6f, -3.0f);
    CameraDesc c;
    c.eye = Vec3f(1, 2, 3);
    c.vfov_degrees = 33.3f;
    o.scene.camera = c;
    o.tree.builder = KdBuilder::thesis;
    o.tree.q = 0.9f;
    o.tree.use_center_split = false;
    o.trace.seed = ~uint64_t(0) - 7;
    o.trace.light_sampling = LightSampling::nee;
    o.film.adaptive_threshold = 0.013f;
    o.stop.seconds = 2.5;
    const std::string text = options_to_json(o);
    // Floats as the shortest text that reads back the same float.
    EXPECT_NE(text.find("\"q\":0.9,"), std::string::npos) << text;
    EXPECT_NE(text.find("2.6"), std::string::npos);
    EXPECT_EQ(text.find("2.5999"), std::string::npos) << text;
    RenderOptions back;
    options_from_json(text, back, "test");
    EXPECT_EQ(options_to_json(back), text);
    EXPECT_EQ(back.trace.seed, o.trace.seed);
    EXPECT_EQ(back.tree.q, 0.9f);
    EXPECT_EQ(*back.scene.env_intensity, 2.6f);
    EXPECT_EQ(back.scene.camera->vfov_degrees, 33.3f);
    EXPECT_EQ(*back.scene.eye, o.scene.eye);
}

TEST(RenderOptions, JsonRefusesWhatItCannotHonour) {
    RenderOptions o;
    auto bad = [&](const std::string& text) {
        return test::error_of_call([&] { options_from_json(text, o, "s.json"); });
    };
    EXPECT_EQ(bad("{\"trace\": {\"max_depht\": 3}}"), "s.json: /trace/max_depht: unknown key");
    EXPECT_EQ(bad("{\"traec\": {}}"), "s.json: /traec: unknown key");
    EXPECT_NE(bad("{\"trace\": {\"max_depth\": -3}}").find("/trace/max_depth"), std::string::npos);
    EXPECT_NE(bad("{\"trace\": {\"filter\": \"gauss\"}}").find("one of: box, tent"),
              std::string::npos);
    EXPECT_NE(bad("{\"trace\": {\"seed\": -1}}"), "");
    EXPECT_NE(bad("{\"scene\": {\"eye\": [1, 2]}}").find("/scene/eye"), std::string::npos);
    EXPECT_NE(bad("{\"scene\": {\"width\": 1.5}}").find("whole number"), std::string::npos);
    EXPECT_NE(bad("[1, 2]"), "");
    EXPECT_NE(bad("{"), "");
    // A repeated key or group would replace the first silently.
    EXPECT_EQ(bad("{\"stop\": {\"spp\": 1}, \"stop\": {\"spp\": 2}}"),
              "s.json: /stop: repeated key");
    EXPECT_EQ(bad("{\"scene\": {\"camera\": {\"vfov_degrees\": 40, \"vfov_degrees\": 90}}}"),
              "s.json: /scene/camera/vfov_degrees: repeated key");
    EXPECT_EQ(bad("{\"scene\": {\"materials\": [{}, {\"albedo\": 0.5, \"albedo\": 1}]}}"),
              "s.json: /scene/materials/1/albedo: repeated key");
    // Errors found after the keys are read name the file, and the JSON path where one is to
    // blame.
    EXPECT_EQ(bad(R"({"scene": {"up": [0, 0, 0]}})"), "s.json: /scene/up: up vector is zero");
    EXPECT_EQ(bad(R"({"scene": {"vfov_degrees": 1e30}})"),
              "s.json: /scene/vfov_degrees: must be in (0, 180) degrees (got 1e+30)");
    EXPECT_EQ(bad(R"({"scene": {"vfov_degrees": 0}})"),
              "s.json: /scene/vfov_degrees: must be in (0, 180) degrees (got 0)");
    const char* cam = R"({"scene": {"camera": {"eye": [0, 0, 0], "target": [0, 0, 0],
        "up": [0, 1, 0], "vfov_degrees": 40}}})";
    EXPECT_EQ(bad(cam), "s.json: /scene/camera: eye and target coincide");
    const char* vfov = R"({"scene": {"camera": {"eye": [0, 0, 5], "target": [0, 0, 0],
        "up": [0, 1, 0], "vfov_degrees": 1e39}}})";
    EXPECT_EQ(
        bad(vfov).rfind("s.json: /scene/camera: vertical field of view must be in (0, 180)", 0), 0u)
        << bad(vfov);
    // Ranges of the scene's keys without a table entry, and the image size, by JSON path.
    EXPECT_EQ(bad(R"({"scene": {"width": 16384, "height": 16384}})"),
              "s.json: /scene/width, /scene/height: 16384x16384 is 268435456 pixels, more than "
              "134217728");
    EXPECT_EQ(bad(R"({"scene": {"env_intensity": -1}})"),
              "s.json: /scene/env_intensity: must be in [0, 3e+38] (got -1)");
    EXPECT_EQ(bad(R"({"scene": {"env_mapping": "polar"}})"),
              "s.json: /scene/env_mapping: must be one of: latlong, angular (got 'polar')");
    // Only the keys the file gave are to blame for the size.
    RenderOptions wide;
    wide.scene.width = 16384;
    EXPECT_EQ(test::error_of_call(
                  [&] { options_from_json(R"({"scene": {"height": 16384}})", wide, "s.json"); }),
              "s.json: /scene/height: 16384x16384 is 268435456 pixels, more than 134217728");
}

}  // namespace
}  // namespace kdt

namespace kdt {
namespace {

// A session's materials (the viewer's edits) read back as written, are checked as a scene
// file's are, and replace the scene's own, one per mesh instance.
TEST(RenderOptions, MaterialsReadBackAreCheckedAndReplaceTheScenes) {
    RenderOptions o;
    MaterialDesc m;
    m.albedo = Vec3f(0.1f, 0.6f, 0.3f);
    MaterialDesc glass;
    glass.type = MaterialType::dielectric;
    glass.ior = 1.33f;
    o.scene.materials = {m, glass};
    const std::string text = options_to_json(o);
    RenderOptions back;
    options_from_json(text, back, "s.json");
    ASSERT_EQ(back.scene.materials.size(), 2u);
    EXPECT_TRUE(back.scene.materials[0] == m);
    EXPECT_TRUE(back.scene.materials[1] == glass);
    EXPECT_EQ(options_to_json(back), text);

    auto bad = [&](const std::string& json) {
        RenderOptions x;
        return test::error_of_call([&] { options_from_json(json, x, "s.json"); });
    };
    EXPECT_NE(bad("{\"scene\": {\"materials\": [{\"albedo\": [2, 0, 0]}]}}")
                  .find("/scene/materials/0/albedo"),
              std::string::npos);
    EXPECT_NE(bad("{\"scene\": {\"materials\": [{\"colour\": 1}]}}").find("unknown key \"colour\""),
              std::string::npos);
    EXPECT_NE(bad("{\"scene\": {\"materials\": 3}}").find("/scene/materials: expected an array"),
              std::string::npos);

    // The default scene has two mesh instances (object and ground).
    SceneOptions s;
    const size_t n = load_scene_with_overrides(s).meshes.size();
    ASSERT_GE(n, 1u);
    s.materials.assign(n, m);
    for (const MeshInstance& inst : load_scene_with_overrides(s).meshes)
        EXPECT_TRUE(inst.material == m);
    s.materials.push_back(m);
    EXPECT_NE(test::error_of_call([&] { load_scene_with_overrides(s); })
                  .find("scene.materials: " + std::to_string(n + 1) + " materials for a scene of " +
                        std::to_string(n) + " mesh instances"),
              std::string::npos);
    // Read from a session, the count found wrong once the scene is loaded names the session
    // and the key.
    RenderOptions from_session;
    from_session.scene.materials = s.materials;
    options_from_json(options_to_json(from_session), from_session, "s.json");
    EXPECT_EQ(test::error_of_call([&] { load_scene_with_overrides(from_session.scene); }),
              "s.json: /scene/materials: " + std::to_string(n + 1) + " materials for a scene of " +
                  std::to_string(n) + " mesh instances");
}

// A session's env_mapping for a scene without an environment map, found once the scene is
// loaded, names the session and the key; a mapping set otherwise (--env-mapping) does not.
TEST(RenderOptions, SessionMappingWithoutAnEnvironmentMapNamesTheSession) {
    RenderOptions o;
    options_from_json(R"({"scene": {"env_mapping": "angular"}})", o, "s.json");
    EXPECT_EQ(test::error_of_call([&] { load_scene_with_overrides(o.scene); }),
              "s.json: /scene/env_mapping: the scene has no environment map to map");
    SceneOptions flag;
    flag.env_mapping = "angular";
    EXPECT_EQ(test::error_of_call([&] { load_scene_with_overrides(flag); }),
              "scene.env_mapping: the scene has no environment map to map");
}

// A scene's rotation loses its whole turns before the flag's is added: 1e20 degrees would
// otherwise swallow --env-rotation 90 in the float sum.
TEST(RenderOptions, HugeSceneRotationKeepsTheFlags) {
    const auto dir = test::temp_dir("rotation_sum");
    write_image((dir / "sky.pfm").string(), ImageRGB(8, 4));
    const std::string scene = (dir / "s.json").string();
    {
        std::ofstream f(scene);
        f << "{\"environment\": {\"file\": \"sky.pfm\", \"rotation_degrees\": 1e20},"
             " \"meshes\": [{\"file\": \"builtin:icosphere\"}]}";
    }
    SceneOptions s;
    s.scene_path = scene;
    s.env_rotation_degrees = 90.0f;
    EXPECT_EQ(load_scene_with_overrides(s).environment.rotation_degrees,
              std::fmod(1e20f, 360.0f) + 90.0f);
}

// A PNG or EXR that kdtrace wrote is a session: its kdtrace:params are read, the pixels never
// decoded; an image without them, or with them twice, is refused naming the file.
TEST(RenderOptions, ImagesWrittenByKdtraceAreSessions) {
    const auto dir = test::temp_dir("image_sessions");
    ImageRGB img(4, 2);
    RenderOptions written;
    written.trace.seed = 77;
    written.scene.width = 4;
    const ImageMetadata meta = {{"kdtrace:params", options_to_json(written)}};
    for (const char* ext : {".png", ".exr"}) {
        const std::string path = (dir / (std::string("a") + ext)).string();
        write_image(path, img, {}, meta);
        RenderOptions o;
        options_from_session_file(path, o);
        EXPECT_EQ(o.trace.seed, 77u) << ext;
        EXPECT_EQ(options_to_json(o), options_to_json(written)) << ext;
        const std::string plain = (dir / (std::string("plain") + ext)).string();
        write_image(plain, img);
        EXPECT_NE(test::error_of_call([&] {
                      options_from_session_file(plain, o);
                  }).find(plain + ": no kdtrace:params text in this"),
                  std::string::npos);
    }
    // PFM and HDR have no place for settings: said so, not "malformed JSON".
    for (const char* ext : {".pfm", ".hdr"}) {
        const std::string path = (dir / (std::string("linear") + ext)).string();
        write_image(path, img);
        RenderOptions o;
        EXPECT_NE(test::error_of_call([&] { options_from_session_file(path, o); })
                      .find(path + ": a " + (ext[1] == 'p' ? "PFM" : "Radiance HDR") +
                            " image carries no kdtrace settings; give the PNG or EXR"),
                  std::string::npos)
            << ext;
    }
    const std::string twice = (dir / "twice.png").string();
    write_image(twice, img, {}, {{"kdtrace:params", "{}"}, {"kdtrace:params", "{}"}});
    RenderOptions o;
    EXPECT_NE(test::error_of_call([&] {
                  options_from_session_file(twice, o);
              }).find("twice.png: kdtrace:params: given twice"),
              std::string::npos);
}

}  // namespace
}  // namespace kdt

namespace kdt {
namespace {

// A camera vector whose number overflows a float is refused where it is written, not as an
// infinite eye at render time.
TEST(RenderOptions, JsonVectorsMustBeFiniteFloats) {
    RenderOptions o;
    const std::string e = test::error_of_call([&] {
        options_from_json("{\"scene\": {\"camera\": {\"eye\": [1e300, 0, 0]}}}", o, "s.json");
    });
    EXPECT_NE(e.find("s.json"), std::string::npos) << e;
    EXPECT_NE(e.find("/scene/camera/eye"), std::string::npos) << e;
    EXPECT_NE(e.find("finite"), std::string::npos) << e;
    EXPECT_NE(test::error_of_call([&] {
                  options_from_json("{\"scene\": {\"up\": [0, 1e39, 0]}}", o, "s.json");
              }).find("/scene/up"),
              std::string::npos);
}

}  // namespace
}  // namespace kdt

namespace kdt {
namespace {

// A file name of a session with a control character is refused where it is read: a NUL would
// cut it short at open() and load another file ("tri.ply\u0000.ply" opening tri.ply). An
// empty scene_path stays "the built-in scene".
TEST(RenderOptions, JsonFileNamesRefuseControlCharacters) {
    for (const char* key : {"scene_path", "env_file", "cache_dir", "tree_file"}) {
        for (const char* bad : {"a.ply\\u0000.ply", "a\\u001b[31m.ply", "a\\n.ply"}) {
            RenderOptions o;
            const std::string json = std::string("{\"scene\": {\"") + key + "\": \"" + bad + "\"}}";
            const std::string e =
                test::error_of_call([&] { options_from_json(json, o, "s.json"); });
            EXPECT_NE(e.find(std::string("s.json: /scene/") + key +
                             ": file name contains a control character"),
                      std::string::npos)
                << json << " -> " << e;
        }
    }
    RenderOptions o;
    o.scene.scene_path = "x.ply";
    options_from_json("{\"scene\": {\"scene_path\": \"\", \"tree_file\": \"t \\u00fc.kdt\"}}", o,
                      "s.json");
    EXPECT_EQ(o.scene.scene_path, "");
    EXPECT_EQ(o.scene.tree_file, "t \xc3\xbc.kdt");
}

// File names are bytes: one that is not valid UTF-8 is stored as NAME_bytes with %XX escapes
// and read back byte for byte (a session image renders the same model again).
TEST(RenderOptions, JsonKeepsFileNamesThatAreNotUtf8) {
    RenderOptions o;
    o.scene.scene_path = "/m/\x9bq%41.ply";                 // a lone continuation byte, a "%"
    o.scene.env_file = "/e/\xc0\xaf\xed\xa0\x80.hdr";       // overlong "/", a surrogate
    o.scene.tree_file = "/t/\xf4\x90\x80\x80\xe2\x82.kdt";  // above U+10FFFF, cut short
    o.scene.cache_dir = "/c/caf\xc3\xa9 %";                 // valid UTF-8 stays as it is
    const std::string json = options_to_json(o);
    EXPECT_NE(json.find("\"scene_path_bytes\":\"/m/%9Bq%2541.ply\""), std::string::npos) << json;
    EXPECT_NE(json.find("\"env_file_bytes\":\"/e/%C0%AF%ED%A0%80.hdr\""), std::string::npos);
    EXPECT_NE(json.find("\"tree_file_bytes\":\"/t/%F4%90%80%80%E2%82.kdt\""), std::string::npos);
    EXPECT_NE(json.find("\"cache_dir\":\"/c/caf\xc3\xa9 %\""), std::string::npos) << json;
    RenderOptions back;
    options_from_json(json, back, "s.json");
    EXPECT_EQ(back.scene.scene_path, o.scene.scene_path);
    EXPECT_EQ(back.scene.env_file, o.scene.env_file);
    EXPECT_EQ(back.scene.tree_file, o.scene.tree_file);
    EXPECT_EQ(back.scene.cache_dir, o.scene.cache_dir);
    EXPECT_EQ(options_to_json(back), json);
    const auto error = [](const std::string& scene) {
        RenderOptions r;
        return test::error_of_call(
            [&] { options_from_json("{\"scene\": {" + scene + "}}", r, "s.json"); });
    };
    EXPECT_EQ(error("\"scene_path_bytes\": \"a%4\""),
              "s.json: /scene/scene_path_bytes: '%' at byte 1 is not followed by two hex digits");
    EXPECT_EQ(error("\"scene_path_bytes\": \"a%1B.ply\""),
              "s.json: /scene/scene_path_bytes: file name contains a control character (byte 0x1b "
              "at offset 1)");
    EXPECT_EQ(error("\"tree_file\": \"a\", \"tree_file_bytes\": \"b\""),
              "s.json: /scene/tree_file_bytes: given with /scene/tree_file");
    EXPECT_NE(error("\"env_mapping_bytes\": \"x\"").find("env_mapping_bytes: unknown key"),
              std::string::npos);
}

}  // namespace
}  // namespace kdt

namespace kdt {
namespace {

// A hand-written session's relative file names resolve against its folder, as a scene
// file's do, whatever the working directory; a missing input is named with the session and
// the key. Absolute names (what kdtrace writes) are kept as they are.
TEST(RenderOptions, SessionFileNamesAreRelativeToTheSession) {
    const auto dir = test::temp_dir("session_relative");
    std::filesystem::create_directories(dir / "sub");
    std::ofstream(dir / "sub" / "m.ply") << "ply\n";
    std::ofstream(dir / "sub" / "sky.pfm") << "PF\n";
    const std::string session = (dir / "sub" / "rel.json").string();
    auto read = [&](const std::string& text) {
        std::ofstream(session) << text;
        RenderOptions o;
        options_from_session_file(session, o);
        return o;
    };
    RenderOptions o = read(
        R"({"scene": {"scene_path": "m.ply", "env_file": "../sub/sky.pfm", "cache_dir": "c"}})");
    EXPECT_EQ(o.scene.scene_path, (dir / "sub" / "m.ply").string());
    EXPECT_EQ(o.scene.env_file, (dir / "sub" / "sky.pfm").string());
    EXPECT_EQ(o.scene.cache_dir, (dir / "sub" / "c").string());  // need not exist
    const std::string absolute = (dir / "sub" / "m.ply").string();
    EXPECT_EQ(read("{\"scene\": {\"scene_path\": \"" + absolute + "\"}}").scene.scene_path,
              absolute);
    const std::string err =
        test::error_of_call([&] { read(R"({"scene": {"tree_file": "t.kdt"}})"); });
    EXPECT_EQ(err, session +
                       ": /scene/tree_file: no such file: " + (dir / "sub" / "t.kdt").string() +
                       " (relative names in a session are relative to its folder)");
    // options_from_json() alone (rank 0's options, the viewer's) keeps names as given.
    RenderOptions plain;
    options_from_json(R"({"scene": {"scene_path": "m.ply"}})", plain, "s.json");
    EXPECT_EQ(plain.scene.scene_path, "m.ply");
}

}  // namespace
}  // namespace kdt
