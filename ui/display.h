// The film on screen: a float RGB texture drawn on a full-viewport quad by a fragment shader
// that applies exposure, the tone curve and sRGB encoding -- the same curve as the CLI's PNG
// output (renderer/core/color.h tonemap_to_srgb8). Needs a current OpenGL 3.3 core context.
// Depends on core (ToneParams) and GL only.
#pragma once

#include <string>

#include "renderer/core/color.h"
#include "ui/gl.h"

namespace kdt::ui {

/// How the texture is shown: tone-mapped radiance, or values that are already display-ready
/// in [0, 1] (heat maps and other debug views, coloured on the CPU).
enum class DisplayMode { radiance, direct };

class FilmDisplay {
public:
    FilmDisplay() = default;
    FilmDisplay(const FilmDisplay&) = delete;
    FilmDisplay& operator=(const FilmDisplay&) = delete;
    ~FilmDisplay();

    /// Compiles the shaders and creates the quad and the texture; throws kdt::Error with the
    /// compiler's log when a shader fails.
    void init();
    /// Uploads width x height linear RGB floats (top row first) into the texture, through a
    /// pixel buffer object; reallocates only when the size changes.
    void upload(int width, int height, const float* rgb);
    /// Draws the texture over the viewport (x, y, w, h in framebuffer pixels), linearly
    /// filtered, so a preview of lower resolution fills it too.
    void draw(int x, int y, int w, int h, const ToneParams& tone, DisplayMode mode) const;
    int width() const { return width_; }
    int height() const { return height_; }

private:
    GLuint program_ = 0, vao_ = 0, texture_ = 0, pbo_ = 0;
    GLint loc_exposure_ = -1, loc_curve_ = -1, loc_mode_ = -1;
    int width_ = 0, height_ = 0;
};

/// "" when glGetError() reports nothing, else the error codes seen, named after `where`.
std::string gl_errors(const char* where);

}  // namespace kdt::ui
