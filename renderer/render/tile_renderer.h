// The per-tile kernel of a render pass: every active pixel of one tile takes its next samples
// of this pass, in pixel and sample order, each a pure function of (seed, pixel, sample
// index). Used by RenderSession; the MPI farm renders tile lists through the session.
// Depends on integrator, film, camera.
#pragma once

#include <cstdint>

#include "renderer/camera/camera.h"
#include "renderer/film/film.h"
#include "renderer/integrator/path_tracer.h"
#include "renderer/integrator/trace_scene.h"

namespace kdt {

/// What a tile reads and where it writes. Only the tile's pixels of `film` and of the heat
/// arrays are written, so tiles render concurrently without locks.
struct TileTarget {
    const TraceScene* scene = nullptr;
    const Camera* camera = nullptr;
    const TraceParams* trace = nullptr;
    Film* film = nullptr;
    /// Per-pixel sums of nodes visited / triangles tested (row-major, film size), or null for
    /// no heat map (then the camera rays go to the kd-tree's batch query).
    uint64_t* heat_nodes = nullptr;
    uint64_t* heat_triangles = nullptr;
    /// Per-pixel sums for the normals and depth views (AOVs), or null for none: of every
    /// sample whose camera ray hits, its aov_shading_normal() (3 floats a pixel), its distance
    /// along the camera ray, and a count of those samples. Read from the camera ray's hit
    /// only: the radiance is the same with or without them.
    float* aov_normal = nullptr;
    float* aov_depth = nullptr;
    uint32_t* aov_hits = nullptr;
    uint32_t max_spp = 0xffffffffu;  ///< no pixel draws a sample index >= this
    /// FilmParams::transparent: a camera ray that escapes adds no radiance, and every kept
    /// sample adds its coverage to the film (which must keep it).
    bool transparent = false;
};

/// The shading normal of a camera ray's hit for the normals view: the unit normal the path
/// tracer shades with (interpolated on smooth instances, else the geometric one), turned to
/// the side the ray comes from. World space; `hit` must be valid.
Vec3f aov_shading_normal(const TraceScene& scene, const Ray& ray, const Hit& hit);

/// Renders trace->samples_per_pass samples (at least 1) for every active pixel of `tile`,
/// none with a sample index at or past max_spp or the pixel's Film::pass_end(), and adds the
/// ray counts to `counters`. Returns the number of pixels that took a sample.
size_t render_tile(const TileTarget& target, const FilmRect& tile, PathCounters& counters);

}  // namespace kdt
