#include "renderer/film/film.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <string>

#include "renderer/core/error.h"

namespace kdt {

namespace {

constexpr uint32_t kNoPassEnd = std::numeric_limits<uint32_t>::max();

// The end of a doubling from `drawn` samples: the next power of two above it.
uint32_t doubling_end(uint32_t drawn) {
    return uint32_t(std::min<uint64_t>(std::bit_ceil(uint64_t(drawn) + 1), kNoPassEnd));
}

}  // namespace

uint8_t linear_to_srgb8(float v) {
    if (!(v > 0.0f)) return 0;
    if (v >= 1.0f) return 255;
    const float s = v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
    return uint8_t(std::lround(std::clamp(s, 0.0f, 1.0f) * 255.0f));
}

void Film::resize(int width, int height) {
    width_ = std::max(width, 0);
    height_ = std::max(height, 0);
    pixels_.assign(pixel_count(), Pixel{});
    active_.assign(pixel_count(), 1);
    pass_end_.assign(pixel_count(), kNoPassEnd);
    error_scratch_.assign(pixel_count(), 0.0f);
    variance_scratch_.assign(pixel_count(), 0.0f);
    open_ = pixel_count();
    keep_coverage(keeps_coverage());
}

void Film::clear() {
    std::fill(pixels_.begin(), pixels_.end(), Pixel{});
    std::fill(active_.begin(), active_.end(), uint8_t(1));
    std::fill(pass_end_.begin(), pass_end_.end(), kNoPassEnd);
    open_ = pixel_count();
    std::fill(coverage_.begin(), coverage_.end(), 0.0);
}

std::vector<float> Film::coverage() const {
    std::vector<float> out(coverage_.size());
    for (size_t i = 0; i < out.size(); ++i) {
        const uint32_t n = pixels_[i].count;
        out[i] = n > 0 ? float(coverage_[i] / double(n)) : 0.0f;
    }
    return out;
}

Vec3f Film::mean(int x, int y) const {
    const Pixel& p = pixels_[index(x, y)];
    if (p.count == 0) return Vec3f(0.0f);
    const double inv = 1.0 / double(p.count);
    return {float(p.r * inv), float(p.g * inv), float(p.b * inv)};
}

float Film::relative_error(int x, int y) const {
    const Pixel& p = pixels_[index(x, y)];
    if (p.count < 2) return kInfinity;
    const double n = double(p.count);
    const double m = p.lum / n;
    const double var = std::max(0.0, (p.lum2 - p.lum * m) / (n - 1.0));
    return float(std::sqrt(var / n) / std::max(m, 1e-4));
}

double Film::mean_relative_error() const {
    double sum = 0.0;
    size_t n = 0;
    for (int y = 0; y < height_; ++y) {
        for (int x = 0; x < width_; ++x) {
            if (pixels_[index(x, y)].count < 2) continue;
            sum += relative_error(x, y);
            ++n;
        }
    }
    return n ? sum / double(n) : 0.0;
}

uint64_t Film::total_samples() const {
    uint64_t n = 0;
    for (const Pixel& p : pixels_) n += p.count;
    return n;
}

uint64_t Film::total_drawn() const {
    uint64_t n = 0;
    for (const Pixel& p : pixels_) n += p.drawn;
    return n;
}

size_t Film::update_active(const FilmParams& params, const AdaptiveInputs& in) {
    pass_samples_ = std::max(in.samples_per_pass, 1);
    if (!params.adaptive) {
        std::fill(active_.begin(), active_.end(), uint8_t(1));
        std::fill(pass_end_.begin(), pass_end_.end(), kNoPassEnd);
        open_ = pixel_count();
        return pixel_count();
    }
    const std::span<const float> cost = in.cost_per_sample;
    if (!cost.empty() && cost.size() != pixel_count()) {
        throw Error("film: " + std::to_string(cost.size()) + " sample costs for a film of " +
                    std::to_string(pixel_count()) + " pixels");
    }
    for (size_t i = 0; i < pixels_.size(); ++i) {
        const Pixel& p = pixels_[i];
        error_scratch_[i] = relative_error(int(i % size_t(width_)), int(i / size_t(width_)));
        // Per-sample variance of the luminance; negative marks "unknown" (below 2 samples).
        const double n = double(p.count);
        variance_scratch_[i] =
            p.count < 2 ? -1.0f : float(std::max(0.0, (p.lum2 - p.lum * (p.lum / n)) / (n - 1.0)));
    }
    const auto min_spp = uint32_t(std::max(params.adaptive_min_spp, 2));
    const auto max_spp = uint32_t(std::max(params.adaptive_max_spp, 0));
    size_t warming = 0;   // open pixels below min_spp, all active
    size_t doubling = 0;  // open pixels between powers of two, all active
    candidates_.clear();
    for (int y = 0; y < height_; ++y) {
        for (int x = 0; x < width_; ++x) {
            const size_t i = index(x, y);
            const Pixel& p = pixels_[i];
            active_[i] = 0;
            pass_end_[i] = kNoPassEnd;
            if ((max_spp > 0 && p.count >= max_spp) ||
                (in.sample_cap > 0 && p.drawn >= in.sample_cap))
                continue;
            if (p.count < min_spp) {
                active_[i] = 1;
                ++warming;
                continue;
            }
            // The 3x3 maximum guards against a pixel whose few samples happened to agree
            // (e.g. all missed a small bright light) stopping while its neighbours are noisy;
            // the 3x3 mean of the variances keeps such a pixel from ranking last.
            float e = 0.0f, v = 0.0f;
            int known = 0;
            for (int dy = -1; dy <= 1; ++dy) {
                for (int dx = -1; dx <= 1; ++dx) {
                    const int xx = x + dx, yy = y + dy;
                    if (xx < 0 || yy < 0 || xx >= width_ || yy >= height_) continue;
                    const size_t j = index(xx, yy);
                    e = std::max(e, error_scratch_[j]);
                    if (variance_scratch_[j] >= 0.0f) {
                        v += variance_scratch_[j];
                        ++known;
                    }
                }
            }
            if (e < params.adaptive_threshold) continue;
            if ((p.drawn & (p.drawn - 1)) != 0) {  // a doubling under way runs to its end
                active_[i] = 1;
                pass_end_[i] = doubling_end(p.drawn);
                ++doubling;
                continue;
            }
            // Doubling n samples costs n c and cuts the variance of the mean by v / (2 n).
            const double n = double(p.count);
            const double c = cost.empty() ? 1.0 : std::max(double(cost[i]), 1e-6);
            const double gain = double(v) / double(std::max(known, 1)) / (n * n * c);
            candidates_.push_back({float(gain), uint32_t(i)});
        }
    }
    open_ = warming + doubling + candidates_.size();
    if (warming == 0) pass_samples_ = std::max(pass_samples_, kAdaptivePassSamples);
    // New doublings, best first, while fewer than the share of the open pixels are doubling;
    // at least one when nothing else would sample.
    const double share = std::ceil(double(open_) * double(kAdaptivePassShare));
    size_t k = share > double(doubling) ? size_t(share - double(doubling)) : 0;
    if (warming + doubling == 0) k = std::max<size_t>(k, 1);
    k = std::min(k, candidates_.size());
    // The top k under a total order (gain, then the lower index first): the same set
    // whatever order nth_element visits the candidates in.
    const auto before = [](const Candidate& a, const Candidate& b) {
        return a.priority != b.priority ? a.priority > b.priority : a.pixel < b.pixel;
    };
    if (k < candidates_.size()) {
        std::nth_element(candidates_.begin(), candidates_.begin() + ptrdiff_t(k), candidates_.end(),
                         before);
    }
    for (size_t j = 0; j < k; ++j) {
        const uint32_t i = candidates_[j].pixel;
        active_[i] = 1;
        pass_end_[i] = doubling_end(pixels_[i].drawn);
    }
    return warming + doubling + k;
}

namespace {

void add_pixel(FilmPixel& to, const FilmPixel& from) {
    to.r += from.r;
    to.g += from.g;
    to.b += from.b;
    to.lum += from.lum;
    to.lum2 += from.lum2;
    to.count += from.count;
    to.drawn += from.drawn;
}

}  // namespace

void Film::merge(const Film& other) {
    if (other.width_ != width_ || other.height_ != height_) {
        throw Error("film merge: sizes differ (" + std::to_string(width_) + "x" +
                    std::to_string(height_) + " and " + std::to_string(other.width_) + "x" +
                    std::to_string(other.height_) + ")");
    }
    if (keeps_coverage() != other.keeps_coverage())
        throw Error("film merge: one film keeps coverage (alpha), the other does not");
    for (size_t i = 0; i < pixels_.size(); ++i) add_pixel(pixels_[i], other.pixels_[i]);
    for (size_t i = 0; i < coverage_.size(); ++i) coverage_[i] += other.coverage_[i];
}

void Film::check_rect(const FilmRect& r, size_t buffer_pixels, const char* what) const {
    if (r.x0 < 0 || r.y0 < 0 || r.x1 > width_ || r.y1 > height_ || r.x0 > r.x1 || r.y0 > r.y1) {
        throw Error(std::string("film ") + what + ": tile [" + std::to_string(r.x0) + ", " +
                    std::to_string(r.x1) + ") x [" + std::to_string(r.y0) + ", " +
                    std::to_string(r.y1) + ") outside the " + std::to_string(width_) + "x" +
                    std::to_string(height_) + " film");
    }
    if (buffer_pixels < r.pixel_count()) {
        throw Error(std::string("film ") + what + ": buffer of " + std::to_string(buffer_pixels) +
                    " pixels for a tile of " + std::to_string(r.pixel_count()));
    }
}

std::vector<FilmPixel> Film::export_tile(const FilmRect& rect) const {
    check_rect(rect, rect.pixel_count(), "export");
    std::vector<FilmPixel> out(rect.pixel_count());
    export_tile(rect, out);
    return out;
}

void Film::export_tile(const FilmRect& rect, std::span<FilmPixel> out) const {
    check_rect(rect, out.size(), "export");
    if (rect.pixel_count() == 0) return;
    const size_t w = size_t(rect.x1 - rect.x0);
    for (int y = rect.y0; y < rect.y1; ++y) {
        std::copy_n(&pixels_[index(rect.x0, y)], w, &out[size_t(y - rect.y0) * w]);
    }
}

void Film::import_tile(const FilmRect& rect, std::span<const FilmPixel> data, bool add) {
    check_rect(rect, data.size(), "import");
    if (data.size() != rect.pixel_count()) {
        throw Error("film import: buffer of " + std::to_string(data.size()) +
                    " pixels for a tile of " + std::to_string(rect.pixel_count()));
    }
    if (rect.pixel_count() == 0) return;
    const size_t w = size_t(rect.x1 - rect.x0);
    for (int y = rect.y0; y < rect.y1; ++y) {
        const FilmPixel* src = &data[size_t(y - rect.y0) * w];
        FilmPixel* dst = &pixels_[index(rect.x0, y)];
        if (add) {
            for (size_t i = 0; i < w; ++i) add_pixel(dst[i], src[i]);
        } else {
            std::copy_n(src, w, dst);
        }
    }
}

std::vector<float> Film::linear_rgb() const {
    std::vector<float> out(pixel_count() * 3);
    for (int y = 0; y < height_; ++y) {
        for (int x = 0; x < width_; ++x) {
            const Vec3f m = mean(x, y);
            const size_t i = index(x, y) * 3;
            out[i] = m.x;
            out[i + 1] = m.y;
            out[i + 2] = m.z;
        }
    }
    return out;
}

std::vector<uint8_t> Film::srgb8(float exposure) const {
    const float scale = std::exp2(exposure);
    std::vector<uint8_t> out(pixel_count() * 3);
    for (int y = 0; y < height_; ++y) {
        for (int x = 0; x < width_; ++x) {
            const Vec3f m = mean(x, y) * scale;
            const size_t i = index(x, y) * 3;
            out[i] = linear_to_srgb8(m.x);
            out[i + 1] = linear_to_srgb8(m.y);
            out[i + 2] = linear_to_srgb8(m.z);
        }
    }
    return out;
}

}  // namespace kdt
