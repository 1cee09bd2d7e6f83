#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/core/output_path.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

namespace fs = std::filesystem;

std::string refusal(const std::string& output, const std::vector<std::string>& inputs) {
    try {
        check_output(output, inputs, "the result");
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

class OutputPathTest : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = test::temp_dir("output_path");
        fs::create_directories(dir_ / "sub");
        input_ = (dir_ / "in.ply").string();
        std::ofstream(input_) << "input data";
    }
    std::string path(const std::string& name) const { return (dir_ / name).string(); }

    fs::path dir_;
    std::string input_;
};

TEST_F(OutputPathTest, EverySpellingOfAnInputIsRefused) {
    fs::create_symlink(input_, path("link.ply"));
    fs::create_hard_link(input_, path("hard.ply"));
    fs::create_symlink(path("link.ply"), path("link2.ply"));  // a chain of links
    // The output names the input: same text, through `..` and `.`, by symlinks, a hard link.
    const std::vector<std::string> outputs = {
        input_,           path("sub/../in.ply"), path("./sub/.././in.ply"),
        path("link.ply"), path("link2.ply"),     path("hard.ply"),
    };
    for (const std::string& out : outputs) {
        const std::string msg = refusal(out, {"", "/nonexistent/x.ply", input_});
        EXPECT_NE(msg.find(out + ": cannot write the result: it is the input " + input_),
                  std::string::npos)
            << out << ": " << msg;
    }
    // And the other way round: the input given through a link, the output the real file.
    EXPECT_NE(refusal(input_, {path("link.ply")}).find("is the input"), std::string::npos);
    EXPECT_NE(refusal(input_, {path("sub/../hard.ply")}).find("is the input"), std::string::npos);
    // The input is untouched by the check.
    std::ifstream in(input_);
    std::string text;
    std::getline(in, text);
    EXPECT_EQ(text, "input data");
}

TEST_F(OutputPathTest, SpecialFilesAndLinksToThemAreRefused) {
    ASSERT_EQ(::mkfifo(path("fifo").c_str(), 0600), 0);
    fs::create_symlink(path("fifo"), path("fifo_link.png"));
    fs::create_symlink("/dev/null", path("null_link.png"));
    fs::create_symlink(dir_ / "sub", path("dir_link.png"));
    struct Case {
        std::string output, expected;
    };
    const Case cases[] = {
        {path("fifo"), "is a FIFO (pipe)"},
        {path("fifo_link.png"), "is a symlink to a FIFO (pipe)"},
        {"/dev/null", "is a character device"},
        {"/dev/zero", "is a character device"},
        {path("null_link.png"), "is a symlink to a character device"},
        {path("sub"), "is a directory"},
        {path("dir_link.png"), "is a symlink to a directory"},
        {path("no_such_dir/out.png"), "directory " + path("no_such_dir") + " does not exist"},
    };
    for (const Case& c : cases) {
        const std::string msg = refusal(c.output, {input_});
        EXPECT_NE(msg.find(c.output + ": cannot write the result: " + c.expected),
                  std::string::npos)
            << c.output << ": " << msg;
    }
    EXPECT_NE(refusal("", {}).find("no file name"), std::string::npos);
}

TEST_F(OutputPathTest, NewFilesAndOtherRegularFilesAreAccepted) {
    std::ofstream(path("old.png")) << "an old image";
    fs::create_symlink(path("old.png"), path("old_link.png"));
    fs::create_symlink(path("missing"), path("dangling.png"));
    for (const std::string& out : {path("new.png"), path("old.png"), path("old_link.png"),
                                   path("dangling.png"), path("sub/../new.png")}) {
        EXPECT_EQ(refusal(out, {input_, "", path("missing.ply")}), "") << out;
    }
    // A relative output in the current directory has an existing parent.
    EXPECT_EQ(refusal("kdt_output_path_test_new_file.png", {input_}), "");
}

TEST_F(OutputPathTest, AWriteProtectedFileIsRefusedButRootMayReplaceIt) {
    std::ofstream(path("ro.png")) << "keep";
    fs::permissions(path("ro.png"),
                    fs::perms::owner_read | fs::perms::group_read | fs::perms::others_read);
    fs::create_symlink(path("ro.png"), path("ro_link.png"));
    const std::string msg = refusal(path("ro.png"), {input_});
    if (::geteuid() == 0) {
        EXPECT_EQ(msg, "");  // as `cp` does (the sticky case runs as nobody in a smoke test)
    } else {
        EXPECT_NE(msg.find(path("ro.png") + ": cannot write the result: the existing file is "
                                            "not writable (Permission denied)"),
                  std::string::npos)
            << msg;
    }
    // A symlink is written through: its target's mode counts.
    const std::string via_link = refusal(path("ro_link.png"), {input_});
    if (::geteuid() == 0) {
        EXPECT_EQ(via_link, "");
    } else {
        EXPECT_NE(via_link.find(": cannot write the result: the symlink's target " +
                                path("ro.png") + " is not writable"),
                  std::string::npos)
            << via_link;
    }
}

TEST_F(OutputPathTest, ABrokenSymlinkChainIsRefused) {
    fs::create_symlink(path("no_such_dir/x.png"), path("dangling_nowhere.png"));
    EXPECT_NE(refusal(path("dangling_nowhere.png"), {input_})
                  .find(": cannot write the result: is a dangling symlink to " +
                        path("no_such_dir/x.png") + ", whose directory " + path("no_such_dir") +
                        " does not exist"),
              std::string::npos);
    fs::create_symlink("loop_b.png", path("loop_a.png"));
    fs::create_symlink("loop_a.png", path("loop_b.png"));
    EXPECT_NE(refusal(path("loop_a.png"), {input_}).find("too many levels of symbolic links"),
              std::string::npos);
}

// A name the system would refuse (ENAMETOOLONG) is said to be too long, with its length and
// the limit, and the path in the message is shortened to its head and tail.
TEST_F(OutputPathTest, ANameTooLongIsSaidToBeSo) {
    const std::string long_name = path(std::string(300, 'a') + ".png");
    const std::string why = refusal(long_name, {input_});
    EXPECT_NE(why.find(": cannot write the result: file name too long: 304 bytes, more than "
                       "the 255 bytes a file name may have"),
              std::string::npos)
        << why;
    EXPECT_NE(why.find(" bytes left out] ... aaa"), std::string::npos) << why;
    EXPECT_LT(why.size(), 400u) << why;
    EXPECT_NE(path_length_problem(path(std::string(300, 'd') + "/x.png"))
                  .find("file name too long: the directory name dddd"),
              std::string::npos);
    std::string deep = path("");
    while (deep.size() < 4200) deep += "b/";
    EXPECT_NE(path_length_problem(deep + "x.png").find("path too long: "), std::string::npos);
    EXPECT_EQ(path_length_problem(path(std::string(255, 'a'))), "");
    EXPECT_EQ(path_length_problem("x.png"), "");
}

}  // namespace
}  // namespace kdt
