// Tests of renderer/light/distribution.h: sampled frequencies match the pmf, zero cells are
// never chosen, samples are continuous within their cell, pdfs integrate to one.
#include "renderer/light/distribution.h"

#include <cmath>
#include <cstdint>

#include <gtest/gtest.h>

#include "tests/test_util.h"

namespace kdt {
namespace {

using test::HashRng;

TEST(Distribution1D, FrequenciesMatchThePmf) {
    Distribution1D d({1.0f, 0.0f, 3.0f, 0.0f, 0.0f, 2.0f, 0.5f});
    ASSERT_FALSE(d.empty());
    EXPECT_DOUBLE_EQ(d.sum(), 6.5);
    const int n = 200000;
    std::vector<int> count(d.size(), 0);
    std::vector<double> offset(d.size(), 0.0);
    HashRng rng(1);
    for (int i = 0; i < n; ++i) {
        size_t cell = 99;
        float x = d.sample_continuous(rng.next(), &cell);
        ASSERT_LT(cell, d.size());
        ASSERT_GE(x, float(cell) / d.size());
        ASSERT_LT(x, float(cell + 1) / d.size());
        ++count[cell];
        offset[cell] += x * d.size() - cell;
    }
    double pdf_integral = 0.0;
    for (size_t i = 0; i < d.size(); ++i) {
        double p = d.pmf(i);
        pdf_integral += d.pdf(i) / d.size();
        EXPECT_NEAR(count[i], n * p, 5 * std::sqrt(n * p * (1 - p)) + 1) << "cell " << i;
        if (d.weight(i) == 0.0f) {
            EXPECT_EQ(count[i], 0);
        }
        if (count[i] > 1000) {
            EXPECT_NEAR(offset[i] / count[i], 0.5, 0.02) << "uniform within cell";
        }
    }
    EXPECT_NEAR(pdf_integral, 1.0, 1e-6);
}

TEST(Distribution1D, ExtremesNeverPickZeroCells) {
    Distribution1D d({0.0f, 0.0f, 1.0f, 0.0f, 1.0f, 0.0f});
    for (float u : {0.0f, 1e-9f, 0.5f, std::nextafter(0.5f, 0.0f), std::nextafter(1.0f, 0.0f)}) {
        size_t cell = 0;
        d.sample_continuous(u, &cell);
        EXPECT_TRUE(cell == 2 || cell == 4) << u;
    }
    Distribution1D zero({0.0f, 0.0f});
    EXPECT_TRUE(zero.empty());
    EXPECT_EQ(zero.pdf(0), 0.0f);
}

TEST(Distribution2D, FrequenciesMatchThePdf) {
    const int nu = 5, nv = 4;
    std::vector<float> w(nu * nv);
    for (int i = 0; i < nu * nv; ++i) w[size_t(i)] = float((i * 7) % 5);  // some zeros
    Distribution2D d(w, nu, nv);
    const int n = 200000;
    std::vector<int> count(w.size(), 0);
    HashRng rng(2);
    double sum = 0.0;
    for (float x : w) sum += x;
    for (int i = 0; i < n; ++i) {
        Vec2i cell;
        Vec2f p = d.sample_continuous({rng.next(), rng.next()}, &cell);
        ASSERT_EQ(int(p.x * nu), cell.x);
        ASSERT_EQ(int(p.y * nv), cell.y);
        ++count[size_t(cell.y * nu + cell.x)];
    }
    double integral = 0.0;
    for (int y = 0; y < nv; ++y) {
        for (int x = 0; x < nu; ++x) {
            double p = w[size_t(y * nu + x)] / sum;
            EXPECT_NEAR(d.pdf(x, y), p * nu * nv, 1e-5);
            integral += d.pdf(x, y) / (nu * nv);
            EXPECT_NEAR(count[size_t(y * nu + x)], n * p, 5 * std::sqrt(n * p * (1 - p)) + 1);
        }
    }
    EXPECT_NEAR(integral, 1.0, 1e-5);
}

}  // namespace
}  // namespace kdt
