// Films that merge and tiles that travel as plain buffers: a render split over sessions and
// merged, or shipped tile by tile, is bit for bit the render of one session.
#include <cstring>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/core/sampler.h"
#include "renderer/film/film.h"
#include "renderer/render/session.h"
#include "tests/renderer/integrator/test_scenes.h"

namespace kdt {
namespace {

std::shared_ptr<const RenderSnapshot> snapshot(int w, int h) {
    const TraceScene scene = test::make_scene(
        {{test::make_icosphere({0, 0.5f, 0}, 0.5f, 2), test::smooth(test::diffuse(0.7f))},
         {test::make_box({-1, -1, -1}, {1, 0, 1}), test::flat(test::diffuse(0.5f))}},
        std::make_shared<test::GradientEnv>());
    return compile_snapshot(scene, make_camera({2, 2, 3}, {0, 0, 0}, {0, 1, 0}, 40.0f, w, h));
}

// Every accumulator of every pixel, as bytes.
std::vector<FilmPixel> all_pixels(const Film& f) {
    return f.export_tile(FilmRect{0, 0, f.width(), f.height()});
}

bool same_bytes(const std::vector<FilmPixel>& a, const std::vector<FilmPixel>& b) {
    return a.size() == b.size() &&
           std::memcmp(a.data(), b.data(), a.size() * sizeof(FilmPixel)) == 0;
}

TEST(FilmMerge, MergedFilmsOfATileSplitEqualTheWholeFilmBitwise) {
    // 37x21 leaves partial tiles at the right and bottom edges.
    auto snap = snapshot(37, 21);
    TraceParams tp;
    tp.samples_per_pass = 3;
    tp.seed = 7;
    RenderSession whole(snap, tp, FilmParams{}), a(snap, tp, FilmParams{}),
        b(snap, tp, FilmParams{});
    std::vector<int> tiles_a, tiles_b;
    for (int t = 0; t < whole.tile_count(); ++t) (t % 3 == 1 ? tiles_a : tiles_b).push_back(t);
    for (int pass = 0; pass < 2; ++pass) {
        whole.render_pass();
        a.render_pass(tiles_a);
        b.render_pass(tiles_b);
    }
    Film merged(37, 21);
    merged.merge(a.film());
    merged.merge(b.film());
    EXPECT_TRUE(same_bytes(all_pixels(merged), all_pixels(whole.film())));
    EXPECT_EQ(merged.total_samples(), 37u * 21u * 6u);
    // Not trivially equal: each half alone misses samples.
    EXPECT_FALSE(same_bytes(all_pixels(a.film()), all_pixels(whole.film())));
    EXPECT_LT(a.film().total_samples(), merged.total_samples());
}

TEST(FilmMerge, MergeAddsSumsCountsAndMoments) {
    Film f(2, 1), g(2, 1);
    f.add_sample(0, 0, Vec3f(1.0f, 2.0f, 3.0f));
    g.add_sample(0, 0, Vec3f(3.0f, 2.0f, 1.0f));
    g.skip_sample(1, 0);
    f.merge(g);
    EXPECT_EQ(f.count(0, 0), 2u);
    EXPECT_EQ(f.next_sample_index(1, 0), 1u);
    EXPECT_EQ(f.count(1, 0), 0u);
    EXPECT_EQ(f.mean(0, 0), Vec3f(2.0f));
    const FilmPixel p = f.export_tile(FilmRect{0, 0, 1, 1})[0];
    const double l1 = 0.2126 * 1.0 + 0.7152 * 2.0 + 0.0722 * 3.0;
    const double l2 = 0.2126 * 3.0 + 0.7152 * 2.0 + 0.0722 * 1.0;
    EXPECT_DOUBLE_EQ(p.lum, l1 + l2);
    EXPECT_DOUBLE_EQ(p.lum2, l1 * l1 + l2 * l2);
    Film wrong(3, 1);
    try {
        f.merge(wrong);
        FAIL() << "merged films of different sizes";
    } catch (const Error& e) {
        EXPECT_STREQ(e.what(), "film merge: sizes differ (2x1 and 3x1)");
    }
}

TEST(FilmMerge, TilesRoundTripBitwiseThroughPlainBuffers) {
    Film src(23, 17), dst(23, 17);
    Pcg32 rng(3);
    for (int s = 0; s < 5; ++s) {
        for (int y = 0; y < 17; ++y) {
            for (int x = 0; x < 23; ++x) {
                src.add_sample(x, y, Vec3f(rng.next_float(), rng.next_float(), rng.next_float()));
            }
        }
    }
    // Tiles of 8x8 with partial ones at the edges, shipped as raw bytes (as MPI does).
    for (int y0 = 0; y0 < 17; y0 += 8) {
        for (int x0 = 0; x0 < 23; x0 += 8) {
            const FilmRect r{x0, y0, std::min(x0 + 8, 23), std::min(y0 + 8, 17)};
            const std::vector<FilmPixel> tile = src.export_tile(r);
            std::vector<unsigned char> bytes(tile.size() * sizeof(FilmPixel));
            std::memcpy(bytes.data(), tile.data(), bytes.size());
            std::vector<FilmPixel> back(r.pixel_count());
            std::memcpy(back.data(), bytes.data(), bytes.size());
            dst.import_tile(r, back);
        }
    }
    EXPECT_TRUE(same_bytes(all_pixels(src), all_pixels(dst)));
    // Importing with add doubles every sum; replacing again restores the source.
    const FilmRect r{3, 2, 9, 5};
    dst.import_tile(r, src.export_tile(r), true);
    EXPECT_EQ(dst.count(4, 3), 2 * src.count(4, 3));
    EXPECT_EQ(dst.mean(4, 3), src.mean(4, 3));
    dst.import_tile(r, src.export_tile(r));
    EXPECT_TRUE(same_bytes(all_pixels(src), all_pixels(dst)));
}

TEST(FilmMerge, BadTilesAreErrors) {
    Film f(8, 8);
    EXPECT_THROW(f.export_tile(FilmRect{4, 4, 9, 8}), Error);
    EXPECT_THROW(f.export_tile(FilmRect{-1, 0, 2, 2}), Error);
    std::vector<FilmPixel> small(3);
    EXPECT_THROW(f.export_tile(FilmRect{0, 0, 2, 2}, small), Error);
    try {
        f.import_tile(FilmRect{0, 0, 2, 2}, small);
        FAIL() << "imported 3 pixels into a 2x2 tile";
    } catch (const Error& e) {
        EXPECT_STREQ(e.what(), "film import: buffer of 3 pixels for a tile of 4");
    }
    EXPECT_TRUE(f.export_tile(FilmRect{2, 2, 2, 5}).empty());
}

}  // namespace
}  // namespace kdt
