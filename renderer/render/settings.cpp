#include "renderer/render/settings.h"

#include <nlohmann/json.hpp>

namespace kdt {

namespace {

using nlohmann::json;

json vec_json(const Vec3f& v) { return json::array({v.x, v.y, v.z}); }

}  // namespace

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
