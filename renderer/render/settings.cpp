#include "renderer/render/settings.h"

#include <cmath>

#include <nlohmann/json.hpp>

namespace kdt {

namespace {

using nlohmann::json;

[[noreturn]] void bad_render_param(const std::string& name, const std::string& value,
                                   const std::string& range) {
    throw Error(ErrorLocation{"", "render parameter " + name},
                "value " + value + " is outside " + range);
}

std::string num(double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%g", v);
    return buf;
}

void check_int(const char* name, int v, int lo, int hi, const char* range) {
    if (v < lo || v > hi) bad_render_param(name, std::to_string(v), range);
}

json vec_json(const Vec3f& v) { return json::array({v.x, v.y, v.z}); }

}  // namespace

void validate_render_params(const TraceParams& t, const FilmParams& f) {
    check_int("max_depth", t.max_depth, 0, 1024, "[0, 1024]");
    check_int("rr_min_depth", t.rr_min_depth, 0, 1024, "[0, 1024]");
    check_int("samples_per_pass", t.samples_per_pass, 1, 1 << 20, "[1, 1048576]");
    check_int("threads", t.threads, 0, kMaxThreads, "[0, 1024] (0 = all)");
    if (size_t(t.light_sampling) >= kLightSamplingNames.size())
        bad_render_param("light_sampling", std::to_string(int(t.light_sampling)),
                         "the known names");
    if (size_t(t.diffuse_sampling) >= kDiffuseSamplingNames.size())
        bad_render_param("diffuse_sampling", std::to_string(int(t.diffuse_sampling)),
                         "the known names");
    if (size_t(t.filter) >= kPixelFilterNames.size())
        bad_render_param("filter", std::to_string(int(t.filter)), "the known names");
    if (!(f.adaptive_threshold > 0.0f && std::isfinite(f.adaptive_threshold)))
        bad_render_param("adaptive_threshold", num(f.adaptive_threshold), "(0, inf)");
    check_int("adaptive_min_spp", f.adaptive_min_spp, 0, 1 << 24, "[0, 16777216]");
    check_int("adaptive_max_spp", f.adaptive_max_spp, 0, 1 << 30, "[0, 2^30] (0 = no cap)");
    if (!(std::fabs(f.exposure) <= 64.0f))
        bad_render_param("exposure", num(f.exposure), "[-64, 64] stops");
}

std::string params_to_json(const TraceParams& t, const FilmParams& f, const KdTreeParams& k) {
    json j;
    j["max_depth"] = t.max_depth;
    j["russian_roulette"] = t.russian_roulette;
    j["rr_min_depth"] = t.rr_min_depth;
    j["light_sampling"] = kLightSamplingNames[size_t(t.light_sampling)];
    j["env_importance"] = t.env_importance;
    j["sample_emitters"] = t.sample_emitters;
    j["diffuse_sampling"] = kDiffuseSamplingNames[size_t(t.diffuse_sampling)];
    j["filter"] = kPixelFilterNames[size_t(t.filter)];
    j["samples_per_pass"] = t.samples_per_pass;
    j["seed"] = t.seed;
    j["adaptive"] = f.adaptive;
    j["adaptive_threshold"] = f.adaptive_threshold;
    j["adaptive_min_spp"] = f.adaptive_min_spp;
    j["adaptive_max_spp"] = f.adaptive_max_spp;
    j["exposure"] = f.exposure;
    j["builder"] = kKdBuilderNames[size_t(k.builder)];
    j["q"] = k.q;
    j["n0"] = k.n0;
    j["tree_max_depth"] = k.max_depth;
    return j.dump();
}

std::string camera_to_json(const Camera& c) {
    json j;
    j["eye"] = vec_json(c.eye);
    j["target"] = vec_json(c.eye + c.forward);
    j["up"] = vec_json(c.up);
    j["vfov_degrees"] = c.vfov_degrees;
    j["width"] = c.width;
    j["height"] = c.height;
    return j.dump();
}

void params_from_json(const std::string& text, TraceParams& t, FilmParams& f, KdTreeParams& k) {
    json j;
    try {
        j = json::parse(text);
    } catch (const json::exception& e) {
        throw Error(ErrorLocation{"kdtrace:params"}, std::string("malformed JSON: ") + e.what());
    }
    if (!j.is_object()) throw Error(ErrorLocation{"kdtrace:params"}, "expected a JSON object");
    try {
        for (auto it = j.begin(); it != j.end(); ++it) {
            const std::string& key = it.key();
            const json& v = it.value();
            if (key == "max_depth")
                t.max_depth = v.get<int>();
            else if (key == "russian_roulette")
                t.russian_roulette = v.get<bool>();
            else if (key == "rr_min_depth")
                t.rr_min_depth = v.get<int>();
            else if (key == "light_sampling")
                t.light_sampling =
                    LightSampling(parse_name(kLightSamplingNames, v.get<std::string>(), key));
            else if (key == "env_importance")
                t.env_importance = v.get<bool>();
            else if (key == "sample_emitters")
                t.sample_emitters = v.get<bool>();
            else if (key == "diffuse_sampling")
                t.diffuse_sampling =
                    DiffuseSampling(parse_name(kDiffuseSamplingNames, v.get<std::string>(), key));
            else if (key == "filter")
                t.filter = PixelFilter(parse_name(kPixelFilterNames, v.get<std::string>(), key));
            else if (key == "samples_per_pass")
                t.samples_per_pass = v.get<int>();
            else if (key == "seed")
                t.seed = v.get<uint64_t>();
            else if (key == "adaptive")
                f.adaptive = v.get<bool>();
            else if (key == "adaptive_threshold")
                f.adaptive_threshold = v.get<float>();
            else if (key == "adaptive_min_spp")
                f.adaptive_min_spp = v.get<int>();
            else if (key == "adaptive_max_spp")
                f.adaptive_max_spp = v.get<int>();
            else if (key == "exposure")
                f.exposure = v.get<float>();
            else if (key == "builder")
                k.builder = KdBuilder(parse_name(kKdBuilderNames, v.get<std::string>(), key));
            else if (key == "q")
                k.q = v.get<float>();
            else if (key == "n0")
                k.n0 = v.get<int>();
            else if (key == "tree_max_depth")
                k.max_depth = v.get<int>();
            else
                throw Error(ErrorLocation{"kdtrace:params", key}, "unknown key");
        }
    } catch (const json::exception& e) {
        throw Error(ErrorLocation{"kdtrace:params"}, std::string("wrong type: ") + e.what());
    }
}

}  // namespace kdt
