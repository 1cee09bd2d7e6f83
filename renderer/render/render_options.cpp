#include "renderer/render/render_options.h"

#include <unistd.h>

#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <string_view>
#include <utility>

#include <nlohmann/json.hpp>

#include "renderer/camera/camera.h"
#include "renderer/core/error.h"
#include "renderer/core/open_file.h"
#include "renderer/io/image_io.h"
#include "renderer/render/settings.h"
#include "renderer/scene/json_parse.h"
#include "renderer/scene/json_vec.h"

namespace kdt {

namespace {

using json = nlohmann::json;
using SO = SceneOptions;
using TP = TraceParams;
using FP = FilmParams;
using SC = StopConditions;

constexpr double kMaxSeed = 18446744073709551615.0;  // 2^64 - 1 as a double (rounds to 2^64)

const Field<SO> kSceneFields[] = {
    KDT_FIELD(SO, width, "--width", "Image width in pixels (width x height at most 134217728)", 1,
              16384),
    KDT_FIELD(SO, height, "--height", "Image height in pixels (width x height at most 134217728)",
              1, 16384),
    KDT_FIELD(SO, env_rotation_degrees, "--env-rotation",
              "Extra rotation of the environment about +y, degrees", -36000.0, 36000.0),
    KDT_FIELD(SO, use_cache, "--no-cache", "Build the kd-tree without the tree cache"),
    KDT_FIELD(SO, drop_invalid, "--drop-invalid", "Drop faces with non-finite vertices"),
    KDT_FIELD(SO, subdivide, "--subdivide",
              "Split every triangle into 4^K after loading (the same surface: the dragon at 2 "
              "is a 13.9M-triangle statue)",
              0, 4),
};

const Field<TP> kTraceFields[] = {
    KDT_FIELD(TP, max_depth, "--path-depth",
              "Maximum bounces per path (0 = directly visible light only)", 0, 1024),
    KDT_FIELD(TP, russian_roulette, "--no-rr", "Switch Russian roulette off"),
    KDT_FIELD(TP, rr_min_depth, "--rr-depth", "Bounces before Russian roulette may end a path", 0,
              1024),
    KDT_FIELD(TP, light_sampling, "--light-sampling",
              "Light sampling: bsdf, nee (next-event estimation) or mis (both)", 0, 2, false,
              kLightSamplingNames),
    KDT_FIELD(TP, env_importance, "--no-env-importance",
              "Sample the environment uniformly instead of by its radiance"),
    KDT_FIELD(TP, sample_emitters, "--no-emitter-sampling",
              "Find emissive triangles by BSDF rays only"),
    KDT_FIELD(TP, diffuse_sampling, "--diffuse-sampling", "Diffuse bounces: cosine or uniform", 0,
              1, false, kDiffuseSamplingNames),
    KDT_FIELD(TP, filter, "--filter", "Pixel filter: box or tent", 0, 1, false, kPixelFilterNames),
    KDT_FIELD(TP, samples_per_pass, "--spp-per-pass",
              "Samples per active pixel and pass (0 = automatic)", 0, 1 << 20),
    KDT_FIELD(TP, seed, "--seed", "Seed of all randomness", 0.0, kMaxSeed),
    KDT_FIELD(TP, threads, "--threads", "Threads (0 = all)", 0, 1024),
    KDT_FIELD(TP, count_traversal, nullptr, "Count kd-tree nodes and triangles per ray"),
    KDT_FIELD(TP, wavefront, "--no-wavefront",
              "Trace one path at a time instead of a tile pass's paths as ray streams"),
    KDT_FIELD(TP, partition, "--no-partition-traversal",
              "Trace the first bounce's rays as ray streams instead of by partition traversal"),
};

const Field<FP> kFilmFields[] = {
    KDT_FIELD(FP, adaptive, "--adaptive", "Adaptive sampling: stop converged pixels"),
    KDT_FIELD(FP, adaptive_threshold, "--adaptive-threshold",
              "Relative error at which an adaptive pixel stops", 0.0, 1e6, true),
    KDT_FIELD(FP, adaptive_min_spp, "--adaptive-min-spp",
              "Samples before an adaptive pixel may stop", 0, 1 << 24),
    KDT_FIELD(FP, adaptive_max_spp, "--adaptive-max-spp",
              "Samples at which an adaptive pixel stops (0 = no cap)", 0, 1 << 30),
    KDT_FIELD(FP, tonemap, "--tonemap",
              "Tone curve of PNG output: clamp, reinhard, aces or filmic (EXR and PFM stay linear)",
              0, 3, false, kToneCurveNames),
    KDT_FIELD(FP, transparent, "--transparent",
              "Transparent background: the environment seen directly is left out, coverage goes "
              "to the alpha of PNG and EXR output"),
    KDT_FIELD(FP, exposure, "--exposure", "Exposure of tone-mapped output, in stops", -64.0, 64.0),
};

const Field<SC> kStopFields[] = {
    KDT_FIELD(SC, spp, "--spp",
              "Stop at N samples per pixel (adaptive: N x pixels in all; 16 when no --spp, "
              "--time or --error is given)",
              0, 1 << 30, true, {}, true),
    KDT_FIELD(SC, seconds, "--time", "Stop after S seconds of rendering", 0.0, 1e9, true, {}, true),
    KDT_FIELD(SC, error, "--error",
              "Stop when every pixel's relative error is below E (turns on adaptive sampling)", 0.0,
              1e6, true, {}, true),
    KDT_FIELD(SC, max_spp, "--max-spp", "Cap on samples per pixel", 1, 1 << 30),
};

// The scene group's strings (written when not empty) and camera parts (written when set),
// by their JSON keys; the other scene keys are read and written one by one below.
template <class T>
using SceneMember = std::pair<const char*, T SO::*>;
constexpr SceneMember<std::string> kSceneStrings[] = {{"scene_path", &SO::scene_path},
                                                      {"env_file", &SO::env_file},
                                                      {"env_mapping", &SO::env_mapping},
                                                      {"cache_dir", &SO::cache_dir},
                                                      {"tree_file", &SO::tree_file}};
constexpr SceneMember<std::optional<Vec3f>> kSceneVectors[] = {
    {"eye", &SO::eye}, {"target", &SO::target}, {"up", &SO::up}};

// A file name of the options JSON: no control characters, as in scene files. Empty is
// allowed: it means "not given" (no scene_path: the built-in scene), as options_to_json()
// writes it.
void check_file_name(const std::string& name, const std::string& where,
                     const std::string& pointer) {
    if (std::string why = file_name_problem(name); !why.empty())
        throw Error(ErrorLocation{where, pointer}, why);
}

bool is_utf8(std::string_view text) {
    for (size_t i = 0, n = 0; i < text.size(); i += n) {
        if ((n = utf8_length_at(text, i)) == 0) return false;
    }
    return true;
}

// A file name that is not valid UTF-8 as JSON text: "%" and each byte outside a well-formed
// UTF-8 sequence become %XX (two upper-case hex digits); all else is kept.
std::string escape_file_name_bytes(std::string_view name) {
    static const char kHex[] = "0123456789ABCDEF";
    std::string out;
    for (size_t i = 0, n = 0; i < name.size(); i += n) {
        n = utf8_length_at(name, i);
        if (n == 0 || name[i] == '%') {
            const auto b = static_cast<unsigned char>(name[i]);
            out += {'%', kHex[b >> 4], kHex[b & 15]};
            n = 1;
        } else {
            out.append(name, i, n);
        }
    }
    return out;
}

// The inverse of escape_file_name_bytes(); a "%" without two hex digits is an error.
std::string unescape_file_name_bytes(const std::string& text, const std::string& where,
                                     const std::string& pointer) {
    const auto hex = [](char c) {
        return c >= '0' && c <= '9'   ? c - '0'
               : c >= 'A' && c <= 'F' ? c - 'A' + 10
               : c >= 'a' && c <= 'f' ? c - 'a' + 10
                                      : -1;
    };
    std::string out;
    for (size_t i = 0; i < text.size(); ++i) {
        if (text[i] != '%') {
            out += text[i];
            continue;
        }
        if (text.size() - i < 3 || hex(text[i + 1]) < 0 || hex(text[i + 2]) < 0) {
            throw Error(ErrorLocation{where, pointer},
                        "'%' at byte " + std::to_string(i) + " is not followed by two hex digits");
        }
        out += char(hex(text[i + 1]) * 16 + hex(text[i + 2]));
        i += 2;
    }
    return out;
}

// The suffix of the key that holds a file name escape_file_name_bytes() escaped.
constexpr std::string_view kBytesSuffix = "_bytes";

// The member named key, or nullptr.
template <class T, size_t N>
T SO::*find_member(const SceneMember<T> (&table)[N], const std::string& key) {
    for (const auto& [name, m] : table) {
        if (key == name) return m;
    }
    return nullptr;
}

template <class S>
json group_json(const S& s, std::span<const Field<S>> fields) {
    json j = json::object();
    for (const Field<S>& f : fields) {
        const FieldRef r = f.at(s);
        if (auto* b = std::get_if<bool*>(&r)) {
            j[f.name] = **b;
        } else if (std::holds_alternative<ChoiceRef>(r)) {
            j[f.name] = field_text(f, s);
        } else if (auto* u = std::get_if<uint64_t*>(&r)) {
            j[f.name] = **u;
        } else if (auto* i = std::get_if<int*>(&r)) {
            j[f.name] = **i;
        } else if (auto* x = std::get_if<float*>(&r)) {
            j[f.name] = float_for_text(**x);
        } else {
            j[f.name] = field_number(r);
        }
    }
    return j;
}

template <class S>
void group_from_json(const json& j, S& s, std::span<const Field<S>> fields,
                     const std::string& where, const std::string& group) {
    if (!j.is_object()) throw Error(ErrorLocation{where, "/" + group}, "expected an object");
    for (auto it = j.begin(); it != j.end(); ++it) {
        const std::string pointer = "/" + group + "/" + it.key();
        const Field<S>* field = nullptr;
        for (const Field<S>& f : fields) {
            if (it.key() == f.name) field = &f;
        }
        if (!field) throw Error(ErrorLocation{where, pointer}, "unknown key");
        const json& v = it.value();
        std::string text;
        if (v.is_string()) {
            text = v.get<std::string>();
        } else if (v.is_boolean()) {
            text = v.get<bool>() ? "true" : "false";
        } else if (v.is_number_unsigned()) {
            text = std::to_string(v.get<uint64_t>());
        } else if (v.is_number()) {
            text = v.dump();
        } else {
            throw Error(ErrorLocation{where, pointer}, "expected a number, bool or name");
        }
        if (field->zero_is_off && v.is_number() && v.get<double>() == 0.0) text = "";
        if (text.empty()) {
            set_field_number(field->at(s), 0.0);  // off
        } else if (std::string why = parse_field(*field, s, text); !why.empty())
            throw Error(ErrorLocation{where, pointer}, why);
    }
}

Vec3f vec_from_json(const json& j, const std::string& where, const std::string& pointer) {
    if (!j.is_array() || j.size() != 3 || !j[0].is_number() || !j[1].is_number() ||
        !j[2].is_number())
        throw Error(ErrorLocation{where, pointer}, "expected an array of 3 numbers");
    const Vec3f v(j[0].get<float>(), j[1].get<float>(), j[2].get<float>());
    if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z))
        throw Error(ErrorLocation{where, pointer}, "expected 3 finite numbers (a float overflows)");
    return v;
}

CameraDesc camera_from_json(const json& x, const std::string& where, const std::string& pointer) {
    if (!x.is_object()) throw Error(ErrorLocation{where, pointer}, "expected an object");
    CameraDesc c;
    for (auto k = x.begin(); k != x.end(); ++k) {
        const std::string p = pointer + "/" + k.key();
        if (k.key() == "eye") {
            c.eye = vec_from_json(k.value(), where, p);
        } else if (k.key() == "target") {
            c.target = vec_from_json(k.value(), where, p);
        } else if (k.key() == "up") {
            c.up = vec_from_json(k.value(), where, p);
        } else if (k.key() == "vfov_degrees" && k.value().is_number()) {
            c.vfov_degrees = k.value().get<float>();
        } else {
            throw Error(ErrorLocation{where, p}, "unknown key or wrong type");
        }
    }
    return c;
}

// The checks of the scene's fields without a table entry, shared by validate() and the
// session reader (which names the JSON path): "" when valid, else why not.
std::string env_intensity_problem(float intensity) {
    return detail::check_number(intensity, 0.0, 3.0e38, false, false, true);
}
std::string env_mapping_problem(const std::string& mapping) {
    for (const char* name : kEnvMappingNames) {
        if (mapping == name) return "";
    }
    return "must be " + detail::choices_text(kEnvMappingNames) + " " + detail::got(mapping);
}
// Each side within its range can still make an image the film and the files cannot hold.
std::string image_size_problem(int width, int height) {
    const int64_t pixels = int64_t(width) * height;
    if (pixels <= kMaxCameraPixels) return "";
    return std::to_string(width) + "x" + std::to_string(height) + " is " + std::to_string(pixels) +
           " pixels, more than " + std::to_string(kMaxCameraPixels);
}

// The scene group: its strings, optionals and camera here, the tabled fields by the table.
// A file name read from a session file: relative to the session's folder, as a scene file's
// names are to the scene's. An input file (not cache_dir, which may not exist yet) must exist
// there, so that a wrong name is reported with the session and its key, not later by the
// loader as a bare name. Absolute names, as kdtrace writes them, are kept as they are.
std::string session_file_name(const std::string& name, const std::string& key,
                              const std::string& relative_to, const std::string& where,
                              const std::string& pointer) {
    if (relative_to.empty() || name.empty() || !std::filesystem::path(name).is_relative())
        return name;
    const std::string resolved =
        (std::filesystem::path(relative_to) / name).lexically_normal().string();
    std::error_code ec;
    if (key != "cache_dir" && !std::filesystem::exists(resolved, ec) && !ec) {
        throw Error(ErrorLocation{where, pointer},
                    "no such file: " + printable(resolved) +
                        " (relative names in a session are relative to its folder)");
    }
    return resolved;
}

// `session`: the text is a session file's, whose camera parts are kept in
// scene.session_camera (not rank 0's options, say, which name no file to fix).
void scene_from_json(const json& v, SceneOptions& scene, const std::string& where,
                     const std::string& relative_to, bool session) {
    if (!v.is_object()) throw Error(ErrorLocation{where, "/scene"}, "expected an object");
    json rest = json::object();
    for (auto s = v.begin(); s != v.end(); ++s) {
        const std::string& key = s.key();
        const std::string pointer = "/scene/" + key;
        const json& x = s.value();
        auto number = [&]() {
            if (!x.is_number()) throw Error(ErrorLocation{where, pointer}, "expected a number");
            return x.get<float>();
        };
        const bool bytes = key.size() > kBytesSuffix.size() && key.ends_with(kBytesSuffix);
        const std::string name = bytes ? key.substr(0, key.size() - kBytesSuffix.size()) : key;
        if (auto member = name == "env_mapping" ? nullptr : find_member(kSceneStrings, name);
            bytes && member) {
            if (!x.is_string()) throw Error(ErrorLocation{where, pointer}, "expected a string");
            if (v.contains(name))
                throw Error(ErrorLocation{where, pointer}, "given with /scene/" + name);
            const std::string file = unescape_file_name_bytes(x.get<std::string>(), where, pointer);
            check_file_name(file, where, pointer);
            scene.*member = session_file_name(file, name, relative_to, where, pointer);
        } else if (auto text = find_member(kSceneStrings, key)) {
            if (!x.is_string()) throw Error(ErrorLocation{where, pointer}, "expected a string");
            if (key == "env_mapping") {
                scene.*text = x.get<std::string>();
                if (std::string why = env_mapping_problem(scene.*text); !why.empty())
                    throw Error(ErrorLocation{where, pointer}, why);
                scene.env_mapping_from = ErrorLocation{where, pointer};
            } else {
                check_file_name(x.get<std::string>(), where, pointer);
                scene.*text =
                    session_file_name(x.get<std::string>(), key, relative_to, where, pointer);
            }
        } else if (auto part = find_member(kSceneVectors, key)) {
            scene.*part = vec_from_json(x, where, pointer);
        } else if (key == "env_intensity") {
            const float intensity = number();
            if (std::string why = env_intensity_problem(intensity); !why.empty())
                throw Error(ErrorLocation{where, pointer}, why);
            scene.env_intensity = intensity;
        } else if (key == "vfov_degrees") {
            // In range whatever camera it replaces the angle of: refused here, with the key.
            const float vfov = number();
            if (!(vfov > 0.0f && vfov < 180.0f)) {
                throw Error(ErrorLocation{where, pointer},
                            "must be in (0, 180) degrees (got " + detail::number_text(vfov) + ")");
            }
            scene.vfov_degrees = vfov;
        } else if (key == "camera") {
            scene.camera = camera_from_json(x, where, pointer);
        } else if (key == "materials") {
            if (!x.is_array()) throw Error(ErrorLocation{where, pointer}, "expected an array");
            scene.materials.clear();
            scene.materials_from = ErrorLocation{where, pointer};
            for (size_t i = 0; i < x.size(); ++i) {
                scene.materials.push_back(
                    material_from_json(x[i].dump(), where, pointer + "/" + std::to_string(i)));
            }
        } else {
            rest[key] = x;
        }
    }
    group_from_json(rest, scene, scene_fields(), where, "scene");
    if (session &&
        (v.contains("camera") || v.contains("eye") || v.contains("target") || v.contains("up"))) {
        SessionCamera& s = scene.session_camera;
        s = SessionCamera{where};
        if (v.contains("camera")) {
            s.camera = scene.camera;
            const json& c = v["camera"];
            s.camera_keys = {c.contains("eye"), c.contains("target"), c.contains("up")};
        }
        if (v.contains("eye")) s.eye = scene.eye;
        if (v.contains("target")) s.target = scene.target;
        if (v.contains("up")) s.up = scene.up;
    }
}

}  // namespace

std::span<const Field<SceneOptions>> scene_fields() { return kSceneFields; }
std::span<const Field<TraceParams>> trace_fields() { return kTraceFields; }
std::span<const Field<FilmParams>> film_fields() { return kFilmFields; }
std::span<const Field<StopConditions>> stop_fields() { return kStopFields; }

RenderOptions resolve(RenderOptions o) {
    if (o.stop.spp == 0 && o.stop.seconds == 0.0 && o.stop.error == 0.0f) o.stop.spp = kDefaultSpp;
    if (o.stop.error > 0.0f) {
        o.film.adaptive = true;
        o.film.adaptive_threshold = o.stop.error;
    }
    if (o.tree.threads == 0) o.tree.threads = o.trace.threads;
    return o;
}

static_assert(kMaxCameraPixels == 134217728, "the help of --width and --height states the limit");

void validate(const SceneOptions& s) {
    validate_fields(s, scene_fields(), "scene");
    if (std::string why = image_size_problem(s.width, s.height); !why.empty())
        throw Error("scene.width x scene.height: " + why);
    if (s.env_intensity) {
        if (std::string why = env_intensity_problem(*s.env_intensity); !why.empty())
            detail::throw_field_error("scene", "env_intensity", why);
    }
    if (!s.env_mapping.empty()) {
        if (std::string why = env_mapping_problem(s.env_mapping); !why.empty())
            detail::throw_field_error("scene", "env_mapping", why);
    }
}

void validate(const TraceParams& t) { validate_fields(t, trace_fields(), "trace"); }
void validate(const FilmParams& f) { validate_fields(f, film_fields(), "film"); }

void validate(const StopConditions& s) { validate_fields(s, stop_fields(), "stop"); }

void validate(const RenderOptions& o) {
    validate(o.scene);
    validate(o.tree);
    validate(o.trace);
    validate(o.film);
    validate(o.stop);
}

void validate_render_params(const TraceParams& t, const FilmParams& f) {
    validate(t);
    validate(f);
}

std::string camera_to_json(const Camera& c) {
    json j;
    j["eye"] = vec3_json(c.eye);
    j["target"] = vec3_json(c.eye + c.forward);
    j["up"] = vec3_json(c.up);
    j["vfov_degrees"] = float_for_text(c.vfov_degrees);
    j["width"] = c.width;
    j["height"] = c.height;
    return j.dump();
}

std::string options_to_json(const RenderOptions& o) {
    json j;
    json scene = group_json(o.scene, scene_fields());
    for (auto [name, m] : kSceneStrings) {
        const std::string& text = o.scene.*m;
        if (text.empty()) continue;
        // JSON holds UTF-8 only: another file name goes, escaped, under NAME_bytes.
        if (is_utf8(text)) {
            scene[name] = text;
        } else {
            scene[name + std::string(kBytesSuffix)] = escape_file_name_bytes(text);
        }
    }
    for (auto [name, m] : kSceneVectors) {
        if (o.scene.*m) scene[name] = vec3_json(*(o.scene.*m));
    }
    if (o.scene.env_intensity) scene["env_intensity"] = float_for_text(*o.scene.env_intensity);
    if (o.scene.camera) {
        scene["camera"] = {{"eye", vec3_json(o.scene.camera->eye)},
                           {"target", vec3_json(o.scene.camera->target)},
                           {"up", vec3_json(o.scene.camera->up)},
                           {"vfov_degrees", float_for_text(o.scene.camera->vfov_degrees)}};
    }
    if (o.scene.vfov_degrees) scene["vfov_degrees"] = float_for_text(*o.scene.vfov_degrees);
    if (!o.scene.materials.empty()) {
        json materials = json::array();
        for (const MaterialDesc& m : o.scene.materials)
            materials.push_back(json::parse(material_to_json(m)));
        scene["materials"] = materials;
    }
    j["scene"] = scene;
    j["tree"] = group_json(o.tree, kd_tree_fields());
    j["trace"] = group_json(o.trace, trace_fields());
    j["film"] = group_json(o.film, film_fields());
    j["stop"] = group_json(o.stop, stop_fields());
    // File names are escaped above; U+FFFD replaces any other bytes that are not UTF-8
    // (material names, say) rather than failing the render that stores them.
    return j.dump(-1, ' ', false, json::error_handler_t::replace);
}

namespace {

void read_options(const std::string& text, RenderOptions& o, const std::string& where,
                  const std::string& relative_to, bool session) {
    // A session's camera parts are this file's only, not an earlier session's.
    if (session) o.scene.session_camera = {};
    json j;
    try {
        j = parse_json_without_repeats(text, where, "/");
    } catch (const json::exception& e) {
        throw Error(ErrorLocation{where}, std::string("malformed JSON: ") + e.what());
    }
    if (!j.is_object()) throw Error(ErrorLocation{where}, "expected a JSON object");
    try {
        for (auto it = j.begin(); it != j.end(); ++it) {
            const std::string& group = it.key();
            const json& v = it.value();
            if (group == "tree") {
                group_from_json(v, o.tree, kd_tree_fields(), where, group);
            } else if (group == "trace") {
                group_from_json(v, o.trace, trace_fields(), where, group);
            } else if (group == "film") {
                group_from_json(v, o.film, film_fields(), where, group);
            } else if (group == "stop") {
                group_from_json(v, o.stop, stop_fields(), where, group);
            } else if (group == "scene") {
                scene_from_json(v, o.scene, where, relative_to, session);
            } else {
                throw Error(ErrorLocation{where, "/" + group}, "unknown key");
            }
        }
    } catch (const json::exception& e) {
        throw Error(ErrorLocation{where}, std::string("bad value: ") + e.what());
    }
    // Value errors found once every key is read name `where` and the JSON path too: the user
    // must know which file and key to fix. The image size is the product of two keys; the
    // ones this file gave are to blame (the others were valid before it was read).
    if (std::string why = image_size_problem(o.scene.width, o.scene.height); !why.empty()) {
        std::string pointers;
        const json* scene = j.contains("scene") ? &j["scene"] : nullptr;
        for (const char* key : {"width", "height"}) {
            if (scene && scene->contains(key))
                pointers += (pointers.empty() ? "/scene/" : ", /scene/") + std::string(key);
        }
        throw Error(ErrorLocation{where, pointers.empty() ? "/scene" : pointers}, why);
    }
    // Any other (validate() repeats the checks made per key above) with the file's name. The
    // camera's rules are make_camera's, which the render applies later; a 1x1 film leaves out
    // only the image size it checks.
    try {
        validate(o);
    } catch (const Error& e) {
        throw Error(ErrorLocation{where}, e.what());
    }
    // make_camera()'s messages start "camera: "; the JSON path says which camera.
    auto camera_error = [&](const char* pointer, const Error& e) {
        std::string m = e.what();
        if (m.starts_with("camera: ")) m.erase(0, 8);
        return Error(ErrorLocation{where, pointer}, m);
    };
    if (o.scene.camera) {
        const CameraDesc& c = *o.scene.camera;
        try {
            make_camera(c.eye, c.target, c.up, c.vfov_degrees, 1, 1);
        } catch (const Error& e) {
            throw camera_error("/scene/camera", e);
        }
    }
    // A zero "up" replaces any camera's up with none; the other parts are checked with the
    // camera they replace parts of, once the scene is known.
    if (o.scene.up && *o.scene.up == Vec3f(0.0f))
        throw Error(ErrorLocation{where, "/scene/up"}, "up vector is zero");
}

}  // namespace

void options_from_json(const std::string& text, RenderOptions& o, const std::string& where,
                       const std::string& relative_to) {
    read_options(text, o, where, relative_to, false);
}

void make_file_names_absolute(SceneOptions& scene) {
    for (std::string* name :
         {&scene.scene_path, &scene.env_file, &scene.tree_file, &scene.cache_dir})
        *name = absolute_file_name(*name);
}

namespace {

// "PNG", "OpenEXR", "PFM" or "Radiance HDR" by the file's first bytes, else nullptr (a short
// file is not an image).
const char* image_kind(const std::string& path) {
    const int fd = open_regular_file(path, "a session file");
    unsigned char head[4] = {};
    const ssize_t n = ::read(fd, head, sizeof head);
    ::close(fd);
    if (n != ssize_t(sizeof head)) return nullptr;
    static const unsigned char kPng[4] = {0x89, 'P', 'N', 'G'}, kExr[4] = {0x76, 0x2f, 0x31, 0x01};
    if (std::memcmp(head, kPng, 4) == 0) return "PNG";
    if (std::memcmp(head, kExr, 4) == 0) return "OpenEXR";
    if (head[0] == 'P' && (head[1] == 'F' || head[1] == 'f') && std::isspace(head[2])) return "PFM";
    if (std::memcmp(head, "#?RA", 4) == 0 || std::memcmp(head, "#?RG", 4) == 0)
        return "Radiance HDR";  // #?RADIANCE or #?RGBE
    return nullptr;
}

}  // namespace

void options_from_session_file(const std::string& path, RenderOptions& o) {
    // Relative file names resolve against the session's folder (the path as given, as for
    // scene files); "." when the session is in the working directory.
    const std::string folder = std::filesystem::path(path).parent_path().string();
    const std::string relative_to = folder.empty() ? "." : folder;
    if (const char* kind = image_kind(path)) {
        const std::string k = kind;
        if (k == "PFM" || k == "Radiance HDR") {
            throw Error(path + ": a " + kind +
                        " image carries no kdtrace settings; give the PNG or EXR kdtrace wrote, "
                        "or a session .json");
        }
        // The metadata alone: the pixels are never decoded.
        const ImageMetadata meta =
            kind[0] == 'P' ? read_png_metadata(path) : read_exr_metadata(path);
        const std::string* params = nullptr;
        for (const auto& [key, value] : meta) {
            if (key != "kdtrace:params") continue;
            if (params) throw Error(ErrorLocation{path, "kdtrace:params", -1}, "given twice");
            params = &value;
        }
        if (!params) {
            throw Error(path + ": no kdtrace:params text in this " + kind +
                        " image (not written by kdtrace?), so it is not a session");
        }
        return read_options(*params, o, path, relative_to, true);
    }
    const std::vector<uint8_t> text = read_regular_file(path, uint64_t(1) << 20, "a session file");
    read_options(std::string(text.begin(), text.end()), o, path, relative_to, true);
}

}  // namespace kdt
