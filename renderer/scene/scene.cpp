// Scene files (JSON) and scenes around a single model. Strict: unknown keys and wrong
// types are errors naming the file and the key's path.
#include "renderer/scene/scene.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>

#include "renderer/core/error.h"
#include "renderer/core/fields.h"
#include "renderer/core/open_file.h"
#include "renderer/io/mesh_io.h"
#include "renderer/scene/json_parse.h"
#include "renderer/scene/json_vec.h"

namespace kdt {
namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;

/// Walks one JSON object, remembering its path for messages and rejecting unknown keys.
class Reader {
public:
    Reader(const std::string& file, const json& j, std::string where)
        : file_(file), j_(j), where_(std::move(where)) {
        if (!j_.is_object()) fail("expected an object");
    }

    [[noreturn]] void fail(const std::string& msg) const {
        throw Error(ErrorLocation{file_, where_.empty() ? "scene" : where_}, msg);
    }

    void allow(std::initializer_list<const char*> keys) const {
        std::set<std::string> ok(keys.begin(), keys.end());
        for (auto it = j_.begin(); it != j_.end(); ++it) {
            if (!ok.count(it.key())) {
                std::string list;
                for (const auto& k : ok) list += (list.empty() ? "" : ", ") + k;
                throw Error(
                    ErrorLocation{file_, child_path(it.key())},
                    "unknown key \"" + excerpt(it.key()) + "\" (expected one of: " + list + ")");
            }
        }
    }

    bool has(const char* key) const { return j_.contains(key); }
    Reader object(const char* key) const { return Reader(file_, j_.at(key), child_path(key)); }
    const json& raw(const char* key) const { return j_.at(key); }
    std::string child_path(const std::string& key) const {
        return where_.empty() ? key : where_ + "/" + key;
    }
    const std::string& file() const { return file_; }
    /// The object's JSON path ("scene" for the root).
    std::string where() const { return where_.empty() ? "scene" : where_; }

    float number(const char* key, float fallback) const {
        if (!has(key)) return fallback;
        const json& v = j_.at(key);
        if (!v.is_number()) fail_key(key, "expected a number");
        double d = v.get<double>();
        if (!std::isfinite(d) || std::fabs(d) > 3.0e38) fail_key(key, "number out of range");
        return float(d);
    }
    bool boolean(const char* key, bool fallback) const {
        if (!has(key)) return fallback;
        if (!j_.at(key).is_boolean()) fail_key(key, "expected true or false");
        return j_.at(key).get<bool>();
    }
    std::string string(const char* key, const std::string& fallback) const {
        if (!has(key)) return fallback;
        if (!j_.at(key).is_string()) fail_key(key, "expected a string");
        return j_.at(key).get<std::string>();
    }
    /// A 3-vector; a single number n is accepted as (n, n, n) when allow_scalar.
    Vec3f vec3(const char* key, Vec3f fallback, bool allow_scalar = false) const {
        if (!has(key)) return fallback;
        const json& v = j_.at(key);
        if (allow_scalar && v.is_number()) return Vec3f(number(key, 0.0f));
        if (!v.is_array() || v.size() != 3) fail_key(key, "expected an array of 3 numbers");
        Vec3f r;
        for (int i = 0; i < 3; ++i) {
            if (!v[i].is_number()) fail_key(key, "expected an array of 3 numbers");
            double d = v[i].get<double>();
            if (!std::isfinite(d) || std::fabs(d) > 3.0e38) fail_key(key, "number out of range");
            r[i] = float(d);
        }
        return r;
    }
    template <size_t N>
    int choice(const char* key, const std::array<const char*, N>& names, int fallback) const {
        if (!has(key)) return fallback;
        std::string s = string(key, "");
        std::string list;
        for (size_t i = 0; i < N; ++i) {
            if (s == names[i]) return int(i);
            list += (i ? ", " : "") + std::string(names[i]);
        }
        fail_key(key, "unknown value \"" + s + "\" (expected one of: " + list + ")");
    }
    [[noreturn]] void fail_key(const char* key, const std::string& msg) const {
        throw Error(ErrorLocation{file_, child_path(key)}, msg);
    }

private:
    const std::string& file_;
    const json& j_;
    std::string where_;
};

std::string format_vec(const Vec3f& v) {
    char buf[128];
    std::snprintf(buf, sizeof(buf), "%g %g %g", double(v.x), double(v.y), double(v.z));
    return buf;
}

double max_abs(const Vec3d& v) {
    return std::max(std::fabs(v.x), std::max(std::fabs(v.y), std::fabs(v.z)));
}

std::string format_row(float a, float b, float c, float d) {
    char buf[128];
    std::snprintf(buf, sizeof(buf), "%g %g %g %g", double(a), double(b), double(c), double(d));
    return buf;
}

// A file name as the scene file gives it: not empty, no control characters.
std::string file_name(const Reader& r, const char* key) {
    const std::string name = r.string(key, "");
    if (name.empty()) r.fail_key(key, "empty file name");
    if (std::string why = file_name_problem(name); !why.empty()) r.fail_key(key, why);
    return name;
}

// The file must be a regular file kdtrace can open (checked without blocking on a FIFO or
// reading a device), reported as the scene file and key; the reader's own message follows.
void check_referenced_file(const Reader& r, const char* key, const std::string& path,
                           const char* what) {
    try {
        ::close(open_regular_file(path, what));
    } catch (const Error& e) {
        r.fail_key(key, e.what());
    }
}

Mat4f read_transform(const Reader& r) {
    r.allow({"translate", "rotate", "scale", "matrix"});
    if (r.has("matrix")) {
        if (r.has("translate") || r.has("rotate") || r.has("scale"))
            r.fail("\"matrix\" cannot be combined with translate/rotate/scale");
        const json& m = r.raw("matrix");
        if (!m.is_array() || m.size() != 16)
            r.fail_key("matrix", "expected 16 numbers (row-major)");
        Mat4f out(1.0f);
        for (int row = 0; row < 4; ++row) {
            for (int col = 0; col < 4; ++col) {
                const json& v = m[size_t(row * 4 + col)];
                if (!v.is_number() || !std::isfinite(v.get<double>()) ||
                    std::fabs(v.get<double>()) > 3.0e38)
                    r.fail_key("matrix", "expected 16 finite numbers (row-major)");
                out[col][row] = v.get<float>();
            }
        }
        // Points are transformed as (x, y, z, 1) and the result used without a division:
        // a projective bottom row would be silently ignored, so it is refused.
        if (out[0][3] != 0.0f || out[1][3] != 0.0f || out[2][3] != 0.0f || out[3][3] != 1.0f) {
            r.fail_key("matrix", "the bottom row must be 0 0 0 1 (an affine transform); got " +
                                     format_row(out[0][3], out[1][3], out[2][3], out[3][3]));
        }
        // Singular when its columns are (nearly) dependent, whatever their lengths: the
        // determinant relative to the product of the column lengths, in double, so a uniform
        // scale of 1e-20 is as good as one of 1.
        const glm::dmat3 a(Mat3f{out});
        const double lengths = glm::length(a[0]) * glm::length(a[1]) * glm::length(a[2]);
        if (!(std::fabs(glm::determinant(a)) > 1e-6 * lengths))
            r.fail_key("matrix", "the matrix is singular");
        return out;
    }
    Vec3f t = r.vec3("translate", Vec3f(0.0f));
    Vec3f rot = r.vec3("rotate", Vec3f(0.0f));  // degrees about x, then y, then z
    Vec3f s = r.vec3("scale", Vec3f(1.0f), true);
    if (s.x == 0.0f || s.y == 0.0f || s.z == 0.0f) r.fail_key("scale", "scale must be non-zero");
    Mat4f m = glm::translate(Mat4f(1.0f), t);
    m = glm::rotate(m, glm::radians(rot.z), Vec3f(0, 0, 1));
    m = glm::rotate(m, glm::radians(rot.y), Vec3f(0, 1, 0));
    m = glm::rotate(m, glm::radians(rot.x), Vec3f(1, 0, 0));
    return glm::scale(m, s);
}

// One warning line ("warning: ..."), through options.warn.
void say_warning(const SceneLoadOptions& options, const std::string& line) {
    if (options.warn) {
        options.warn(line);
    } else {
        std::fprintf(stderr, "kdtrace: %s\n", line.c_str());
    }
}

// A warning about the key `key` of `r` (its object when empty), through options.warn.
void warn(const SceneLoadOptions& options, const Reader& r, const char* key,
          const std::string& message) {
    say_warning(options, "warning: " + printable(r.file()) + ": " +
                             excerpt(*key ? r.child_path(key) : r.where(), 240) + ": " + message);
}

}  // namespace

TriangleMesh load_model(const std::string& file, const SceneLoadOptions& options,
                        MeshLoadInfo* load_info) {
    MeshLoadOptions mo;
    mo.drop_invalid = options.drop_invalid;
    MeshLoadInfo local;
    MeshLoadInfo& info = load_info ? *load_info : local;
    TriangleMesh mesh = load_mesh(file, mo, &info);
    const std::string name = printable(file);
    for (const std::string& w : info.warnings) say_warning(options, "warning: " + w);
    if (info.dropped_faces > 0) {
        say_warning(options, "warning: " + name + ": --drop-invalid dropped " +
                                 std::to_string(info.dropped_faces) +
                                 (info.dropped_faces == 1 ? " face" : " faces") +
                                 " (non-finite vertices, or fewer than 3 indices)");
    }
    if (mesh.triangle_count() == 0) {
        say_warning(options, "warning: " + name +
                                 (info.dropped_faces > 0 ? ": no faces left"
                                                         : ": no faces (a point cloud?)") +
                                 ": the model renders nothing");
    }
    return mesh;
}

namespace {

MaterialDesc read_material(const Reader& r) {
    r.allow({"type", "albedo", "ior", "emission", "roughness"});
    MaterialDesc m;
    m.type = MaterialType(r.choice("type", kMaterialTypeNames, int(m.type)));
    m.albedo = r.vec3("albedo", m.albedo, true);
    m.ior = r.number("ior", m.ior);
    m.emission = r.vec3("emission", m.emission, true);
    m.roughness = r.number("roughness", m.roughness);
    // The ranges the viewer's edits check too (scene.h).
    if (!kAlbedoRange.contains(m.albedo))
        r.fail_key("albedo", "albedo must lie in " + kAlbedoRange.text());
    if (!kIorRange.contains(m.ior)) r.fail_key("ior", "ior must be positive");
    if (!kEmissionRange.contains(m.emission))
        r.fail_key("emission", "emission must be non-negative");
    // Only the emissive type emits; elsewhere a non-zero emission would be dropped unseen.
    // Zero is accepted on any type: the scene and session writers of earlier versions wrote it.
    if (m.type != MaterialType::emissive && m.emission != Vec3f(0.0f)) {
        r.fail_key("emission", std::string("a ") + kMaterialTypeNames[size_t(m.type)] +
                                   " material does not emit" +
                                   (r.has("type") ? "" : " (type defaults to diffuse)") +
                                   "; emission needs type emissive");
    }
    if (!kRoughnessRange.contains(m.roughness))
        r.fail_key("roughness", "roughness must lie in " + kRoughnessRange.text());
    return m;
}

// "diffuse, mirror and conductor use it": the types that use `field`.
std::string users_of(MaterialField field) {
    std::vector<std::string> names;
    for (size_t t = 0; t < kMaterialTypeNames.size(); ++t)
        if (material_uses(MaterialType(t), field)) names.push_back(kMaterialTypeNames[t]);
    std::string text;
    for (size_t i = 0; i < names.size(); ++i)
        text += (i == 0 ? "" : i + 1 == names.size() ? " and " : ", ") + names[i];
    return text + (names.size() > 1 ? " use it" : " uses it");
}

// One warning per field the material's type ignores (material_uses()): a user who typed it
// expects it to matter. A zero emission is what a type that does not emit emits, and what
// earlier writers wrote for every material: no warning (a non-zero one is an error).
void warn_ignored_fields(const SceneLoadOptions& options, const Reader& r, const MaterialDesc& m) {
    const std::string type = kMaterialTypeNames[size_t(m.type)];
    for (size_t f = 0; f < kMaterialFieldNames.size(); ++f) {
        const MaterialField field = MaterialField(f);
        const char* key = kMaterialFieldNames[f];
        if (!r.has(key) || material_uses(m.type, field)) continue;
        if (field == MaterialField::emission && m.emission == Vec3f(0.0f)) continue;
        warn(options, r, key,
             "'" + std::string(key) + "' is ignored by " +
                 (m.type == MaterialType::emissive ? "an " : "a ") + type + " material" +
                 (r.has("type") ? "" : " (type defaults to diffuse)") + "; " + users_of(field));
    }
}

// Only the fields the material's type uses (material_uses()): the viewer keeps the others
// when the type changes, and the reader would warn about them.
json material_json(const MaterialDesc& m) {
    json j = {{"type", kMaterialTypeNames[size_t(m.type)]}};
    if (material_uses(m.type, MaterialField::albedo)) j["albedo"] = vec3_json(m.albedo);
    if (material_uses(m.type, MaterialField::ior)) j["ior"] = float_for_text(m.ior);
    if (material_uses(m.type, MaterialField::emission)) j["emission"] = vec3_json(m.emission);
    if (material_uses(m.type, MaterialField::roughness))
        j["roughness"] = float_for_text(m.roughness);
    return j;
}

CameraDesc read_camera(const Reader& r) {
    // vfov_degrees as in views files and the docs; "vfov" is read for files written before.
    r.allow({"eye", "target", "up", "vfov_degrees", "vfov"});
    CameraDesc c;
    c.eye = r.vec3("eye", c.eye);
    c.target = r.vec3("target", c.target);
    c.up = r.vec3("up", c.up);
    if (r.has("vfov") && r.has("vfov_degrees")) r.fail("give vfov_degrees or vfov, not both");
    const char* vfov = r.has("vfov") ? "vfov" : "vfov_degrees";
    c.vfov_degrees = r.number(vfov, c.vfov_degrees);
    if (!(c.vfov_degrees > 0.0f && c.vfov_degrees < 180.0f))
        r.fail_key(vfov, "vertical field of view must lie in (0, 180) degrees");
    // In double, on unit vectors: in float the difference of two coordinates near 3e38
    // overflows, and products of large components overflow to inf or NaN, which read as
    // "parallel" before.
    const Vec3d fwd = Vec3d(c.target) - Vec3d(c.eye);
    if (fwd == Vec3d(0.0)) r.fail("eye and target coincide");
    if (!is_finite(Vec3f(fwd))) {
        r.fail("eye and target are too far apart: their difference overflows float (eye " +
               format_vec(c.eye) + ", target " + format_vec(c.target) + ")");
    }
    if (c.up == Vec3f(0.0f)) r.fail_key("up", "up vector is zero");
    auto unit = [](const Vec3d& v) { return v / glm::length(v / max_abs(v)) / max_abs(v); };
    if (!(glm::length(glm::cross(unit(fwd), unit(Vec3d(c.up)))) > 1e-6))
        r.fail("up is parallel to the view direction");
    return c;
}

EnvironmentDesc read_environment(const Reader& r, const fs::path& base,
                                 const SceneLoadOptions& options) {
    // rotation_degrees as in the docs; "rotation" is read for files written before.
    r.allow({"color", "file", "mapping", "rotation_degrees", "rotation", "intensity"});
    // A constant colour or a map, never both (the map would win unseen); mapping and rotation
    // orient a map, so on a constant colour they are mistakes, as --env-mapping is without one.
    if (r.has("color") && r.has("file")) r.fail("give color or file, not both");
    if (!r.has("file")) {
        for (const char* key : {"mapping", "rotation_degrees", "rotation"}) {
            if (r.has(key)) {
                r.fail_key(key, std::string(key) +
                                    " orients an environment map, and this environment has no "
                                    "file; give file or drop " +
                                    key);
            }
        }
    }
    EnvironmentDesc e;
    e.color = r.vec3("color", e.color, true);
    if (glm::any(glm::lessThan(e.color, Vec3f(0.0f))))
        r.fail_key("color", "colour must be non-negative");
    if (r.has("file")) {
        fs::path f = file_name(r, "file");
        e.file = (f.is_relative() ? base / f : f).lexically_normal().string();
        if (options.check_files) check_referenced_file(r, "file", e.file, "an environment map");
    }
    e.mapping = EnvMapping(r.choice("mapping", kEnvMappingNames, int(e.mapping)));
    if (r.has("rotation") && r.has("rotation_degrees"))
        r.fail("give rotation_degrees or rotation, not both");
    e.rotation_degrees =
        r.number(r.has("rotation") ? "rotation" : "rotation_degrees", e.rotation_degrees);
    e.intensity = r.number("intensity", e.intensity);
    if (!(e.intensity >= 0.0f && std::isfinite(e.intensity)))
        r.fail_key("intensity", "intensity must be finite and non-negative");
    return e;
}

std::shared_ptr<const TriangleMesh> builtin_mesh(const std::string& name,
                                                 const SceneMeshSource& source) {
    const bool known = name == "displaced_sphere" || name == "icosphere" || name == "ground_plane";
    if (known && source) return source("builtin:" + name);
    if (name == "displaced_sphere")
        return std::make_shared<const TriangleMesh>(make_displaced_sphere(7));
    if (name == "icosphere") return std::make_shared<const TriangleMesh>(make_icosphere(5));
    if (name == "ground_plane")
        return std::make_shared<const TriangleMesh>(make_ground_plane(20.0f, 0.0f));
    return nullptr;
}

// Physical memory available now (MemAvailable), 0 when unknown.
uint64_t available_memory_bytes() {
    std::FILE* f = std::fopen("/proc/meminfo", "r");
    if (!f) return 0;
    char line[256];
    uint64_t kb = 0;
    while (std::fgets(line, sizeof(line), f)) {
        unsigned long long v = 0;
        if (std::sscanf(line, "MemAvailable: %llu kB", &v) == 1) {
            kb = v;
            break;
        }
    }
    std::fclose(f);
    return kb * 1024;
}

// Address space left under RLIMIT_AS (the limit less the process's mapped size), or
// UINT64_MAX when there is no limit; 0 when the mapped size cannot be read.
uint64_t address_space_headroom_bytes() {
    rlimit limit{};
    if (getrlimit(RLIMIT_AS, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) return UINT64_MAX;
    std::FILE* f = std::fopen("/proc/self/statm", "r");
    if (!f) return 0;
    unsigned long long pages = 0;
    const bool ok = std::fscanf(f, "%llu", &pages) == 1;
    std::fclose(f);
    if (!ok) return 0;
    const uint64_t mapped = pages * uint64_t(sysconf(_SC_PAGESIZE));
    return uint64_t(limit.rlim_cur) > mapped ? uint64_t(limit.rlim_cur) - mapped : 0;
}

std::string describe_budget(const SceneLoadOptions& options) {
    const uint64_t memory = allocatable_memory_bytes();
    return "at most " + std::to_string(options.max_triangles) + " triangles, and about " +
           std::to_string(kRenderBytesPerTriangle) + " bytes each must fit the " +
           std::to_string(memory >> 20) + " MiB of memory available";
}

std::string read_text_file(const std::string& path) {
    const std::vector<uint8_t> bytes = read_regular_file(path, uint64_t(64) << 20, "a scene file");
    return std::string(bytes.begin(), bytes.end());
}

}  // namespace

std::string MaterialRange::text() const {
    return detail::range_text(double(lo), double(hi), open_low, false);
}

Scene load_scene(const std::string& path, const SceneLoadOptions& options) {
    return load_scene_text(read_text_file(path), path, options);
}

Scene load_scene_text(const std::string& text, const std::string& path,
                      const SceneLoadOptions& options) {
    json root;
    try {
        root = parse_json_without_repeats(text, path, "");
    } catch (const json::parse_error& e) {
        // nlohmann's message already names the line and column.
        ErrorLocation where{path};
        where.offset = int64_t(e.byte);
        throw Error(where, std::string("invalid JSON: ") + e.what());
    } catch (const json::exception& e) {
        // The parser's other errors, e.g. out_of_range for a number beyond double (1e400).
        throw Error(ErrorLocation{path}, std::string("invalid JSON: ") + e.what());
    }
    Reader r(path, root, "");
    r.allow({"name", "meshes", "camera", "environment"});
    const fs::path base = fs::path(path).parent_path();

    Scene scene;
    scene.name = r.string("name", fs::path(path).stem().string());
    if (r.has("environment"))
        scene.environment = read_environment(r.object("environment"), base, options);

    std::map<std::string, std::shared_ptr<const TriangleMesh>> loaded;
    // Instances share their meshes here, but a render flattens them into one mesh and tree:
    // a few bytes of JSON can ask for any number of copies, so the total is bounded before
    // anything is allocated for it, and checked as it grows, so that a file of a million
    // instances is refused at the first one over the budget, not after reading them all.
    const uint64_t budget = scene_triangle_budget(options.max_triangles);
    uint64_t instanced_triangles = 0;
    Bounds3f world;
    if (!r.has("meshes") || !r.raw("meshes").is_array() || r.raw("meshes").empty())
        r.fail_key("meshes", "expected a non-empty array of meshes");
    const json& meshes = r.raw("meshes");
    for (size_t i = 0; i < meshes.size(); ++i) {
        Reader m(path, meshes[i], "meshes/" + std::to_string(i));
        m.allow({"file", "transform", "material", "smooth"});
        MeshInstance inst;
        if (!m.has("file")) m.fail("missing \"file\"");
        std::string file = file_name(m, "file");
        if (file.rfind("builtin:", 0) == 0) {
            inst.file = file;
            // Generated once per scene and shared by every instance, like a mesh file.
            auto& slot = loaded[file];
            if (!slot) slot = builtin_mesh(file.substr(8), options.mesh_source);
            inst.mesh = slot;
            if (!inst.mesh)
                m.fail_key("file", "unknown builtin mesh \"" + file +
                                       "\" (expected builtin:displaced_sphere, builtin:icosphere "
                                       "or builtin:ground_plane)");
        } else {
            fs::path f = file;
            inst.file = (f.is_relative() ? base / f : f).lexically_normal().string();
            auto& slot = loaded[inst.file];
            if (!slot) {
                try {
                    slot =
                        options.mesh_source
                            ? options.mesh_source(inst.file)
                            : std::make_shared<const TriangleMesh>(load_model(inst.file, options));
                    if (!slot) throw Error(ErrorLocation{inst.file}, "no mesh");
                } catch (const Error& e) {
                    // Name the scene file and the key too, then the mesh file's own message.
                    throw Error(ErrorLocation{path, "meshes/" + std::to_string(i) + "/file"},
                                e.what());
                }
            }
            inst.mesh = slot;
        }
        if (m.has("transform")) inst.world_from_object = read_transform(m.object("transform"));
        if (m.has("material")) {
            const Reader mr = m.object("material");
            inst.material = read_material(mr);
            warn_ignored_fields(options, mr, inst.material);
            if (inst.material.type == MaterialType::emissive &&
                inst.material.emission == Vec3f(0.0f)) {
                warn(options, mr, mr.has("emission") ? "emission" : "",
                     std::string(mr.has("emission") ? "emission 0 0 0 on type emissive"
                                                    : "type emissive without \"emission\"") +
                         ": it emits no light, and the mesh (" + printable(file) +
                         ") renders black");
            }
        }
        inst.smooth = m.boolean("smooth", inst.smooth);
        Bounds3f b = inst.mesh->bounds();
        if (!b.empty()) {
            for (int c = 0; c < 8; ++c) {
                Vec3f p((c & 1) ? b.upper.x : b.lower.x, (c & 2) ? b.upper.y : b.lower.y,
                        (c & 4) ? b.upper.z : b.lower.z);
                world.extend(Vec3f(inst.world_from_object * Vec4f(p, 1.0f)));
            }
        }
        instanced_triangles += inst.mesh->triangle_count();
        scene.meshes.push_back(std::move(inst));
        if (instanced_triangles > budget) {
            const std::string count = std::to_string(scene.meshes.size());
            r.fail_key("meshes",
                       (i + 1 == meshes.size()
                            ? count
                            : "the first " + count + " of " + std::to_string(meshes.size())) +
                           " instances make " + std::to_string(instanced_triangles) +
                           " triangles to render, over the budget of " + std::to_string(budget) +
                           " (" + describe_budget(options) + ")");
        }
    }
    if (r.has("camera")) {
        scene.camera = read_camera(r.object("camera"));
    } else {
        try {
            scene.camera = frame_bounds(world);
        } catch (const Error& e) {
            r.fail_key("camera", std::string(e.what()) + "; give the scene a camera");
        }
    }
    return scene;
}

CameraDesc frame_bounds(const Bounds3f& bounds, float vfov_degrees) {
    CameraDesc c;
    c.vfov_degrees = vfov_degrees;
    if (bounds.empty()) return c;
    Vec3f center = bounds.center();
    // Scaled by the largest extent, so that the squares cannot overflow for huge scenes.
    const Vec3f ext = 0.5f * bounds.upper - 0.5f * bounds.lower;
    const float m = std::max(ext.x, std::max(ext.y, ext.z));
    const float half_diagonal = m > 0.0f ? m * glm::length(ext / m) : 0.0f;
    const float radius = std::max(half_diagonal, 1e-6f);
    float dist = radius / std::sin(glm::radians(0.5f * vfov_degrees)) * 1.05f;
    Vec3f dir = glm::normalize(Vec3f(0.35f, 0.3f, 1.0f));
    c.eye = center + dist * dir;
    c.target = center;
    c.up = Vec3f(0.0f, 1.0f, 0.0f);
    const bool finite = is_finite(c.eye) && is_finite(c.target);
    if (finite && glm::length(c.eye - c.target) > 0.0f) return c;
    if (!finite)
        throw Error("cannot frame the scene automatically: its bounds (extent " +
                    std::to_string(2.0f * radius) + ") are beyond float range");
    // A small model far from the origin: the camera's offset is below float's spacing there
    // (a model of size 1 at 1e20, whose spacing is about 1e13).
    char text[200];
    std::snprintf(text, sizeof(text),
                  "cannot frame the scene automatically: its extent %g is below float's "
                  "resolution at its centre (%g, %g, %g), too far from the origin",
                  double(2.0f * half_diagonal), double(center.x), double(center.y),
                  double(center.z));
    throw Error(text);
}

Scene scene_from_model(const std::string& path, const SceneLoadOptions& options) {
    Scene scene;
    scene.name = fs::path(path).filename().string();
    MeshInstance inst;
    inst.file = path;
    inst.mesh = std::make_shared<const TriangleMesh>(load_model(path, options));
    inst.material.albedo = Vec3f(0.8f);
    try {
        scene.camera = frame_bounds(inst.mesh->bounds());
    } catch (const Error& e) {
        // --eye and --target replace the camera only once the scene is made.
        throw Error(ErrorLocation{path},
                    std::string(e.what()) + "; render it from a scene file that gives a camera");
    }
    scene.meshes.push_back(std::move(inst));
    scene.environment.color = Vec3f(1.0f);
    return scene;
}

Scene load_scene_or_model(const std::string& path, const SceneLoadOptions& options) {
    std::string ext = fs::path(path).extension().string();
    for (char& ch : ext) ch = char(std::tolower(static_cast<unsigned char>(ch)));
    if (ext == ".json") return load_scene(path, options);
    return scene_from_model(path, options);
}

uint64_t scene_triangle_budget(uint64_t max_triangles, uint64_t bytes_per_triangle) {
    const uint64_t memory = allocatable_memory_bytes();
    if (memory == 0) return max_triangles;
    return std::min<uint64_t>(max_triangles, memory / std::max<uint64_t>(bytes_per_triangle, 1));
}

uint64_t allocatable_memory_bytes() {
    const uint64_t physical = available_memory_bytes();
    const uint64_t headroom = address_space_headroom_bytes();
    if (headroom == UINT64_MAX) return physical;
    return physical == 0 ? headroom : std::min(physical, headroom);
}

uint64_t instanced_triangle_count(const Scene& scene) {
    uint64_t n = 0;
    for (const MeshInstance& m : scene.meshes) n += m.mesh ? m.mesh->triangle_count() : 0;
    return n;
}

namespace {

// subdivide_mesh() with running out of memory an Error naming the model and the flag.
TriangleMesh subdivided(const std::string& model, const TriangleMesh& mesh, int levels) {
    try {
        return subdivide_mesh(mesh, levels);
    } catch (const std::bad_alloc&) {
        throw Error((model.empty() ? "" : model + ": ") + "--subdivide " + std::to_string(levels) +
                    ": out of memory making " +
                    std::to_string(subdivided_triangle_count(mesh.triangle_count(), levels)) +
                    " triangles");
    }
}

}  // namespace

void check_subdivide(uint64_t triangles, int levels, const SubdivideMemory& memory,
                     const std::string& model) {
    const uint64_t result = subdivided_triangle_count(triangles, levels);
    const uint64_t budget = scene_triangle_budget(memory.max_triangles, memory.bytes);
    if (result <= budget) return;
    throw Error((model.empty() ? "" : model + ": ") + "--subdivide " + std::to_string(levels) +
                ": " + std::to_string(triangles) + " triangles become " + std::to_string(result) +
                ", more than the " + std::to_string(budget) +
                " that fit the kd-tree and the memory available (about " +
                std::to_string(memory.bytes) + " bytes each" +
                (memory.why.empty() ? "" : ", with " + memory.why) + ")");
}

void subdivide_model(const std::string& model, TriangleMesh& mesh, int levels,
                     const SubdivideMemory& memory) {
    check_subdivide(mesh.triangle_count(), levels, memory);
    mesh = subdivided(model, mesh, levels);
}

void subdivide_scene(Scene& scene, int levels, const std::string& what) {
    if (levels <= 0) return;
    SubdivideMemory render;  // the scene loader's limit too: a render holds the result
    render.max_triangles = std::min(render.max_triangles, kDefaultMaxSceneTriangles);
    check_subdivide(instanced_triangle_count(scene), levels, render, what);
    std::set<const TriangleMesh*> smooth_meshes;  // used by at least one smooth instance
    for (const MeshInstance& inst : scene.meshes)
        if (inst.smooth) smooth_meshes.insert(inst.mesh.get());
    std::map<const TriangleMesh*, std::shared_ptr<const TriangleMesh>> done;
    for (MeshInstance& inst : scene.meshes) {
        if (!inst.mesh) continue;
        auto& slot = done[inst.mesh.get()];
        if (!slot) {
            TriangleMesh m = *inst.mesh;
            const bool smooth = smooth_meshes.count(inst.mesh.get()) > 0;
            // What a render does not read is not subdivided (merge_instances()).
            m.colors.clear();
            if (m.normals.size() != m.positions.size() || !smooth) m.normals.clear();
            if (smooth && m.normals.empty()) m.normals = compute_vertex_normals(m);
            slot = std::make_shared<const TriangleMesh>(subdivided(what, m, levels));
        }
        inst.mesh = slot;
    }
}

std::string subdivided_model_key(const std::string& model, int levels) {
    if (model.empty() || levels <= 0) return model;
    return model + ".sub" + std::to_string(levels);
}

std::vector<std::string> scene_input_files(const Scene& scene) {
    std::vector<std::string> files;
    for (const MeshInstance& m : scene.meshes)
        if (!m.file.empty() && m.file.rfind("builtin:", 0) != 0) files.push_back(m.file);
    if (!scene.environment.file.empty()) files.push_back(scene.environment.file);
    return files;
}

std::string material_to_json(const MaterialDesc& material) {
    return material_json(material).dump();
}

MaterialDesc material_from_json(const std::string& json_text, const std::string& file,
                                const std::string& where) {
    json j;
    try {
        j = json::parse(json_text);
    } catch (const json::exception& e) {
        throw Error(ErrorLocation{file, where}, std::string("malformed JSON: ") + e.what());
    }
    return read_material(Reader(file, j, where));
}

std::string scene_to_json(const Scene& scene) {
    json root;
    root["name"] = scene.name;
    const auto v3 = vec3_json;
    root["camera"] = {{"eye", v3(scene.camera.eye)},
                      {"target", v3(scene.camera.target)},
                      {"up", v3(scene.camera.up)},
                      {"vfov_degrees", float_for_text(scene.camera.vfov_degrees)}};
    json env;
    if (scene.environment.file.empty()) {
        env["color"] = v3(scene.environment.color);
    } else {
        env["file"] = scene.environment.file;
        env["mapping"] = kEnvMappingNames[size_t(scene.environment.mapping)];
        env["rotation_degrees"] = float_for_text(scene.environment.rotation_degrees);
    }
    env["intensity"] = float_for_text(scene.environment.intensity);
    root["environment"] = env;
    json meshes = json::array();
    for (const MeshInstance& m : scene.meshes) {
        json jm;
        jm["file"] = m.file;
        json mat = json::array();
        for (int row = 0; row < 4; ++row)
            for (int col = 0; col < 4; ++col)
                mat.push_back(float_for_text(m.world_from_object[col][row]));
        jm["transform"] = {{"matrix", mat}};
        jm["material"] = material_json(m.material);
        jm["smooth"] = m.smooth;
        meshes.push_back(jm);
    }
    root["meshes"] = meshes;
    // A file name that is not valid UTF-8 gets U+FFFD for its bad bytes (as options_to_json()).
    return root.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

}  // namespace kdt
