#include <sys/stat.h>

#include <cmath>
#include <fstream>
#include <map>

#include <gtest/gtest.h>

#include "renderer/camera/camera.h"
#include "renderer/core/error.h"
#include "renderer/scene/scene.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

std::string write_file(const std::filesystem::path& dir, const std::string& name,
                       const std::string& text) {
    auto p = dir / name;
    std::ofstream(p) << text;
    return p.string();
}

const char* kCubePly =
    "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\n"
    "property float z\nelement face 6\nproperty list uchar int vertex_indices\nend_header\n"
    "-1 -1 -1\n1 -1 -1\n1 1 -1\n-1 1 -1\n-1 -1 1\n1 -1 1\n1 1 1\n-1 1 1\n"
    "4 0 1 2 3\n4 5 4 7 6\n4 6 2 1 5\n4 3 7 4 0\n4 7 3 2 6\n4 5 1 0 4\n";

std::string error_of(const std::string& path) {
    try {
        load_scene(path);
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

TEST(Scene, DefaultSceneIsLargeAndClosed) {
    Scene s = make_default_scene();
    ASSERT_EQ(s.meshes.size(), 2u);
    EXPECT_EQ(s.meshes[0].mesh->triangle_count(), 327680u);
    // Watertight: every edge is shared by exactly two triangles.
    std::map<std::pair<uint32_t, uint32_t>, int> edges;
    for (const Vec3u& t : s.meshes[0].mesh->triangles) {
        for (int k = 0; k < 3; ++k) {
            uint32_t a = t[k], b = t[(k + 1) % 3];
            edges[{std::min(a, b), std::max(a, b)}]++;
        }
    }
    for (const auto& [e, n] : edges) ASSERT_EQ(n, 2);
    Bounds3f b = s.meshes[0].mesh->bounds();
    EXPECT_GT(b.extent().x, 1.5f);
    EXPECT_LT(b.extent().x, 2.6f);
}

TEST(Scene, LoadsFileWithTransformMaterialCameraEnvironment) {
    auto dir = test::temp_dir("scene_load");
    write_file(dir, "cube.ply", kCubePly);
    write_file(dir, "sky.hdr", "read by the renderer, only opened by the scene");
    auto path = write_file(dir, "s.json", R"({
      "name": "t",
      "meshes": [{"file": "cube.ply", "transform": {"translate": [1, 2, 3], "scale": 2},
                  "material": {"type": "mirror", "albedo": [0.9, 0.8, 0.7]}, "smooth": false},
                 {"file": "cube.ply"}],
      "camera": {"eye": [0, 0, 10], "target": [0, 0, 0], "up": [0, 1, 0], "vfov": 30},
      "environment": {"file": "sky.hdr", "mapping": "angular", "rotation": 90, "intensity": 2}
    })");
    Scene s = load_scene(path);
    ASSERT_EQ(s.meshes.size(), 2u);
    EXPECT_EQ(s.meshes[0].mesh.get(), s.meshes[1].mesh.get()) << "same file loaded once";
    EXPECT_EQ(s.meshes[0].mesh->triangle_count(), 12u);
    Vec4f p = s.meshes[0].world_from_object * Vec4f(1, 1, 1, 1);
    EXPECT_FLOAT_EQ(p.x, 3.0f);
    EXPECT_FLOAT_EQ(p.y, 4.0f);
    EXPECT_FLOAT_EQ(p.z, 5.0f);
    EXPECT_EQ(s.meshes[0].material.type, MaterialType::mirror);
    EXPECT_FALSE(s.meshes[0].smooth);
    EXPECT_TRUE(s.meshes[1].smooth);
    EXPECT_FLOAT_EQ(s.camera.vfov_degrees, 30.0f);
    EXPECT_EQ(s.environment.mapping, EnvMapping::angular);
    EXPECT_EQ(std::filesystem::path(s.environment.file), (dir / "sky.hdr").lexically_normal());
    EXPECT_FLOAT_EQ(s.environment.intensity, 2.0f);
}

TEST(Scene, RoundTripsThroughJson) {
    auto dir = test::temp_dir("scene_json");
    Scene a = make_default_scene();
    auto path = write_file(dir, "default.json", scene_to_json(a));
    Scene b = load_scene(path);
    ASSERT_EQ(b.meshes.size(), a.meshes.size());
    for (size_t i = 0; i < a.meshes.size(); ++i) {
        EXPECT_EQ(b.meshes[i].mesh->triangles, a.meshes[i].mesh->triangles);
        EXPECT_EQ(b.meshes[i].mesh->positions, a.meshes[i].mesh->positions);
        EXPECT_EQ(b.meshes[i].material.type, a.meshes[i].material.type);
        for (int c = 0; c < 4; ++c)
            for (int r = 0; r < 4; ++r)
                EXPECT_FLOAT_EQ(b.meshes[i].world_from_object[c][r],
                                a.meshes[i].world_from_object[c][r]);
    }
    EXPECT_EQ(b.camera.eye, a.camera.eye);
    EXPECT_EQ(b.environment.color, a.environment.color);
}

TEST(Scene, ErrorsNameFileAndKey) {
    auto dir = test::temp_dir("scene_err");
    write_file(dir, "cube.ply", kCubePly);
    struct Case {
        const char* json;
        const char* expect;
    } cases[] = {
        {R"({"meshes": [{"file": "cube.ply", "colour": 1}]})",
         "meshes/0/colour: unknown key \"colour\""},
        {R"({"meshes": [{"file": "cube.ply"}], "camrea": {}})", "camrea: unknown key"},
        {R"({"meshes": [{"file": "cube.ply", "material": {"type": "plastic"}}]})",
         "meshes/0/material/type: unknown value \"plastic\""},
        {R"({"meshes": [{"file": "cube.ply", "material": {"albedo": [1, 2]}}]})",
         "meshes/0/material/albedo: expected an array of 3 numbers"},
        {R"({"meshes": [{"file": "cube.ply", "material": {"albedo": 1.5}}]})",
         "albedo must lie in [0, 1]"},
        {R"({"meshes": [{"file": "missing.ply"}]})", "missing.ply"},
        {R"({"meshes": []})", "meshes: expected a non-empty array"},
        {R"({"meshes": [{"file": "cube.ply"}], "camera": {"vfov": 180}})", "camera/vfov"},
        {R"({"meshes": [{"file": "cube.ply"}], "camera": {"eye": [0,0,0], "target": [0,0,0]}})",
         "eye and target coincide"},
        {R"({"meshes": [{"file": "cube.ply", "transform": {"scale": 0}}]})",
         "scale must be non-zero"},
        {R"({"meshes": [{"file": "builtin:teapot"}]})", "unknown builtin mesh"},
        // A zero column, and two parallel columns: singular at any scale.
        {R"({"meshes": [{"file": "cube.ply", "transform": {"matrix":
            [1, 0, 0, 0, 2, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]}}]})",
         "meshes/0/transform/matrix: the matrix is singular"},
        {R"({"meshes": [{"file": "cube.ply", "transform": {"matrix":
            [1e-20, 1e-20, 0, 0, 0, 0, 1e-20, 0, 0, 0, 0, 0, 0, 0, 0, 1]}}]})",
         "meshes/0/transform/matrix: the matrix is singular"},
        {R"({"meshes": [{"file": "cube.ply"}], "environment": {"intensity": -1}})",
         "environment/intensity"},
        // Keys that would be ignored: a map with a colour, a map's orientation on a constant
        // colour, emission on a type that does not emit.
        {R"({"meshes": [{"file": "cube.ply"}], "environment": {"color": 1, "file": "cube.ply"}})",
         "environment: give color or file, not both"},
        {R"({"meshes": [{"file": "cube.ply"}], "environment": {"color": 1, "mapping": "latlong"}})",
         "environment/mapping: mapping orients an environment map"},
        {R"({"meshes": [{"file": "cube.ply"}], "environment": {"rotation_degrees": 0}})",
         "environment/rotation_degrees: rotation_degrees orients an environment map"},
        {R"({"meshes": [{"file": "cube.ply"}], "environment": {"rotation": 90}})",
         "environment/rotation: rotation orients"},
        {R"({"meshes": [{"file": "cube.ply", "material": {"type": "diffuse", "emission": 5}}]})",
         "meshes/0/material/emission: a diffuse material does not emit"},
        {R"({"meshes": [{"file": "cube.ply", "material": {"type": "dielectric",
            "emission": [0, 0, 1]}}]})",
         "meshes/0/material/emission: a dielectric material does not emit"},
        {R"({"meshes": [{"file": "cube.ply", "material": {"emission": 1}}]})",
         "does not emit (type defaults to diffuse)"},
        {R"({"meshes": [{"file": "cube.ply", "material": {"albdo": 0.5}}]})",
         "meshes/0/material/albdo: unknown key \"albdo\" (expected one of: albedo,"},
        {R"({"meshes": [{"file": "cube.ply"}] )", "invalid JSON"},
        {R"([1, 2])", "expected an object"},
        // nlohmann keeps a repeated key's last value without a word.
        {R"({"meshes": [{"file": "cube.ply"}], "camera": {"vfov_degrees": 40,
            "vfov_degrees": 170}})",
         "camera/vfov_degrees: repeated key"},
        {R"({"name": "a", "meshes": [{"file": "cube.ply"}], "name": "b"})", ": name: repeated key"},
        {R"({"meshes": [{"file": "cube.ply"}, {"file": "cube.ply", "material": {"albedo": 0.5},
            "file": "cube.ply"}]})",
         "meshes/1/file: repeated key"},
    };
    int i = 0;
    for (const Case& c : cases) {
        auto path = write_file(dir, "bad" + std::to_string(i++) + ".json", c.json);
        std::string msg = error_of(path);
        EXPECT_NE(msg.find(path), std::string::npos) << msg;
        EXPECT_NE(msg.find(c.expect), std::string::npos)
            << "got: " << msg << "\nwanted: " << c.expect;
    }
    EXPECT_NE(error_of((dir / "nope.json").string()).find("cannot open"), std::string::npos);
    EXPECT_NE(error_of(dir.string()).find("is a directory"), std::string::npos);
}

// A FIFO or device, as the scene file or named by it, is refused at once (a FIFO without a
// writer would block the reader forever), naming the file.
TEST(Scene, FifosAndDevicesAreRefusedNamingTheFile) {
    auto dir = test::temp_dir("scene_fifo");
    const std::string fifo = (dir / "scene.json").string();
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    std::string msg = error_of(fifo);
    EXPECT_NE(msg.find(fifo + ": is a FIFO (pipe), not a scene file"), std::string::npos) << msg;
    msg = error_of("/dev/zero");
    EXPECT_NE(msg.find("/dev/zero: is a character device"), std::string::npos) << msg;
    const std::string mesh_fifo = (dir / "mesh.ply").string();
    ASSERT_EQ(::mkfifo(mesh_fifo.c_str(), 0600), 0);
    const std::string a = write_file(dir, "a.json", R"({"meshes": [{"file": "mesh.ply"}]})");
    msg = error_of(a);
    EXPECT_NE(msg.find(a), std::string::npos) << msg;
    EXPECT_NE(msg.find("is a FIFO (pipe)"), std::string::npos) << msg;
}

// Found by tests/fuzz/scene_fuzzer: nlohmann's parser throws out_of_range (not parse_error)
// for a number beyond double, which escaped load_scene and terminated the program.
TEST(Scene, NumberBeyondDoubleIsAnErrorNamingTheFile) {
    auto dir = test::temp_dir("scene_overflow");
    auto path = write_file(dir, "huge.json",
                           R"({"meshes": [{"file": "builtin:icosphere", "transform": )"
                           R"({"translate": [1e380, 0, 0]}}]})");
    const std::string msg = error_of(path);
    EXPECT_EQ(msg.rfind(path + ": invalid JSON: ", 0), 0u) << msg;
    EXPECT_NE(msg.find("number overflow"), std::string::npos) << msg;
}

TEST(Scene, MeshSourceReplacesMeshFilesAndBuiltins) {
    auto tri = std::make_shared<const TriangleMesh>(make_ground_plane(1.0f, 0.0f));
    std::vector<std::string> asked;
    SceneLoadOptions options;
    options.mesh_source = [&](const std::string& file) {
        asked.push_back(file);
        return tri;
    };
    Scene s = load_scene_text(
        R"({"meshes": [{"file": "a/m.ply"}, {"file": "builtin:displaced_sphere"}]})", "dir/s.json",
        options);
    ASSERT_EQ(s.meshes.size(), 2u);
    EXPECT_EQ(s.meshes[0].mesh, tri);
    EXPECT_EQ(s.meshes[1].mesh, tri);
    EXPECT_EQ(asked, (std::vector<std::string>{"dir/a/m.ply", "builtin:displaced_sphere"}));
    try {
        load_scene_text(R"({"meshes": [{"file": "builtin:teapot"}]})", "s.json", options);
        FAIL() << "no error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("s.json: meshes/0/file: unknown builtin mesh"),
                  std::string::npos)
            << e.what();
    }
}

// An emissive material that emits nothing renders black without a word otherwise: a warning
// naming the file and the key, not an error (black emitters may be meant); any emission, or
// another type, gives none.
TEST(Scene, EmissiveWithoutEmissionIsAWarning) {
    std::vector<std::string> warnings;
    SceneLoadOptions options;
    options.warn = [&](const std::string& line) { warnings.push_back(line); };
    const Scene s = load_scene_text(
        R"({"meshes": [{"file": "builtin:icosphere", "material": {"type": "diffuse"}},)"
        R"( {"file": "builtin:icosphere", "material": {"type": "emissive"}},)"
        R"( {"file": "builtin:icosphere", "material": {"type": "emissive", "emission": [0, 0, 0]}},)"
        R"( {"file": "builtin:icosphere", "material": {"type": "emissive", "emission": [0, 0, 1]}},)"
        R"( {"file": "builtin:icosphere", "material": {"type": "mirror", "emission": [0, 0, 0]}}]})",
        "dir/s.json", options);
    ASSERT_EQ(s.meshes.size(), 5u);
    ASSERT_EQ(warnings.size(), 2u);
    EXPECT_EQ(warnings[0],
              "warning: dir/s.json: meshes/1/material: type emissive without \"emission\": it "
              "emits no light, and the mesh (builtin:icosphere) renders black");
    EXPECT_EQ(warnings[1],
              "warning: dir/s.json: meshes/2/material/emission: emission 0 0 0 on type emissive: "
              "it emits no light, and the mesh (builtin:icosphere) renders black");
}

// A field the material's type ignores is a warning naming the file, the material and the
// field (a user who typed it expects it to matter); the fields a type uses, a zero emission
// and unknown keys (errors) give none.
TEST(Scene, FieldsTheMaterialTypeIgnoresAreWarnings) {
    std::vector<std::string> warnings;
    SceneLoadOptions options;
    options.warn = [&](const std::string& line) { warnings.push_back(line); };
    auto load = [&](const std::string& material) {
        warnings.clear();
        load_scene_text(
            R"({"meshes": [{"file": "builtin:icosphere", "material": )" + material + "}]}",
            "dir/s.json", options);
        return warnings;
    };
    using Lines = std::vector<std::string>;
    EXPECT_EQ(load(R"({"type": "diffuse", "albedo": [0.5, 0.5, 0.5], "ior": 1.5})"),
              Lines{"warning: dir/s.json: meshes/0/material/ior: 'ior' is ignored by a diffuse "
                    "material; dielectric uses it"});
    EXPECT_EQ(load(R"({"albedo": 0.5, "roughness": 0.3})"),
              Lines{"warning: dir/s.json: meshes/0/material/roughness: 'roughness' is ignored by "
                    "a diffuse material (type defaults to diffuse); conductor uses it"});
    EXPECT_EQ(load(R"({"type": "dielectric", "ior": 1.33, "roughness": 0.1, "albedo": 1})"),
              (Lines{"warning: dir/s.json: meshes/0/material/albedo: 'albedo' is ignored by a "
                     "dielectric material; diffuse, mirror and conductor use it",
                     "warning: dir/s.json: meshes/0/material/roughness: 'roughness' is ignored "
                     "by a dielectric material; conductor uses it"}));
    EXPECT_EQ(load(R"({"type": "emissive", "emission": 2, "albedo": 1, "ior": 2})"),
              (Lines{"warning: dir/s.json: meshes/0/material/albedo: 'albedo' is ignored by an "
                     "emissive material; diffuse, mirror and conductor use it",
                     "warning: dir/s.json: meshes/0/material/ior: 'ior' is ignored by an emissive "
                     "material; dielectric uses it"}));
    EXPECT_EQ(load(R"({"type": "mirror", "ior": 1.5, "roughness": 0.5, "emission": 0})").size(),
              2u);
    // Each type with the fields it uses, and a zero emission anywhere: no warning.
    EXPECT_EQ(load(R"({"type": "diffuse", "albedo": 0.5, "emission": [0, 0, 0]})"), Lines{});
    EXPECT_EQ(load(R"({"type": "mirror", "albedo": 0.5})"), Lines{});
    EXPECT_EQ(load(R"({"type": "dielectric", "ior": 1.5, "emission": 0})"), Lines{});
    EXPECT_EQ(load(R"({"type": "emissive", "emission": 3})"), Lines{});
    EXPECT_EQ(load(R"({"type": "conductor", "albedo": 0.9, "roughness": 0.1})"), Lines{});
    // Unknown keys stay errors, as do values out of range on an ignored field.
    EXPECT_THROW(load(R"({"type": "diffuse", "iorr": 1.5})"), Error);
    EXPECT_THROW(load(R"({"type": "diffuse", "roughness": 2})"), Error);
}

// What the writers write (scene files, the materials of option and session files) holds the
// fields of the material's type only, also when the viewer kept others across a type change:
// it reads back as the same material for rendering, without warnings.
TEST(Scene, WrittenMaterialsHoldTheirTypesFieldsOnly) {
    std::vector<std::string> warnings;
    SceneLoadOptions options;
    options.check_files = false;
    options.warn = [&](const std::string& line) { warnings.push_back(line); };
    Scene scene = make_default_scene();
    scene.meshes.resize(1);
    for (size_t t = 0; t < kMaterialTypeNames.size(); ++t) {
        MaterialDesc m;  // every field edited, as a viewer user switching types leaves them
        m.type = MaterialType(t);
        m.albedo = Vec3f(0.25f, 0.5f, 0.75f);
        m.ior = 1.33f;
        m.emission = m.type == MaterialType::emissive ? Vec3f(2.0f) : Vec3f(0.0f);
        m.roughness = 0.4f;
        scene.meshes.push_back(scene.meshes[0]);
        scene.meshes.back().material = m;
        const std::string text = material_to_json(m);
        for (size_t f = 0; f < kMaterialFieldNames.size(); ++f) {
            const bool written =
                text.find("\"" + std::string(kMaterialFieldNames[f]) + "\"") != std::string::npos;
            EXPECT_EQ(written, material_uses(m.type, MaterialField(f))) << text;
        }
        // The used fields read back; the others take their defaults.
        MaterialDesc expected;
        expected.type = m.type;
        if (material_uses(m.type, MaterialField::albedo)) expected.albedo = m.albedo;
        if (material_uses(m.type, MaterialField::ior)) expected.ior = m.ior;
        if (material_uses(m.type, MaterialField::emission)) expected.emission = m.emission;
        if (material_uses(m.type, MaterialField::roughness)) expected.roughness = m.roughness;
        EXPECT_TRUE(material_from_json(text, "m.json", "m") == expected) << text;
    }
    const Scene back = load_scene_text(scene_to_json(scene), "back.json", options);
    EXPECT_EQ(back.meshes.size(), scene.meshes.size());
    EXPECT_EQ(warnings, std::vector<std::string>{});
}

// Singularity does not depend on scale: a uniform scale of 1e-20 (or a strong anisotropic
// one) is an invertible transform, and its normals stay finite unit vectors.
TEST(Scene, TinyAndAnisotropicScalesAreNotSingular) {
    auto dir = test::temp_dir("scene_scale");
    write_file(dir, "cube.ply", kCubePly);
    for (const char* m : {"[1e-20, 0, 0, 0, 0, 1e-20, 0, 0, 0, 0, 1e-20, 0, 0, 0, 0, 1]",
                          "[1e-15, 0, 0, 0, 0, 1e15, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]"}) {
        const std::string path =
            write_file(dir, "s.json",
                       std::string(R"({"meshes": [{"file": "cube.ply", "transform": {"matrix": )") +
                           m + "}}]}");
        EXPECT_EQ(error_of(path), "") << m;
    }
}

TEST(Scene, FramingBoundsBeyondFloatRangeIsAnError) {
    const CameraDesc c = frame_bounds(Bounds3f{Vec3f(-1e30f), Vec3f(1e30f)});
    EXPECT_GT(glm::length(c.eye - c.target), 0.0f);
    EXPECT_TRUE(is_finite(c.eye));
    // A camera can be made from it: huge but finite scenes render.
    const Camera cam = make_camera(c.eye, c.target, c.up, c.vfov_degrees, 8, 8);
    const Ray r = cam.generate_ray(Vec2f(4.0f, 4.0f));
    EXPECT_TRUE(is_finite(r.dir));
    EXPECT_GT(glm::dot(r.dir, glm::normalize(c.target / 1e30f - c.eye / 1e30f)), 0.99f);
    try {
        frame_bounds(Bounds3f{Vec3f(-3e38f), Vec3f(3e38f)});
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("cannot frame the scene automatically"),
                  std::string::npos)
            << e.what();
    }
}

// A small model far from the origin cannot be framed either, since float cannot place the
// camera beside it; the error says so instead of calling its tiny extent beyond float range.
TEST(Scene, FramingASmallModelFarFromTheOriginSaysWhy) {
    try {
        // Vertices within about 1e13 of 1e20 all round to one float: a point.
        frame_bounds(Bounds3f{Vec3f(1e20f), Vec3f(1e20f)});
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        const std::string msg = e.what();
        EXPECT_EQ(msg.rfind("cannot frame the scene automatically: its extent 0 is "
                            "below float's resolution at its centre (1e+20, 1e+20, 1e+20), too "
                            "far from the origin",
                            0),
                  0u)
            << msg;
    }
}

// A model or camera-less scene too large to frame is an error naming the file.
TEST(Scene, FramingErrorsNameTheFile) {
    auto dir = test::temp_dir("scene_framing");
    const std::string model = write_file(
        dir, "huge.ply",
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
        "3e38 3e38 3e38\n-3e38 -3e38 -3e38\n3e38 -3e38 0\n3 0 1 2\n");
    std::string msg;
    try {
        load_scene_or_model(model);
    } catch (const Error& e) {
        msg = e.what();
    }
    EXPECT_EQ(msg.rfind(model + ": cannot frame the scene automatically: its bounds (extent inf) "
                                "are beyond float range; render it from a scene file that gives "
                                "a camera",
                        0),
              0u)
        << msg;
    const std::string scene = write_file(dir, "s.json", R"({"meshes": [{"file": "huge.ply"}]})");
    EXPECT_EQ(error_of(scene), scene +
                                   ": camera: cannot frame the scene automatically: its bounds "
                                   "(extent inf) are beyond float range; give the scene a camera");
}

TEST(Scene, ModelSceneFramesTheModel) {
    auto dir = test::temp_dir("scene_model");
    auto path = write_file(dir, "cube.ply", kCubePly);
    Scene s = load_scene_or_model(path);
    ASSERT_EQ(s.meshes.size(), 1u);
    // The whole cube (bounding sphere radius sqrt 3) lies inside the vertical field of view.
    Vec3f to_center = glm::normalize(s.camera.target - s.camera.eye);
    float dist = glm::length(s.camera.target - s.camera.eye);
    EXPECT_GT(dist * std::sin(glm::radians(s.camera.vfov_degrees / 2)), std::sqrt(3.0f));
    EXPECT_NEAR(glm::length(to_center), 1.0f, 1e-6f);
}

// A projective bottom row cannot be honoured (points are used without a division): refused.
TEST(Scene, TransformBottomRowMustBeAffine) {
    auto dir = test::temp_dir("scene_bottom_row");
    write_file(dir, "cube.ply", kCubePly);
    const char* rows[] = {"0, 0, 0, 2",  "0, 0, 1, 1",     "1e-30, 0, 0, 1",    "0, 0, 0, 0",
                          "0, 0, 0, -1", "0.5, 0.5, 0, 1", "0, 0, 0, 1.0000001"};
    int i = 0;
    for (const char* row : rows) {
        const std::string json =
            std::string(R"({"meshes": [{"file": "cube.ply", "transform": {"matrix": )") +
            "[2, 0, 0, 1, 0, 2, 0, 0, 0, 0, 2, 0, " + row + "]}}]}";
        const std::string path = write_file(dir, "s" + std::to_string(i++) + ".json", json);
        const std::string msg = error_of(path);
        EXPECT_EQ(
            msg.rfind(path + ": meshes/0/transform/matrix: the bottom row must be 0 0 0 1", 0), 0u)
            << row << ": " << msg;
    }
    const std::string ok = write_file(dir, "ok.json",
                                      R"({"meshes": [{"file": "cube.ply", "transform": {"matrix": )"
                                      R"([2, 0, 0, 1, 0, 2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 1]}}]})");
    EXPECT_EQ(error_of(ok), "");
}

// A NUL would cut the name short ("tri.ply\u0000.obj" opened tri.ply); no control
// character is a plausible part of a file name.
TEST(Scene, ControlCharactersInFileNamesAreErrors) {
    auto dir = test::temp_dir("scene_control");
    write_file(dir, "cube.ply", kCubePly);
    write_file(dir, "sky.pfm", "PF\n1 1\n-1\n");
    int i = 0;
    for (const char* escape : {"\\u0000", "\\u0001", "\\t", "\\n", "\\r", "\\u001b", "\\u007f"}) {
        for (const bool env : {false, true}) {
            const std::string name = std::string("cube.ply") + escape + ".obj";
            const std::string json =
                env ? R"({"meshes": [{"file": "cube.ply"}], "environment": {"file": ")" + name +
                          "\"}}"
                    : R"({"meshes": [{"file": ")" + name + "\"}]}";
            const std::string path = write_file(dir, "s" + std::to_string(i++) + ".json", json);
            const std::string msg = error_of(path);
            const std::string key = env ? "environment/file" : "meshes/0/file";
            EXPECT_EQ(
                msg.rfind(path + ": " + key + ": file name contains a control character (byte 0x",
                          0),
                0u)
                << escape << ": " << msg;
            EXPECT_NE(msg.find("at offset 8)"), std::string::npos) << msg;
        }
    }
    EXPECT_NE(error_of(write_file(dir, "empty.json", R"({"meshes": [{"file": ""}]})"))
                  .find("meshes/0/file: empty file name"),
              std::string::npos);
}

// The environment map a scene names is checked when the scene is read (not only when a
// render decodes it), and the message names the scene file and the key, then the problem.
TEST(Scene, EnvironmentFileIsCheckedNamingSceneAndKey) {
    auto dir = test::temp_dir("scene_env_file");
    write_file(dir, "cube.ply", kCubePly);
    std::filesystem::create_directories(dir / "probe_dir.hdr");
    ASSERT_EQ(::mkfifo((dir / "probe_fifo.hdr").c_str(), 0600), 0);
    write_file(dir, "locked.hdr", "#?RADIANCE\n");
    ASSERT_EQ(::chmod((dir / "locked.hdr").c_str(), 0), 0);
    struct Case {
        std::string file, expect;
    };
    std::vector<Case> cases = {
        {"missing.hdr", "cannot open file: No such file or directory"},
        {"probe_dir.hdr", "is a directory"},
        {"probe_fifo.hdr", "is a FIFO (pipe), not an environment map"},
        {"/dev/zero", "is a character device, not an environment map"},
        {"cube.ply/inside.hdr", "cannot open file: Not a directory"},
    };
    // Root reads any file whatever its mode: the unreadable case only means something
    // for other users.
    if (::geteuid() != 0) cases.push_back({"locked.hdr", "Permission denied"});
    int i = 0;
    for (const Case& c : cases) {
        const std::string path = write_file(
            dir, "s" + std::to_string(i++) + ".json",
            R"({"meshes": [{"file": "cube.ply"}], "environment": {"file": ")" + c.file + "\"}}");
        const std::string msg = error_of(path);
        EXPECT_EQ(msg.rfind(path + ": environment/file: ", 0), 0u) << c.file << ": " << msg;
        EXPECT_NE(msg.find(c.file), std::string::npos) << msg;
        EXPECT_NE(msg.find(c.expect), std::string::npos) << c.file << ": " << msg;
    }
}

// Relative mesh and environment paths resolve against the directory of the scene path as
// given: through a symlink, the link's directory, not its target's (as the shell would).
TEST(Scene, RelativePathsResolveAgainstTheSceneFileAsGivenNotASymlinksTarget) {
    const auto dir = test::temp_dir("scene_symlink");
    std::filesystem::create_directories(dir / "real");
    std::filesystem::create_directories(dir / "link");
    write_file(dir, "real/s.json",
               R"({"meshes": [{"file": "cube.ply"}], "environment": {"file": "sky.hdr"}})");
    std::filesystem::create_symlink("../real/s.json", dir / "link" / "s.json");
    write_file(dir, "link/cube.ply", kCubePly);
    write_file(dir, "link/sky.hdr", "opened, not decoded, by the scene reader");
    const Scene s = load_scene((dir / "link" / "s.json").string());
    EXPECT_EQ(std::filesystem::path(s.meshes[0].file),
              (dir / "link" / "cube.ply").lexically_normal());
    EXPECT_EQ(std::filesystem::path(s.environment.file),
              (dir / "link" / "sky.hdr").lexically_normal());
}

// Instances of one file or builtin share one mesh: a scene of many copies loads one.
TEST(Scene, InstancesShareOneMesh) {
    auto dir = test::temp_dir("scene_share");
    write_file(dir, "cube.ply", kCubePly);
    std::string json = R"({"meshes": [)";
    for (int i = 0; i < 60; ++i) {
        json += std::string(i ? ", " : "") + R"({"file": ")" +
                (i % 3 == 0 ? "cube.ply" : (i % 3 == 1 ? "builtin:icosphere" : "./cube.ply")) +
                R"(", "transform": {"translate": [)" + std::to_string(i) + ", 0, 0]}}";
    }
    const Scene s = load_scene(write_file(dir, "many.json", json + "]}"));
    ASSERT_EQ(s.meshes.size(), 60u);
    for (size_t i = 0; i < s.meshes.size(); ++i) {
        const size_t first_of_kind = i % 3 == 1 ? 1 : 0;
        EXPECT_EQ(s.meshes[i].mesh.get(), s.meshes[first_of_kind].mesh.get()) << i;
    }
    EXPECT_EQ(instanced_triangle_count(s), 40u * 12u + 20u * 20480u);
}

// A few bytes of JSON can ask for any number of copies: the total after instancing is
// bounded, with an error naming the scene file, before a render allocates it.
TEST(Scene, TriangleBudgetAfterInstancingIsEnforced) {
    auto dir = test::temp_dir("scene_budget");
    SceneLoadOptions options;
    options.max_triangles = 100000;
    EXPECT_LE(scene_triangle_budget(options.max_triangles), options.max_triangles);
    EXPECT_GT(scene_triangle_budget(), 0u);
    for (int n = 1; n <= 9; ++n) {
        std::string json = R"({"meshes": [)";
        for (int i = 0; i < n; ++i)
            json += std::string(i ? ", " : "") + R"({"file": "builtin:icosphere"})";
        const std::string path = write_file(dir, "s" + std::to_string(n) + ".json", json + "]}");
        const uint64_t triangles = uint64_t(n) * 20480u;
        std::string msg;
        try {
            load_scene(path, options);
        } catch (const Error& e) {
            msg = e.what();
        }
        const uint64_t budget = scene_triangle_budget(options.max_triangles);
        if (triangles <= budget) {
            EXPECT_EQ(msg, "") << n;
        } else {
            // The first instance over the budget ends the reading.
            const int over = int(budget / 20480u) + 1;
            const std::string count =
                over == n ? std::to_string(n)
                          : "the first " + std::to_string(over) + " of " + std::to_string(n);
            EXPECT_EQ(msg.rfind(path + ": meshes: " + count + " instances make " +
                                    std::to_string(uint64_t(over) * 20480u) +
                                    " triangles to render, over the budget of 100000 (at most "
                                    "100000 triangles",
                                0),
                      0u)
                << msg;
        }
    }
}

// The budget is checked as instances are read: a file of 100,000 instances (3.5 MB) is refused
// at the first one over, naming the count read so far, not after all of them (tens of seconds).
TEST(Scene, TriangleBudgetStopsReadingInstances) {
    auto dir = test::temp_dir("scene_budget_early");
    SceneLoadOptions options;
    options.max_triangles = 100000;
    std::string json = R"({"meshes": [)";
    for (int i = 0; i < 100000; ++i)
        json += std::string(i ? ", " : "") + R"({"file": "builtin:icosphere"})";
    // A broken instance far past the budget: reading it would fail with another message.
    json += R"(, {"file": "builtin:icosphere", "smooth": 1}]})";
    const std::string path = write_file(dir, "many.json", json);
    std::string msg;
    try {
        load_scene(path, options);
    } catch (const Error& e) {
        msg = e.what();
    }
    EXPECT_EQ(msg.rfind(path + ": meshes: the first 5 of 100001 instances make 102400 triangles "
                               "to render, over the budget of 100000",
                        0),
              0u)
        << msg;
}

// An eye or target near the float limit, or an up vector of huge components, is an
// overflow, not "up is parallel to the view direction" (which NaN products used to say).
TEST(Scene, CameraOverflowIsReportedAsOverflow) {
    auto dir = test::temp_dir("scene_camera_overflow");
    struct Case {
        const char* camera;
        const char* expect;
    } cases[] = {
        {R"("eye": [3e38, 3e38, 3e38], "target": [-3e38, -3e38, -3e38])",
         "eye and target are too far apart: their difference overflows float"},
        {R"("eye": [-3e38, 0, 0], "target": [3e38, 0, 0])",
         "eye and target are too far apart: their difference overflows float"},
        {R"("eye": [0, 0, 2e38], "target": [0, 0, -2e38])", "overflows float"},
        {R"("eye": [0, 0, 0], "target": [0, 0, 0])", "eye and target coincide"},
        {R"("eye": [0, 0, 5], "target": [0, 0, 0], "up": [0, 0, 0])",
         "camera/up: up vector is zero"},
        {R"("eye": [0, 0, 5], "target": [0, 0, 0], "up": [0, 0, 3e38])",
         "up is parallel to the view direction"},
    };
    int i = 0;
    for (const Case& c : cases) {
        const std::string path =
            write_file(dir, "c" + std::to_string(i++) + ".json",
                       std::string(R"({"meshes": [{"file": "builtin:icosphere"}], "camera": {)") +
                           c.camera + "}}");
        const std::string msg = error_of(path);
        EXPECT_EQ(msg.rfind(path + ": camera", 0), 0u) << msg;
        EXPECT_NE(msg.find(c.expect), std::string::npos) << c.camera << ": " << msg;
    }
    // Huge but representable cameras still load: up of huge components, a far eye.
    const std::string ok = write_file(
        dir, "ok.json",
        R"({"meshes": [{"file": "builtin:icosphere"}], "camera": {"eye": [3e38, 3e38, 3e38], )"
        R"("target": [1e38, 1e38, 1e38], "up": [0, 3e38, 0]}})");
    EXPECT_EQ(error_of(ok), "");
    // make_camera (views, the command line) says which vector is not finite.
    auto camera_error = [](Vec3f eye, Vec3f target, Vec3f up) {
        try {
            make_camera(eye, target, up, 40.0f, 8, 8);
        } catch (const Error& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    const float inf = INFINITY, big = 3e38f;
    EXPECT_NE(camera_error({inf, 0, 0}, {0, 0, 0}, {0, 1, 0}).find("camera: eye (inf"),
              std::string::npos);
    EXPECT_NE(camera_error({0, 0, 5}, {NAN, 0, 0}, {0, 1, 0}).find("camera: target (nan"),
              std::string::npos);
    EXPECT_NE(camera_error({0, 0, 5}, {0, 0, 0}, {0, inf, 0}).find("camera: up (0"),
              std::string::npos);
    EXPECT_NE(camera_error({-big, 0, 0}, {big, 0, 0}, {0, 1, 0})
                  .find("eye and target are too far apart: their difference overflows float"),
              std::string::npos);
    EXPECT_EQ(camera_error({big, big, big}, {0, 0, 0}, {0, big, 0}), "");
}

}  // namespace
}  // namespace kdt

namespace kdt {
namespace {

// One spelling of every key, and numbers written as the shortest text that reads back the
// same float: a scene written and read again is the same scene.
TEST(SceneJson, WritesShortestFloatsAndTheDocumentedKeys) {
    Scene scene = make_default_scene();
    scene.camera.vfov_degrees = 33.3f;
    scene.environment.file = "probe.hdr";
    scene.environment.rotation_degrees = 12.7f;
    const std::string text = scene_to_json(scene);
    EXPECT_NE(text.find("\"vfov_degrees\": 33.3"), std::string::npos) << text;
    EXPECT_NE(text.find("\"rotation_degrees\": 12.7"), std::string::npos);
    EXPECT_NE(text.find("2.6"), std::string::npos);
    EXPECT_EQ(text.find("2.5999"), std::string::npos);
    EXPECT_EQ(text.find("\"vfov\""), std::string::npos);
}

// Zero emission on a type that does not emit is what earlier writers wrote for every
// material; it still loads. An emission the viewer kept when an emissive material changed
// type is written as zero, so what is written reads back.
TEST(SceneJson, ZeroEmissionLoadsOnAnyTypeAndStaleEmissionIsNotWritten) {
    const auto dir = test::temp_dir("scene_emission");
    SceneLoadOptions o;
    o.check_files = false;
    for (const char* type : kMaterialTypeNames) {
        const std::string path =
            write_file(dir, "s.json",
                       std::string(R"({"meshes": [{"file": "builtin:icosphere", "material": )") +
                           R"({"type": ")" + type + R"(", "emission": [0, 0, 0]}}]})");
        EXPECT_EQ(load_scene(path, o).meshes[0].material.emission, Vec3f(0.0f)) << type;
    }
    Scene scene = load_scene(write_file(dir, "lamp.json",
                                        R"({"meshes": [{"file": "builtin:icosphere", "material": )"
                                        R"({"type": "emissive", "emission": [1, 2, 3]}}]})"),
                             o);
    EXPECT_EQ(scene.meshes[0].material.emission, Vec3f(1, 2, 3));
    scene.meshes[0].material.type = MaterialType::diffuse;  // as the viewer leaves it
    const Scene back = load_scene(write_file(dir, "back.json", scene_to_json(scene)), o);
    EXPECT_EQ(back.meshes[0].material.type, MaterialType::diffuse);
    EXPECT_EQ(back.meshes[0].material.emission, Vec3f(0.0f));
    MaterialDesc lamp;
    lamp.type = MaterialType::emissive;
    lamp.emission = Vec3f(4.0f);
    EXPECT_TRUE(material_from_json(material_to_json(lamp), "m.json", "m") == lamp);
}

TEST(SceneJson, ReadsTheDocumentedKeysAndTheFormerOnes) {
    const auto dir = test::temp_dir("scene_keys");
    auto load = [&](const std::string& camera_and_env) {
        const std::string path =
            write_file(dir, "s.json",
                       "{\"meshes\": [{\"file\": \"builtin:icosphere\"}], " + camera_and_env + "}");
        SceneLoadOptions o;
        o.check_files = false;
        return load_scene(path, o);
    };
    Scene s = load("\"camera\": {\"vfov_degrees\": 30}, \"environment\": {\"color\": [1, 1, 1]}");
    EXPECT_EQ(s.camera.vfov_degrees, 30.0f);
    s = load("\"camera\": {\"vfov\": 31}");
    EXPECT_EQ(s.camera.vfov_degrees, 31.0f);
    EXPECT_THROW(load("\"camera\": {\"vfov\": 31, \"vfov_degrees\": 30}"), Error);
    EXPECT_THROW(load("\"camera\": {\"fov\": 31}"), Error);
}

}  // namespace
}  // namespace kdt

namespace kdt {
namespace {

// A model that renders nothing (no faces, or none left after drop_invalid) and faces that
// drop_invalid dropped are warned about, for PLY and OBJ alike; a whole model is not.
TEST(Scene, ModelsThatRenderNothingWarn) {
    auto dir = test::temp_dir("scene_nothing");
    const std::string points =
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n";
    std::string nan_face = points;
    nan_face.replace(nan_face.find("end_header"), 10,
                     "element face 2\nproperty list uchar int vertex_indices\nend_header");
    nan_face.replace(nan_face.find("0 1 0"), 5, "nan 1 0");
    nan_face += "3 0 1 2\n2 0 1\n";
    struct Case {
        std::string name, text, want;
    } cases[] = {
        {"points.ply", points, "points.ply: no faces (a point cloud?): the model renders nothing"},
        {"points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n", "points.obj: no faces (a point cloud?)"},
        {"nan.ply", nan_face,
         "nan.ply: --drop-invalid dropped 2 faces (non-finite vertices, or fewer than 3 "
         "indices)\nwarning: "},
        {"nan.ply", nan_face, "nan.ply: no faces left: the model renders nothing"},
        {"cube.ply", kCubePly, ""},
    };
    for (const Case& c : cases) {
        const std::string path = write_file(dir, c.name, c.text);
        std::string warnings;
        SceneLoadOptions o;
        o.drop_invalid = true;
        o.warn = [&](const std::string& line) { warnings += line + "\n"; };
        load_scene_or_model(path, o);
        if (c.want.empty()) {
            EXPECT_EQ(warnings, "");
        } else {
            EXPECT_NE(warnings.find(c.want), std::string::npos) << warnings;
        }
        // The same through a scene file, which names the mesh file as given.
        const std::string scene =
            write_file(dir, "s.json", "{\"meshes\": [{\"file\": \"" + c.name + "\"}]}");
        warnings.clear();
        load_scene(scene, o);
        EXPECT_EQ(warnings.empty(), c.want.empty()) << warnings;
    }
}

double surface_area(const TriangleMesh& m) {
    double a = 0.0;
    for (const Vec3u& t : m.triangles)
        a += 0.5 * double(glm::length(
                       triangle_cross(m.positions[t.x], m.positions[t.y], m.positions[t.z])));
    return a;
}

// --subdivide: the same surface in 4^K as many triangles, a shared mesh subdivided once, and
// smooth instances shaded from normals made before the split (interpolated by it), so that
// the statue shades like the model.
TEST(Scene, SubdivideSplitsSharedMeshesOnceAndKeepsSmoothNormals) {
    Scene s;
    auto sphere = std::make_shared<const TriangleMesh>(make_icosphere(1));
    auto plane = std::make_shared<const TriangleMesh>(make_ground_plane(2.0f, 0.0f));
    for (int i = 0; i < 3; ++i) {
        MeshInstance inst;
        inst.mesh = i < 2 ? sphere : plane;
        inst.smooth = i == 0;  // the sphere: one smooth and one flat instance; the plane flat
        s.meshes.push_back(inst);
    }
    subdivide_scene(s, 2, "s.json");
    ASSERT_EQ(s.meshes[0].mesh.get(), s.meshes[1].mesh.get());
    const TriangleMesh& m = *s.meshes[0].mesh;
    EXPECT_EQ(m.triangle_count(), 16 * sphere->triangle_count());
    EXPECT_EQ(s.meshes[2].mesh->triangle_count(), 32u);
    EXPECT_NEAR(surface_area(m), surface_area(*sphere), 1e-5 * surface_area(*sphere));
    EXPECT_NEAR(surface_area(*s.meshes[2].mesh), 16.0, 1e-4);
    // Interpolated from the icosphere's vertex normals: every one unit length and within
    // the angle of one original face of the point's radius, where the subdivided mesh's own
    // computed normals would be those faces' normals inside each original triangle.
    ASSERT_EQ(m.normals.size(), m.positions.size());
    const std::vector<Vec3f> computed = compute_vertex_normals(m);
    size_t differ = 0;
    for (size_t v = 0; v < m.positions.size(); ++v) {
        EXPECT_NEAR(glm::length(m.normals[v]), 1.0f, 1e-5f) << v;
        EXPECT_GT(glm::dot(m.normals[v], glm::normalize(m.positions[v])), 0.97f) << v;
        differ += glm::dot(m.normals[v], computed[v]) < 0.9999f;
    }
    EXPECT_GT(differ, m.positions.size() / 4);
    EXPECT_TRUE(s.meshes[2].mesh->normals.empty());  // flat only: no normals to carry
}

TEST(Scene, SubdivideOverTheBudgetIsRefusedBeforeAnyWork) {
    Scene s;
    auto sphere = std::make_shared<const TriangleMesh>(make_icosphere(2));  // 320 triangles
    // 2500 instances: 800,000 triangles, 204.8M at 4 levels, over the 200M of any machine.
    for (int i = 0; i < 2500; ++i) s.meshes.push_back(MeshInstance{.mesh = sphere});
    const std::string msg = test::error_of_call([&] { subdivide_scene(s, 4, "big.json"); });
    EXPECT_EQ(msg.rfind("big.json: --subdivide 4: 800000 triangles become 204800000, "
                        "more than the ",
                        0),
              0u)
        << msg;
    EXPECT_EQ(s.meshes[0].mesh.get(), sphere.get());  // nothing was subdivided
    subdivide_scene(s, 0, "big.json");                // 0: nothing to do
    EXPECT_EQ(s.meshes[0].mesh.get(), sphere.get());
}

}  // namespace
}  // namespace kdt
