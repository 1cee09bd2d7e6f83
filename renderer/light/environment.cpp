#include "renderer/light/environment.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <new>

#include "renderer/core/color.h"
#include "renderer/core/error.h"
#include "renderer/io/image_io.h"
#include "renderer/light/image_environment.h"
#include "renderer/light/mapping.h"

namespace kdt {
namespace {

/// SplitMix64 (Steele, Lea & Flood 2014): the rejection loop below needs a few extra
/// random numbers and derives them from the bits of the caller's sample.
uint64_t splitmix64(uint64_t& state) {
    uint64_t z = (state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

float unit_float(uint64_t bits) { return float(bits >> 40) * 0x1p-24f; }

uint32_t float_bits(float f) {
    uint32_t b;
    std::memcpy(&b, &f, 4);
    return b;
}

/// Angular-map image coordinates -> disk coordinates (a right, b up).
Vec2f disk_from_uv(const Vec2f& uv) { return {2.0f * uv.x - 1.0f, 1.0f - 2.0f * uv.y}; }

std::string where(const std::string& name) { return name.empty() ? "environment map" : name; }

std::string xy(size_t i, int w) {
    return "(x " + std::to_string(i % size_t(w)) + ", y " + std::to_string(i / size_t(w)) + ")";
}

std::string number(double v) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%g", v);
    return buf;
}

/// Throws unless radiance (the largest channel of a colour or texel, times the intensity,
/// computed in double) is within kMaxEnvironmentRadiance.
void check_radiance_bound(double channel, float intensity, const std::string& path,
                          const std::string& what) {
    const double radiance = channel * double(intensity);
    if (radiance > double(kMaxEnvironmentRadiance)) {
        throw Error(ErrorLocation{path}, what + " " + number(channel) + " times intensity " +
                                             number(intensity) + " is radiance " +
                                             number(radiance) + ", above the limit " +
                                             number(kMaxEnvironmentRadiance) +
                                             " (path throughput products would overflow float)");
    }
}

/// Sampling cells per pixel along each axis: 8, 4, 2, or 1, the largest whose grid stays
/// within kMaxSamplingCells (4M cells, about 50 MB of tables): 8 up to 256x256 pixels
/// (e.g. 362x181), 4 up to 512x512 (724x362), 2 up to 1024x1024 (1448x724), 1 above.
int sampling_subdivision(int w, int h) {
    constexpr uint64_t kMaxSamplingCells = uint64_t(1) << 22;
    const uint64_t pixels = uint64_t(w) * uint64_t(h);
    for (int s = 8; s > 1; s /= 2) {
        if (pixels * uint64_t(s * s) <= kMaxSamplingCells) return s;
    }
    return 1;
}

}  // namespace

// The smallest power of two that keeps the grid within 2^25 cells (1 up to 8192 x 4096
// pixels, 2 for 16k x 8k). The tables cost about 24 bytes per cell and their construction
// 40 more, against 12 per pixel for the map itself: a 16k map with a cell per pixel
// needed 9 GB.
int automatic_sampling_pixels_per_cell(int width, int height) {
    constexpr uint64_t kMaxCoarseCells = uint64_t(1) << 25;
    auto cells = [&](uint64_t t) {
        return ((uint64_t(std::max(width, 1)) + t - 1) / t) *
               ((uint64_t(std::max(height, 1)) + t - 1) / t);
    };
    int t = 1;
    while (cells(uint64_t(t)) > kMaxCoarseCells) t *= 2;
    return t;
}

void check_environment_texels(const ImageRGB& image, float intensity, const std::string& path) {
    uint64_t nonfinite = 0, negative = 0;
    size_t first_nonfinite = 0, first_negative = 0, brightest = 0;
    float max_channel = 0.0f;
    for (size_t i = 0; i < image.pixel_count(); ++i) {
        for (int c = 0; c < 3; ++c) {
            const float v = image.rgb[i * 3 + size_t(c)];
            if (!std::isfinite(v)) {
                if (nonfinite++ == 0) first_nonfinite = i;
                break;
            }
            if (v < 0.0f) {
                if (negative++ == 0) first_negative = i;
                break;
            }
            if (v > max_channel) {
                max_channel = v;
                brightest = i;
            }
        }
    }
    const std::string count = std::to_string(image.pixel_count());
    if (nonfinite > 0) {
        const Vec3f v = image.at(int(first_nonfinite % size_t(image.width)),
                                 int(first_nonfinite / size_t(image.width)));
        throw Error(ErrorLocation{path, "pixel", int64_t(first_nonfinite)},
                    xy(first_nonfinite, image.width) + " is " +
                        (std::isnan(v.x + v.y + v.z) ? "NaN" : "infinite") + "; " +
                        std::to_string(nonfinite) + " of " + count + " texels are not finite");
    }
    if (negative > 0) {
        const Vec3f v = image.at(int(first_negative % size_t(image.width)),
                                 int(first_negative / size_t(image.width)));
        throw Error(ErrorLocation{path, "pixel", int64_t(first_negative)},
                    xy(first_negative, image.width) + " is negative (" + number(v.x) + ", " +
                        number(v.y) + ", " + number(v.z) + "); " + std::to_string(negative) +
                        " of " + count + " texels have a negative channel");
    }
    check_radiance_bound(max_channel, intensity, path,
                         "the brightest texel " + xy(brightest, image.width) + " has a channel");
}

EnvSample ConstantEnvironment::sample(const Vec2f& u) const {
    float z = 1.0f - 2.0f * u.x;
    float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
    float phi = 2.0f * kPi * u.y;
    EnvSample s;
    s.dir = Vec3f(r * std::cos(phi), z, r * std::sin(phi));
    s.radiance = radiance_;
    s.pdf_solid_angle = 0.25f * kInvPi;
    return s;
}

ImageEnvironment::ImageEnvironment(ImageRGB image, EnvMapping mapping, float rotation_degrees,
                                   float intensity, const std::string& name, int cells_per_pixel)
    : image_(std::move(image)), mapping_(mapping), intensity_(intensity) {
    const int w = image_.width, h = image_.height;
    if (w < 1 || h < 1 || image_.rgb.size() != image_.pixel_count() * 3) {
        throw Error(ErrorLocation{where(name)}, "empty or inconsistent environment image");
    }
    if (!std::isfinite(rotation_degrees)) {
        throw Error(ErrorLocation{where(name)}, "rotation is not finite");
    }
    if (!std::isfinite(intensity) || intensity < 0.0f) {
        throw Error(ErrorLocation{where(name)}, "intensity must be finite and >= 0");
    }
    if (cells_per_pixel != 0 && cells_per_pixel != 1 &&
        !(cells_per_pixel % 2 == 0 && cells_per_pixel >= 2 && cells_per_pixel <= 16) &&
        !(cells_per_pixel >= -64 && cells_per_pixel <= -2)) {
        throw Error(ErrorLocation{where(name)},
                    "sampling cells per pixel must be 0 (automatic), 1, even in [2, 16], or -T "
                    "for T x T pixels per cell, T in [2, 64]");
    }
    // Whole turns taken off before the trigonometry, so that any multiple of 360 is exactly
    // 0 and -90 exactly 270: fmod is exact, an angle in [0, 360) stays as it is, and adding
    // 360 to a negative remainder is exact for multiples of 2^-15 degrees (integers, halves;
    // one that rounds to 360 is 0). +0 for -0 keeps the sine's sign, which atan2 reads at
    // the seam.
    float degrees = std::fmod(rotation_degrees, 360.0f);
    if (degrees < 0.0f) degrees += 360.0f;
    if (degrees == 0.0f || degrees == 360.0f) degrees = 0.0f;
    const float radians = degrees * (kPi / 180.0f);
    cos_rot_ = std::cos(radians);
    sin_rot_ = std::sin(radians);

    check_environment_texels(image_, intensity, where(name));

    // Sampling weights on the grid of sampling cells (sub_ x sub_ per pixel, or a cell per
    // pixels_ x pixels_): the mean luminance of the bilinear reconstruction over the cell
    // times the cell's solid angle per unit uv area, so that the solid-angle pdf is close to
    // proportional to what eval() returns, and positive wherever eval() is.
    // In double: luminance times a Jacobian of up to 4 pi^2 overflows float for huge cells.
    if (cells_per_pixel < 0) {
        pixels_ = -cells_per_pixel;
    } else if (cells_per_pixel == 0) {
        pixels_ = automatic_sampling_pixels_per_cell(w, h);
    }
    if (pixels_ > 1) {
        sub_ = 1;
        grid_w_ = (w + pixels_ - 1) / pixels_;
        grid_h_ = (h + pixels_ - 1) / pixels_;
    } else {
        sub_ = cells_per_pixel != 0 ? cells_per_pixel : sampling_subdivision(w, h);
        grid_w_ = w * sub_;
        grid_h_ = h * sub_;
    }
    const int gw = grid_w_, gh = grid_h_;
    const size_t cells = size_t(gw) * size_t(gh);
    const std::vector<double> lum = cell_mean_luminance();
    // jac: each cell's solid angle per unit uv area (its mean Jacobian), zero outside the
    // angular map's disk.
    std::vector<double> jac(cells, 0.0);
    std::vector<float> cover(cells, 1.0f);
    if (mapping_ == EnvMapping::latlong) {
        for (int y = 0; y < gh; ++y) {
            // Mean of sin(theta) over the row: (cos theta0 - cos theta1) / (theta1 - theta0).
            double t0 = M_PI * y / gh, t1 = M_PI * (y + 1) / gh;
            double mean_sin = (std::cos(t0) - std::cos(t1)) / (t1 - t0);
            std::fill_n(jac.begin() + ptrdiff_t(size_t(y) * size_t(gw)), gw, mean_sin);
        }
    } else {
        for (int y = 0; y < gh; ++y) {
            for (int x = 0; x < gw; ++x) {
                size_t i = size_t(y) * size_t(gw) + size_t(x);
                cover[i] = coverage(x, y);
                if (!(cover[i] > 0.0f)) continue;
                // A floor keeps cells cut by the rim with no grid point inside samplable,
                // so that pdf > 0 wherever eval > 0.
                jac[i] = std::max(angular_mean_jacobian(x, y), double(cover[i]) * 1e-3);
            }
        }
    }
    std::vector<double> weights(cells, 0.0);
    double sum_weights = 0.0, sum_jac = 0.0;
    for (size_t i = 0; i < cells; ++i) {
        weights[i] = lum[i] * jac[i];
        sum_weights += weights[i];
        sum_jac += jac[i];
    }
    full_ = make_cell_sampling(weights, cover);
    // MIS compensation: the map's mean luminance over the sphere subtracted.
    const double mean = sum_jac > 0.0 ? sum_weights / sum_jac : 0.0;
    for (size_t i = 0; i < cells; ++i) weights[i] = std::max(lum[i] - mean, 0.0) * jac[i];
    mis_ = make_cell_sampling(weights, cover);
}

ImageEnvironment::CellSampling ImageEnvironment::make_cell_sampling(
    const std::vector<double>& weights, const std::vector<float>& cover) const {
    const int gw = grid_w_, gh = grid_h_;
    // Normalised to a maximum of 1 so that the float distribution can neither overflow nor
    // lose the scale; cells below 1e-38 of the brightest one round to weight 0.
    double max_weight = *std::max_element(weights.begin(), weights.end());
    std::vector<float> normalised(weights.size(), 0.0f);
    if (max_weight > 0.0) {
        for (size_t i = 0; i < weights.size(); ++i) normalised[i] = float(weights[i] / max_weight);
    }
    CellSampling cs;
    cs.distribution = Distribution2D(normalised, gw, gh);
    cs.density.assign(weights.size(), 0.0f);
    if (!cs.distribution.empty()) {
        for (int y = 0; y < gh; ++y) {
            for (int x = 0; x < gw; ++x) {
                size_t i = size_t(y) * size_t(gw) + size_t(x);
                if (normalised[i] > 0.0f) cs.density[i] = cs.distribution.pdf(x, y) / cover[i];
            }
        }
    }
    return cs;
}

double ImageEnvironment::angular_mean_jacobian(int x, int y) const {
    // Zero outside the disk: the centre value for cells inside the disk, a kSub^2 grid for
    // cells cut by the rim. It only shapes the weights; the density stays exact.
    constexpr int kSub = 4;
    const auto gw = float(grid_w_), gh = float(grid_h_);
    if (coverage(x, y) >= 1.0f) {
        if (auto d = angular_dir_from_uv({(float(x) + 0.5f) / gw, (float(y) + 0.5f) / gh}))
            return angular_jacobian(*d);
    }
    double mean_j = 0.0;
    for (int sy = 0; sy < kSub; ++sy) {
        for (int sx = 0; sx < kSub; ++sx) {
            Vec2f uv((float(x) + (float(sx) + 0.5f) / kSub) / gw,
                     (float(y) + (float(sy) + 0.5f) / kSub) / gh);
            if (auto d = angular_dir_from_uv(uv)) mean_j += angular_jacobian(*d);
        }
    }
    return mean_j / (kSub * kSub);
}

int ImageEnvironment::column(int x) const {
    if (mapping_ == EnvMapping::latlong)
        return x < 0 ? x + image_.width : (x >= image_.width ? x - image_.width : x);
    return std::clamp(x, 0, image_.width - 1);
}

std::vector<double> ImageEnvironment::cell_mean_luminance() const {
    const int w = image_.width, h = image_.height;
    if (pixels_ > 1) {
        // Cells of several pixels, uniform in uv (their edges need not fall on pixel edges):
        // the mean luminance of the pixels the reconstruction reads anywhere in the cell,
        // those whose centres lie within a pixel of it. Not the exact mean, but positive
        // wherever the reconstruction is, which is all unbiasedness needs; read from the map
        // itself, with no per-pixel arrays.
        const int gw = grid_w_, gh = grid_h_;
        std::vector<double> out(size_t(gw) * size_t(gh));
        // Pixel range [lo, hi] of the reconstruction over cell c of n along an axis of m.
        auto range = [](int c, int n, int m, int& lo, int& hi) {
            lo = int(std::floor(double(c) * m / n - 0.5));
            hi = int(std::floor(double(c + 1) * m / n - 0.5)) + 1;
        };
        for (int gy = 0; gy < gh; ++gy) {
            int y0, y1;
            range(gy, gh, h, y0, y1);
            y0 = std::clamp(y0, 0, h - 1);
            y1 = std::clamp(y1, 0, h - 1);
            for (int gx = 0; gx < gw; ++gx) {
                int x0, x1;
                range(gx, gw, w, x0, x1);
                double sum = 0.0;
                for (int y = y0; y <= y1; ++y) {
                    for (int x = x0; x <= x1; ++x)
                        sum += double(luminance(image_.at(column(std::clamp(x, -1, w)), y)));
                }
                out[size_t(gy) * size_t(gw) + size_t(gx)] =
                    sum / (double(y1 - y0 + 1) * double(x1 - x0 + 1));
            }
        }
        return out;
    }
    std::vector<double> texel(image_.pixel_count());
    for (size_t i = 0; i < texel.size(); ++i) {
        texel[i] = double(luminance(image_.at(int(i % size_t(w)), int(i / size_t(w)))));
    }
    auto at = [&](int x, int y) { return texel[size_t(y) * size_t(w) + size_t(x)]; };
    if (sub_ == 1) {
        // Over a pixel, the bilinear reconstruction's mean is the pixel and its neighbours
        // weighted 1/8, 3/4, 1/8 along each axis (each half of the pixel interpolates towards
        // one neighbour), with the neighbours eval() uses at the edges.
        std::vector<double> row(texel.size()), out(texel.size());
        for (int y = 0; y < h; ++y) {
            for (int x = 0; x < w; ++x) {
                row[size_t(y) * size_t(w) + size_t(x)] =
                    0.125 * at(column(x - 1), y) + 0.75 * at(x, y) + 0.125 * at(column(x + 1), y);
            }
        }
        for (int y = 0; y < h; ++y) {
            const int up = std::max(y - 1, 0), down = std::min(y + 1, h - 1);
            for (int x = 0; x < w; ++x) {
                out[size_t(y) * size_t(w) + size_t(x)] =
                    0.125 * row[size_t(up) * size_t(w) + size_t(x)] +
                    0.75 * row[size_t(y) * size_t(w) + size_t(x)] +
                    0.125 * row[size_t(down) * size_t(w) + size_t(x)];
            }
        }
        return out;
    }
    // sub_ even: pixel centres lie on cell edges, so each cell lies inside one bilinear patch
    // and the mean over it is the interpolated value at its centre, which is strictly inside
    // the patch: positive if any of the patch's four texels is (the same texels, wrapping
    // and clamping as lookup()).
    const int gw = w * sub_, gh = h * sub_;
    std::vector<double> out(size_t(gw) * size_t(gh));
    for (int gy = 0; gy < gh; ++gy) {
        const double fy = (gy + 0.5) / sub_ - 0.5, y_floor = std::floor(fy), ty = fy - y_floor;
        const int ya = std::clamp(int(y_floor), 0, h - 1),
                  yb = std::clamp(int(y_floor) + 1, 0, h - 1);
        for (int gx = 0; gx < gw; ++gx) {
            const double fx = (gx + 0.5) / sub_ - 0.5, x_floor = std::floor(fx), tx = fx - x_floor;
            const int xa = column(std::clamp(int(x_floor), -1, w)),
                      xb = column(std::clamp(int(x_floor) + 1, -1, w));
            out[size_t(gy) * size_t(gw) + size_t(gx)] =
                (at(xa, ya) * (1.0 - tx) + at(xb, ya) * tx) * (1.0 - ty) +
                (at(xa, yb) * (1.0 - tx) + at(xb, yb) * tx) * ty;
        }
    }
    return out;
}

Vec3f ImageEnvironment::lookup(const Vec2f& uv) const {
    // Pixel centres sit at (x + 1/2) / W; between them the map is interpolated bilinearly,
    // wrapping around in longitude (lat-long) and clamped at the other edges.
    const float fx = uv.x * float(image_.width) - 0.5f, fy = uv.y * float(image_.height) - 0.5f;
    const float x_floor = std::floor(fx), y_floor = std::floor(fy);
    const float tx = fx - x_floor, ty = fy - y_floor;
    const int x0 = int(x_floor), y0 = int(y_floor);
    const int xa = column(std::clamp(x0, -1, image_.width)),
              xb = column(std::clamp(x0 + 1, -1, image_.width));
    const int ya = std::clamp(y0, 0, image_.height - 1),
              yb = std::clamp(y0 + 1, 0, image_.height - 1);
    const Vec3f top = image_.at(xa, ya) * (1.0f - tx) + image_.at(xb, ya) * tx;
    const Vec3f bottom = image_.at(xa, yb) * (1.0f - tx) + image_.at(xb, yb) * tx;
    return top * (1.0f - ty) + bottom * ty;
}

float ImageEnvironment::coverage(int x, int y) const {
    if (mapping_ == EnvMapping::latlong) return 1.0f;
    const int w = grid_w_, h = grid_h_;
    double a0 = 2.0 * x / w - 1.0, a1 = 2.0 * (x + 1) / w - 1.0;
    double b0 = 1.0 - 2.0 * (y + 1) / h, b1 = 1.0 - 2.0 * y / h;
    double far_a = std::max(std::abs(a0), std::abs(a1));
    double far_b = std::max(std::abs(b0), std::abs(b1));
    if (far_a * far_a + far_b * far_b <= 1.0) return 1.0f;  // exactly, inside the disk
    return float(disk_rect_area(a0, a1, b0, b1) / ((a1 - a0) * (b1 - b0)));
}

Vec3f ImageEnvironment::to_map(const Vec3f& world_dir) const {
    Vec3f d = rotate_y(world_dir, cos_rot_, -sin_rot_);  // map = R_y(-alpha) world
    float len2 = glm::dot(d, d);
    if (len2 > 0.0f && std::abs(len2 - 1.0f) > 1e-4f) d *= 1.0f / std::sqrt(len2);
    return d;
}

size_t ImageEnvironment::cell_index(const Vec2f& uv) const {
    const int gw = grid_w_, gh = grid_h_;
    int x = std::clamp(int(uv.x * float(gw)), 0, gw - 1);
    int y = std::clamp(int(uv.y * float(gh)), 0, gh - 1);
    return size_t(y) * size_t(gw) + size_t(x);
}

float ImageEnvironment::pdf_map(const CellSampling& cs, const Vec3f& map_dir, size_t cell) const {
    float density = cs.density[cell];
    if (density <= 0.0f) return 0.0f;
    float jacobian = env_jacobian(mapping_, map_dir);
    return jacobian > 0.0f ? density / jacobian : 0.0f;
}

// Out of line, as radiance_at(): eval() and sample() then run one compiled copy of the
// mapping and the lookup, which the compiler could otherwise contract into FMAs differently
// at each call site, so both give bitwise the same radiance for a direction.
[[gnu::noinline]] Vec2f ImageEnvironment::uv_from_dir(const Vec3f& world_dir) const {
    return env_uv_from_dir(mapping_, to_map(world_dir));
}

std::optional<Vec3f> ImageEnvironment::dir_from_uv(const Vec2f& uv) const {
    auto d = env_dir_from_uv(mapping_, uv);
    if (!d) return std::nullopt;
    return rotate_y(*d, cos_rot_, sin_rot_);
}

[[gnu::noinline]] Vec3f ImageEnvironment::radiance_at(const Vec2f& uv) const {
    return lookup(uv) * intensity_;
}

Vec3f ImageEnvironment::eval(const Vec3f& dir) const { return radiance_at(uv_from_dir(dir)); }

float ImageEnvironment::pdf(const Vec3f& dir) const { return pdf_from(full_, dir); }

float ImageEnvironment::pdf_mis(const Vec3f& dir) const { return pdf_from(mis_, dir); }

EnvSample ImageEnvironment::sample(const Vec2f& u) const { return sample_from(full_, u); }

EnvSample ImageEnvironment::sample_mis(const Vec2f& u) const { return sample_from(mis_, u); }

float ImageEnvironment::pdf_from(const CellSampling& cs, const Vec3f& dir) const {
    Vec3f d = to_map(dir);
    if (!(glm::dot(d, d) > 0.0f)) return 0.0f;
    return pdf_map(cs, d, cell_index(env_uv_from_dir(mapping_, d)));
}

EnvSample ImageEnvironment::sample_from(const CellSampling& cs, const Vec2f& u) const {
    EnvSample s;
    if (cs.distribution.empty()) return s;
    Vec2i cell;
    Vec2f uv = cs.distribution.sample_continuous(u, &cell);
    std::optional<Vec3f> map_dir = env_dir_from_uv(mapping_, uv);
    if (!map_dir) {
        // Angular map, a cell cut by the rim: uniform within its part of the disk by
        // rejection, with random numbers derived from u. The density stays
        // pdf(cell) / coverage; failing 256 times has negligible probability and yields
        // a zero-pdf sample the integrator skips.
        uint64_t state = (uint64_t(float_bits(u.x)) << 32) | float_bits(u.y);
        const auto w = float(grid_w_), h = float(grid_h_);
        for (int attempt = 0; attempt < 256 && !map_dir; ++attempt) {
            uint64_t r = splitmix64(state);
            Vec2f p((float(cell.x) + unit_float(r)) / w, (float(cell.y) + unit_float(r << 24)) / h);
            Vec2f ab = disk_from_uv(p);
            if (ab.x * ab.x + ab.y * ab.y < 1.0f) map_dir = angular_dir_from_uv(p);
        }
        if (!map_dir) return s;
    }
    s.dir = rotate_y(*map_dir, cos_rot_, sin_rot_);
    // Radiance and pdf are looked up again from the final direction, as eval() and pdf() do:
    // the radiance bit for bit (the same out-of-line functions), the pdf to a few ulps (its
    // Jacobian is computed inline); a sample on a cell edge may round into the neighbouring
    // cell, and it is then that cell's density that counts.
    const Vec2f uv_d = uv_from_dir(s.dir);
    s.radiance = radiance_at(uv_d);
    s.pdf_solid_angle = pdf_map(cs, to_map(s.dir), cell_index(uv_d));
    return s;
}

std::shared_ptr<const EnvironmentLight> make_environment_light(const EnvironmentDesc& desc,
                                                               ImageRGB image) {
    const std::string size = std::to_string(image.width) + "x" + std::to_string(image.height);
    try {
        return std::make_shared<ImageEnvironment>(std::move(image), desc.mapping,
                                                  desc.rotation_degrees, desc.intensity, desc.file);
    } catch (const std::bad_alloc&) {
        throw Error(ErrorLocation{where(desc.file)},
                    "out of memory for the sampling tables of the " + size + " map");
    }
}

std::string environment_mapping_warning(EnvMapping mapping, int width, int height) {
    const std::string size = std::to_string(width) + "x" + std::to_string(height);
    if (mapping == EnvMapping::angular && width == 2 * height) {
        return "mapping angular for a " + size +
               " image, which looks like a lat-long map (2:1); angular maps are square";
    }
    if (mapping == EnvMapping::latlong && width == height) {
        return "mapping latlong for a square " + size +
               " image, which looks like an angular map; lat-long maps are 2:1";
    }
    // Any other aspect outside [1.5, 2.5] (a 1x4096 strip, a 16x96 cube cross) is not a
    // lat-long map either.
    if (mapping == EnvMapping::latlong &&
        (2 * int64_t(width) < 3 * int64_t(height) || 2 * int64_t(width) > 5 * int64_t(height))) {
        return "mapping latlong for a " + size + " image, far from 2:1; lat-long maps are 2:1";
    }
    return "";
}

std::shared_ptr<const EnvironmentLight> make_environment_light(const EnvironmentDesc& desc,
                                                               const EnvLog& log) {
    if (desc.file.empty()) return make_environment_light(desc);
    ImageMetadata metadata;
    ImageRGB image = load_image(desc.file, &metadata);
    for (const auto& [key, value] : metadata) {
        if (key == "envmap" && value != "latlong") {
            throw Error(ErrorLocation{desc.file},
                        "its envmap attribute says '" + printable(value) +
                            "' (a cube-face map, six faces in a strip?): environment maps must "
                            "be lat-long or angular; convert it, e.g. exrenvmap -l IN OUT");
        }
    }
    const std::string warning =
        environment_mapping_warning(desc.mapping, image.width, image.height);
    if (log && !warning.empty()) log("warning: " + desc.file + ": " + warning);
    return make_environment_light(desc, std::move(image));
}

std::shared_ptr<const EnvironmentLight> make_environment_light(const EnvironmentDesc& desc) {
    if (desc.file.empty()) {
        if (!is_finite(desc.color) || desc.color.x < 0.0f || desc.color.y < 0.0f ||
            desc.color.z < 0.0f) {
            throw Error("environment colour must be finite and >= 0");
        }
        if (!std::isfinite(desc.intensity) || desc.intensity < 0.0f) {
            throw Error("environment intensity must be finite and >= 0");
        }
        check_radiance_bound(std::max({desc.color.x, desc.color.y, desc.color.z}), desc.intensity,
                             "", "environment colour channel");
        return std::make_shared<ConstantEnvironment>(desc.color * desc.intensity);
    }
    return make_environment_light(desc, EnvLog{});  // the map's checks, without the warning
}

}  // namespace kdt
