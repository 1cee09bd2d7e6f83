#include "renderer/scene/views.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <set>

#include <nlohmann/json.hpp>

#include "renderer/core/error.h"
#include "renderer/core/open_file.h"
#include "renderer/scene/json_parse.h"

namespace kdt {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

[[noreturn]] void bad(const std::string& path, const std::string& pointer, const std::string& msg) {
    throw Error(ErrorLocation{path, pointer}, msg);
}

void check_keys(const std::string& path, const std::string& pointer, const json& obj,
                const std::set<std::string>& allowed) {
    if (!obj.is_object()) bad(path, pointer.empty() ? "/" : pointer, "expected an object");
    for (const auto& [key, value] : obj.items()) {
        (void)value;
        if (!allowed.count(key)) bad(path, pointer + "/" + key, "unknown key");
    }
}

const json& need(const std::string& path, const std::string& pointer, const json& obj,
                 const char* key) {
    auto it = obj.find(key);
    if (it == obj.end()) bad(path, pointer + "/" + key, "missing");
    return *it;
}

double number(const std::string& path, const std::string& pointer, const json& v) {
    if (!v.is_number()) bad(path, pointer, "expected a number");
    double d = v.get<double>();
    if (!std::isfinite(d)) bad(path, pointer, "expected a finite number");
    return d;
}

int positive_int(const std::string& path, const std::string& pointer, const json& v, int max) {
    if (!v.is_number_integer()) bad(path, pointer, "expected an integer");
    int64_t i = v.get<int64_t>();
    if (i < 1 || i > max) bad(path, pointer, "must be in [1, " + std::to_string(max) + "]");
    return int(i);
}

Vec3f vec3(const std::string& path, const std::string& pointer, const json& v) {
    if (!v.is_array() || v.size() != 3) bad(path, pointer, "expected an array of 3 numbers");
    return Vec3f(float(number(path, pointer + "/0", v[0])),
                 float(number(path, pointer + "/1", v[1])),
                 float(number(path, pointer + "/2", v[2])));
}

}  // namespace

ViewSet load_views(const std::string& path) {
    const std::vector<uint8_t> text = read_regular_file(path, uint64_t(16) << 20, "a views file");
    json doc;
    try {
        doc = parse_json_without_repeats(
            std::string_view(reinterpret_cast<const char*>(text.data()), text.size()), path, "/");
    } catch (const json::parse_error& e) {
        throw Error(ErrorLocation{path, "", -1, -1, int64_t(e.byte)}, "invalid JSON");
    } catch (const json::exception& e) {
        // out_of_range for a number beyond double (1e400), and any other parser error.
        throw Error(ErrorLocation{path}, std::string("invalid JSON: ") + e.what());
    }
    check_keys(path, "", doc,
               {"description", "model", "width", "height", "samples_per_pixel", "seed", "views"});
    ViewSet set;
    if (doc.contains("model")) {
        if (!doc["model"].is_string()) bad(path, "/model", "expected a string");
        set.model = doc["model"].get<std::string>();
    }
    if (doc.contains("width")) set.width = positive_int(path, "/width", doc["width"], 16384);
    if (doc.contains("height")) set.height = positive_int(path, "/height", doc["height"], 16384);
    if (doc.contains("samples_per_pixel")) {
        set.samples_per_pixel =
            positive_int(path, "/samples_per_pixel", doc["samples_per_pixel"], 4096);
    }
    if (doc.contains("seed")) {
        if (!doc["seed"].is_number_unsigned()) bad(path, "/seed", "expected an unsigned integer");
        set.seed = doc["seed"].get<uint64_t>();
    }
    const json& views = need(path, "", doc, "views");
    if (!views.is_array() || views.empty()) bad(path, "/views", "expected a non-empty array");
    // --view NAME picks by name, so a name given twice would leave one view unreachable.
    std::map<std::string, size_t> first_with_name;
    for (size_t i = 0; i < views.size(); ++i) {
        const std::string ptr = "/views/" + std::to_string(i);
        const json& v = views[i];
        check_keys(path, ptr, v, {"name", "label", "eye", "target", "up", "vfov_degrees"});
        View view;
        const json& name = need(path, ptr, v, "name");
        if (!name.is_string() || name.get<std::string>().empty()) {
            bad(path, ptr + "/name", "expected a non-empty string");
        }
        view.name = name.get<std::string>();
        const auto [seen, fresh] = first_with_name.emplace(view.name, i);
        if (!fresh) {
            bad(path, ptr + "/name",
                "view name \"" + excerpt(view.name) + "\" repeated (also /views/" +
                    std::to_string(seen->second) + "/name)");
        }
        if (v.contains("label")) {
            if (!v["label"].is_string()) bad(path, ptr + "/label", "expected a string");
            view.label = v["label"].get<std::string>();
        }
        view.camera.eye = vec3(path, ptr + "/eye", need(path, ptr, v, "eye"));
        view.camera.target = vec3(path, ptr + "/target", need(path, ptr, v, "target"));
        if (v.contains("up")) view.camera.up = vec3(path, ptr + "/up", v["up"]);
        view.camera.vfov_degrees =
            float(number(path, ptr + "/vfov_degrees", need(path, ptr, v, "vfov_degrees")));
        if (!(view.camera.vfov_degrees > 0.0f && view.camera.vfov_degrees < 180.0f)) {
            bad(path, ptr + "/vfov_degrees", "must be in (0, 180)");
        }
        const Vec3f forward = view.camera.target - view.camera.eye;
        if (!(glm::length(forward) > 0.0f) ||
            !(glm::length(glm::cross(forward, view.camera.up)) > 0.0f)) {
            bad(path, ptr, "eye, target and up must span a camera frame");
        }
        set.views.push_back(std::move(view));
    }
    return set;
}

std::string views_file_path(const std::string& views_path) {
    return views_path.empty() ? find_asset("views/dragon.json") : views_path;
}

std::string view_model_warning(const std::string& views_path, const ViewSet& set,
                               const std::string& label, const std::string& scene,
                               const std::vector<std::string>& files) {
    // The name up to its first dot: dragon_vrip.ply.gz -> dragon_vrip.
    auto stem = [](const std::string& file) {
        const std::string name = fs::path(file).filename().string();
        return name.substr(0, name.find('.'));
    };
    const std::string model = stem(set.model);
    if (model.empty()) return "";
    for (const std::string& f : files) {
        if (stem(f).rfind(model, 0) == 0) return "";
    }
    return printable(label + ": the views file " + views_path + " places its cameras for " +
                     set.model + ", not for " + scene + "; the view may not frame it");
}

CameraDesc find_view(const std::string& views_path, const std::string& name) {
    const std::string path = views_file_path(views_path);
    const ViewSet set = load_views(path);
    for (const View& v : set.views) {
        if (v.name == name) return v.camera;
    }
    // The first names show how they are spelt; a file of thousands would flood the terminal.
    constexpr size_t kListed = 20;
    std::string names;
    for (size_t i = 0; i < std::min(kListed, set.views.size()); ++i)
        names += (i ? ", " : "") + excerpt(set.views[i].name, 40);
    if (set.views.size() > kListed)
        names += ", ... (" + std::to_string(set.views.size()) + " views)";
    throw Error(ErrorLocation{path},
                "no view named \"" + excerpt(name) + "\" (views: " + names + ")");
}

std::string find_asset(const std::string& relative) {
    std::vector<fs::path> roots;
    if (const char* env = std::getenv("KDT_ASSETS_DIR"); env && *env) roots.emplace_back(env);
    roots.emplace_back("assets");
    std::error_code ec;
    fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (!ec) {
        fs::path bin = exe.parent_path();
        roots.push_back(bin / ".." / ".." / "assets");
        roots.push_back(bin / ".." / "assets");
        roots.push_back(bin / ".." / "share" / "kdtrace" / "assets");
    }
#ifdef KDT_SOURCE_ASSETS_DIR
    roots.emplace_back(KDT_SOURCE_ASSETS_DIR);
#endif
    for (const fs::path& r : roots) {
        fs::path p = r / relative;
        if (fs::is_regular_file(p, ec)) return fs::weakly_canonical(p, ec).string();
    }
    throw Error(
        ErrorLocation{relative},
        "asset not found (looked in $KDT_ASSETS_DIR, ./assets, next to the executable and in "
        "the source tree)");
}

}  // namespace kdt
