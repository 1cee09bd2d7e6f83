// `kdtrace bench kdtree`: the best tree of table 6.1 against Embree on the same primary and
// one-bounce diffuse rays, same threads: single rays, batches or streams, and (ours) diffuse
// rays that start from the leaf of the hit they leave from.
#include <omp.h>
#include <algorithm>
#include <cstring>
#include <iterator>
#include <memory>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "app/bench/bench_kdtree.h"
#include "app/bench/bench_options.h"
#include "app/bench/bench_rays.h"
#include "renderer/accel/traversal_partition.h"
#include "renderer/accel/traversal_stream.h"
#include "renderer/core/error.h"

namespace kdt::app::kdtree_bench {
namespace {

#ifdef KDT_HAVE_EMBREE
// Embree's scene (built --repeat times, the median build time kept), queried by single rays
// and by rtcIntersect1M streams.
void add_embree_engines(const Context& ctx, bool robust, EngineSet& set) {
    EmbreePeerParams ep;
    ep.threads = ctx.threads;
    ep.robust = robust;
    std::vector<double> builds;
    std::unique_ptr<EmbreePeer> peer;
    for (int k = 0; k < ctx.repeat; ++k) {
        peer.reset();
        peer = std::make_unique<EmbreePeer>(*ctx.mesh, ep);
        builds.push_back(peer->build_seconds());
    }
    const EmbreePeer* p = peer.get();
    Engine e;
    e.name = robust ? "Embree 3 (robust)" : "Embree 3";
    e.peer = p;
    e.build_seconds = median(builds);
    e.bytes_per_triangle = double(p->bvh_bytes()) / ctx.triangles;
    e.peak_mb = double(p->peak_build_bytes()) / (1024.0 * 1024.0);
    set.peers.push_back(std::move(peer));
    Engine stream = e;
    stream.name += robust ? ", rtcIntersect1M" : " rtcIntersect1M";
    stream.batch = true;
    set.engines.push_back(std::move(e));
    set.engines.push_back(std::move(stream));
}
#endif

// Hits that differ from the reference in any bit of t, u, v or the triangle.
uint64_t bitwise_differences(const std::vector<Hit>& a, const std::vector<Hit>& b) {
    uint64_t n = 0;
    for (size_t i = 0; i < a.size(); ++i) n += std::memcmp(&a[i], &b[i], sizeof(Hit)) != 0;
    return n;
}

// Calls batch(begin, count) for every tile batch on `threads` OpenMP threads (as
// time_chunks() does for fixed chunks); returns seconds of bench_clock().
template <class Batch>
double time_tile_batches(const TileBatches& b, int threads, const Batch& batch) {
    const int64_t n = int64_t(b.first.size()) - 1;
    const int nthreads = threads > 0 ? threads : omp_get_max_threads();
    const double cpu0 = process_cpu_seconds();
    Timer timer;
#pragma omp parallel for schedule(dynamic, 1) num_threads(nthreads)
    for (int64_t k = 0; k < n; ++k)
        batch(b.first[size_t(k)], b.first[size_t(k) + 1] - b.first[size_t(k)]);
    if (bench_clock() == BenchClock::cpu) return (process_cpu_seconds() - cpu0) / nthreads;
    return timer.seconds();
}

// Closest hits of the tile batches, put back in the diffuse rays' order.
template <class IntersectBatch>
double trace_tiles_closest(const TileBatches& b, std::vector<Hit>& hits, int threads,
                           const IntersectBatch& intersect) {
    std::vector<Hit> tiled(b.rays.size());
    const double s = time_tile_batches(b, threads, [&](size_t begin, size_t n) {
        intersect(b.rays.data() + begin, n, tiled.data() + begin);
    });
    hits.assign(b.rays.size(), Hit{});
    for (size_t j = 0; j < tiled.size(); ++j) hits[b.index[j]] = tiled[j];
    return s;
}

template <class OccludedBatch>
double trace_tiles_occluded(const TileBatches& b, int threads, const OccludedBatch& occluded,
                            uint64_t* occluded_count) {
    std::vector<uint8_t> flags(b.rays.size(), 0);
    const double s = time_tile_batches(b, threads, [&](size_t begin, size_t n) {
        occluded(b.rays.data() + begin, n, flags.data() + begin);
    });
    uint64_t count = 0;
    for (uint8_t f : flags) count += f;
    *occluded_count = count;
    return s;
}

}  // namespace

TileBatches make_tile_batches(const Context& ctx, const RaySets& rays) {
    // The 16x16 tile of each primary ray of a view, in make_primary_rays()'s order.
    const ViewSet& set = ctx.views;
    const int w = set.width, h = set.height, spp = set.samples_per_pixel;
    const uint32_t tiles_x = uint32_t(w + 15) / 16, tiles = tiles_x * (uint32_t(h + 15) / 16);
    std::vector<uint32_t> tile_of;
    tile_of.reserve(size_t(w) * size_t(h) * size_t(spp));
    for (int ty = 0; ty < h; ty += 8)
        for (int tx = 0; tx < w; tx += 8)
            for (int y = ty; y < std::min(h, ty + 8); ++y)
                for (int x = tx; x < std::min(w, tx + 8); ++x)
                    for (int s = 0; s < spp; ++s)
                        tile_of.push_back(uint32_t(y / 16) * tiles_x + uint32_t(x / 16));
    const size_t per_view = tile_of.size();
    auto key = [&](size_t i) {
        const uint32_t src = rays.diffuse_sources[i];
        return uint32_t(src / per_view) * tiles + tile_of[src % per_view];
    };
    // Counting sort by (view, tile), keeping the rays' order within a tile.
    const uint32_t keys = uint32_t(set.views.size()) * tiles;
    std::vector<size_t> start(keys + 1, 0);
    for (size_t i = 0; i < rays.diffuse.size(); ++i) ++start[key(i) + 1];
    for (uint32_t k = 0; k < keys; ++k) start[k + 1] += start[k];
    TileBatches b;
    b.rays.resize(rays.diffuse.size());
    b.index.resize(rays.diffuse.size());
    std::vector<size_t> fill(start.begin(), start.end() - 1);
    for (size_t i = 0; i < rays.diffuse.size(); ++i) {
        const size_t j = fill[key(i)]++;
        b.rays[j] = rays.diffuse[i];
        b.index[j] = uint32_t(i);
    }
    for (uint32_t k = 0; k < keys; ++k)
        for (size_t f = start[k]; f < start[k + 1]; f += TileBatches::kMaxRays)
            b.first.push_back(f);
    b.first.push_back(rays.diffuse.size());
    return b;
}

std::vector<int> partition_min_rays(const std::string& list) {
    std::vector<int> values;
    std::stringstream ss(list);
    std::string item;
    while (std::getline(ss, item, ',')) {
        const bool digits =
            !item.empty() && item.size() <= 7 &&
            std::all_of(item.begin(), item.end(), [](char c) { return c >= '0' && c <= '9'; });
        const int v = digits ? std::stoi(item) : 0;
        if (v < 1 || v > 1000000) {
            throw Error(ErrorLocation{"--partition-min-rays"},
                        "'" + item + "' is not a whole number from 1 to 1000000");
        }
        values.push_back(v);
    }
    refuse_repeated_entries("--partition-min-rays", values);
    return values;
}

std::vector<int> stream_lane_counts(const std::string& list) {
    std::vector<int> counts;
    std::stringstream ss(list);
    std::string item;
    while (std::getline(ss, item, ',')) {
        const auto& choices = kStreamLaneChoices;
        const bool known = std::any_of(std::begin(choices), std::end(choices),
                                       [&](int c) { return std::to_string(c) == item; });
        if (!known) {
            throw Error(ErrorLocation{"--stream-lanes"},
                        "unknown lane count '" + item + "' (1, 4, 8, 16, 24 or 32)");
        }
        counts.push_back(std::stoi(item));
    }
    refuse_repeated_entries("--stream-lanes", counts);
    return counts;
}

const RowResult& best_row(const std::vector<RowResult>& rows) {
    const RowResult* best = &rows[0];
    for (const RowResult& r : rows) {
        if (r.mrays > best->mrays) best = &r;
    }
    return *best;
}

EngineSet make_engines(const Context& ctx, const RowResult& best) {
    EngineSet set;
    const KdTree& tree = *best.tree;
    Engine ours;
    ours.name = "kdtrace row " + best.config.id + " (" +
                kKdBuilderNames[size_t(best.config.params.builder)] + ")";
    ours.tree = &tree;
    ours.build_seconds = best.build_seconds;
    ours.bytes_per_triangle = double(tree_size(tree).bytes) / ctx.triangles;
    ours.peak_mb = double(tree.stats().peak_build_bytes) / (1024.0 * 1024.0);
    Engine ours_batch = ours;
    ours_batch.name += ", batch";
    ours_batch.batch = true;
    Engine ours_from_leaf = ours;
    ours_from_leaf.name += ", from the hit's leaf";
    ours_from_leaf.from_leaf = true;
    set.engines.push_back(std::move(ours));
    set.engines.push_back(std::move(ours_batch));
    set.engines.push_back(std::move(ours_from_leaf));
    for (int lanes : stream_lane_counts(ctx.opt.stream_lanes)) {
        Engine stream = set.engines[0];
        stream.name += ", stream of " + std::to_string(lanes) + " lanes";
        stream.stream_lanes = lanes;
        set.engines.push_back(std::move(stream));
    }
    // The renderer's batches: streams and partitions per 16x16-tile batch of diffuse rays.
    const std::string tiled = ", 16x16-tile batches";
    for (int lanes : stream_lane_counts(ctx.opt.stream_lanes)) {
        Engine stream = set.engines[0];
        stream.name += tiled + ", stream of " + std::to_string(lanes) + " lanes";
        stream.stream_lanes = lanes;
        stream.tiled = true;
        set.engines.push_back(std::move(stream));
    }
    for (int min_rays : partition_min_rays(ctx.opt.partition_min_rays)) {
        Engine part = set.engines[0];
        part.name += tiled + ", partition, min " + std::to_string(min_rays) + " rays";
        part.partition_min_rays = min_rays;
        part.tiled = true;
        set.engines.push_back(std::move(part));
    }
#ifdef KDT_HAVE_EMBREE
    if (ctx.opt.embree) {
        add_embree_engines(ctx, false, set);
        if (ctx.opt.embree_robust) add_embree_engines(ctx, true, set);
        for (const Engine& e : std::vector<Engine>(set.engines)) {
            if (!e.peer || e.batch) continue;
            Engine t = e;
            t.name += ", single rays in tile-batch order";
            t.tiled = true;
            set.engines.push_back(std::move(t));
        }
    }
#endif
    return set;
}

LeafPaths make_leaf_paths(const KdTree& tree, RaySets& rays) {
    LeafPaths paths;
    paths.diffuse = rays.diffuse.data();
    paths.first.assign(1, 0);
    paths.first.reserve(rays.diffuse.size() + 1);
    for (uint32_t src : rays.diffuse_sources) {
        Hit h;
        KdPath path;
        tree.intersect(rays.primary[src], h, path);
        paths.nodes.insert(paths.nodes.end(), path.nodes, path.nodes + path.length);
        paths.first.push_back(paths.nodes.size());
    }
    rays.diffuse_sources.clear();
    rays.diffuse_sources.shrink_to_fit();
    return paths;
}

// Engines interleaved within each repeat so drift (thermal, other load) hits all alike.
void time_engines(const Context& ctx, const RaySets& rays, const LeafPaths& paths,
                  const TileBatches& tiles, std::vector<Engine>& engines) {
    const int threads = ctx.threads;
    const std::vector<Ray>& primary = rays.primary;
    const std::vector<Ray>& diffuse = rays.diffuse;
    // A batch engine's three timings: the primary rays in chunks, the diffuse rays in 16x16
    // tile batches (tiled) or in chunks of their own order. The queries stay template
    // arguments, so that the timed loops make no indirect call per ray.
    const auto time_batches = [&](Engine& e, const auto& intersect, const auto& occluded) {
        e.primary_s.push_back(trace_closest_batch(primary, e.primary_hits, threads, intersect));
        if (e.tiled) {
            e.diffuse_s.push_back(trace_tiles_closest(tiles, e.diffuse_hits, threads, intersect));
            e.shadow_s.push_back(
                trace_tiles_occluded(tiles, threads, occluded, &e.diffuse_occluded));
        } else {
            e.diffuse_s.push_back(trace_closest_batch(diffuse, e.diffuse_hits, threads, intersect));
            e.shadow_s.push_back(
                trace_occluded_batch(diffuse, threads, occluded, &e.diffuse_occluded));
        }
    };
    for (int k = 0; k < ctx.repeat; ++k) {
        for (Engine& e : engines) {
            if (e.from_leaf) {
                const KdTree* t = e.tree;
                e.primary_s.push_back(
                    trace_closest(primary, e.primary_hits, threads, [t](const Ray& r, Hit& h) {
                        KdPath path;
                        t->intersect(r, h, path);
                    }));
                e.diffuse_s.push_back(
                    trace_closest(diffuse, e.diffuse_hits, threads, [&](const Ray& r, Hit& h) {
                        const auto [start, length] = paths.start_of(r);
                        t->intersect_from(start, length, r, h);
                    }));
                e.shadow_s.push_back(trace_occluded(
                    diffuse, threads,
                    [&](const Ray& r) {
                        const auto [start, length] = paths.start_of(r);
                        return t->occluded_from(start, length, r);
                    },
                    &e.diffuse_occluded));
                continue;
            }
            if (e.tiled && e.partition_min_rays > 0) {
                const KdTree& t = *e.tree;
                const int m = e.partition_min_rays;
                time_batches(
                    e,
                    [&](const Ray* r, size_t n, Hit* h) {
                        intersect_partition(t, r, n, h, nullptr, m);
                    },
                    [&](const Ray* r, size_t n, uint8_t* o) {
                        occluded_partition(t, r, n, o, nullptr, m);
                    });
                continue;
            }
            if (e.stream_lanes > 0) {
                const KdTree& t = *e.tree;
                const int lanes = e.stream_lanes;
                time_batches(
                    e, [&](const Ray* r, size_t n, Hit* h) { intersect_stream(t, r, n, h, lanes); },
                    [&](const Ray* r, size_t n, uint8_t* o) {
                        occluded_stream(t, r, n, o, lanes);
                    });
                continue;
            }
            if (e.tiled) {
                with_queries(e, [&](const auto& isect, const auto& occ) {
                    e.primary_s.push_back(trace_closest(primary, e.primary_hits, threads, isect));
                    e.diffuse_s.push_back(trace_tiles_closest(tiles, e.diffuse_hits, threads,
                                                              [&](const Ray* r, size_t n, Hit* h) {
                                                                  for (size_t i = 0; i < n; ++i)
                                                                      isect(r[i], h[i]);
                                                              }));
                    e.shadow_s.push_back(trace_tiles_occluded(
                        tiles, threads,
                        [&](const Ray* r, size_t n, uint8_t* o) {
                            for (size_t i = 0; i < n; ++i) o[i] = occ(r[i]) ? 1 : 0;
                        },
                        &e.diffuse_occluded));
                });
                continue;
            }
            if (e.batch) {
                with_batch_queries(
                    e, [&](const auto& coherent, const auto& incoherent, const auto& occ) {
                        e.primary_s.push_back(
                            trace_closest_batch(primary, e.primary_hits, threads, coherent));
                        e.diffuse_s.push_back(
                            trace_closest_batch(diffuse, e.diffuse_hits, threads, incoherent));
                        e.shadow_s.push_back(
                            trace_occluded_batch(diffuse, threads, occ, &e.diffuse_occluded));
                    });
                continue;
            }
            with_queries(e, [&](const auto& isect, const auto& occ) {
                e.primary_s.push_back(trace_closest(primary, e.primary_hits, threads, isect));
                e.diffuse_s.push_back(trace_closest(diffuse, e.diffuse_hits, threads, isect));
                e.shadow_s.push_back(trace_occluded(diffuse, threads, occ, &e.diffuse_occluded));
            });
        }
    }
}

Table embree_table(const Context& ctx, const RowResult& best, const RaySets& rays,
                   const std::vector<Engine>& engines) {
    const std::vector<Ray>& primary = rays.primary;
    const std::vector<Ray>& diffuse = rays.diffuse;
    Table t2;
    t2.name = "embree";
    t2.title = "Best tree (row " + best.config.id +
               ") against Embree (single rays: rtcIntersect1/rtcOccluded1; batch: "
               "rtcIntersect1M/rtcOccluded1M, ratios against single-ray Embree): " +
               std::to_string(primary.size()) + " primary rays, " + std::to_string(diffuse.size()) +
               " one-bounce diffuse rays, " + std::to_string(ctx.threads) +
               " threads, medians of " + std::to_string(ctx.repeat) +
               (ctx.opt.cpu_time ? ", CPU seconds" : "");
    t2.header = {"engine",
                 "build s",
                 "bytes/tri",
                 "peak build MB",
                 "primary Mrays/s",
                 "diffuse Mrays/s",
                 "diffuse occluded Mrays/s",
                 "primary x Embree",
                 "diffuse x Embree",
                 "occluded x Embree",
                 "primary hit diffs",
                 "diffuse hit diffs",
                 "diffuse x kd single",
                 "occluded x kd single",
                 "bitwise diffs vs kd single (primary / diffuse / occluded count)"};
    // The ratios' reference: Embree's single-ray engine (none without Embree).
    const Engine* ref = nullptr;
#ifdef KDT_HAVE_EMBREE
    for (const Engine& e : engines) {
        if (e.peer && !e.batch) {
            ref = &e;
            break;
        }
    }
#endif
    auto mr = [](size_t n, double s) { return mega_rate(double(n), s); };
    for (const Engine& e : engines) {
        const double p = mr(primary.size(), median(e.primary_s));
        const double d = mr(diffuse.size(), median(e.diffuse_s));
        const double o = mr(diffuse.size(), median(e.shadow_s));
        std::vector<std::string> row = {e.name,
                                        fmt("%.3f", e.build_seconds),
                                        fmt("%.1f", e.bytes_per_triangle),
                                        fmt("%.1f", e.peak_mb),
                                        fmt("%.2f", p),
                                        fmt("%.2f", d),
                                        fmt("%.2f", o)};
        if (ref) {
            row.push_back(fmt("%.2f", quotient(p, mr(primary.size(), median(ref->primary_s)))));
            row.push_back(fmt("%.2f", quotient(d, mr(diffuse.size(), median(ref->diffuse_s)))));
            row.push_back(fmt("%.2f", quotient(o, mr(diffuse.size(), median(ref->shadow_s)))));
            row.push_back(std::to_string(count_disagreements(e.primary_hits, ref->primary_hits)));
            row.push_back(std::to_string(count_disagreements(e.diffuse_hits, ref->diffuse_hits)));
        } else {
            row.insert(row.end(), {"-", "-", "-", "-", "-"});
        }
        // engines[0] is our single-ray engine: the streams' peer, whose results they must
        // reproduce bit for bit.
        const Engine& kd = engines[0];
        row.push_back(fmt("%.2f", quotient(d, mr(diffuse.size(), median(kd.diffuse_s)))));
        row.push_back(fmt("%.2f", quotient(o, mr(diffuse.size(), median(kd.shadow_s)))));
        if (e.stream_lanes || e.partition_min_rays) {
            row.push_back(std::to_string(bitwise_differences(e.primary_hits, kd.primary_hits)) +
                          " / " +
                          std::to_string(bitwise_differences(e.diffuse_hits, kd.diffuse_hits)) +
                          " / " + (e.diffuse_occluded == kd.diffuse_occluded ? "same" : "DIFFERS"));
        } else {
            row.push_back("-");
        }
        t2.rows.push_back(std::move(row));
    }
    return t2;
}

}  // namespace kdt::app::kdtree_bench
