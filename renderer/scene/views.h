// Views files (assets/views/*.json): named cameras with an image size, samples per pixel and
// a seed, used by --view and the benchmarks; and finding the files kdtrace ships (assets/)
// wherever it is run from.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "renderer/scene/scene.h"

namespace kdt {

/// One named camera of a views file.
struct View {
    std::string name;   ///< "A", "B", ...
    std::string label;  ///< "front", "side", ...
    CameraDesc camera;
};

/// A views file: image size, samples per pixel, seed and the cameras.
struct ViewSet {
    std::string model;  ///< the model the cameras were placed for ("model" key), or empty
    int width = 640;
    int height = 480;
    int samples_per_pixel = 8;
    uint64_t seed = 1;
    std::vector<View> views;
};

/// Reads a views file. Unknown keys, wrong types and missing values throw kdt::Error naming
/// the file and the key (a JSON pointer).
ViewSet load_views(const std::string& path);

/// The camera of view `name` in a views file (empty path = the shipped views/dragon.json).
/// Throws kdt::Error naming the file and the views it has when there is no such view.
CameraDesc find_view(const std::string& views_path, const std::string& name);

/// The views file --views names, or the shipped views/dragon.json for an empty path.
std::string views_file_path(const std::string& views_path);

/// A warning (one line, without "warning: ") when the views file at `views_path` names a model
/// ("model" key) and none of `files`, the mesh files of the scene rendered with a camera of it,
/// is that model: the camera was placed for another one. `label` says what took the camera
/// ("--view A", "--frames views:all") and starts the message. A file counts as the model
/// when its name starts with the model's name less its extensions, so that
/// dragon_vrip_res4.ply.gz matches dragon_vrip.ply; `scene` names what is rendered in the
/// message. "" when it matches or the file names no model.
std::string view_model_warning(const std::string& views_path, const ViewSet& set,
                               const std::string& label, const std::string& scene,
                               const std::vector<std::string>& files);

/// Finds a file kdtrace ships under assets/: in $KDT_ASSETS_DIR, ./assets, then relative to the
/// executable (build/bin/../../assets, bin/../assets, bin/../share/kdtrace/assets) and the
/// source tree it was built from (KDT_SOURCE_ASSETS_DIR). Throws kdt::Error when none exists.
std::string find_asset(const std::string& relative);

}  // namespace kdt
