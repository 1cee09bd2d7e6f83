// Reproduces the thesis's table 1 (section 6.1) on the Stanford dragon: trees for q in
// {0.90, 0.95, 0.98, 1.00} and without median / center splits (n0 = 5, depth 20), primary
// rays from four views, split counts and sizes. A report, not a pass/fail test: disabled by
// default, run with
//   build/tests/kdt_accel_tests --gtest_also_run_disabled_tests
//       --gtest_filter='*DISABLED_ThesisTableOnDragon*'  (one line)
// Set KDT_REPORT_DEPTH to use another depth limit (0 = automatic).
#include <time.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/accel/kdtree.h"
#include "renderer/io/mesh_io.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

// CPU time of this thread: stable on a shared, loaded machine, unlike wall-clock time.
double thread_seconds() {
    timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

struct View {
    const char* name;
    Vec3f dir;  // from the target to the eye
};

TEST(ThesisReport, DISABLED_ThesisTableOnDragon) {
    const auto dir = test::dragon_dir();
    if (dir.empty()) GTEST_SKIP() << "Stanford dragon not fetched (scripts/fetch_assets.sh)";
    auto mesh = std::make_shared<TriangleMesh>(load_mesh((dir / "dragon_vrip.ply").string()));
    const int depth =
        std::getenv("KDT_REPORT_DEPTH") ? std::atoi(std::getenv("KDT_REPORT_DEPTH")) : 20;
    struct Row {
        const char* note;
        float q;
        bool median, center;
    };
    const Row rows[] = {
        {"no median split", 0.98f, false, true}, {"no center split", 0.98f, true, false},
        {"q = 0.90", 0.90f, true, true},         {"q = 0.95", 0.95f, true, true},
        {"q = 0.98", 0.98f, true, true},         {"q = 1.00", 1.00f, true, true}};
    const View views[] = {{"A", Vec3f(0.0f, 0.1f, 1.0f)},
                          {"B", Vec3f(1.0f, 0.2f, 0.3f)},
                          {"C", Vec3f(-0.6f, 0.3f, -1.0f)},
                          {"D", Vec3f(0.2f, 1.0f, 0.4f)}};
    const int width = 640, height = 480, reps = 5;
    std::printf(
        "dragon %zu triangles, n0 = 5, max depth %d, %dx%d primary rays per view, "
        "median of %d runs, CPU time of 1 thread\n",
        mesh->triangle_count(), depth, width, height, reps);
    std::printf("%-16s %5s %8s %7s | %7s %7s %7s %7s | %9s %9s | %7s %7s %7s\n", "row", "q", "KB",
                "build", "A [ms]", "B [ms]", "C [ms]", "D [ms]", "nodes/ray", "tris/ray", "median",
                "center", "cutoff");
    for (const Row& row : rows) {
        KdTreeParams p;
        p.builder = KdBuilder::thesis;
        p.q = row.q;
        p.n0 = 5;
        p.max_depth = depth;
        p.use_median_split = row.median;
        p.use_center_split = row.center;
        auto tree = build_kdtree(mesh, p);
        const KdTreeStats& s = tree->stats();
        const Bounds3f b = tree->bounds();
        const float size = glm::length(b.extent());
        double ms[4];
        TraversalCounters counters;
        uint64_t rays = 0;
        for (int v = 0; v < 4; ++v) {
            const Vec3f eye = b.center() + glm::normalize(views[v].dir) * (1.1f * size);
            const Vec3f fwd = glm::normalize(b.center() - eye);
            const Vec3f right = glm::normalize(glm::cross(fwd, Vec3f(0.0f, 1.0f, 0.0f)));
            const Vec3f up = glm::cross(right, fwd);
            const float tan_half = std::tan(0.5f * 40.0f * kPi / 180.0f);
            std::vector<Ray> primary(size_t(width) * height);
            for (int y = 0; y < height; ++y)
                for (int x = 0; x < width; ++x) {
                    Ray& r = primary[size_t(y) * width + x];
                    r.origin = eye;
                    const float px =
                        (2.0f * (float(x) + 0.5f) / width - 1.0f) * tan_half * width / height;
                    const float py = (1.0f - 2.0f * (float(y) + 0.5f) / height) * tan_half;
                    r.dir = glm::normalize(fwd + px * right + py * up);
                }
            std::vector<double> t;
            for (int rep = 0; rep < reps; ++rep) {
                const double start = thread_seconds();
                Hit hit;
                for (const Ray& r : primary) tree->intersect(r, hit);
                t.push_back((thread_seconds() - start) * 1e3);
            }
            std::sort(t.begin(), t.end());
            ms[v] = t[t.size() / 2];
            Hit hit;
            for (const Ray& r : primary) tree->intersect(r, hit, &counters);
            rays += primary.size();
        }
        std::printf(
            "%-16s %5.2f %8.0f %7.3f | %7.1f %7.1f %7.1f %7.1f | %9.2f %9.2f | %7lu %7lu "
            "%7lu\n",
            row.note, row.q, double(s.bytes) / 1024.0, s.build_seconds, ms[0], ms[1], ms[2], ms[3],
            double(counters.nodes_visited) / double(rays),
            double(counters.triangles_tested) / double(rays), (unsigned long)s.median_splits,
            (unsigned long)s.center_splits, (unsigned long)s.cutoff_splits);
        std::fflush(stdout);
    }
}

}  // namespace
}  // namespace kdt
