#include "app/rescue.h"

#include <unistd.h>

#include <cstdlib>
#include <filesystem>

#include "renderer/core/error.h"

namespace kdt::app {

void write_or_rescue(const std::string& output, const ImageRGB& image, const ToneParams& tone,
                     const ImageMetadata& meta) {
    try {
        write_image(output, image, tone, meta);
        return;
    } catch (const Error& e) {
        const char* tmp = std::getenv("TMPDIR");
        const std::filesystem::path dir = tmp && *tmp ? tmp : "/tmp";
        const std::string rescue = (dir / ("kdtrace-rescued-" + std::to_string(::getpid()) + "-" +
                                           std::filesystem::path(output).filename().string()))
                                       .string();
        try {
            write_image(rescue, image, tone, meta);
        } catch (const Error& again) {
            throw Error(std::string(e.what()) + "; the image could not be saved to " + rescue +
                        " either: " + again.what());
        }
        throw Error(std::string(e.what()) + "; the image was saved to " + rescue + " instead");
    }
}

}  // namespace kdt::app
