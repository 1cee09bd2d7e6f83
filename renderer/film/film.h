// The progressive film: per-pixel RGB sums, luminance moments and sample counts, the
// variance-based relative error estimate, adaptive-sampling masks and tone mapping.
// Depends on core only. One pixel is only ever written by one thread at a time.
#pragma once

#include <cstdint>
#include <span>
#include <type_traits>
#include <vector>

#include "renderer/core/color.h"
#include "renderer/core/math.h"

namespace kdt {

/// Film and adaptive-sampling settings (documented defaults; CLI and UI share them).
struct FilmParams {
    bool adaptive = false;                 ///< stop converged pixels and spend samples elsewhere
    float adaptive_threshold = 0.02f;      ///< relative error (stderr / mean luminance) to stop at
    int adaptive_min_spp = 16;             ///< no pixel stops before this many samples
    int adaptive_max_spp = 0;              ///< per-pixel cap while adaptive; 0 = no cap
    float exposure = 0.0f;                 ///< PNG tone mapping: scale by 2^exposure before sRGB
    ToneCurve tonemap = ToneCurve::clamp;  ///< PNG tone curve after the exposure
    /// The environment seen directly is transparent: escaping camera rays add no radiance
    /// and the film keeps each pixel's coverage (alpha) for PNG and EXR output.
    bool transparent = false;
};

/// Adaptive sampling grows a pixel's sample count in doublings once it has
/// adaptive_min_spp samples: the Owen-scrambled Sobol samples of a pixel are best
/// stratified at power-of-two counts, so a doubling runs to the next power of two of the
/// drawn count and no pass draws past it (Film::pass_end). New doublings start while fewer
/// than this share of the open pixels are doubling; a smaller share follows the priority
/// order more closely.
inline constexpr float kAdaptivePassShare = 0.25f;
/// Samples each active pixel takes in a pass once no open pixel is below adaptive_min_spp
/// (at least TraceParams::samples_per_pass), in passes long enough to pay for their serial
/// update and parallel region. 8 divides every power of two from 8 on, so with pass sizes
/// that are powers of two no doubling from 16 or more is cut short by its end.
inline constexpr int kAdaptivePassSamples = 8;

/// What Film::update_active() needs besides FilmParams (RenderSession fills it in).
struct AdaptiveInputs {
    /// Each pixel's cost per sample, row-major, in any positive unit (e.g. traversal steps);
    /// empty: equal costs.
    std::span<const float> cost_per_sample;
    uint32_t sample_cap = 0;   ///< pixels that drew this many samples stop; 0 = no cap
    int samples_per_pass = 1;  ///< the fewest samples an active pixel takes in a pass
};

/// Linear -> sRGB-encoded 8-bit value (clamped to [0, 1] first).
uint8_t linear_to_srgb8(float v);

/// One pixel's accumulators as plain data: tiles travel between processes (MPI) as arrays of
/// these, byte for byte, so a pixel rendered anywhere lands with the same bits.
struct FilmPixel {
    double r = 0.0, g = 0.0, b = 0.0;  ///< sums of the kept samples' radiance
    double lum = 0.0, lum2 = 0.0;      ///< sums of Rec. 709 luminance and its square
    uint32_t count = 0;                ///< samples accumulated
    uint32_t drawn = 0;                ///< samples drawn, including dropped ones
};
static_assert(std::is_trivially_copyable_v<FilmPixel> && sizeof(FilmPixel) == 48);

/// A pixel rectangle [x0, x1) x [y0, y1) of a film.
struct FilmRect {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    size_t pixel_count() const { return size_t(x1 - x0) * size_t(y1 - y0); }
};

class Film {
public:
    Film() = default;
    Film(int width, int height) { resize(width, height); }

    /// Resizes and clears; every pixel becomes active.
    void resize(int width, int height);
    /// Forgets all samples; every pixel becomes active.
    void clear();

    int width() const { return width_; }
    int height() const { return height_; }
    size_t pixel_count() const { return size_t(width_) * size_t(height_); }

    /// Adds one finite sample to pixel (x, y). Never allocates.
    void add_sample(int x, int y, const Vec3f& rgb) {
        Pixel& p = pixels_[size_t(y) * size_t(width_) + size_t(x)];
        // Rec. 709 luminance drives the error estimate.
        const double l = 0.2126 * rgb.x + 0.7152 * rgb.y + 0.0722 * rgb.z;
        p.r += rgb.x;
        p.g += rgb.y;
        p.b += rgb.z;
        p.lum += l;
        p.lum2 += l * l;
        ++p.count;
        ++p.drawn;
    }
    /// Keeps, or stops keeping, per-pixel coverage (cleared either way). Not while a pass runs.
    void keep_coverage(bool on) {
        keep_coverage_ = on;
        coverage_.assign(on ? pixel_count() : 0, 0.0);
    }
    bool keeps_coverage() const { return keep_coverage_; }
    /// Adds the coverage of a kept sample (1: the camera ray hit the scene; 0: it escaped).
    /// Only with keeps_coverage(); never allocates.
    void add_coverage(int x, int y, float alpha) { coverage_[index(x, y)] += alpha; }
    /// Mean coverage of each pixel's kept samples, row-major; empty without keeps_coverage().
    std::vector<float> coverage() const;

    /// Records a drawn sample that was dropped (non-finite): the sample index advances so
    /// the pixel does not redraw it, but nothing is accumulated.
    void skip_sample(int x, int y) { ++pixels_[index(x, y)].drawn; }
    /// Index of the next sample of pixel (x, y): samples drawn so far, kept or dropped.
    uint32_t next_sample_index(int x, int y) const { return pixels_[index(x, y)].drawn; }
    /// Finite samples accumulated so far at pixel (x, y).
    uint32_t count(int x, int y) const { return pixels_[index(x, y)].count; }
    /// Mean radiance at (x, y); 0 before any sample.
    Vec3f mean(int x, int y) const;
    /// Standard error of the mean luminance divided by max(mean luminance, 1e-4);
    /// infinity with fewer than 2 samples.
    float relative_error(int x, int y) const;
    /// Mean of relative_error() over pixels with at least 2 samples (0 when none).
    double mean_relative_error() const;
    /// Total samples over all pixels.
    uint64_t total_samples() const;
    /// Total samples drawn over all pixels, kept or dropped (non-finite).
    uint64_t total_drawn() const;

    /// Recomputes which pixels take samples in the next pass, and how many each takes
    /// (pass_samples()); returns how many pixels do. Without adaptivity all pixels are
    /// active. With it a pixel is *open* until it stops, and it stops when it has
    /// adaptive_max_spp samples (when > 0) or drew in.sample_cap (when > 0), or when it has
    /// at least adaptive_min_spp samples and the largest relative error in its 3x3
    /// neighbourhood is below adaptive_threshold. Open pixels below adaptive_min_spp are all
    /// active, and so are open pixels whose drawn count is not a power of two (a doubling
    /// under way: it runs to the next power of two, pass_end(), whatever the pass size; one
    /// that left adaptive_min_spp between two powers of two first completes to the next).
    /// Of the other open pixels the pass starts doublings for those with the largest drop
    /// of the image's squared error per unit cost, v / (n^2 c), while fewer than
    /// kAdaptivePassShare of the open pixels are doubling: v the per-sample luminance
    /// variance averaged over the 3x3 neighbourhood (one pixel's few samples can agree by
    /// chance), n the pixel's samples, c its in.cost_per_sample. This drives n towards
    /// proportional to sigma / sqrt(c) (within a factor of 2), the allocation that
    /// minimises the summed variance of the pixel means for a given total cost. The result
    /// depends on the film's sums and the inputs only (ties go to the lower pixel index),
    /// so it is the same for any thread count. At least one pixel is active while any is
    /// open. Throws kdt::Error for costs of the wrong size.
    size_t update_active(const FilmParams& params, const AdaptiveInputs& in = {});
    /// Pixels open after the last update_active() (all of them without adaptivity).
    size_t open_count() const { return open_; }
    /// Samples each active pixel takes in the next pass: in.samples_per_pass, or while
    /// adaptive and no open pixel is below adaptive_min_spp, at least kAdaptivePassSamples.
    int pass_samples() const { return pass_samples_; }
    bool active(int x, int y) const { return active_[index(x, y)] != 0; }
    /// The sample index at which active pixel (x, y) stops drawing in the next pass: the
    /// end of its doubling while adaptive (a power of two above next_sample_index()), else
    /// no limit (UINT32_MAX). Set by update_active() for every pixel.
    uint32_t pass_end(int x, int y) const { return pass_end_[index(x, y)]; }
    void set_active(int x, int y, bool on) { active_[index(x, y)] = on ? 1 : 0; }

    /// Adds every pixel's sums and counts of `other` to this film's (the active mask is
    /// kept). Films of disjoint tile sets merge into exactly the film of all tiles, since
    /// adding to zero is exact. Throws kdt::Error when the sizes differ.
    void merge(const Film& other);

    /// The accumulators of `rect`, row-major; export_tile(rect, out) fills
    /// out[0, rect.pixel_count()) without allocating. Throws kdt::Error for a rectangle
    /// outside the film or an output too small.
    std::vector<FilmPixel> export_tile(const FilmRect& rect) const;
    void export_tile(const FilmRect& rect, std::span<FilmPixel> out) const;
    /// Writes `data` (row-major, rect.pixel_count() pixels) into `rect`: replacing the
    /// pixels, or adding to them like merge() when add is true. Throws kdt::Error for a
    /// rectangle outside the film or a buffer of the wrong size.
    void import_tile(const FilmRect& rect, std::span<const FilmPixel> data, bool add = false);

    /// Linear RGB means, row-major from the top row, 3 floats per pixel.
    std::vector<float> linear_rgb() const;
    /// sRGB 8-bit, scaled by 2^exposure, 3 bytes per pixel.
    std::vector<uint8_t> srgb8(float exposure) const;

private:
    using Pixel = FilmPixel;
    size_t index(int x, int y) const { return size_t(y) * size_t(width_) + size_t(x); }
    void check_rect(const FilmRect& rect, size_t buffer_pixels, const char* what) const;

    int width_ = 0, height_ = 0;
    std::vector<Pixel> pixels_;
    std::vector<uint8_t> active_;
    std::vector<uint32_t> pass_end_;  ///< pass_end(), row-major
    std::vector<float> error_scratch_, variance_scratch_;
    struct Candidate {
        float priority;
        uint32_t pixel;
    };
    std::vector<Candidate> candidates_;
    size_t open_ = 0;
    int pass_samples_ = 1;
    bool keep_coverage_ = false;
    std::vector<double> coverage_;  ///< sums of kept samples' alpha (keep_coverage_ only)
};

}  // namespace kdt
