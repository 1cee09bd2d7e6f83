#include "renderer/scene/json_parse.h"

#include <fstream>
#include <functional>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/render/render_options.h"
#include "renderer/scene/scene.h"
#include "renderer/scene/views.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

std::string nested(size_t depth, char open = '[', char close = ']') {
    return std::string(depth, open) + std::string(depth, close);
}

template <class F>
std::string error_of(F&& f) {
    try {
        f();
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

TEST(JsonParse, NestingUpToTheLimitIsRead) {
    const nlohmann::json j = parse_json_without_repeats(nested(kMaxJsonNesting), "x.json", "");
    EXPECT_TRUE(j.is_array());
}

TEST(JsonParse, NestingPastTheLimitIsRefusedNamingTheFile) {
    std::string objects;
    for (int i = 0; i < 100000; ++i) objects += "{\"a\":";
    objects += "1" + std::string(100000, '}');
    for (const std::string& text : {nested(kMaxJsonNesting + 1), nested(1000000), objects,
                                    "{\"meshes\": [{\"file\": " + nested(100000) + "}]}"}) {
        const std::string msg =
            error_of([&] { parse_json_without_repeats(text, "deep.json", ""); });
        EXPECT_NE(msg.find("deep.json"), std::string::npos) << msg;
        EXPECT_NE(msg.find("nested deeper than 64 levels"), std::string::npos) << msg;
    }
}

// Scene, views and session files all go through the parser: a file of brackets is refused
// with its name instead of being built in memory first (about 200 bytes per level).
TEST(JsonParse, DeepScenesViewsAndSessionsAreRefused) {
    const auto dir = test::temp_dir("json_deep");
    const std::string path = (dir / "deep.json").string();
    std::ofstream(path) << nested(200000, '[', ']');
    for (const auto& load :
         std::vector<std::function<void()>>{[&] { load_scene(path); }, [&] { load_views(path); },
                                            [&] {
                                                RenderOptions o;
                                                options_from_session_file(path, o);
                                            }}) {
        const std::string msg = error_of(load);
        EXPECT_NE(msg.find(path), std::string::npos) << msg;
        EXPECT_NE(msg.find("nested deeper than"), std::string::npos) << msg;
    }
}

}  // namespace
}  // namespace kdt
