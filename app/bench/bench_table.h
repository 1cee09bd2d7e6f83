// Reporting helpers the benchmarks share: the median of repeated timings, quotients that
// may have nothing to divide by, one number formatted printf-style (or "-"), and a table
// printed as Markdown and appended to a CSV file. Standard library only.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ostream>
#include <sstream>
#include <string>
#include <vector>

namespace kdt::app {

/// The median of `v` (the mean of the two middle values for an even count); 0 when empty.
inline double median(std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/// `num / den`, or NaN when `den` is zero: a mean, share or ratio of nothing, which fmt
/// prints as "-".
inline double quotient(double num, double den) { return den != 0.0 ? num / den : std::nan(""); }

/// Millions of `items` per second; NaN (printed "-") when there are no items: a rate of no
/// rays is no measurement.
inline double mega_rate(double items, double seconds) {
    return items > 0.0 ? quotient(items, seconds) * 1e-6 : std::nan("");
}

/// `v` formatted by the printf format `f`, which takes one double (e.g. "%.2f"); "-" when
/// `v` is not finite (a quotient without a denominator), in the Markdown and the CSV alike.
inline std::string fmt(const char* f, double v) {
    if (!std::isfinite(v)) return "-";
    char buf[64];
    std::snprintf(buf, sizeof(buf), f, v);
    return buf;
}

/// A table printed as Markdown (first column left-aligned, the others right-aligned) and
/// appended to a CSV file whose first column names the table.
struct Table {
    std::string name, title;
    std::vector<std::string> header;
    std::vector<std::vector<std::string>> rows;

    std::string markdown() const {
        std::ostringstream o;
        o << "### " << title << "\n\n|";
        for (const auto& h : header) o << " " << h << " |";
        o << "\n|";
        for (size_t i = 0; i < header.size(); ++i) o << (i == 0 ? " --- |" : " ---: |");
        o << "\n";
        for (const auto& r : rows) {
            o << "|";
            for (const auto& c : r) o << " " << c << " |";
            o << "\n";
        }
        return o.str();
    }
    void csv(std::ostream& o) const {
        o << "table";
        for (const auto& h : header) o << ",\"" << h << "\"";
        o << "\n";
        for (const auto& r : rows) {
            o << name;
            for (const auto& c : r) o << ",\"" << c << "\"";
            o << "\n";
        }
    }
};

}  // namespace kdt::app
