// The real kdtrace executable under Xvfb (xvfb-run, installed by scripts/setup.sh; Mesa's
// software GL): the window shows the model and the panels and changes after scripted input,
// and the viewer's image after N samples per pixel is bit for bit what `kdtrace render` writes.
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "renderer/io/image_io.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

// Runs a shell command; returns its exit status and puts its output in *log.
int run(const std::string& command, const std::filesystem::path& log_path, std::string* log) {
    const int rc = std::system((command + " > '" + log_path.string() + "' 2>&1").c_str());
    std::ifstream f(log_path);
    std::stringstream ss;
    ss << f.rdbuf();
    *log = ss.str();
    return rc;
}

std::string xvfb() {
    EXPECT_EQ(std::system("command -v xvfb-run > /dev/null"), 0)
        << "xvfb-run is missing: run scripts/setup.sh (Debian package xvfb)";
    return "xvfb-run -a -s '-screen 0 1280x800x24' ";
}

// Mean absolute difference of two images' channels over columns [x0, x1).
double mean_difference(const ImageRGB& a, const ImageRGB& b, int x0, int x1) {
    double sum = 0.0;
    size_t n = 0;
    for (int y = 0; y < a.height; ++y) {
        for (int x = x0; x < x1; ++x) {
            for (int c = 0; c < 3; ++c) {
                const size_t i = (size_t(y) * size_t(a.width) + size_t(x)) * 3 + size_t(c);
                sum += std::abs(double(a.rgb[i]) - double(b.rgb[i]));
                ++n;
            }
        }
    }
    return n ? sum / double(n) : 0.0;
}

// Fraction of pixels in columns [x0, x1) whose colour differs from the window's clear colour
// (0.08, 0.08, 0.09 in sRGB codes), and how many distinct grey levels they have.
double covered(const ImageRGB& img, int x0, int x1, int* levels) {
    const float clear = srgb_to_linear(0.08f);
    size_t n = 0, lit = 0;
    bool seen[256] = {};
    for (int y = 0; y < img.height; ++y) {
        for (int x = x0; x < x1; ++x) {
            const size_t i = (size_t(y) * size_t(img.width) + size_t(x)) * 3;
            ++n;
            lit += std::abs(img.rgb[i] - clear) > 0.01f || std::abs(img.rgb[i + 1] - clear) > 0.01f;
            seen[tonemap_to_srgb8(img.rgb[i + 1], ToneParams{})] = true;
        }
    }
    *levels = 0;
    for (bool s : seen) *levels += s;
    return n ? double(lit) / double(n) : 0.0;
}

TEST(ViewerE2E, WindowShowsModelAndPanelsAndChangesAfterInput) {
    const auto dir = test::temp_dir("view_e2e");
    const std::string before = (dir / "before.png").string(), after = (dir / "after.png").string();
    const std::string script = "wait_passes 2; screenshot " + before +
                               "; orbit 40 10; set tree.builder thesis; set tree.q 0.9;"
                               " wait_rebuild; wait_passes 1";
    std::string log;
    const int rc = run(xvfb() + KDT_EXE + " view --width 320 --height 240 --no-cache --script '" +
                           script + "' --frames 2 --screenshot " + after,
                       dir / "log.txt", &log);
    ASSERT_EQ(rc, 0) << log;
    EXPECT_NE(log.find("view: "), std::string::npos) << log;  // the summary line
    const ImageRGB a = load_image(before), b = load_image(after);
    ASSERT_EQ(a.width, b.width);
    ASSERT_EQ(a.width, 320 + 380);  // the image and the panel column
    // The image area: the model and the ground in many tones, not an empty window (a flat
    // image has one or two; how many more an early pass shows depends on its noise, 40 or so).
    int levels = 0;
    EXPECT_GT(covered(a, 0, 320, &levels), 0.25);
    EXPECT_GT(levels, 20);
    // The panel column: ImGui's widgets and text (its window background is close to the clear
    // colour) over a good part of it, in several tones.
    EXPECT_GT(covered(a, 330, a.width, &levels), 0.2);
    EXPECT_GT(levels, 5);
    // The orbit and the new tree changed the image; the panels show the new parameters.
    EXPECT_GT(mean_difference(a, b, 0, 320), 0.02);
    EXPECT_GT(mean_difference(a, b, 330, a.width), 0.0);
}

TEST(ViewerE2E, ImageAfterNSamplesEqualsRenderBitwise) {
    const auto dir = test::temp_dir("view_equals_render");
    const std::string common = " --width 96 --height 64 --spp 4 --no-cache --seed 7";
    const std::string view = (dir / "view.pfm").string(), render = (dir / "render.pfm").string();
    std::string log;
    ASSERT_EQ(run(xvfb() + KDT_EXE + " view" + common + " --script 'wait_done; save " + view +
                      "' --frames 1",
                  dir / "view.txt", &log),
              0)
        << log;
    ASSERT_EQ(run(std::string(KDT_EXE) + " render" + common + " --quiet -o " + render,
                  dir / "render.txt", &log),
              0)
        << log;
    const std::vector<unsigned char> v = test::read_bytes(view), r = test::read_bytes(render);
    ASSERT_GT(r.size(), size_t(96 * 64 * 12));
    EXPECT_TRUE(v == r) << "the viewer's image differs from kdtrace render's";
}

// A material edited in the viewer travels in its session file: `kdtrace render --session`
// of it renders the image on screen, bit for bit.
TEST(ViewerE2E, EditedMaterialSessionRendersTheSameImage) {
    const auto dir = test::temp_dir("view_material_session");
    const std::string common = " --width 96 --height 64 --spp 4 --no-cache --seed 7";
    const std::string view = (dir / "view.pfm").string(), render = (dir / "render.pfm").string(),
                      plain = (dir / "plain.pfm").string(),
                      session = (dir / "session.json").string();
    std::string log;
    ASSERT_EQ(run(xvfb() + KDT_EXE + " view" + common +
                      " --script 'set material.albedo 0.1,0.7,0.2; wait_done; save " + view +
                      "; save_session " + session + "' --frames 1",
                  dir / "view.txt", &log),
              0)
        << log;
    ASSERT_EQ(run(std::string(KDT_EXE) + " render --session " + session + " --quiet -o " + render,
                  dir / "render.txt", &log),
              0)
        << log;
    ASSERT_EQ(run(std::string(KDT_EXE) + " render" + common + " --quiet -o " + plain,
                  dir / "plain.txt", &log),
              0)
        << log;
    const std::vector<unsigned char> v = test::read_bytes(view), r = test::read_bytes(render),
                                     p = test::read_bytes(plain);
    ASSERT_GT(r.size(), size_t(96 * 64 * 12));
    EXPECT_TRUE(v == r) << "the session's render differs from the viewer's image";
    EXPECT_FALSE(v == p) << "the material edit did not change the image";
}

// An image saved in the viewer carries a command that renders it again from the image alone
// (the image is its own session), material edits included, bit for bit, from any directory.
TEST(ViewerE2E, SavedImageCommandRendersItAgain) {
    const auto dir = test::temp_dir("view_image_command");
    const std::string shot = (dir / "shot").string(), again = (dir / "again.exr").string();
    std::string log;
    ASSERT_EQ(run(xvfb() + KDT_EXE +
                      " view --width 96 --height 64 --spp 4 --no-cache --seed 7"
                      " --script 'set material.albedo 0.1,0.7,0.2; wait_done; save " +
                      shot + "' --frames 1",
                  dir / "view.txt", &log),
              0)
        << log;
    ImageMetadata meta;
    const ImageRGB saved = load_image(shot + ".exr", &meta);
    std::string command;
    for (const auto& [key, value] : meta)
        if (key == "kdtrace:command") command = value;
    const std::string prefix = "kdtrace render --session '" + shot + ".exr' --spp 4";
    ASSERT_EQ(command, prefix);
    ASSERT_EQ(run("cd / && " + std::string(KDT_EXE) + command.substr(7) + " --quiet -o " + again,
                  dir / "render.txt", &log),
              0)
        << log;
    const ImageRGB rendered = load_image(again);
    EXPECT_TRUE(saved.rgb == rendered.rgb) << "the command's image differs from the viewer's";
    // An image that kdtrace did not write is no session.
    write_image((dir / "plain.png").string(), saved);
    EXPECT_NE(run(std::string(KDT_EXE) + " render --session " + (dir / "plain.png").string() +
                      " --quiet -o " + again,
                  dir / "plain.txt", &log),
              0);
    EXPECT_NE(log.find("plain.png: no kdtrace:params text in this PNG image"), std::string::npos)
        << log;
}

// An adaptive render's stop.spp is a sample budget that no pass draws past, the viewer's first
// pass (which samples every pixel) included: --spp-per-pass 64 after `set stop.spp 1` drew
// 64 spp. Non-adaptive passes were already capped per pixel.
TEST(ViewerE2E, AdaptivePassesKeepToTheStopSpp) {
    const auto dir = test::temp_dir("view_spp_budget");
    struct Case {
        std::string flags, script_spp;
        const char* spp;
    };
    for (const Case& c : {Case{"--spp-per-pass 64", "1", "1.000000"},
                          Case{"--spp 16 --spp-per-pass 12", "", "16.000000"}}) {
        const std::string exr = (dir / "view.exr").string();
        const std::string set = c.script_spp.empty() ? "" : "set stop.spp " + c.script_spp + "; ";
        std::string log;
        ASSERT_EQ(run(xvfb() + KDT_EXE + " view --width 48 --height 32 --no-cache --adaptive " +
                          c.flags + " --script '" + set + "wait_done; save " + exr + "' --frames 1",
                      dir / "view.txt", &log),
                  0)
            << log;
        std::string spp;
        for (const auto& [key, value] : read_image_info(exr).metadata) {
            if (key == "kdtrace:spp") spp = value;
        }
        EXPECT_EQ(spp, c.spp) << c.flags << " " << set;
    }
}

// The split view end to end: side B with its own tree, the divider moved, the normals and
// radiance views drawn with no GL error (check_gl fails the script, and the run, on one).
TEST(ViewerE2E, SplitViewDrawsBothSidesWithNoGlError) {
    const auto dir = test::temp_dir("view_split");
    const std::string normals = (dir / "normals.png").string(),
                      after = (dir / "after.png").string();
    const std::string script =
        "split on; split.set tree.n0 2; wait_split; divider 0.3; check_gl;"
        " mode normals; wait_passes 1; wait 2; check_gl; screenshot " +
        normals + "; mode radiance; wait_passes 1; check_gl; stats end";
    std::string log;
    const int rc = run(xvfb() + KDT_EXE + " view --width 160 --height 120 --no-cache --script '" +
                           script + "' --frames 2 --screenshot " + after,
                       dir / "log.txt", &log);
    ASSERT_EQ(rc, 0) << log;
    EXPECT_EQ(log.find("GL error"), std::string::npos) << log;
    EXPECT_NE(log.find("view split end: A "), std::string::npos) << log;  // both sides' speed
    const ImageRGB n = load_image(normals), a = load_image(after);
    ASSERT_EQ(n.width, 160 + 380);
    // The image is 160 x 120 at (0, (height - 120) / 2); the divider at 30 % is column 48.
    const int y0 = (n.height - 120) / 2 + 20;
    auto px = [](const ImageRGB& img, int x, int y) {
        const size_t i = (size_t(y) * size_t(img.width) + size_t(x)) * 3;
        return Vec3f(img.rgb[i], img.rgb[i + 1], img.rgb[i + 2]);
    };
    for (const ImageRGB* img : {&n, &a}) {
        const Vec3f line = px(*img, 47, y0);
        EXPECT_GT(std::min({line.x, line.y, line.z}), 0.7f);  // the light divider
    }
    // The normals view on both sides of the divider: colours of several hues (n * 0.5 + 0.5
    // of differently turned surfaces), not the radiance's greys and browns alone.
    int coloured_left = 0, coloured_right = 0;
    for (int y = y0; y < y0 + 60; ++y) {
        for (int x = 2; x < 158; ++x) {
            if (x >= 45 && x <= 50) continue;
            const Vec3f c = px(n, x, y);
            const bool coloured = std::max({c.x, c.y, c.z}) - std::min({c.x, c.y, c.z}) > 0.2f;
            (x < 47 ? coloured_left : coloured_right) += coloured;
        }
    }
    EXPECT_GT(coloured_left, 100);
    EXPECT_GT(coloured_right, 100);
    EXPECT_GT(mean_difference(n, a, 0, 160), 0.02);  // radiance looks otherwise
}

// ---- Opening files while the viewer runs (ui/viewer_files.cpp, ui/scene_loader.*)

// An ASCII PLY of an axis-aligned cube of half-size 1 (12 triangles).
std::string write_cube_ply(const std::filesystem::path& dir) {
    const std::string path = (dir / "cube.ply").string();
    std::ofstream f(path);
    f << "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\n"
         "property float z\nelement face 12\nproperty list uchar int vertex_indices\n"
         "end_header\n";
    for (int i = 0; i < 8; ++i)
        f << (i & 1 ? 1 : -1) << ' ' << (i & 2 ? 1 : -1) << ' ' << (i & 4 ? 1 : -1) << '\n';
    const int quads[6][4] = {{0, 1, 3, 2}, {4, 6, 7, 5}, {0, 4, 5, 1},
                             {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 5, 7, 3}};
    for (const auto& q : quads) {
        f << "3 " << q[0] << ' ' << q[1] << ' ' << q[2] << '\n';
        f << "3 " << q[0] << ' ' << q[2] << ' ' << q[3] << '\n';
    }
    return path;
}

// Pixels of the whole window within 40 sRGB codes of the loading bar's colour
// (0.1, 0.85, 0.95 in ui/viewer_files.cpp), which no other widget uses.
int progress_pixels(const ImageRGB& img) {
    int n = 0;
    for (size_t i = 0; i + 2 < img.rgb.size(); i += 3) {
        const int r = tonemap_to_srgb8(img.rgb[i], ToneParams{});
        const int g = tonemap_to_srgb8(img.rgb[i + 1], ToneParams{});
        const int b = tonemap_to_srgb8(img.rgb[i + 2], ToneParams{});
        n += std::abs(r - 26) < 40 && std::abs(g - 217) < 40 && std::abs(b - 242) < 40;
    }
    return n;
}

// Mean linear colour of the rectangle [x0, x1) x [y0, y1).
Vec3f mean_color(const ImageRGB& img, int x0, int x1, int y0, int y1) {
    Vec3f sum(0.0f);
    for (int y = y0; y < y1; ++y) {
        for (int x = x0; x < x1; ++x) {
            const size_t i = (size_t(y) * size_t(img.width) + size_t(x)) * 3;
            sum += Vec3f(img.rgb[i], img.rgb[i + 1], img.rgb[i + 2]);
        }
    }
    return sum / float(std::max((x1 - x0) * (y1 - y0), 1));
}

TEST(ViewerE2E, OpenModelShowsProgressThenTheModel) {
    const auto dir = test::temp_dir("view_open_model");
    const std::string cube = write_cube_ply(dir);
    const std::string a = (dir / "a.png").string(), p = (dir / "p.png").string(),
                      b = (dir / "b.png").string();
    const std::string script = "wait_passes 1; screenshot " + a + "; open " + cube +
                               "; screenshot " + p + "; wait_loaded; wait_passes 1; screenshot " +
                               b;
    std::string log;
    const int rc = run(xvfb() + KDT_EXE + " view --width 320 --height 240 --no-cache --script '" +
                           script + "' --frames 2",
                       dir / "log.txt", &log);
    ASSERT_EQ(rc, 0) << log;
    EXPECT_NE(log.find("view: loaded the default scene"), std::string::npos) << log;
    EXPECT_NE(log.find("view: loaded " + cube + ": 12 triangles"), std::string::npos) << log;
    const ImageRGB ia = load_image(a), ip = load_image(p), ib = load_image(b);
    // The progress bar is in the window in the frame of the request only.
    EXPECT_EQ(progress_pixels(ia), 0);
    EXPECT_GT(progress_pixels(ip), 100);
    EXPECT_EQ(progress_pixels(ib), 0);
    // The cube replaced the default scene's sphere and ground.
    EXPECT_GT(mean_difference(ia, ib, 0, 320), 0.02);
}

TEST(ViewerE2E, FileErrorsShowInTheWindowAndTheViewerKeepsRunning) {
    const auto dir = test::temp_dir("view_open_errors");
    const std::string missing = (dir / "missing.ply").string(), bad = (dir / "bad.ply").string(),
                      probe = (dir / "bad.hdr").string(), shot = (dir / "s.png").string();
    std::ofstream(bad) << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                          "property float y\nproperty float z\nend_header\n0 0 0\n";
    std::ofstream(probe) << "not a probe\n";
    const std::string script = "open " + missing + "; wait_loaded; message; open " + bad +
                               "; wait_loaded; message; open " + probe +
                               "; wait_loaded; message; wait_passes 1; screenshot " + shot;
    std::string log;
    const int rc = run(xvfb() + KDT_EXE + " view --width 160 --height 120 --no-cache --script '" +
                           script + "' --frames 2",
                       dir / "log.txt", &log);
    ASSERT_EQ(rc, 0) << log;
    EXPECT_NE(log.find("view message: " + missing + ": cannot open"), std::string::npos) << log;
    EXPECT_NE(log.find("view message: " + bad + ": "), std::string::npos) << log;
    EXPECT_NE(log.find("view message: " + probe + ": "), std::string::npos) << log;
    EXPECT_NE(log.find("view: "), std::string::npos) << log;  // the summary: it ran to the end
    // The last error is in the window: red text (1, 0.4, 0.3) in the File panel.
    const ImageRGB img = load_image(shot);
    int red = 0;
    for (size_t i = 0; i + 2 < img.rgb.size(); i += 3) {
        red += tonemap_to_srgb8(img.rgb[i], ToneParams{}) > 200 &&
               tonemap_to_srgb8(img.rgb[i + 1], ToneParams{}) < 140 &&
               tonemap_to_srgb8(img.rgb[i + 2], ToneParams{}) < 120;
    }
    EXPECT_GT(red, 50);
}

TEST(ViewerE2E, ScriptErrorsQuoteTheCommandAsTypedAndSavesNeverReplaceTheModel) {
    const auto dir = test::temp_dir("view_script_errors");
    std::string log;
    int rc = run(xvfb() + KDT_EXE +
                     " view --width 64 --height 48 --script 'set tree.max_depth 65' --frames 2",
                 dir / "log.txt", &log);
    EXPECT_NE(rc, 0) << log;
    EXPECT_NE(log.find("view --script: 'set tree.max_depth 65': tree.max_depth (--depth) must "
                       "be in [0, 64] (got 65)"),
              std::string::npos)
        << log;
    // A session saved over the model being viewed is refused; the model stays.
    const std::string model = (dir / "tri.ply").string();
    std::ofstream(model) << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                            "property float y\nproperty float z\nelement face 1\n"
                            "property list uchar int vertex_indices\nend_header\n"
                            "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    rc = run(xvfb() + KDT_EXE + " view " + model + " --width 64 --height 48 --no-cache " +
                 "--script 'save_session " + model + "' --frames 2",
             dir / "log2.txt", &log);
    EXPECT_NE(rc, 0) << log;
    EXPECT_NE(log.find("cannot write the session file: it is the input " + model),
              std::string::npos)
        << log;
    std::ifstream f(model);
    std::string first;
    std::getline(f, first);
    EXPECT_EQ(first, "ply");
}

TEST(ViewerE2E, MaterialChangeAndProbeSwapChangeTheImage) {
    const auto dir = test::temp_dir("view_probe_material");
    ImageRGB red_sky(16, 8);
    for (size_t i = 0; i < red_sky.rgb.size(); ++i) red_sky.rgb[i] = i % 3 == 0 ? 3.0f : 0.05f;
    const std::string probe = (dir / "red.pfm").string();
    write_image(probe, red_sky);
    const std::string a = (dir / "a.png").string(), b = (dir / "b.png").string(),
                      c = (dir / "c.png").string();
    const std::string script = "wait_passes 2; screenshot " + a +
                               "; set material.albedo 0.05,0.9,0.05; wait_passes 2; screenshot " +
                               b + "; open " + probe + "; wait_loaded; wait_passes 2; screenshot " +
                               c + "; message";
    std::string log;
    const int rc = run(xvfb() + KDT_EXE + " view --width 320 --height 240 --no-cache --script '" +
                           script + "' --frames 2",
                       dir / "log.txt", &log);
    ASSERT_EQ(rc, 0) << log;
    EXPECT_NE(log.find("view message: \n"), std::string::npos) << log;  // no error
    // The image rectangle: 320 x 240, centred in the 720 rows of the window.
    const Vec3f ma = mean_color(load_image(a), 0, 320, 240, 480);
    const Vec3f mb = mean_color(load_image(b), 0, 320, 240, 480);
    const Vec3f mc = mean_color(load_image(c), 0, 320, 240, 480);
    // A green model under the default sky; then everything under a red sky.
    EXPECT_GT(mb.y - mb.x, ma.y - ma.x + 0.02f)
        << ma.x << ' ' << ma.y << ' ' << mb.x << ' ' << mb.y;
    EXPECT_GT(mc.x - mc.y, mb.x - mb.y + 0.05f)
        << mb.x << ' ' << mb.y << ' ' << mc.x << ' ' << mc.y;
}

}  // namespace
}  // namespace kdt
