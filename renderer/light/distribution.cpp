#include "renderer/light/distribution.h"

#include <algorithm>
#include <cmath>

#include "renderer/core/check.h"

namespace kdt {

Distribution1D::Distribution1D(std::vector<float> weights) : func_(std::move(weights)) {
    const size_t n = func_.size();
    cdf_.assign(n + 1, 0.0f);
    std::vector<double> acc(n + 1, 0.0);
    for (size_t i = 0; i < n; ++i) {
        KDT_CHECK(std::isfinite(func_[i]) && func_[i] >= 0.0f);
        acc[i + 1] = acc[i] + double(func_[i]);
    }
    sum_ = acc[n];
    if (sum_ > 0.0) {
        for (size_t i = 1; i < n; ++i) cdf_[i] = float(acc[i] / sum_);
        cdf_[n] = 1.0f;
    }
}

float Distribution1D::sample_continuous(float u, size_t* cell) const {
    KDT_DCHECK(!empty());
    const size_t n = func_.size();
    // Largest i with cdf[i] <= u: always a cell of non-zero width since u < 1 = cdf[n].
    size_t i = size_t(std::upper_bound(cdf_.begin(), cdf_.end(), u) - cdf_.begin());
    i = std::clamp<size_t>(i, 1, n) - 1;
    while (i + 1 < n && func_[i] == 0.0f) ++i;  // only reached through float rounding
    float width = cdf_[i + 1] - cdf_[i];
    float du = width > 0.0f ? (u - cdf_[i]) / width : 0.5f;
    du = std::clamp(du, 0.0f, 0.99999994f);
    if (cell) *cell = i;
    float x = (float(i) + du) / float(n);
    // Keep x inside cell i despite rounding so that the caller's cell lookup agrees.
    float lo = float(i) / float(n), hi = float(i + 1) / float(n);
    if (x >= hi) x = std::nextafter(hi, lo);
    if (x < lo) x = lo;
    return x;
}

Distribution2D::Distribution2D(const std::vector<float>& weights, int nu, int nv)
    : nu_(nu), nv_(nv) {
    KDT_CHECK(nu > 0 && nv > 0 && weights.size() == size_t(nu) * size_t(nv));
    conditional_.reserve(size_t(nv));
    std::vector<float> row_sums(static_cast<size_t>(nv));
    for (int y = 0; y < nv; ++y) {
        auto begin = weights.begin() + ptrdiff_t(size_t(y) * size_t(nu));
        conditional_.emplace_back(std::vector<float>(begin, begin + nu));
        row_sums[size_t(y)] = float(conditional_.back().sum());
    }
    marginal_ = Distribution1D(std::move(row_sums));
}

Vec2f Distribution2D::sample_continuous(const Vec2f& u, Vec2i* cell) const {
    size_t row = 0, col = 0;
    float v = marginal_.sample_continuous(u.y, &row);
    float x = conditional_[row].sample_continuous(u.x, &col);
    if (cell) *cell = Vec2i(int(col), int(row));
    return {x, v};
}

float Distribution2D::pdf(int x, int y) const {
    if (empty()) return 0.0f;
    return float(double(conditional_[size_t(y)].weight(size_t(x))) * double(nu_) * double(nv_) /
                 marginal_.sum());
}

float Distribution2D::pdf(const Vec2f& p) const {
    int x = std::clamp(int(p.x * float(nu_)), 0, nu_ - 1);
    int y = std::clamp(int(p.y * float(nv_)), 0, nv_ - 1);
    return pdf(x, y);
}

}  // namespace kdt
