// Piecewise-constant 1D and 2D distributions for importance sampling (inversion of the
// cumulative distribution, continuous within each cell; Pharr, Jakob & Humphreys,
// "Physically Based Rendering", sec. 13.3 (3rd ed.) / A.4 (4th ed.)). Depends on core.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "renderer/core/math.h"

namespace kdt {

/// A piecewise-constant density on [0,1) with n cells of non-negative weights.
/// The density of cell i is n * w[i] / sum(w); a zero sum leaves the distribution empty.
class Distribution1D {
public:
    Distribution1D() = default;
    /// weights must be finite and >= 0 (checked).
    explicit Distribution1D(std::vector<float> weights);

    size_t size() const { return func_.size(); }
    /// Sum of the weights (in double precision).
    double sum() const { return sum_; }
    /// True when every weight is zero (or there are none): nothing can be sampled.
    bool empty() const { return !(sum_ > 0.0); }

    /// Samples x in [0,1) by inversion; `cell` receives its cell. Requires !empty().
    float sample_continuous(float u, size_t* cell) const;
    /// Probability of cell i (w[i] / sum).
    float pmf(size_t i) const { return empty() ? 0.0f : float(func_[i] / sum_); }
    /// Density at any x inside cell i (n * w[i] / sum).
    float pdf(size_t i) const { return empty() ? 0.0f : float(func_[i] * double(size()) / sum_); }
    float weight(size_t i) const { return func_[i]; }

private:
    std::vector<float> func_;
    std::vector<float> cdf_;  ///< size n + 1, cdf_[0] = 0, cdf_[n] = 1
    double sum_ = 0.0;
};

/// A piecewise-constant density on [0,1)^2 over an nu x nv grid, row-major weights
/// (row v, column u): a marginal over rows and one conditional per row.
class Distribution2D {
public:
    Distribution2D() = default;
    Distribution2D(const std::vector<float>& weights, int nu, int nv);

    int nu() const { return nu_; }
    int nv() const { return nv_; }
    bool empty() const { return marginal_.empty(); }
    double sum() const { return marginal_.sum(); }

    /// Samples a point in [0,1)^2 (uniform within its cell); `cell` receives (column, row).
    /// Requires !empty().
    Vec2f sample_continuous(const Vec2f& u, Vec2i* cell) const;
    /// Density (w.r.t. area in [0,1)^2) of cell (column x, row y): nu nv w / sum.
    float pdf(int x, int y) const;
    /// Density at a point of [0,1)^2 (clamped to the grid).
    float pdf(const Vec2f& p) const;

private:
    int nu_ = 0, nv_ = 0;
    std::vector<Distribution1D> conditional_;
    Distribution1D marginal_;
};

}  // namespace kdt
