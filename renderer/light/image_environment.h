// The concrete environment lights behind make_environment_light(): a constant colour and
// an HDR map (lat-long or angular, see mapping.h) with its sampling distribution, exposed
// for tests and tools. Depends on core, io.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "renderer/io/image_io.h"
#include "renderer/light/distribution.h"
#include "renderer/light/environment.h"

namespace kdt {

/// Constant radiance from every direction; samples the sphere uniformly (pdf 1/(4 pi)).
class ConstantEnvironment final : public EnvironmentLight {
public:
    explicit ConstantEnvironment(const Vec3f& radiance) : radiance_(radiance) {}
    Vec3f eval(const Vec3f&) const override { return radiance_; }
    EnvSample sample(const Vec2f& u) const override;
    float pdf(const Vec3f&) const override { return 0.25f * kInvPi; }
    bool is_constant() const override { return true; }

private:
    Vec3f radiance_;
};

/// An HDR environment map. eval() interpolates bilinearly between pixel centres (wrapping
/// in longitude for lat-long maps, clamped at other edges), so the map shows no pixel
/// blocks. Sampling is piecewise constant on a grid of sampling cells, S x S per pixel
/// (S = 8, or 4, 2, 1 for larger maps, see sampling_cells_per_pixel(); maps beyond 8192 x
/// 4096 pixels get a cell per T x T pixels instead): it picks a cell with
/// probability proportional to the mean luminance of the interpolated map over the cell
/// times the cell's solid angle, then a point uniformly inside the cell (for the angular
/// map: inside the cell's part of the unit disk), hence
///   pdf_solid_angle(d) = density_uv(cell(d)) / jacobian(d),
/// jacobian = 2 pi^2 sin(theta) (lat-long) or 4 pi^2 sin(theta')/theta' (angular).
/// With S even each cell lies inside one bilinear patch, so its mean is the interpolated
/// value at its centre and the density follows eval() to within the patch's variation over
/// 1/S pixel; with S = 1 a pixel's mean weighs it and its 8 neighbours; a cell of T x T
/// pixels takes the mean of the pixels the reconstruction reads in it.
/// sample() and pdf() agree exactly, and the pdf is positive wherever eval() is, so
/// estimates stay unbiased. sample_mis() and pdf_mis() use a second distribution on the same
/// cells, weighted by max(0, luminance - mean) times the solid angle, the mean being the
/// map's mean luminance over the sphere; with no cell above the mean it is empty
/// (sample_mis() returns pdf 0, and BSDF sampling alone estimates the map).
class ImageEnvironment final : public EnvironmentLight {
public:
    /// Throws kdt::Error (naming `name`, usually the file) as check_environment_texels(), and
    /// unless cells_per_pixel is 0 (automatic, see sampling_cells_per_pixel()), 1, even in
    /// [2, 16], or -T for a cell per T x T pixels, T in [2, 64].
    ImageEnvironment(ImageRGB image, EnvMapping mapping, float rotation_degrees, float intensity,
                     const std::string& name = "", int cells_per_pixel = 0);

    Vec3f eval(const Vec3f& dir) const override;
    EnvSample sample(const Vec2f& u) const override;
    float pdf(const Vec3f& dir) const override;
    bool is_constant() const override { return false; }
    EnvSample sample_mis(const Vec2f& u) const override;
    float pdf_mis(const Vec3f& dir) const override;

    EnvMapping mapping() const { return mapping_; }
    /// The map, not multiplied by intensity.
    const ImageRGB& image() const { return image_; }
    float intensity() const { return intensity_; }
    /// Image coordinates (u, v) of a world direction (rotation applied).
    Vec2f uv_from_dir(const Vec3f& world_dir) const;
    /// World direction of image coordinates (u, v); nullopt outside the angular disk.
    std::optional<Vec3f> dir_from_uv(const Vec2f& uv) const;
    /// Sampling cells per pixel along each axis (S); automatic: 8 up to 256x256 pixels, 4 up
    /// to 512x512, 2 up to 1024x1024 (the tables stay within 4M cells), else 1.
    int sampling_cells_per_pixel() const { return sub_; }
    /// Pixels per sampling cell along each axis (T; 1 unless S = 1): automatic, 1 up to
    /// 8192x4096 pixels (2^25), else the smallest power of two that keeps the grid within
    /// 2^25 cells.
    int sampling_pixels_per_cell() const { return pixels_; }
    /// The sampling grid: width S or ceil(width / T) cells, and the same for the height.
    int sampling_grid_width() const { return grid_w_; }
    int sampling_grid_height() const { return grid_h_; }
    /// Sampling density w.r.t. image area (u, v) in [0,1]^2 inside sampling cell (x, y) of
    /// the grid.
    float density_uv(int x, int y) const {
        return full_.density[size_t(y) * size_t(grid_w_) + size_t(x)];
    }
    /// Fraction of sampling cell (x, y) inside the angular map's disk (1 for lat-long).
    float coverage(int x, int y) const;
    const Distribution2D& distribution() const { return full_.distribution; }
    /// The compensated distribution of sample_mis(), and its density in cell (x, y).
    const Distribution2D& mis_distribution() const { return mis_.distribution; }
    float mis_density_uv(int x, int y) const {
        return mis_.density[size_t(y) * size_t(grid_w_) + size_t(x)];
    }

private:
    /// A distribution over the sampling cells and its density w.r.t. uv area per cell.
    struct CellSampling {
        Distribution2D distribution;
        std::vector<float> density;
    };
    /// The cell sampling of weights (one per cell, >= 0); empty if all are 0.
    CellSampling make_cell_sampling(const std::vector<double>& weights,
                                    const std::vector<float>& cover) const;
    EnvSample sample_from(const CellSampling& cs, const Vec2f& u) const;
    float pdf_from(const CellSampling& cs, const Vec3f& dir) const;
    /// World direction -> unit map direction (rotation undone); zero stays zero.
    Vec3f to_map(const Vec3f& world_dir) const;
    /// lookup(uv) times the intensity: eval()'s radiance.
    Vec3f radiance_at(const Vec2f& uv) const;
    /// Bilinear lookup of the map (no intensity) at image coordinates uv.
    Vec3f lookup(const Vec2f& uv) const;
    /// Column x of the map for x in [-1, width]: wrapped (lat-long) or clamped (angular).
    int column(int x) const;
    /// Per sampling cell (row-major), the mean luminance of the bilinear reconstruction.
    std::vector<double> cell_mean_luminance() const;
    /// Angular map: mean Jacobian over sampling cell (x, y), zero outside the disk.
    double angular_mean_jacobian(int x, int y) const;
    size_t cell_index(const Vec2f& uv) const;  // uv: env_uv_from_dir of a map direction
    float pdf_map(const CellSampling& cs, const Vec3f& map_dir, size_t cell) const;

    ImageRGB image_;
    EnvMapping mapping_;
    float intensity_;
    float cos_rot_, sin_rot_;
    int sub_ = 1;                  ///< sampling cells per pixel along each axis
    int pixels_ = 1;               ///< pixels per sampling cell along each axis
    int grid_w_ = 1, grid_h_ = 1;  ///< the sampling grid
    CellSampling full_, mis_;      ///< for sample() / pdf() and sample_mis() / pdf_mis()
};

/// The automatic pixels per sampling cell of a width x height map (ImageEnvironment's
/// sampling_pixels_per_cell()).
int automatic_sampling_pixels_per_cell(int width, int height);

/// Throws kdt::Error naming path unless every texel is finite and >= 0 (naming the first
/// bad one, its position and the count) and the brightest channel times intensity is
/// within kMaxEnvironmentRadiance.
void check_environment_texels(const ImageRGB& image, float intensity, const std::string& path);

/// Builds the light from an image already in memory (same checks as for a file).
std::shared_ptr<const EnvironmentLight> make_environment_light(const EnvironmentDesc& desc,
                                                               ImageRGB image);

}  // namespace kdt
