#include "renderer/light/mapping.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "renderer/core/check.h"

namespace kdt {
namespace {

Vec3f nearest(const ImageRGB& img, const Vec2f& uv) {
    int x = std::clamp(int(uv.x * float(img.width)), 0, img.width - 1);
    int y = std::clamp(int(uv.y * float(img.height)), 0, img.height - 1);
    return img.at(x, y);
}

}  // namespace

double disk_rect_area(double x0, double x1, double y0, double y1) {
    x0 = std::max(x0, -1.0);
    x1 = std::min(x1, 1.0);
    if (!(x1 > x0) || !(y1 > y0)) return 0.0;
    // Break [x0, x1] where the circle's upper or lower half crosses y0 or y1; on each piece
    // the clipped height is y1 or sqrt(1-x^2) above and y0 or -sqrt(1-x^2) below.
    double xs[6] = {x0, x1};
    int n = 2;
    for (double y : {y0, y1}) {
        if (std::abs(y) < 1.0) {
            double s = std::sqrt(1.0 - y * y);
            for (double xb : {-s, s}) {
                if (xb > x0 && xb < x1) xs[n++] = xb;
            }
        }
    }
    for (int i = 1; i < n;
         ++i) {  // insertion sort (std::sort on 6 elements trips GCC 12's -Warray-bounds)
        for (int j = i; j > 0 && xs[j] < xs[j - 1]; --j) std::swap(xs[j], xs[j - 1]);
    }
    auto circle_integral = [](double x) {  // integral of sqrt(1 - x^2)
        x = std::clamp(x, -1.0, 1.0);
        return 0.5 * (x * std::sqrt(1.0 - x * x) + std::asin(x));
    };
    double area = 0.0;
    for (int i = 0; i + 1 < n; ++i) {
        double a = xs[i], b = xs[i + 1];
        if (!(b > a)) continue;
        double m = 0.5 * (a + b);
        double c = std::sqrt(std::max(0.0, 1.0 - m * m));
        double hi = std::min(y1, c), lo = std::max(y0, -c);
        if (!(hi > lo)) continue;
        double ci = circle_integral(b) - circle_integral(a);
        // Strict comparisons: equality at the midpoint means the line touches the circle
        // there (y = +-1), so the circle is the bound on the whole piece.
        double upper = y1 < c ? y1 * (b - a) : ci;
        double lower = y0 > -c ? y0 * (b - a) : -ci;
        area += upper - lower;
    }
    return area;
}

ImageRGB latlong_to_angular(const ImageRGB& latlong, int size, int supersample) {
    KDT_CHECK(size > 0 && supersample > 0 && latlong.width > 0 && latlong.height > 0);
    ImageRGB out(size, size);
    for (int y = 0; y < size; ++y) {
        for (int x = 0; x < size; ++x) {
            Vec3f sum(0.0f);
            int inside = 0;
            for (int sy = 0; sy < supersample; ++sy) {
                for (int sx = 0; sx < supersample; ++sx) {
                    Vec2f st((float(x) + (float(sx) + 0.5f) / float(supersample)) / float(size),
                             (float(y) + (float(sy) + 0.5f) / float(supersample)) / float(size));
                    if (auto d = angular_dir_from_uv(st)) {
                        sum += nearest(latlong, latlong_uv_from_dir(*d));
                        ++inside;
                    }
                }
            }
            if (inside > 0) out.set(x, y, sum / float(inside));
        }
    }
    return out;
}

ImageRGB angular_to_latlong(const ImageRGB& angular, int width, int supersample) {
    KDT_CHECK(width > 1 && supersample > 0 && angular.width > 0 && angular.height > 0);
    const int height = width / 2;
    ImageRGB out(width, height);
    for (int y = 0; y < height; ++y) {
        for (int x = 0; x < width; ++x) {
            Vec3f sum(0.0f);
            for (int sy = 0; sy < supersample; ++sy) {
                for (int sx = 0; sx < supersample; ++sx) {
                    Vec2f uv((float(x) + (float(sx) + 0.5f) / float(supersample)) / float(width),
                             (float(y) + (float(sy) + 0.5f) / float(supersample)) / float(height));
                    sum += nearest(angular, angular_uv_from_dir(latlong_dir_from_uv(uv)));
                }
            }
            out.set(x, y, sum / float(supersample * supersample));
        }
    }
    return out;
}

}  // namespace kdt
