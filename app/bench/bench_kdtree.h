// `kdtrace bench kdtree`, shared by its files: the options, the loaded model and its ray
// sets, the rows of table 6.1 and the engines compared, and one function per printed table.
// bench_kdtree.cpp parses the flags, loads and writes; bench_kdtree_rows.cpp times table 6.1;
// bench_kdtree_engines.cpp the best tree against Embree; bench_kdtree_work.cpp the work per
// ray; bench_kdtree_robustness.cpp the aimed and NaN/Inf rays. Depends on app/bench, renderer.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "app/bench/bench_table.h"
#include "app/bench/peer_embree.h"
#include "renderer/accel/kdtree.h"
#include "renderer/core/math.h"
#include "renderer/geometry/mesh.h"
#include "renderer/scene/views.h"

namespace kdt::app::kdtree_bench {

struct Options {
    std::string model, views, csv, md, save_views, rows = "1,2,3,4,5,6,7,sah";
    int repeat = 5;
    int threads = 0;
    int subdivide = 0;
    int spp = 0;    // 0 = the views file's
    int depth = 0;  // 0 = the thesis's 20
    int n0 = -1;    // -1 = the thesis's 5
    // SAH row: 0 (costs) or < 0 (bonus) keeps KdTreeParams' default.
    float sah_traversal_cost = 0.0f, sah_intersect_cost = 0.0f, sah_empty_bonus = -1.0f;
    int sah_depth = 0;                         // 0 = automatic
    std::string leaf_vertex_indices = "auto";  // auto | on | off, for every row
    bool embree = true;
    bool embree_robust = false;
    bool use_cache = false;
    bool robustness = true;
    int robust_rays = 100000;
    std::string stream_lanes = "16";  // lane counts of the stream engines; "" = none
    // min_rays of the partition engines (traversal_partition.h) on tile batches; "" = none
    std::string partition_min_rays = "4";
    bool cpu_time = false;  // time tracing by CPU seconds (bench_rays.h BenchClock)
};

/// The --save-views picture of view `name` in directory `dir`.
inline std::string save_view_path(const std::string& dir, const std::string& name) {
    return dir + "/view_" + name + ".pgm";
}

/// One configuration of table 6.1.
struct Config {
    std::string id, remark;
    KdTreeParams params;
};

/// The rows named in `rows` ("1,2,sah"), in that order; throws Error naming --rows when a
/// name is unknown or none is given.
std::vector<Config> select_rows(const std::string& rows);

/// What every table reads: the options with their defaults resolved, the views, the rows
/// asked for and the model (normals and colours dropped, in the renderer's spatial order).
struct Context {
    Options opt;
    int threads = 1, repeat = 1;
    std::string model, model_key, views_path;
    ViewSet views;
    std::vector<Config> configs;
    std::shared_ptr<const TriangleMesh> mesh;
    double triangles = 0.0;
};

/// The rays of one view and the reference hits (first configuration traced).
struct ViewRays {
    std::string name;
    std::vector<Ray> rays;
    std::vector<Hit> reference;
    uint64_t hits = 0;
};

/// The ray sets: each view's rays, all primary rays in one array, and one-bounce diffuse
/// rays from the reference hits (diffuse_sources[i]: the index in `primary` of the ray
/// diffuse ray i leaves from).
struct RaySets {
    std::vector<ViewRays> views;
    std::vector<Ray> primary, diffuse;
    std::vector<uint32_t> diffuse_sources;
    std::vector<Hit> diffuse_reference;
};

/// Closest hits agree when hit/miss agree and t agrees to 1e-5 relative (the triangle may
/// differ where two triangles meet at the hit point).
bool same_hit(const Hit& a, const Hit& b);
uint64_t count_disagreements(const std::vector<Hit>& a, const std::vector<Hit>& b);

/// Sizes counted from the arrays themselves (a cache file's statistics are informational:
/// its loader bounds them but does not recount them).
struct TreeSize {
    uint64_t nodes = 0, leaves = 0, refs = 0, bytes = 0;
};
TreeSize tree_size(const KdTree& tree);

/// Mean traversal work of one ray set, from the compiled-in counters; NaN for no rays.
struct WorkPerRay {
    double nodes = 0.0, tests = 0.0;
};

struct RowResult {
    Config config;
    std::shared_ptr<const KdTree> tree;
    double build_seconds = 0.0;
    double rss_build_mb = 0.0;
    std::vector<double> view_seconds;
    double mrays = 0.0, diffuse_mrays = 0.0;  ///< NaN for no rays (mega_rate)
    uint64_t disagreements = 0, diffuse_disagreements = 0;
    WorkPerRay primary_work, diffuse_work;
};

// ---- table 6.1 (bench_kdtree_rows.cpp) ----

/// Each view's primary rays (no hits yet).
std::vector<ViewRays> make_view_rays(const Context& ctx);
/// Builds every row's tree (--repeat times, the median time kept, unless --use-cache).
std::vector<RowResult> build_rows(const Context& ctx);
/// Traces the reference hits with `tree`, writes the --save-views pictures, and fills
/// rays.primary, rays.diffuse, rays.diffuse_sources and rays.diffuse_reference.
void trace_references(const Context& ctx, const KdTree& tree, RaySets& rays);
/// Times every row on every view and on the diffuse rays (rows interleaved within each
/// repeat), counts hit disagreements against the reference and the work per ray.
void time_rows(const Context& ctx, const RaySets& rays, std::vector<RowResult>& rows);
Table table_6_1(const Context& ctx, const std::vector<RowResult>& rows);

// ---- the best tree against Embree (bench_kdtree_engines.cpp, the work table in
// bench_kdtree_work.cpp) ----

/// One engine of the comparison: our tree (single rays, batches, or from the hit's leaf)
/// or an Embree scene (single rays or rtcIntersect1M streams), with its timings and hits.
struct Engine {
    std::string name;
    const KdTree* tree = nullptr;
#ifdef KDT_HAVE_EMBREE
    const EmbreePeer* peer = nullptr;
#endif
    bool batch = false;  ///< batch queries (ours) / rtcIntersect1M streams (Embree)
    /// Ours, with paths: primary rays record the path to their hit's leaf, and each
    /// diffuse ray starts from the path of the primary hit it leaves from.
    bool from_leaf = false;
    /// Ours, stream queries (traversal_stream.h) with this many lanes; 0 = not a stream.
    int stream_lanes = 0;
    /// Ours, partition queries (traversal_partition.h) with this min_rays; 0 = not one.
    int partition_min_rays = 0;
    /// Diffuse and shadow rays in the renderer's batches (TileBatches): streams and
    /// partitions query one batch at a time, single rays go in the batches' order.
    bool tiled = false;
    double build_seconds = 0.0, bytes_per_triangle = 0.0, peak_mb = 0.0;
    std::vector<double> primary_s, diffuse_s, shadow_s;
    std::vector<Hit> primary_hits, diffuse_hits;
    uint64_t diffuse_occluded = 0;
};

/// The engines and the Embree scenes they point to. engines[0..2] are ours: single rays,
/// batch, from the hit's leaf; then ours as streams, one per --stream-lanes count.
struct EngineSet {
    std::vector<Engine> engines;
#ifdef KDT_HAVE_EMBREE
    std::vector<std::unique_ptr<EmbreePeer>> peers;
#endif
};

/// The path of each diffuse ray's primary hit in our tree, as a path tracer keeps it from
/// one bounce to the next: nodes[first[i], first[i + 1]) for diffuse ray i.
struct LeafPaths {
    const Ray* diffuse = nullptr;  ///< the diffuse rays the paths belong to
    std::vector<uint32_t> nodes;
    std::vector<uint64_t> first;

    /// The start path of `r`, which must be an element of the diffuse rays.
    std::pair<const uint32_t*, uint32_t> start_of(const Ray& r) const {
        const size_t i = size_t(&r - diffuse);
        return {nodes.data() + first[i], uint32_t(first[i + 1] - first[i])};
    }
};

/// The diffuse rays regrouped as the renderer's wavefront hands them over: by the 16x16-pixel
/// tile of the primary ray they leave from (every sample of the tile), at most kMaxRays per
/// batch. rays[first[k], first[k + 1]) is batch k; rays[j] is diffuse ray index[j].
struct TileBatches {
    static constexpr size_t kTile = 16, kMaxRays = 4096;
    std::vector<Ray> rays;
    std::vector<uint32_t> index;
    std::vector<size_t> first;
};

/// Groups rays.diffuse by rays.diffuse_sources (call before make_leaf_paths()).
TileBatches make_tile_batches(const Context& ctx, const RaySets& rays);

/// The min_rays of "--partition-min-rays 8,16"; throws Error naming the flag on a value
/// that is not a whole number in [1, 1000000].
std::vector<int> partition_min_rays(const std::string& list);

/// The lane counts of "--stream-lanes 4,8,16"; throws Error naming the flag on a count
/// that is not one of kStreamLaneChoices.
std::vector<int> stream_lane_counts(const std::string& list);
/// The row with the highest primary Mrays/s (the first on a tie).
const RowResult& best_row(const std::vector<RowResult>& rows);
/// Our three engines over `best`'s tree, then Embree's unless --no-embree (its scenes built
/// --repeat times, the median time kept).
EngineSet make_engines(const Context& ctx, const RowResult& best);
/// Leaf paths in `tree` of the primary hits the diffuse rays leave from; frees
/// rays.diffuse_sources.
LeafPaths make_leaf_paths(const KdTree& tree, RaySets& rays);
/// Times every engine on the primary, diffuse and diffuse any-hit rays (engines
/// interleaved within each repeat), keeping each engine's hits.
void time_engines(const Context& ctx, const RaySets& rays, const LeafPaths& paths,
                  const TileBatches& tiles, std::vector<Engine>& engines);
Table embree_table(const Context& ctx, const RowResult& best, const RaySets& rays,
                   const std::vector<Engine>& engines);
/// Work per ray of the best tree from its traversal counters, with the ray anatomy
/// (first descent, first leaf, leaves, empty children skipped); times from engines[0..2].
Table work_table(const Context& ctx, const RowResult& best, const RaySets& rays,
                 const LeafPaths& paths, const std::vector<Engine>& engines);

/// Calls body(intersect, occluded) with the engine's queries as concrete (inlinable)
/// lambdas: no std::function between the timing loop and either engine.
template <class Body>
void with_queries(const Engine& e, const Body& body) {
#ifdef KDT_HAVE_EMBREE
    if (e.peer) {
        const EmbreePeer* p = e.peer;
        body([p](const Ray& r, Hit& h) { p->intersect(r, h); },
             [p](const Ray& r) { return p->occluded(r); });
        return;
    }
#endif
    const KdTree* t = e.tree;
    body([t](const Ray& r, Hit& h) { t->intersect(r, h); },
         [t](const Ray& r) { return t->occluded(r); });
}

/// Batch queries: body(coherent closest, incoherent closest, incoherent any-hit), each
/// called once per chunk of rays.
template <class Body>
void with_batch_queries(const Engine& e, const Body& body) {
#ifdef KDT_HAVE_EMBREE
    if (e.peer) {
        const EmbreePeer* p = e.peer;
        body([p](const Ray* r, size_t n, Hit* h) { p->intersect(r, n, h, true); },
             [p](const Ray* r, size_t n, Hit* h) { p->intersect(r, n, h, false); },
             [p](const Ray* r, size_t n, uint8_t* o) { p->occluded(r, n, o, false); });
        return;
    }
#endif
    const KdTree* t = e.tree;
    auto isect = [t](const Ray* r, size_t n, Hit* h) { t->intersect(r, n, h); };
    body(isect, isect, [t](const Ray* r, size_t n, uint8_t* o) { t->occluded(r, n, o); });
}

// ---- robustness (bench_kdtree_robustness.cpp) ----

/// Vertex- and edge-aimed rays and NaN/Inf rays (against the first primary rays) on every
/// engine except from-the-hit's-leaf.
Table robustness_table(const Context& ctx, const std::vector<Ray>& primary,
                       const std::vector<Engine>& engines);

}  // namespace kdt::app::kdtree_bench
