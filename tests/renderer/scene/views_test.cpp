#include "renderer/scene/views.h"

#include <fstream>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

std::string views_error(const std::string& name, const std::string& text) {
    const std::string path = (test::temp_dir("views_err") / name).string();
    std::ofstream(path) << text;
    return test::error_of_call([&] { load_views(path); });
}

const char* kView = R"("eye": [0, 0, 5], "target": [0, 0, 0], "vfov_degrees": 40)";

// A repeated key or view name would be taken silently: nlohmann keeps a key's last value,
// and --view NAME the first view of that name.
TEST(Views, RepeatedKeysAndNamesAreRefused) {
    const std::string one = std::string("{\"name\": \"A\", ") + kView + "}";
    const std::string two = std::string("{\"name\": \"B\", ") + kView + "}";
    EXPECT_EQ(views_error("ok.json", "{\"views\": [" + one + ", " + two + "]}"), "");
    const std::string err = views_error("dup_name.json", "{\"views\": [" + one + ", " + one + "]}");
    EXPECT_NE(err.find("dup_name.json: /views/1/name: view name \"A\" repeated (also "
                       "/views/0/name)"),
              std::string::npos)
        << err;
    const std::string key =
        views_error("dup_key.json", "{\"views\": [" + one + ", " + "{\"name\": \"B\", " + kView +
                                        ", \"eye\": [0, 0, 6]}]}");
    EXPECT_NE(key.find("dup_key.json: /views/1/eye: repeated key"), std::string::npos) << key;
    const std::string top =
        views_error("dup_top.json", "{\"width\": 8, \"views\": [" + one + "], \"width\": 9}");
    EXPECT_NE(top.find("dup_top.json: /width: repeated key"), std::string::npos) << top;
}

}  // namespace
}  // namespace kdt
