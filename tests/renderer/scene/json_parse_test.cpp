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
            test::error_of_call([&] { parse_json_without_repeats(text, "deep.json", ""); });
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
        const std::string msg = test::error_of_call(load);
        EXPECT_NE(msg.find(path), std::string::npos) << msg;
        EXPECT_NE(msg.find("nested deeper than"), std::string::npos) << msg;
    }
}

// Syntax errors reach the callers as nlohmann's own exception types, which they report with
// the byte offset (parse_error) or as they are (out_of_range, a number beyond double).
TEST(JsonParse, SyntaxErrorsKeepTheirTypes) {
    EXPECT_THROW(parse_json_without_repeats("{\"a\": [1, 2}", "x.json", ""),
                 nlohmann::json::parse_error);
    EXPECT_THROW(parse_json_without_repeats("{} x", "x.json", ""), nlohmann::json::parse_error);
    EXPECT_THROW(parse_json_without_repeats("", "x.json", ""), nlohmann::json::parse_error);
    EXPECT_THROW(parse_json_without_repeats("[1e400]", "x.json", ""), nlohmann::json::out_of_range);
}

// An array of many objects is read in time linear in its length (a parser callback made it
// quadratic: 300,000 objects took about 20 s, now 0.3 s), its indices counted in the paths of
// repeated keys.
TEST(JsonParse, LongArraysOfObjects) {
    constexpr int kCount = 300000;
    std::string text = "{\"views\": [";
    for (int i = 0; i < kCount; ++i)
        text += std::string(i ? "," : "") + "{\"n\": " + std::to_string(i) + "}";
    const nlohmann::json j = parse_json_without_repeats(text + "]}", "v.json", "/");
    ASSERT_EQ(j.at("views").size(), size_t(kCount));
    EXPECT_EQ(j.at("views").back().at("n").get<int>(), kCount - 1);
    text += ", {\"n\": 1, \"m\": [{}, {\"k\": 1, \"k\": 2}]}]}";
    EXPECT_EQ(test::error_of_call([&] { parse_json_without_repeats(text, "v.json", "/"); }),
              "v.json: /views/" + std::to_string(kCount) + "/m/1/k: repeated key");
}

}  // namespace
}  // namespace kdt
