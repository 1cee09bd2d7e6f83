// Vectors written into JSON (scene files, session and options files) as arrays of the
// floats' shortest texts. Depends on core/math.h, core/fields.h and nlohmann/json.
#pragma once

#include <nlohmann/json.hpp>

#include "renderer/core/fields.h"
#include "renderer/core/math.h"

namespace kdt {

/// [x, y, z], each float as its shortest text (2.6, not 2.5999999046325684), which reads back
/// as the same float. Non-finite components pass through (nlohmann writes them as null).
inline nlohmann::json vec3_json(const Vec3f& v) {
    return nlohmann::json::array({float_for_text(v.x), float_for_text(v.y), float_for_text(v.z)});
}

}  // namespace kdt
