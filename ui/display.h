// The film on screen: a float RGB texture tone-mapped by a fragment shader that applies
// exposure, the tone curve and sRGB encoding -- the same curve as the CLI's PNG output
// (renderer/core/color.h tonemap_to_srgb8) -- into an 8-bit texture of the image's size, which
// a full-viewport quad shows. The tone map runs only when the image, the tone or the mode
// changed: a frame that shows the same image costs one texture fetch per pixel, not the curve
// (which dominates a frame under software GL). Needs a current OpenGL 3.3 core context.
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
    /// Draws the tone-mapped image over the viewport (x, y, w, h in framebuffer pixels) of the
    /// bound draw framebuffer, linearly filtered (between display codes), so a preview of
    /// lower resolution fills it too. Tone-maps first when the image, `tone` or `mode`
    /// changed since the last draw. Leaves the viewport at (x, y, w, h).
    void draw(int x, int y, int w, int h, const ToneParams& tone, DisplayMode mode);
    int width() const { return width_; }
    int height() const { return height_; }

private:
    /// Renders the float texture through the tone shader into toned_ (allocated at the
    /// image's size), restoring the caller's draw framebuffer.
    void tone_map(const ToneParams& tone, DisplayMode mode);

    GLuint program_ = 0, copy_program_ = 0, vao_ = 0, texture_ = 0, pbo_ = 0;
    GLuint toned_ = 0, fbo_ = 0;  ///< the tone-mapped RGBA8 image and its framebuffer
    GLint loc_exposure_ = -1, loc_curve_ = -1, loc_mode_ = -1;
    int width_ = 0, height_ = 0;
    // What toned_ shows; valid_ is false after an upload or a resize.
    bool valid_ = false;
    ToneParams toned_tone_;
    DisplayMode toned_mode_ = DisplayMode::radiance;
};

/// "" when glGetError() reports nothing, else the error codes seen, named after `where`.
std::string gl_errors(const char* where);

}  // namespace kdt::ui
