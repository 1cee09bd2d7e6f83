// Writing a render's image at the end without losing the render when the write fails: used
// by `render` and by the MPI and sequence renders (app/mpi_cli.cpp).
#pragma once

#include <string>

#include "renderer/io/image_io.h"

namespace kdt::app {

/// write_image(output, ...); when that fails (a full disk, the directory gone) the image is
/// written to "kdtrace-rescued-<pid>-<output's name>" in $TMPDIR (or /tmp) instead, and the
/// kdt::Error thrown names that file (or says that it could not be written either).
void write_or_rescue(const std::string& output, const ImageRGB& image, const ToneParams& tone,
                     const ImageMetadata& meta);

}  // namespace kdt::app
