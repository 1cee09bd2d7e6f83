// ASCII PLY elements: whole buffers of lines in one tight loop (on one thread or two), the
// token-by-token fast paths, and the general line parser that also reports every error.
#include <algorithm>
#include <bit>
#include <memory>
#include <string>
#include <system_error>
#include <vector>

#include "renderer/io/ply_line_scan.h"
#include "renderer/io/ply_parser.h"

namespace kdt::ply {

// The next non-blank line; false at the end of the data.
bool PlyParser::next_data_line(const char*& b, const char*& e) {
    auto too_long = [&] {
        ErrorLocation w;
        w.path = reader_.path();
        w.line = line_ + 1;
        throw Error(w, "line longer than 256 MiB");
    };
    while (in_.next_line(b, e, too_long)) {
        ++line_;
        if (skip_blanks(b, e) != e) return true;
    }
    return false;
}

// Fast paths: parse one element straight from the buffer, without finding the line end
// first; a newline ends the last token. They return false, consuming nothing, on anything
// unusual (blank line, line cut by the buffer end, bad value, extra values), and the
// caller then takes the line-based general path, which also reports the errors.
// Line-at-once versions of the fast paths (see classify_line): the same results, false on
// anything they do not take (the fast paths then try token by token).
[[gnu::always_inline]] inline bool PlyParser::line_ascii_scalars(const Element& el, const char*& p,
                                                                 const char* e, float* v) const {
    if constexpr (!kHaveLineClasses) return false;
    const LineClasses c = classify_line(p);
    const int len = line_length(c, p, e);
    if (len <= 0) return false;
    const uint64_t line = low_bits(len);
    const uint64_t tok = line & ~c.blank;
    if (tok & ~(c.digit | c.dot | c.minus)) return false;
    uint64_t starts = tok & ~(tok << 1);
    uint64_t ends = tok & ~(tok >> 1);  // last byte of each token
    if (size_t(__builtin_popcountll(starts)) != el.props.size()) return false;
    const char* le = p + len;
    for (const Property& prop : el.props) {
        const int s = __builtin_ctzll(starts);
        const int n = __builtin_ctzll(ends) - s + 1;
        starts &= starts - 1;
        ends &= ends - 1;
        if (prop.slot < 0) continue;
        const char* t = p + s;
        if (prop.type == PlyType::f32) {
            const uint64_t m = low_bits(n);
            if (!parse_plain_decimal(t, n, (c.dot >> s) & m, (c.minus >> s) & m, v[prop.slot]) &&
                !parse_real(t, le, v[prop.slot]))
                return false;
        } else if (prop.type == PlyType::f64) {
            const uint64_t m = low_bits(n);
            double d;
            if (!parse_plain_decimal(t, n, (c.dot >> s) & m, (c.minus >> s) & m, d) &&
                !parse_real(t, le, d))
                return false;
            v[prop.slot] = float(d);
        } else {
            int64_t x;
            if (parse_int(t, le, x) != IntResult::ok || x < type_min(prop.type) ||
                x > type_max(prop.type))
                return false;
            v[prop.slot] = float(x) * prop.scale;
        }
    }
    p = le + 1;
    return true;
}

// "3 a b c" with indices of up to 8 digits.
[[gnu::always_inline]] inline bool PlyParser::line_ascii_triangle(const char*& p, const char* e,
                                                                  int64_t* idx) const {
    if constexpr (!kHaveLineClasses) return false;
    const LineClasses c = classify_line(p);
    const int len = line_length(c, p, e);
    if (len <= 0 || !triangle_from_classes(c, p, len, idx)) return false;
    p += len + 1;
    return true;
}

bool PlyParser::fast_ascii_scalars(const Element& el, const char*& p, const char* e,
                                   float* v) const {
    if (line_ascii_scalars(el, p, e, v)) return true;
    for (const Property& prop : el.props) {
        p = skip_blanks(p, e);
        if (p == e || *p == '\n') return false;
        if (prop.slot < 0) {
            p = skip_token(p, e);
        } else if (prop.type == PlyType::f32) {
            if (!parse_real(p, e, v[prop.slot])) return false;
        } else if (prop.type == PlyType::f64) {
            double d;
            if (!parse_real(p, e, d)) return false;
            v[prop.slot] = float(d);
        } else {
            int64_t x;
            if (parse_int(p, e, x) != IntResult::ok || x < type_min(prop.type) ||
                x > type_max(prop.type))
                return false;
            v[prop.slot] = float(x) * prop.scale;
        }
    }
    p = skip_blanks(p, e);
    if (p < e && *p == '\n') {
        ++p;
        return true;
    }
    return p == e && in_.eof();
}

bool PlyParser::fast_ascii_triangle(const char*& p, const char* e, int64_t* idx) const {
    if (line_ascii_triangle(p, e, idx)) return true;
    p = skip_blanks(p, e);
    if (e - p < 2 || p[0] != '3' || !is_blank(p[1])) return false;
    ++p;
    for (int k = 0; k < 3; ++k) {
        p = skip_blanks(p, e);
        if (p == e || parse_int(p, e, idx[k]) != IntResult::ok) return false;
    }
    p = skip_blanks(p, e);
    if (p < e && *p == '\n') {
        ++p;
        return true;
    }
    return p == e && in_.eof();
}

// Lines from p (up to e) of an all-scalar element, or "3 a b c" faces, stored as elements
// first, first + 1, ..., at most max_lines of them; stops at the first line the fast path
// cannot take (including a line cut by e, non-finite vertices and invalid or degenerate
// faces) and never throws. Faces are written to their entries of a sized array, or appended
// when `append` (one thread). Threads call it on disjoint line ranges, so they write disjoint
// array entries.
PlyParser::LinesResult PlyParser::parse_lines(const Element& el, bool faces, bool is_vertex,
                                              const char* p, const char* e, uint64_t first,
                                              uint64_t max_lines, bool append) {
    LinesResult r;
    r.end = p;
    float v[9] = {};
    int64_t idx[3];
    const bool xyz = is_vertex && xyz_only_;
    // Byte classes of the window [p, p + have): one classification serves every line that
    // ends inside it, so finding the next line is a shift, not a dependent 64-byte load.
    LineClasses c;
    int have = 0;
#ifdef KDT_PLY_VBMI
    __m512i wd = _mm512_setzero_si512();  // digit values of the window
    int off = 0;                          // p's offset in the window
#endif
    while (p < e && r.lines < max_lines) {
        const char* q = p;
        const size_t k = size_t(first + r.lines);
        int len = -1;
        if (kHaveLineClasses && (faces || xyz)) {
            if (have == 0 || (c.newline == 0 && have < 64)) {
                c = classify_line(p);
                have = int(std::min<ptrdiff_t>(64, e - p));
                c.newline &= low_bits(have);
#ifdef KDT_PLY_VBMI
                wd = window_digits(p);
                off = 0;
#endif
            }
            if (c.newline) len = __builtin_ctzll(c.newline);
        }
        if (faces) {
            int64_t ix[3];  // registers; idx[] is the token path's, in memory
#ifdef KDT_PLY_VBMI
            const bool line_ok = len > 0 && triangle_vbmi(c, wd, off, p, len, ix);
#else
            const bool line_ok = len > 0 && triangle_from_classes(c, p, len, ix);
#endif
            if (line_ok) {
                q = p + len + 1;
            } else {
                if (!fast_ascii_triangle(q, e, idx)) break;
                ix[0] = idx[0], ix[1] = idx[1], ix[2] = idx[2];
                have = 0;
            }
            if (uint64_t(ix[0]) >= vertex_count_ || uint64_t(ix[1]) >= vertex_count_ ||
                uint64_t(ix[2]) >= vertex_count_ || ix[0] == ix[1] || ix[1] == ix[2] ||
                ix[0] == ix[2])
                break;
            const Vec3u t{uint32_t(ix[0]), uint32_t(ix[1]), uint32_t(ix[2])};
            if (append)
                mesh_.triangles.push_back(t);
            else
                mesh_.triangles[k] = t;
        } else if (xyz) {
            Vec3f pos;
#ifdef KDT_PLY_VBMI
            const bool line_ok =
                len > 0 && (xyz_vbmi(c, wd, off, len, pos) || xyz_from_classes(c, p, len, pos));
#else
            const bool line_ok = len > 0 && xyz_from_classes(c, p, len, pos);
#endif
            if (line_ok) {
                q = p + len + 1;
            } else {
                if (!fast_ascii_scalars(el, q, e, v)) break;
                pos = Vec3f(v[kPosX], v[kPosY], v[kPosZ]);
                have = 0;
            }
            if (!is_finite(pos)) break;
            mesh_.positions[k] = pos;
        } else {
            if (!line_ascii_scalars(el, q, e, v) && !fast_ascii_scalars(el, q, e, v)) break;
            if (is_vertex) {
                // Exponent bits per coordinate, read back one float at a time: a wider load of
                // v[] would wait for the three separate stores (no store forwarding).
                const uint32_t bx = std::bit_cast<uint32_t>(v[kPosX]);
                const uint32_t by = std::bit_cast<uint32_t>(v[kPosY]);
                const uint32_t bz = std::bit_cast<uint32_t>(v[kPosZ]);
                constexpr uint32_t kExp = 0x7f800000u;
                if ((bx & kExp) == kExp || (by & kExp) == kExp || (bz & kExp) == kExp) break;
                Vec3f& pos = mesh_.positions[k];
                pos.x = std::bit_cast<float>(bx);
                pos.y = std::bit_cast<float>(by);
                pos.z = std::bit_cast<float>(bz);
                if (has_normals_) mesh_.normals[k] = Vec3f(v[kNormX], v[kNormY], v[kNormZ]);
                if (has_colors_) mesh_.colors[k] = Vec3f(v[kColR], v[kColG], v[kColB]);
            }
        }
        if (have > 0) {
            // Move the window's classes on to the next line (or drop them at its end).
            const int shift = int(q - p);
            if (shift >= have) {
                have = 0;
            } else {
                c.digit >>= shift;
                c.blank >>= shift;
                c.dot >>= shift;
                c.minus >>= shift;
                c.newline >>= shift;
                have -= shift;
#ifdef KDT_PLY_VBMI
                off += shift;
#endif
            }
        }
        p = q;
        ++r.lines;
        r.end = p;
    }
    return r;
}

// Parses the complete lines in the buffer (up to the element's end) in one tight loop. One
// thread runs it straight over the buffer. Two threads take half of the bytes each, split at
// a newline; the second half's first element index comes from counting newlines in the
// first. Returns how many elements were committed; 0 means "take the serial path for the
// next line" (small input, partial state, or a line the fast path cannot take, which the
// serial path then parses or reports). `poor` tells the caller to stay serial for the rest of
// the element (two threads: nothing or under half the chunk committed).
uint64_t PlyParser::parallel_chunk(const Element& el, uint64_t i, bool faces, bool is_vertex,
                                   bool& poor) {
    constexpr size_t kMinChunk = size_t(256) << 10;
    const uint64_t remaining = el.count - i;
    if (in_.avail() < kMinChunk && !in_.eof()) in_.fill(in_.capacity());
    if (threads_ == 1) {
        // No newline count: the loop stops at the element's end, the first line it cannot
        // take, or the line cut by the buffer end, and costs nothing when it stops at once.
        poor = false;
        if (faces && (mesh_.triangles.size() != i || !bad_vertex_.empty())) {
            poor = true;
            return 0;
        }
        // The arrays hold the lines the buffer can hold: a byte and a separator per value.
        const uint64_t fit = std::min<uint64_t>(
            remaining, in_.avail() / (2 * std::max<size_t>(el.props.size(), 1)) + 1);
        if (is_vertex) grow_vertices(el, i + fit);
        if (faces) grow_capacity(mesh_.triangles, i + fit, el);
        LinesResult r =
            parse_lines(el, faces, is_vertex, in_.pos(), in_.end(), i, remaining, faces);
        if (faces) source_faces_ += r.lines;
        in_.advance(size_t(r.end - in_.pos()));
        line_ += int64_t(r.lines);
        return r.lines;
    }
    // Every early exit turns the parallel path off for the rest of the element, so no
    // buffer is ever scanned once per line.
    poor = true;
    if (faces && (mesh_.triangles.size() != i || !bad_vertex_.empty())) return 0;
    const char* b = in_.pos();
    const char* e = in_.end();
    if (size_t(e - b) < kMinChunk) return 0;
    const void* last = memrchr(b, '\n', size_t(e - b));
    if (!last) return 0;
    e = static_cast<const char*>(last) + 1;
    if (!helper_) {
        try {
            helper_ = std::make_unique<Helper>();
        } catch (const std::system_error&) {
            threads_ = 1;  // no second thread to be had: one thread from now on
            poor = false;
            return 0;
        }
    }
    // Pieces of about kPieceBytes, cut after a newline; the threads count each piece's
    // lines, the prefix sums give each piece its first element index, and the threads
    // parse the pieces.
    constexpr size_t kPieceBytes = size_t(64) << 10;
    std::vector<const char*> cut{b};
    while (size_t(e - cut.back()) > kPieceBytes) {
        const char* q = cut.back() + kPieceBytes;
        cut.push_back(static_cast<const char*>(std::memchr(q, '\n', size_t(e - q))) + 1);
    }
    if (cut.back() != e) cut.push_back(e);
    const size_t pieces = cut.size() - 1;
    std::vector<uint64_t> lines(pieces), first(pieces);
    helper_->parallel_for(pieces, [&](size_t k) { lines[k] = count_newlines(cut[k], cut[k + 1]); });
    uint64_t total = 0;
    size_t used = 0;
    for (; used < pieces && total < remaining; ++used) {
        first[used] = total;
        // The element ends inside this piece: parse only its own lines.
        lines[used] = std::min(lines[used], remaining - total);
        total += lines[used];
    }
    if (is_vertex) grow_vertices(el, i + total);
    if (faces) {
        grow_capacity(mesh_.triangles, i + total, el);
        mesh_.triangles.resize(size_t(i + total));
    }
    std::vector<LinesResult> result(used);
    helper_->parallel_for(used, [&](size_t k) {
        result[k] =
            parse_lines(el, faces, is_vertex, cut[k], cut[k + 1], i + first[k], lines[k], false);
    });
    // Commit the pieces up to and including the first one the fast path stopped in.
    uint64_t done = 0;
    const char* end = b;
    for (size_t k = 0; k < used; ++k) {
        done += result[k].lines;
        end = result[k].end;
        if (result[k].lines != lines[k]) break;
    }
    if (faces) {
        mesh_.triangles.resize(size_t(i + done));
        source_faces_ += done;
    }
    poor = done < total / 2;
    in_.advance(size_t(end - in_.pos()));
    line_ += int64_t(done);
    return done;
}

void PlyParser::read_ascii_element(Element& el) {
    const bool is_vertex = &el == &elements_[size_t(vertex_el_)];
    const bool is_face = face_el_ >= 0 && &el == &elements_[size_t(face_el_)];
    const bool face_fast = is_face && el.props.size() == 1;
    float v[9] = {};
    const bool scalars_fast = !el.has_lists;
    // The tight loop over whole buffers, on one thread or two.
    bool parallel = scalars_fast || face_fast;
    uint64_t misses = 0, hits = 0;
    for (uint64_t i = 0; i < el.count; ++i) {
        if (parallel) {
            uint64_t before = i;
            bool poor = false;
            uint64_t done = parallel_chunk(el, i, face_fast, is_vertex, poor);
            hits += done;
            // Inputs the fast path keeps rejecting (say, blank lines or quads everywhere) go
            // serial, so no line is tried twice for long.
            if (done == 0 && ++misses > 64 && misses * 16 > hits) poor = true;
            if (poor) parallel = false;
            if (done > 0) {
                i = before + done - 1;
                continue;
            }
        }
        if (scalars_fast || face_fast) {
            // A partial line at the buffer end fails the fast path; refill early instead.
            if (in_.avail() < 256 && !in_.eof()) in_.fill(256);
            const char* p = in_.pos();
            int64_t idx[3];
            if (scalars_fast ? fast_ascii_scalars(el, p, in_.end(), v)
                             : fast_ascii_triangle(p, in_.end(), idx)) {
                in_.advance(size_t(p - in_.pos()));
                ++line_;
                if (is_vertex) {
                    store_vertex(el, i, v);
                } else if (face_fast) {
                    if (uint64_t(idx[0]) < vertex_count_ && uint64_t(idx[1]) < vertex_count_ &&
                        uint64_t(idx[2]) < vertex_count_ && bad_vertex_.empty() &&
                        idx[0] != idx[1] && idx[1] != idx[2] && idx[0] != idx[2]) {
                        ++source_faces_;
                        mesh_.triangles.emplace_back(uint32_t(idx[0]), uint32_t(idx[1]),
                                                     uint32_t(idx[2]));
                    } else {
                        emit_face(el, i, idx, 3);
                    }
                }
                continue;
            }
        }
        read_ascii_line(el, i, v);
    }
}

// One element from the next non-blank line, property by property: the path for any layout,
// and the one that reports every error in a line. v: scratch for the 9 vertex slots.
void PlyParser::read_ascii_line(Element& el, uint64_t i, float* v) {
    const bool is_vertex = &el == &elements_[size_t(vertex_el_)];
    const char* b;
    const char* e;
    if (!next_data_line(b, e))
        fail_data(el, i, line_ + 1, -1,
                  "unexpected end of data (file truncated? the header declares " +
                      std::to_string(el.count) + " " + excerpt(el.name) + " elements)");
    const char* p = b;
    bool have_face = false, face_kept = true;
    for (const Property& prop : el.props) {
        p = skip_blanks(p, e);
        if (p == e)
            fail_at(el, i,
                    "missing value for property " + excerpt(prop.name) + " (line too short)");
        if (!prop.is_list()) {
            if (prop.slot < 0) {
                p = skip_token(p, e);
                continue;
            }
            bool ok = true;
            if (prop.type == PlyType::f32) {
                ok = parse_real(p, e, v[prop.slot]);
            } else if (prop.type == PlyType::f64) {
                double d = 0;
                ok = parse_real(p, e, d);
                v[prop.slot] = float(d);
            } else {
                int64_t x = 0;
                const char* start = p;
                IntResult r = parse_int(p, e, x);
                ok = r == IntResult::ok;
                if (ok && (x < type_min(prop.type) || x > type_max(prop.type)))
                    fail_at(el, i,
                            "value " + token_text(start, e) + " of property " + excerpt(prop.name) +
                                " out of range for its type");
                v[prop.slot] = float(x) * prop.scale;
            }
            if (!ok)
                fail_at(
                    el, i,
                    "invalid number '" + token_text(p, e) + "' for property " + excerpt(prop.name));
            continue;
        }
        int64_t count = 0;
        const char* start = p;
        IntResult r = parse_int(p, e, count);
        if (r != IntResult::ok || count > type_max(prop.count_type) ||
            count < type_min(prop.count_type))
            fail_at(el, i,
                    "invalid list count '" + token_text(start, e) + "' for " + excerpt(prop.name));
        if (count < 0)
            fail_at(el, i,
                    "negative list count " + std::to_string(count) + " in " + excerpt(prop.name));
        if (prop.slot != kIndices) {
            for (int64_t k = 0; k < count; ++k) {
                p = skip_blanks(p, e);
                if (p == e)
                    fail_at(el, i,
                            "list " + excerpt(prop.name) + " has " + std::to_string(k) + " of " +
                                std::to_string(count) + " values");
                p = skip_token(p, e);
            }
            continue;
        }
        face_kept = check_face_size(el, i, count);
        poly_.clear();
        for (int64_t k = 0; k < count; ++k) {
            p = skip_blanks(p, e);
            if (p == e)
                fail_at(el, i,
                        "face lists " + std::to_string(k) + " of " + std::to_string(count) +
                            " vertex indices");
            int64_t x = 0;
            const char* s = p;
            if (is_integer(prop.type)) {
                if (parse_int(p, e, x) != IntResult::ok)
                    fail_at(el, i, "invalid vertex index '" + token_text(s, e) + "'");
            } else {
                // Read as a double whatever the item type, so an integer written out in full
                // is that integer even past float's 2^24.
                double d = 0;
                if (!parse_real(p, e, d))
                    fail_at(el, i, "invalid vertex index '" + token_text(s, e) + "'");
                x = real_index(el, i, d, token_text(s, e));
            }
            poly_.push_back(x);
        }
        have_face = true;
    }
    if (skip_blanks(p, e) != e)
        fail_at(el, i,
                "more values on the line than the header declares ('" +
                    token_text(skip_blanks(p, e), e) + "' after the last property)");
    if (is_vertex) store_vertex(el, i, v);
    if (have_face && !face_kept) return;
    if (have_face && is_strip(el))
        emit_strip(el, i, poly_.data(), poly_.size());
    else if (have_face)
        emit_face(el, i, poly_.data(), poly_.size());
}

}  // namespace kdt::ply
