// Render settings as text: enum names for flags, and the JSON written into image metadata
// (kdtrace:params, kdtrace:camera) so that any image can be re-rendered exactly.
// Depends on integrator, film, accel, scene.
#pragma once

#include <array>
#include <cstddef>
#include <string>

#include "renderer/accel/kdtree.h"
#include "renderer/camera/camera.h"
#include "renderer/core/error.h"
#include "renderer/film/film.h"
#include "renderer/integrator/path_tracer.h"

namespace kdt {

/// Index of `value` in a names table; throws kdt::Error listing the allowed names.
template <size_t N>
size_t parse_name(const std::array<const char*, N>& names, const std::string& value,
                  const std::string& what) {
    std::string allowed;
    for (size_t i = 0; i < N; ++i) {
        if (value == names[i]) return i;
        allowed += (i ? ", " : "") + std::string(names[i]);
    }
    throw Error(what + ": unknown value '" + value + "' (one of: " + allowed + ")");
}

/// Largest thread count a render or build accepts (more is a typo, not a machine).
inline constexpr int kMaxThreads = 1024;

/// Throws kdt::Error naming the parameter when a trace or film parameter is out of range
/// or not finite (for example a negative depth, a NaN threshold, 10^5 threads).
void validate_render_params(const TraceParams& trace, const FilmParams& film);

/// JSON object of all trace, film and tree parameters (one line).
std::string params_to_json(const TraceParams& trace, const FilmParams& film,
                           const KdTreeParams& tree);
/// JSON object of the camera: eye, target, up, vfov_degrees, width, height (one line).
std::string camera_to_json(const Camera& camera);
/// Reads params_to_json() output back; unknown keys throw kdt::Error.
void params_from_json(const std::string& json, TraceParams& trace, FilmParams& film,
                      KdTreeParams& tree);

}  // namespace kdt
