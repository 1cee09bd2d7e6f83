#include "ui/display.h"

#include <cstring>
#include <vector>

#include "renderer/core/error.h"

namespace kdt::ui {

namespace {

// A full-screen triangle pair from gl_VertexID: no vertex buffer. The texture's top row is
// the image's top row, so v runs downwards.
const char* const kVertexShader = R"(#version 330 core
out vec2 uv;
void main() {
    vec2 p = vec2((gl_VertexID == 1 || gl_VertexID == 4 || gl_VertexID == 5) ? 1.0 : 0.0,
                  (gl_VertexID == 2 || gl_VertexID == 3 || gl_VertexID == 5) ? 1.0 : 0.0);
    uv = vec2(p.x, 1.0 - p.y);
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
)";

// The tone curves of renderer/core/color.h apply_tone_curve and linear_to_srgb, in GLSL.
const char* const kFragmentShader = R"(#version 330 core
out vec4 color;
uniform sampler2D image;
uniform float exposure;
uniform int curve;  // 0 clamp, 1 reinhard, 2 aces
uniform int mode;   // 0 radiance, 1 direct
float tone(float x) {
    if (!(x > 0.0)) return 0.0;
    if (curve == 1) return isinf(x) ? 1.0 : x / (1.0 + x);
    if (curve == 2) {
        if (isinf(x)) return 1.0;
        return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
    }
    return min(x, 1.0);
}
float srgb(float x) {
    return x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055;
}
void main() {
    // Drawn at the image's size into the 8-bit texture: fragment (x, y) is texel (x, y).
    vec3 v = texelFetch(image, ivec2(gl_FragCoord.xy), 0).rgb;
    if (mode == 1) {
        color = vec4(clamp(v, 0.0, 1.0), 1.0);
        return;
    }
    float s = exp2(exposure);
    color = vec4(srgb(tone(v.r * s)), srgb(tone(v.g * s)), srgb(tone(v.b * s)), 1.0);
}
)";

// Shows the tone-mapped 8-bit image as it is.
const char* const kCopyShader = R"(#version 330 core
in vec2 uv;
out vec4 color;
uniform sampler2D image;
void main() {
    color = vec4(texture(image, uv).rgb, 1.0);
}
)";

// Throws kdt::Error with `object`'s info log (deleting it first) when `ok` is false.
void check_built(GLint ok, GLuint object, void (*info_log)(GLuint, GLsizei, GLsizei*, GLchar*),
                 void (*remove)(GLuint), const char* what) {
    if (ok) return;
    char log[2048] = {};
    info_log(object, sizeof log, nullptr, log);
    remove(object);
    throw Error(std::string(what) + log);
}

GLuint compile(GLenum type, const char* source) {
    const GLuint s = glCreateShader(type);
    glShaderSource(s, 1, &source, nullptr);
    glCompileShader(s);
    GLint ok = 0;
    glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    check_built(ok, s, glGetShaderInfoLog, glDeleteShader, "display shader: ");
    return s;
}

GLuint link_program(const char* vertex, const char* fragment) {
    const GLuint vs = compile(GL_VERTEX_SHADER, vertex);
    GLuint fs = 0;
    try {
        fs = compile(GL_FRAGMENT_SHADER, fragment);
    } catch (...) {
        glDeleteShader(vs);
        throw;
    }
    const GLuint program = glCreateProgram();
    glAttachShader(program, vs);
    glAttachShader(program, fs);
    glLinkProgram(program);
    glDeleteShader(vs);
    glDeleteShader(fs);
    GLint ok = 0;
    glGetProgramiv(program, GL_LINK_STATUS, &ok);
    check_built(ok, program, glGetProgramInfoLog, glDeleteProgram, "display shader link: ");
    return program;
}

}  // namespace

std::string gl_errors(const char* where) {
    std::string out;
    for (GLenum e = glGetError(); e != GL_NO_ERROR; e = glGetError()) {
        char buf[32];
        std::snprintf(buf, sizeof buf, "0x%04x", unsigned(e));
        out += (out.empty() ? std::string(where) + ": GL error " : std::string(", ")) + buf;
    }
    return out;
}

FilmDisplay::~FilmDisplay() {
    if (program_) glDeleteProgram(program_);
    if (copy_program_) glDeleteProgram(copy_program_);
    if (fbo_) glDeleteFramebuffers(1, &fbo_);
    if (toned_) glDeleteTextures(1, &toned_);
    if (vao_) glDeleteVertexArrays(1, &vao_);
    if (texture_) glDeleteTextures(1, &texture_);
    if (pbo_) glDeleteBuffers(1, &pbo_);
}

void FilmDisplay::init() {
    program_ = link_program(kVertexShader, kFragmentShader);
    copy_program_ = link_program(kVertexShader, kCopyShader);
    loc_exposure_ = glGetUniformLocation(program_, "exposure");
    loc_curve_ = glGetUniformLocation(program_, "curve");
    loc_mode_ = glGetUniformLocation(program_, "mode");
    glGenVertexArrays(1, &vao_);
    glGenBuffers(1, &pbo_);
    glGenFramebuffers(1, &fbo_);
    for (GLuint* t : {&texture_, &toned_}) {
        glGenTextures(1, t);
        glBindTexture(GL_TEXTURE_2D, *t);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    }
    glBindTexture(GL_TEXTURE_2D, 0);
}

void FilmDisplay::upload(int width, int height, const float* rgb) {
    if (width <= 0 || height <= 0) return;
    const size_t bytes = size_t(width) * size_t(height) * 3 * sizeof(float);
    glBindTexture(GL_TEXTURE_2D, texture_);
    glBindBuffer(GL_PIXEL_UNPACK_BUFFER, pbo_);
    // Orphaning the buffer lets the driver keep the previous upload in flight.
    glBufferData(GL_PIXEL_UNPACK_BUFFER, GLsizeiptr(bytes), nullptr, GL_STREAM_DRAW);
    glBufferSubData(GL_PIXEL_UNPACK_BUFFER, 0, GLsizeiptr(bytes), rgb);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    if (width != width_ || height != height_) {
        glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB32F, width, height, 0, GL_RGB, GL_FLOAT, nullptr);
        glBindTexture(GL_TEXTURE_2D, toned_);
        glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, width, height, 0, GL_RGBA, GL_UNSIGNED_BYTE,
                     nullptr);
        width_ = width;
        height_ = height;
    } else {
        glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, width, height, GL_RGB, GL_FLOAT, nullptr);
    }
    glBindBuffer(GL_PIXEL_UNPACK_BUFFER, 0);
    glBindTexture(GL_TEXTURE_2D, 0);
    valid_ = false;
}

void FilmDisplay::tone_map(const ToneParams& tone, DisplayMode mode) {
    GLint previous = 0;
    glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &previous);
    // The whole texture is written whatever scissor the caller draws with (the split view).
    const GLboolean scissor = glIsEnabled(GL_SCISSOR_TEST);
    glDisable(GL_SCISSOR_TEST);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, fbo_);
    glFramebufferTexture2D(GL_DRAW_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, toned_, 0);
    glViewport(0, 0, width_, height_);
    glUseProgram(program_);
    glUniform1f(loc_exposure_, tone.exposure);
    glUniform1i(loc_curve_, int(tone.curve));
    glUniform1i(loc_mode_, mode == DisplayMode::direct ? 1 : 0);
    glBindTexture(GL_TEXTURE_2D, texture_);
    glDrawArrays(GL_TRIANGLES, 0, 6);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, GLuint(previous));
    if (scissor) glEnable(GL_SCISSOR_TEST);
    valid_ = true;
    toned_tone_ = tone;
    toned_mode_ = mode;
}

void FilmDisplay::draw(int x, int y, int w, int h, const ToneParams& tone, DisplayMode mode) {
    if (width_ == 0) return;
    glActiveTexture(GL_TEXTURE0);
    glBindVertexArray(vao_);
    if (!valid_ || mode != toned_mode_ || tone != toned_tone_) {
        tone_map(tone, mode);
    }
    glViewport(x, y, w, h);
    glUseProgram(copy_program_);
    glBindTexture(GL_TEXTURE_2D, toned_);
    glDrawArrays(GL_TRIANGLES, 0, 6);
    glBindVertexArray(0);
    glBindTexture(GL_TEXTURE_2D, 0);
    glUseProgram(0);
}

}  // namespace kdt::ui
