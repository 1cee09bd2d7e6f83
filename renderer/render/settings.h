// Render settings as text: enum names, and the camera's JSON written into image metadata
// (kdtrace:camera; the parameters are options_to_json(), render_options.h).
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

/// Throws kdt::Error naming the field ("trace.max_depth must be in [0, 1024] (got -1)") when
/// a trace or film parameter is out of its range (render_options.h's tables).
void validate_render_params(const TraceParams& trace, const FilmParams& film);

/// JSON object of the camera: eye, target, up, vfov_degrees, width, height (one line).
std::string camera_to_json(const Camera& camera);

}  // namespace kdt
