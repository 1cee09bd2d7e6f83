// Ray sets shared by the benchmarks: jittered primary rays per view of a views file
// (renderer/scene/views.h), one-bounce cosine-distributed diffuse rays, and parallel tracing
// helpers.
// Deterministic: every random number is a hash of (seed, view, pixel, sample).
#pragma once

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include <omp.h>
#include <time.h>

#include "renderer/accel/kdtree.h"
#include "renderer/core/math.h"
#include "renderer/core/timer.h"
#include "renderer/geometry/mesh.h"
#include "renderer/scene/views.h"

namespace kdt::app {

/// width*height*spp primary rays with box-filter jitter, in 8x8-pixel tiles (tile-major,
/// then pixels row-major, then samples) so consecutive rays are coherent.
/// The jitter of (pixel, sample) depends only on (seed, view_index, pixel, sample).
std::vector<Ray> make_primary_rays(const ViewSet& set, size_t view_index);

/// For every ray that hit (hits[i].valid()), one cosine-distributed ray about the
/// geometric normal flipped to face the incoming ray, starting at the hit point offset
/// along that normal by a few float ULPs of the hit position. Misses produce no ray. If
/// `sources` is given, it receives the index in `rays` of each diffuse ray's primary ray.
std::vector<Ray> make_diffuse_rays(const TriangleMesh& mesh, const std::vector<Ray>& rays,
                                   const std::vector<Hit>& hits, uint64_t seed,
                                   std::vector<uint32_t>* sources = nullptr);

/// Uniform float in [0,1) from a 64-bit hash of the arguments (splitmix64 finaliser).
float hash_uniform(uint64_t a, uint64_t b, uint64_t c, uint64_t d);

/// Rays per OpenMP work item: one 8x8 tile of 8 samples.
inline constexpr size_t kRayChunk = 512;

/// Traces every ray with `intersect(ray, hit)` on `threads` OpenMP threads (0 = default),
/// writing hits; returns wall seconds.
template <class Intersect>
double trace_closest(const std::vector<Ray>& rays, std::vector<Hit>& hits, int threads,
                     const Intersect& intersect);
/// Traces every ray with `occluded(ray)`; returns wall seconds; `occluded_count` receives
/// the number of occluded rays.
template <class Occluded>
double trace_occluded(const std::vector<Ray>& rays, int threads, const Occluded& occluded,
                      uint64_t* occluded_count);
/// Same as trace_closest, with `intersect(rays, n, hits)` called once per chunk of
/// kRayChunk consecutive rays (batch queries).
template <class IntersectBatch>
double trace_closest_batch(const std::vector<Ray>& rays, std::vector<Hit>& hits, int threads,
                           const IntersectBatch& intersect);
/// Same as trace_occluded, with `occluded(rays, n, flags)` once per chunk.
template <class OccludedBatch>
double trace_occluded_batch(const std::vector<Ray>& rays, int threads,
                            const OccludedBatch& occluded, uint64_t* occluded_count);

// ---- implementation of the templates ----

/// What the tracing helpers time: wall seconds (the default), or the process's CPU seconds
/// divided by the threads, which on an oversubscribed machine leaves out the time the
/// threads wait descheduled (`bench kdtree --cpu-time`; meant for --threads 1, where no
/// OpenMP thread spins idle).
enum class BenchClock { wall, cpu };
inline BenchClock& bench_clock() {
    static BenchClock clock = BenchClock::wall;
    return clock;
}

inline double process_cpu_seconds() {
    timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

// Calls chunk(begin, count) for consecutive ranges of kRayChunk of [0, n) (the last may be
// shorter) on `threads` OpenMP threads (0 = default); returns seconds of bench_clock().
template <class Chunk>
double time_chunks(size_t n, int threads, const Chunk& chunk) {
    const int64_t chunks = int64_t((n + kRayChunk - 1) / kRayChunk);
    const int nthreads = threads > 0 ? threads : omp_get_max_threads();
    const double cpu0 = process_cpu_seconds();
    Timer timer;
#pragma omp parallel for schedule(dynamic, 1) num_threads(nthreads)
    for (int64_t c = 0; c < chunks; ++c) {
        const size_t begin = size_t(c) * kRayChunk;
        chunk(begin, std::min(n, begin + kRayChunk) - begin);
    }
    if (bench_clock() == BenchClock::cpu) return (process_cpu_seconds() - cpu0) / nthreads;
    return timer.seconds();
}

template <class IntersectBatch>
double trace_closest_batch(const std::vector<Ray>& rays, std::vector<Hit>& hits, int threads,
                           const IntersectBatch& intersect) {
    hits.assign(rays.size(), Hit{});
    return time_chunks(rays.size(), threads, [&](size_t begin, size_t count) {
        intersect(rays.data() + begin, count, hits.data() + begin);
    });
}

template <class OccludedBatch>
double trace_occluded_batch(const std::vector<Ray>& rays, int threads,
                            const OccludedBatch& occluded, uint64_t* occluded_count) {
    std::vector<uint8_t> flags(rays.size(), 0);
    const double seconds = time_chunks(rays.size(), threads, [&](size_t begin, size_t count) {
        occluded(rays.data() + begin, count, flags.data() + begin);
    });
    uint64_t count = 0;
    for (uint8_t f : flags) count += f;
    if (occluded_count) *occluded_count = count;
    return seconds;
}

// One query per ray, chunk by chunk as the batch drivers do.
template <class Intersect>
double trace_closest(const std::vector<Ray>& rays, std::vector<Hit>& hits, int threads,
                     const Intersect& intersect) {
    return trace_closest_batch(rays, hits, threads, [&](const Ray* r, size_t n, Hit* h) {
        for (size_t i = 0; i < n; ++i) intersect(r[i], h[i]);
    });
}

template <class Occluded>
double trace_occluded(const std::vector<Ray>& rays, int threads, const Occluded& occluded,
                      uint64_t* occluded_count) {
    return trace_occluded_batch(
        rays, threads,
        [&](const Ray* r, size_t n, uint8_t* o) {
            for (size_t i = 0; i < n; ++i) o[i] = occluded(r[i]) ? 1 : 0;
        },
        occluded_count);
}

}  // namespace kdt::app
