// `kdtrace info IMAGE` (app/cmd_info.cpp) on metadata that could drive a terminal: a PNG
// written here with a tEXt/iTXt value holding a C1 control (0x9b, CSI on some terminals),
// invalid UTF-8 and several lines is printed escaped, line by line. Runs the built kdtrace;
// skips when it is not built (the sanitizer presets build no app).
#include <cstdio>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "renderer/io/image_io.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

TEST(ImageInfoCli, MetadataValuesArePrintedEscapedLineByLine) {
    const std::string exe = std::string(KDT_BINARY_DIR) + "/bin/kdtrace";
    if (!std::filesystem::exists(exe)) GTEST_SKIP() << "no " << exe;
    const std::filesystem::path dir = test::temp_dir("kdt_info_cli");
    const std::string png = (dir / "meta.png").string();
    ImageRGB image(2, 2);
    write_png(png, image, {},
              {{"note",
                "csi \x9b"
                "1m, \xc2\x9b"
                "31m red\nbad \xff\xfe utf-8\tand \xc3\xa9 kept"}});
    FILE* p = ::popen(("'" + exe + "' info '" + png + "' 2>&1").c_str(), "r");
    ASSERT_NE(p, nullptr);
    std::string out;
    char buf[4096];
    for (size_t n; (n = std::fread(buf, 1, sizeof(buf), p)) > 0;) out.append(buf, n);
    EXPECT_EQ(::pclose(p), 0) << out;
    std::filesystem::remove_all(dir);
    EXPECT_EQ(out.find('\x9b'), std::string::npos) << out;  // raw, or in C1's UTF-8 (c2 9b)
    EXPECT_EQ(out.find('\xff'), std::string::npos) << out;
    EXPECT_NE(out.find("note: csi \\x9b1m, \\u009b31m red\n"
                       "             bad \\xff\\xfe utf-8\tand \xc3\xa9 kept\n"),
              std::string::npos)
        << out;
}

// A long value (a file may hold megabytes in one) is summarised unless --all.
TEST(ImageInfoCli, LongValuesAreSummarisedUnlessAll) {
    const std::string exe = std::string(KDT_BINARY_DIR) + "/bin/kdtrace";
    if (!std::filesystem::exists(exe)) GTEST_SKIP() << "no " << exe;
    const std::filesystem::path dir = test::temp_dir("kdt_info_long");
    const std::string png = (dir / "long.png").string();
    write_png(png, ImageRGB(2, 2), {}, {{"junk", std::string(100000, 'x')}, {"short", "kept"}});
    auto info = [&](const std::string& flags) {
        FILE* p = ::popen(("'" + exe + "' info " + flags + "'" + png + "' 2>&1").c_str(), "r");
        std::string out;
        char buf[4096];
        for (size_t n; p && (n = std::fread(buf, 1, sizeof(buf), p)) > 0;) out.append(buf, n);
        if (p) ::pclose(p);
        return out;
    };
    const std::string brief = info(""), all = info("--all ");
    std::filesystem::remove_all(dir);
    EXPECT_NE(brief.find("junk: 100000 bytes (--all prints it)\n"), std::string::npos) << brief;
    EXPECT_NE(brief.find("short: kept\n"), std::string::npos) << brief;
    EXPECT_LT(brief.size(), size_t(10000));
    EXPECT_NE(all.find("junk: " + std::string(100000, 'x') + "\n"), std::string::npos);
}

}  // namespace
}  // namespace kdt
