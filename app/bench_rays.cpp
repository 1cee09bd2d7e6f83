#include "app/bench_rays.h"

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "renderer/core/error.h"
#include "renderer/core/open_file.h"
#include "renderer/material/material.h"

namespace kdt::app {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

uint64_t splitmix64(uint64_t x) {
    x += 0x9e3779b97f4a7c15ull;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
    return x ^ (x >> 31);
}

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

float hash_uniform(uint64_t a, uint64_t b, uint64_t c, uint64_t d) {
    uint64_t h = splitmix64(a);
    h = splitmix64(h ^ b);
    h = splitmix64(h ^ c);
    h = splitmix64(h ^ d);
    // 24 high bits: exactly representable, strictly below 1.
    return float(h >> 40) * 0x1.0p-24f;
}

BenchViewSet load_views(const std::string& path) {
    const std::vector<uint8_t> text = read_regular_file(path, uint64_t(16) << 20, "a views file");
    json doc;
    try {
        doc = json::parse(text.begin(), text.end());
    } catch (const json::parse_error& e) {
        throw Error(ErrorLocation{path, "", -1, -1, int64_t(e.byte)}, "invalid JSON");
    } catch (const json::exception& e) {
        // out_of_range for a number beyond double (1e400), and any other parser error.
        throw Error(ErrorLocation{path}, std::string("invalid JSON: ") + e.what());
    }
    check_keys(path, "", doc,
               {"description", "model", "width", "height", "samples_per_pixel", "seed", "views"});
    BenchViewSet set;
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
    for (size_t i = 0; i < views.size(); ++i) {
        const std::string ptr = "/views/" + std::to_string(i);
        const json& v = views[i];
        check_keys(path, ptr, v, {"name", "label", "eye", "target", "up", "vfov_degrees"});
        BenchView view;
        const json& name = need(path, ptr, v, "name");
        if (!name.is_string() || name.get<std::string>().empty()) {
            bad(path, ptr + "/name", "expected a non-empty string");
        }
        view.name = name.get<std::string>();
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

CameraDesc find_view(const std::string& views_path, const std::string& name) {
    const std::string path = views_path.empty() ? find_asset("views/dragon.json") : views_path;
    const BenchViewSet set = load_views(path);
    std::string names;
    for (const BenchView& v : set.views) {
        if (v.name == name) return v.camera;
        names += (names.empty() ? "" : ", ") + v.name;
    }
    throw Error(ErrorLocation{path}, "no view named \"" + name + "\" (views: " + names + ")");
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
    for (const fs::path& r : roots) {
        fs::path p = r / relative;
        if (fs::is_regular_file(p, ec)) return fs::weakly_canonical(p, ec).string();
    }
    throw Error(ErrorLocation{relative},
                "asset not found (looked in $KDT_ASSETS_DIR, ./assets and next to the executable)");
}

Ray camera_ray(const CameraDesc& camera, int width, int height, float x, float y) {
    const Vec3f forward = glm::normalize(camera.target - camera.eye);
    const Vec3f right = glm::normalize(glm::cross(forward, camera.up));
    const Vec3f up = glm::cross(right, forward);
    const float tan_half = std::tan(0.5f * camera.vfov_degrees * kPi / 180.0f);
    const float aspect = float(width) / float(height);
    const float sx = (2.0f * x / float(width) - 1.0f) * tan_half * aspect;
    const float sy = (1.0f - 2.0f * y / float(height)) * tan_half;
    Ray r;
    r.origin = camera.eye;
    r.dir = glm::normalize(forward + sx * right + sy * up);
    return r;
}

std::vector<Ray> make_primary_rays(const BenchViewSet& set, size_t view_index) {
    const CameraDesc& cam = set.views.at(view_index).camera;
    const int w = set.width, h = set.height, spp = set.samples_per_pixel;
    constexpr int kTile = 8;
    std::vector<Ray> rays;
    rays.reserve(size_t(w) * size_t(h) * size_t(spp));
    for (int ty = 0; ty < h; ty += kTile) {
        for (int tx = 0; tx < w; tx += kTile) {
            for (int y = ty; y < std::min(h, ty + kTile); ++y) {
                for (int x = tx; x < std::min(w, tx + kTile); ++x) {
                    const uint64_t pixel = uint64_t(y) * uint64_t(w) + uint64_t(x);
                    for (int s = 0; s < spp; ++s) {
                        const float jx = hash_uniform(set.seed, view_index, pixel, 2 * uint64_t(s));
                        const float jy =
                            hash_uniform(set.seed, view_index, pixel, 2 * uint64_t(s) + 1);
                        rays.push_back(camera_ray(cam, w, h, float(x) + jx, float(y) + jy));
                    }
                }
            }
        }
    }
    return rays;
}

std::vector<Ray> make_diffuse_rays(const TriangleMesh& mesh, const std::vector<Ray>& rays,
                                   const std::vector<Hit>& hits, uint64_t seed,
                                   std::vector<uint32_t>* sources) {
    std::vector<Ray> out;
    out.reserve(rays.size());
    if (sources) sources->clear();
    for (size_t i = 0; i < rays.size(); ++i) {
        const Hit& hit = hits[i];
        if (!hit.valid() || hit.prim >= mesh.triangle_count()) continue;
        const Vec3u t = mesh.triangles[hit.prim];
        const Vec3f p0 = mesh.positions[t.x], p1 = mesh.positions[t.y], p2 = mesh.positions[t.z];
        // The hit point from barycentrics is accurate to a few ULPs of the vertices; o + t d
        // would carry the error of t times the ray length.
        const Vec3f p = (1.0f - hit.u - hit.v) * p0 + hit.u * p1 + hit.v * p2;
        Vec3f n = glm::cross(p1 - p0, p2 - p0);
        const float len = glm::length(n);
        if (!(len > 0.0f) || !std::isfinite(len)) continue;
        n /= len;
        if (glm::dot(n, rays[i].dir) > 0.0f) n = -n;
        // Offset by 16 ULPs of the largest coordinate of p: scales with the position, not
        // with the scene (Wächter & Binder 2019 argue the same in integer ULP space).
        const float m = std::max({std::fabs(p.x), std::fabs(p.y), std::fabs(p.z)});
        const float offset = std::max(m, 1e-30f) * 0x1.0p-19f;
        Ray r;
        r.origin = p + offset * n;
        // Cosine-distributed direction about n, with the path tracer's own sampling.
        const Vec3f local = sample_cosine_hemisphere(
            {hash_uniform(seed, 0x5eed, i, 0), hash_uniform(seed, 0x5eed, i, 1)});
        Vec3f b1, b2;
        make_basis(n, b1, b2);
        r.dir = glm::normalize(local.x * b1 + local.y * b2 + local.z * n);
        out.push_back(r);
        if (sources) sources->push_back(uint32_t(i));
    }
    return out;
}

}  // namespace kdt::app
