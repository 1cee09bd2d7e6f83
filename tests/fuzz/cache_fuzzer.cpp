// libFuzzer target for the kd-tree cache loader: any input must load or throw a kdt::Error
// naming the file, never crash, leak, hang or trip a sanitizer; and a tree that loads must be
// safe to trace (closest-hit and any-hit, single rays and 8-ray packets). The first byte is
// the mode (tests/fuzz/fuzz_inputs.h): most inputs are resealed so that the structure checks
// behind the checksums see the mutations. Built by tests/fuzz/tests.cmake.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <vector>

#include "renderer/accel/kdtree_cache.h"
#include "renderer/core/error.h"
#include "tests/fuzz/fuzz_inputs.h"

namespace {

constexpr char kPath[] = "fuzz.kdt";

void check_hit(const kdt::KdTree& tree, const kdt::Ray& ray, const kdt::Hit& hit) {
    if (!hit.valid()) return;
    if (hit.prim >= tree.mesh().triangle_count()) __builtin_trap();
    if (!(hit.t >= ray.tmin && hit.t <= ray.tmax)) __builtin_trap();
}

// Rays through the mesh from all sides, axis-aligned ones lying in split planes of the
// loaded tree (the traversal's NaN case), and a coherent packet of 8.
void trace(const kdt::KdTree& tree) {
    std::vector<kdt::Ray> rays;
    const kdt::Vec3f centre(2.0f, 2.0f, 0.5f);
    for (int i = 0; i < 14; ++i) {
        kdt::Ray r;
        const float a = 0.45f * float(i), b = 0.3f * float(i) - 2.0f;
        r.origin = centre + 8.0f * kdt::Vec3f(std::cos(a) * std::cos(b), std::sin(a) * std::cos(b),
                                              std::sin(b));
        r.dir = centre + kdt::Vec3f(0.3f * float(i % 3), -0.2f * float(i % 5), 0.1f) - r.origin;
        r.tmax = i % 4 == 0 ? 0.5f : kdt::kInfinity;
        rays.push_back(r);
    }
    const auto& nodes = tree.nodes();
    for (size_t i = 0; i < nodes.size() && i < 8; ++i) {
        if (nodes[i].is_leaf()) continue;
        kdt::Ray r;
        r.origin = centre;
        r.origin[nodes[i].axis()] = nodes[i].split;
        const int along = (nodes[i].axis() + 1 + int(i % 2)) % 3;
        r.origin[along] = -5.0f;
        r.dir = kdt::Vec3f(0.0f);
        r.dir[along] = 1.0f;
        rays.push_back(r);
    }
    for (int i = 0; i < 8; ++i) {
        kdt::Ray r;
        r.origin = kdt::Vec3f(2.0f, 2.0f, 6.0f);
        r.dir = kdt::Vec3f(0.05f * float(i % 4) - 0.1f, 0.05f * float(i / 4) - 0.05f, -1.0f);
        rays.push_back(r);
    }
    for (const kdt::Ray& r : rays) {
        kdt::Hit hit;
        kdt::TraversalCounters counters;
        tree.intersect(r, hit, &counters);
        check_hit(tree, r, hit);
        // A finite tree visits each node at most once per ray.
        if (counters.nodes_visited > tree.nodes().size()) __builtin_trap();
        (void)tree.occluded(r);
    }
    std::vector<kdt::Hit> hits(rays.size());
    std::vector<uint8_t> occluded(rays.size());
    const size_t packet = rays.size() - 8;
    tree.intersect(rays.data() + packet, 8, hits.data() + packet);
    tree.occluded(rays.data() + packet, 8, occluded.data() + packet);
    for (size_t i = packet; i < rays.size(); ++i) check_hit(tree, rays[i], hits[i]);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    static const std::shared_ptr<const kdt::TriangleMesh> mesh = kdt::fuzz::cache_mesh();
    if (size == 0) return 0;
    const uint8_t mode = data[0];
    std::vector<unsigned char> image(data + 1, data + size);
    if (kdt::fuzz::cache_mode_reseal(mode)) {
        try {
            kdt::reseal_kdtree_cache_image(image);
        } catch (const kdt::Error&) {
            // Shorter than a header: load it as it is.
        }
    }
    try {
        auto tree = kdt::load_kdtree_memory(image.data(), image.size(), kPath, mesh,
                                            kdt::fuzz::cache_params(mode));
        trace(*tree);
    } catch (const kdt::Error& e) {
        // Every error must name the file.
        if (std::strncmp(e.what(), "fuzz.kdt: ", 10) != 0) {
            std::fprintf(stderr, "error without the file name: %s\n", e.what());
            __builtin_trap();
        }
    }
    return 0;
}
