#include "renderer/io/obj_reader.h"

#include <algorithm>
#include <charconv>
#include <cstdint>
#include <cstring>
#include <exception>
#include <limits>
#include <new>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "renderer/core/error.h"
#include "renderer/core/timer.h"
#include "renderer/geometry/polygon.h"
#include "renderer/io/ply_simd.h"

namespace kdt {
namespace {

constexpr size_t kBlockBytes = size_t(1) << 20;
// The longest value or corner read; independent of the block size, so that a smaller block
// (obj::set_block_bytes) reads any file alike.
constexpr size_t kMaxTokenBytes = size_t(1) << 20;
size_t g_block_bytes = kBlockBytes;
// Vertices and normals are addressed by 32-bit indices; kNone (= the cap) marks a corner
// without a normal.
constexpr uint64_t kMaxElements = UINT32_MAX;
constexpr uint32_t kNone = UINT32_MAX;

bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\v' || c == '\f'; }
bool is_letter(char c) { return (c | 0x20) >= 'a' && (c | 0x20) <= 'z'; }
bool is_eol(char c) { return c == '\n' || c == '\r'; }

// The first CR or LF in [p, end), or end: one pass, where two memchr calls would scan a
// file of CR-only line endings to the end of its block for each line.
const char* find_eol(const char* p, const char* end) {
#if defined(__SSE2__)
    const __m128i lf = _mm_set1_epi8('\n'), cr = _mm_set1_epi8('\r');
    for (; end - p >= 16; p += 16) {
        const __m128i x = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p));
        const int m = _mm_movemask_epi8(_mm_or_si128(_mm_cmpeq_epi8(x, lf), _mm_cmpeq_epi8(x, cr)));
        if (m != 0) return p + __builtin_ctz(unsigned(m));
    }
#endif
    while (p < end && !is_eol(*p)) ++p;
    return p;
}

// A token for messages: quoted, at most 40 bytes, through printable(). Not excerpt(), whose
// "[N bytes]" would mislead here: a token longer than 40 bytes is often only the piece of it
// read so far (a statement longer than a block, a value past 1 MiB), so N would be the
// piece's length, not the token's.
std::string quoted(const char* b, const char* e) {
    const std::string_view token(b, size_t(std::min<ptrdiff_t>(e - b, 40)));
    return "'" + printable(token) + (e - b > 40 ? "...'" : "'");
}

// The next blank-separated token of [b, e) in [tb, te); false at the end of the statement
// or at a comment after it.
bool next_token(const char*& b, const char* e, const char*& tb, const char*& te) {
    while (b < e && is_blank(*b)) ++b;
    if (b == e || *b == '#') return false;
    tb = b;
    while (b < e && !is_blank(*b)) ++b;
    te = b;
    return true;
}

// For a decimal number that from_chars found out of float's range: true when it is huge
// (overflow, to infinity), false when tiny (underflow, to zero). The decimal exponent of
// its leading digit decides; it is far from 0 either way (>= 38 or <= -45).
bool overflows(const char* b, const char* e) {
    if (b < e && (*b == '-' || *b == '+')) ++b;
    int64_t magnitude = 0;  // the value lies in [10^(magnitude-1), 10^magnitude)
    bool point = false, nonzero = false;
    for (; b < e && (*b == '.' || (*b >= '0' && *b <= '9')); ++b) {
        if (*b == '.') {
            point = true;
        } else if (nonzero) {
            magnitude += point ? 0 : 1;
        } else if (*b != '0') {
            nonzero = true;
            magnitude = point ? magnitude : 1;
        } else if (point) {
            --magnitude;
        }
    }
    int64_t exponent = 0;
    if (b < e && (*b == 'e' || *b == 'E')) {
        ++b;
        const bool negative = b < e && *b == '-';
        if (b < e && (*b == '-' || *b == '+')) ++b;
        for (; b < e && *b >= '0' && *b <= '9'; ++b)
            exponent = std::min<int64_t>(exponent * 10 + (*b - '0'), int64_t(1) << 40);
        if (negative) exponent = -exponent;
    }
    return magnitude + exponent > 0;
}

// The values of a `v` or `vn` statement read so far.
struct Values {
    float v[3] = {0.0f, 0.0f, 0.0f};
    int count = 0;
};

// Where the largest positive (1-based) index of a kind was seen: positive indices may point
// at elements defined later, so they are checked at the end of the file.
struct Farthest {
    uint64_t index = 0;  // 0: none seen
    int64_t line = -1;
    int64_t face = -1;
};

class ObjParser {
public:
    ObjParser(FileReader& in, const MeshLoadOptions& options)
        : in_(in), options_(options), block_(g_block_bytes), all_normals_(options.keep_normals) {}

    TriangleMesh run(MeshLoadInfo* info) {
        const char *b = nullptr, *e = nullptr;
        while (next_line(b, e)) statement(b, e);
        return build(info);
    }

private:
    // `index` is 0-based (-1: none); messages count from 1, as OBJ indices do, so that
    // "vertex 1" is the vertex that "f 1 2 3" names.
    [[noreturn]] void fail_at(int64_t line, const std::string& element, int64_t index,
                              const std::string& message) const {
        ErrorLocation w;
        w.path = in_.path();
        w.line = line;
        w.element = element;
        w.index = index < 0 ? -1 : index + 1;
        throw Error(w, message);
    }
    [[noreturn]] void fail(const std::string& element, int64_t index,
                           const std::string& message) const {
        fail_at(line_, element, index, message);
    }

    bool next_line(const char*& b, const char*& e);
    bool long_line();
    void long_statement();
    void refill();
    void statement(const char* b, const char* e);
    void vertex(const char* b, const char* e);
    void normal(const char* b, const char* e);
    void face(const char* b, const char* e);
    // The parts of vertex(), normal() and face() that long_statement() shares: one value or
    // corner each, then the end of the statement.
    [[gnu::always_inline]] inline void vertex_value(Values& s, const char* tb, const char* te);
    [[gnu::always_inline]] inline void vertex_end(const Values& s);
    [[gnu::always_inline]] inline void normal_value(Values& s, const char* tb, const char* te);
    [[gnu::always_inline]] inline void normal_end(const Values& s);
    [[gnu::always_inline]] inline void face_corner(uint64_t& n, const char* tb, const char* te);
    [[gnu::always_inline]] inline void face_end(uint64_t n);
    [[noreturn, gnu::noinline]] void too_long(const char* element, uint64_t index, const char* what,
                                              const char* b, const char* e) const;
    void corner(const char* b, const char* e, int64_t face, uint64_t k);
    uint32_t index(const char* b, const char* e, uint64_t count, const char* what,
                   const char* plural, Farthest& farthest, int64_t face);
    float number(const char* b, const char* e, const char* element, uint64_t index) const;
    [[gnu::noinline]] void non_finite_vertex(uint64_t i, const Vec3f& p);
    TriangleMesh build(MeshLoadInfo* info);

    FileReader& in_;
    const MeshLoadOptions& options_;
    const size_t block_;  // bytes read at a time; a statement not ended within one is long

    // Input: buf_[pos_, end_) is unparsed; the next line's end is searched from scan_.
    std::vector<char> buf_;
    size_t pos_ = 0, scan_ = 0, end_ = 0;
    bool eof_ = false;
    bool skipping_ = false;  // inside a long comment whose read part was dropped
    std::string joined_;     // a line continued with '\', joined
    int64_t line_ = 0;       // the line the current statement starts on (1-based)
    int64_t next_line_ = 1;  // the line the next statement starts on
    uint64_t bytes_ = 0;

    std::vector<Vec3f> positions_, normals_;
    uint64_t normal_count_ = 0;  // normals_ is filled only with options.keep_normals
    std::vector<uint8_t> bad_;   // non-finite positions (drop_invalid), sized once one is seen
    uint64_t bad_count_ = 0;
    // Faces as read: corner counts, position index per corner, normal index per corner
    // while every corner so far has one (and normals are kept).
    // A face of fewer than 3 corners that drop_invalid drops has size 0 here, so that faces
    // keep their numbers in the file.
    std::vector<uint32_t> face_sizes_, corner_v_, corner_n_;
    bool all_normals_;
    bool face_lacks_normal_ = false;  // a corner of the current face has no normal
    uint64_t triangles_ = 0;
    Farthest farthest_v_, farthest_n_;
    Farthest face_start_v_, face_start_n_;  // farthest_v_ and farthest_n_ before this face
};

bool ObjParser::next_line(const char*& b, const char*& e) {
    line_ = next_line_;
    bool continued = false;
    for (;;) {
        const char* base = buf_.data();
        const size_t at = size_t(find_eol(base + scan_, base + end_) - base);
        // CR, LF and CRLF end a line; a CR ending the data read so far waits for the next
        // byte, which may be its LF.
        if (at < end_ && (base[at] == '\n' || at + 1 < end_ || eof_)) {
            const size_t next =
                at + 1 + size_t(base[at] == '\r' && at + 1 < end_ && base[at + 1] == '\n');
            ++next_line_;
            if (skipping_) {  // the end of a long comment: an empty statement
                skipping_ = false;
                b = e = base + at;
                pos_ = scan_ = next;
                break;
            }
            if (at > pos_ && base[at - 1] == '\\') {
                // A '\' ending the line continues the statement on the next line, except in
                // a comment line (which must not swallow a statement): one whose first byte
                // past blanks and continued line ends is '#'.
                const char* s = base + pos_;
                if (line_ == 1 && at - pos_ >= 3 && std::memcmp(s, "\xef\xbb\xbf", 3) == 0)
                    s += 3;  // BOM
                for (;;) {
                    while (s < base + at && is_blank(*s)) ++s;
                    if (s + 1 >= base + at || *s != '\\' || !is_eol(s[1])) break;
                    s += 2 + size_t(s[1] == '\r' && s[2] == '\n');
                }
                if (*s != '#') {
                    continued = true;
                    scan_ = next;
                    continue;
                }
            }
            b = base + pos_;
            e = base + at;
            pos_ = scan_ = next;
            break;
        }
        if (eof_) {
            if (pos_ == end_) return false;
            b = base + pos_;
            e = base + end_;  // the last line has no line end
            // A '\' ending the data continues the statement onto nothing, as one before a
            // final line end does (a comment line, which it would not continue, is dropped).
            if (e[-1] == '\\') --e;
            pos_ = scan_ = end_;
            break;
        }
        if ((skipping_ || end_ - pos_ >= block_) && long_line()) {
            b = e = buf_.data() + pos_;  // read by long_statement(): an empty statement
            return true;
        }
        refill();
    }
    if (continued) {
        // Each '\' before a line end becomes a blank.
        joined_.clear();
        for (const char* p = b; p < e; ++p) {
            if (*p == '\\' && p + 1 < e && is_eol(p[1])) {
                const char* q = p + 1;
                if (*q == '\r' && q + 1 < e && q[1] == '\n') ++q;
                joined_ += ' ';
                p = q;
                continue;
            }
            joined_ += *p;
        }
        b = joined_.data();
        e = b + joined_.size();
    }
    return true;
}

// A statement not ended within a block. A comment line (never continued) is dropped as it is
// read. Any other statement first gets the checks statement() would make first, so binary
// data fails at its first line after one block with the same message (tokens are quoted up
// to 40 bytes); then long_statement() reads it. Returns true once the statement is read.
bool ObjParser::long_line() {
    const char* b = buf_.data() + pos_;
    const char* e = buf_.data() + end_;
    const char* s = b;
    while (s < e && is_blank(*s)) ++s;
    if (skipping_ || (s < e && *s == '#')) {  // the rule next_line() applies to comments
        skipping_ = true;
        // A final CR is kept: it ends the comment, alone or with an LF still unread.
        const bool cr = e > b && e[-1] == '\r';
        if (cr) buf_[0] = '\r';
        pos_ = scan_ = 0;
        end_ = cr ? 1 : 0;
        return false;
    }
    if (line_ == 1 && e - b >= 3 && std::memcmp(b, "\xef\xbb\xbf", 3) == 0) b += 3;  // BOM
    while (b < e && is_blank(*b)) ++b;
    const char* k = b;
    while (k < e && !is_blank(*k)) ++k;
    // A line end (continuation) inside the first token changes the token, and 40 bytes or
    // less may not hold all of it, nor a '\' ending the data read, whose line end is unread:
    // long_statement() checks those.
    if (e - b > 40 && *b != '#' && !std::memchr(b, '\n', size_t(k - b)) &&
        !std::memchr(b, '\r', size_t(k - b)) && !(k == e && e[-1] == '\\')) {
        if (!is_letter(b[0]))
            fail("", -1,
                 "not an OBJ statement: " + quoted(b, k) + " (binary data or UTF-16 text?)");
        if (std::memchr(b, '\0', size_t(e - b)))
            fail("", -1, "NUL byte in a statement (binary data or UTF-16 text?)");
    }
    long_statement();
    return true;
}

// Reads the statement starting at pos_ to its end, holding one token (keyword, value or
// corner) at a time: blanks, comments and whole skipped statements are dropped as they are
// read, so a line's length costs no memory. A value or corner of kMaxTokenBytes or more is an
// error. Lines are counted again from line_: next_line() may have counted continued ones.
void ObjParser::long_statement() {
    enum class Kind { kKeyword, kVertex, kNormal, kFace, kOther };
    Kind kind = Kind::kKeyword;
    Values values;
    uint64_t corners = 0;
    bool comment = false;         // after a '#', up to the line end
    std::exception_ptr deferred;  // a value's error, thrown at the end of the statement
    char prev = '\n';             // the byte before pos_, for a '\' ending a line
    next_line_ = line_;
    if (line_ == 1) {  // a BOM, once its 3 bytes are read (a small block may hold fewer)
        while (end_ - pos_ < 3 && !eof_) refill();
        if (end_ - pos_ >= 3 && std::memcmp(buf_.data() + pos_, "\xef\xbb\xbf", 3) == 0) pos_ += 3;
    }
    // The length of the line end at p (CR, LF or CRLF).
    auto eol_length = [](const char* p, const char* end) {
        return size_t(1) + size_t(*p == '\r' && p + 1 < end && p[1] == '\n');
    };
    // A '\' at q continues the line: one before a line end, or one ending the data (onto
    // nothing, as next_line() reads it). Before lim, q + 1 < end unless the data has ended.
    auto continues_at = [this](const char* q, const char* end) {
        return *q == '\\' && (q + 1 < end ? is_eol(q[1]) : eof_);
    };
    bool done = false;
    while (!done) {
        const char* base = buf_.data();
        const char* p = base + pos_;
        const char* end = base + end_;
        // Up to two bytes of look-ahead ('\', CR, LF) tell line ends apart until the data ends.
        const char* lim = eof_ ? end : p + (end_ - pos_ > 2 ? end_ - pos_ - 2 : 0);
        while (p < lim) {
            if (comment || kind == Kind::kOther) {
                // Dropped up to the line end; a comment line may hold NULs and is not continued.
                const bool line_comment = kind == Kind::kKeyword;
                const char* x = find_eol(p, lim);
                if (!line_comment && std::memchr(p, '\0', size_t(x - p)))
                    fail("", -1, "NUL byte in a statement (binary data or UTF-16 text?)");
                if (x == lim) {
                    prev = lim[-1];
                    p = lim;
                    break;
                }
                const bool continues = !line_comment && (x > p ? x[-1] : prev) == '\\';
                p = x + eol_length(x, end);
                ++next_line_;
                prev = '\n';
                // A comment goes on over a continued line, as in a joined one.
                if (!continues) {
                    done = true;
                    break;
                }
                continue;
            }
            const char c = *p;
            if (is_blank(c)) {
                ++p;
            } else if (continues_at(p, end)) {  // continued: a blank
                if (p + 1 < end) {
                    p += 1 + eol_length(p + 1, end);
                    ++next_line_;
                } else {
                    ++p;
                }
            } else if (is_eol(c)) {
                p += eol_length(p, end);
                ++next_line_;
                done = true;
                break;
            } else if (c == '#') {
                comment = true;
            } else {
                const char* t = p;
                while (t < lim && !is_blank(*t) && !is_eol(*t) && !continues_at(t, end)) ++t;
                // A token reaching lim may go on; a keyword of over 40 bytes is none we read,
                // and a value or corner of kMaxTokenBytes is refused by the *_value() call
                // (deferred as any value's error; the rest is dropped as read).
                if (t == lim && !eof_ &&
                    (kind == Kind::kKeyword ? t - p <= 40 : size_t(t - p) < kMaxTokenBytes))
                    break;
                if (kind == Kind::kKeyword) {
                    if (!is_letter(*p))
                        fail("", -1,
                             "not an OBJ statement: " + quoted(p, t) +
                                 " (binary data or UTF-16 text?)");
                    const size_t n = size_t(t - p);
                    kind = n == 1 && p[0] == 'v'                  ? Kind::kVertex
                           : n == 2 && p[0] == 'v' && p[1] == 'n' ? Kind::kNormal
                           : (n == 1 && p[0] == 'f') || (n == 2 && p[0] == 'f' && p[1] == 'o')
                               ? Kind::kFace
                               : Kind::kOther;
                    if (kind == Kind::kOther) continue;  // dropped from p on, NULs checked
                } else {
                    if (std::memchr(p, '\0', size_t(t - p)))
                        fail("", -1, "NUL byte in a statement (binary data or UTF-16 text?)");
                    try {
                        if (kind == Kind::kVertex) vertex_value(values, p, t);
                        if (kind == Kind::kNormal) normal_value(values, p, t);
                        if (kind == Kind::kFace) face_corner(corners, p, t);
                    } catch (const Error&) {
                        // statement() refuses a NUL anywhere in the statement before its
                        // values: the rest is checked for one before this error is thrown.
                        deferred = std::current_exception();
                        kind = Kind::kOther;
                    }
                }
                p = t;
            }
        }
        pos_ = scan_ = size_t(p - base);
        if (done || (eof_ && pos_ == end_)) break;
        // Only a token that may go on is kept: under kMaxTokenBytes plus the look-ahead.
        refill();
    }
    if (deferred) std::rethrow_exception(deferred);
    if (kind == Kind::kVertex) vertex_end(values);
    if (kind == Kind::kNormal) normal_end(values);
    if (kind == Kind::kFace) face_end(corners);
}

void ObjParser::refill() {
    if (pos_ > 0) {
        std::memmove(buf_.data(), buf_.data() + pos_, end_ - pos_);
        end_ -= pos_;
        scan_ -= pos_;
        pos_ = 0;
    }
    if (buf_.empty()) {
        // One block, or less for a small file: +1 so that the read finding the end fits.
        buf_.resize(size_t(std::min<uint64_t>(block_, in_.size_bound() + 1)));
    } else if (end_ == buf_.size()) {
        // A line longer than the buffer (only before long_line() takes it, for a small
        // buffer) or a value that does not fit with its look-ahead (up to kMaxTokenBytes + 2
        // bytes): grow it, doubling, so that it costs linear time.
        buf_.resize(2 * buf_.size());
    }
    const size_t got = in_.read(buf_.data() + end_, buf_.size() - end_);
    if (got == 0) eof_ = true;
    end_ += got;
    bytes_ += got;
}

void ObjParser::statement(const char* b, const char* e) {
    if (line_ == 1 && e - b >= 3 && std::memcmp(b, "\xef\xbb\xbf", 3) == 0) b += 3;  // BOM
    while (b < e && is_blank(*b)) ++b;
    if (b == e || *b == '#') return;
    const char* k = b;
    while (k < e && !is_blank(*k)) ++k;
    if (!is_letter(b[0]))
        fail("", -1, "not an OBJ statement: " + quoted(b, k) + " (binary data or UTF-16 text?)");
    if (std::memchr(b, '\0', size_t(e - b)))
        fail("", -1, "NUL byte in a statement (binary data or UTF-16 text?)");
    const size_t n = size_t(k - b);
    if (n == 1 && b[0] == 'v') return vertex(k, e);
    if (n == 2 && b[0] == 'v' && b[1] == 'n') return normal(k, e);
    if ((n == 1 && b[0] == 'f') || (n == 2 && b[0] == 'f' && b[1] == 'o')) return face(k, e);
    // Anything else (vt, vp, l, p, o, g, s, usemtl, mtllib, free-form geometry, extensions)
    // is not needed for rendering.
}

float ObjParser::number(const char* b, const char* e, const char* element, uint64_t i) const {
    const char* p = b;
    if (e - p >= 2 && p[0] == '+' && p[1] != '+' && p[1] != '-') ++p;  // from_chars takes no '+'
    float x = 0.0f;
    const auto [end, ec] = std::from_chars(p, e, x);
    if (end != e || ec == std::errc::invalid_argument)
        fail(element, int64_t(i), "invalid number " + quoted(b, e));
    if (ec == std::errc::result_out_of_range) {
        x = overflows(p, e) ? std::numeric_limits<float>::infinity() : 0.0f;
        if (*p == '-') x = -x;
    }
    return x;
}

void ObjParser::vertex(const char* b, const char* e) {
    Values s;
    const char *tb = nullptr, *te = nullptr;
    while (next_token(b, e, tb, te)) vertex_value(s, tb, te);
    vertex_end(s);
}

// A value or corner of kMaxTokenBytes or more, whichever way it was read: in a line
// statement() takes whole or piece by piece in long_statement(), at any block size.
void ObjParser::too_long(const char* element, uint64_t i, const char* what, const char* b,
                         const char* e) const {
    fail(element, int64_t(i), std::string(what) + " " + quoted(b, e) + " longer than 1 MiB");
}

void ObjParser::vertex_value(Values& s, const char* tb, const char* te) {
    const uint64_t i = positions_.size();
    if (size_t(te - tb) >= kMaxTokenBytes) [[unlikely]]
        too_long("vertex", i, "value", tb, te);
    if (s.count == 7)
        fail("vertex", int64_t(i), "more than 7 values (x y z [w] or x y z r g b [a])");
    const float x = number(tb, te, "vertex", i);
    if (s.count < 3) s.v[s.count] = x;
    ++s.count;
}

void ObjParser::vertex_end(const Values& s) {
    const uint64_t i = positions_.size();
    if (i >= kMaxElements) fail("vertex", int64_t(i), "more than 2^32-1 vertices");
    if (s.count < 3)
        fail("vertex", int64_t(i),
             "has " + std::to_string(s.count) + " coordinates (x y z needed)");
    const Vec3f p(s.v[0], s.v[1], s.v[2]);
    if (!is_finite(p)) [[unlikely]]
        non_finite_vertex(i, p);
    positions_.push_back(p);
}

void ObjParser::non_finite_vertex(uint64_t i, const Vec3f& p) {
    if (!options_.drop_invalid)
        fail("vertex", int64_t(i),
             "non-finite coordinate (" + std::to_string(p.x) + ", " + std::to_string(p.y) + ", " +
                 std::to_string(p.z) + "); --drop-invalid drops the faces using it");
    bad_.resize(size_t(i) + 1, 0);
    bad_[size_t(i)] = 1;
    ++bad_count_;
}

void ObjParser::normal(const char* b, const char* e) {
    Values s;
    const char *tb = nullptr, *te = nullptr;
    while (next_token(b, e, tb, te)) normal_value(s, tb, te);
    normal_end(s);
}

void ObjParser::normal_value(Values& s, const char* tb, const char* te) {
    if (size_t(te - tb) >= kMaxTokenBytes) [[unlikely]]
        too_long("normal", normal_count_, "value", tb, te);
    if (s.count == 3) fail("normal", int64_t(normal_count_), "more than 3 values (x y z)");
    s.v[s.count++] = number(tb, te, "normal", normal_count_);
}

void ObjParser::normal_end(const Values& s) {
    const uint64_t i = normal_count_;
    if (i >= kMaxElements) fail("normal", int64_t(i), "more than 2^32-1 normals");
    if (s.count < 3)
        fail("normal", int64_t(i), "has " + std::to_string(s.count) + " values (x y z needed)");
    if (options_.keep_normals) normals_.emplace_back(s.v[0], s.v[1], s.v[2]);
    ++normal_count_;
}

void ObjParser::face(const char* b, const char* e) {
    uint64_t n = 0;
    const char *tb = nullptr, *te = nullptr;
    while (next_token(b, e, tb, te)) face_corner(n, tb, te);
    face_end(n);
}

void ObjParser::face_corner(uint64_t& n, const char* tb, const char* te) {
    const int64_t f = int64_t(face_sizes_.size());
    if (size_t(te - tb) >= kMaxTokenBytes) [[unlikely]]
        too_long("face", uint64_t(f), "corner", tb, te);
    if (n == kMaxElements) fail("face", f, "more than 2^32-1 vertices");
    if (n == 0) {
        face_lacks_normal_ = false;
        face_start_v_ = farthest_v_;
        face_start_n_ = farthest_n_;
    }
    corner(tb, te, f, n);
    ++n;
}

void ObjParser::face_end(uint64_t n) {
    const int64_t f = int64_t(face_sizes_.size());
    if (n < 3) [[unlikely]] {
        if (!options_.drop_invalid)
            fail("face", f,
                 std::to_string(n) + (n == 1 ? " index" : " indices") +
                     ", a face needs at least 3; --drop-invalid drops such faces");
        // Dropped, as PLY drops it: its corners go, and its indices are not checked against
        // the vertex and normal counts (build() counts it in info->dropped_faces).
        corner_v_.resize(corner_v_.size() - size_t(n));
        if (all_normals_) corner_n_.resize(corner_n_.size() - size_t(n));
        if (n > 0) {
            farthest_v_ = face_start_v_;
            farthest_n_ = face_start_n_;
        }
        face_sizes_.push_back(0);
        return;
    }
    face_sizes_.push_back(uint32_t(n));
    triangles_ += n - 2;
}

// Corner k (0-based) of face f: v, v/vt, v//vn or v/vt/vn. Texture coordinates are checked for
// form only.
void ObjParser::corner(const char* b, const char* e, int64_t f, uint64_t k) {
    const char* s1 = std::find(b, e, '/');
    if (s1 == b) fail("face", f, "corner " + quoted(b, e) + " has no vertex index");
    corner_v_.push_back(index(b, s1, positions_.size(), "vertex", "vertices", farthest_v_, f));
    uint32_t n = kNone;
    if (s1 < e) {
        const char* s2 = std::find(s1 + 1, e, '/');
        if (s2 > s1 + 1) {
            Farthest ignored;
            index(s1 + 1, s2, kMaxElements, "texture coordinate", "texture coordinates", ignored,
                  f);
        }
        if (s2 < e) {
            if (std::find(s2 + 1, e, '/') != e) fail("face", f, "invalid corner " + quoted(b, e));
            if (s2 + 1 < e)
                n = index(s2 + 1, e, normal_count_, "normal", "normals", farthest_n_, f);
        }
    }
    if (!all_normals_) return;
    // A face's first two corners may belong to a face that drop_invalid drops: a missing
    // normal there turns normals off only once a third corner keeps the face.
    face_lacks_normal_ |= n == kNone;
    if (face_lacks_normal_ && k >= 2) {
        all_normals_ = false;
        std::vector<uint32_t>().swap(corner_n_);
    } else {
        corner_n_.push_back(n);
    }
}

// A 1-based or (negative) relative index, resolved to 0-based against the `count` elements
// defined so far. Positive indices may point ahead; the farthest is checked at the end.
uint32_t ObjParser::index(const char* b, const char* e, uint64_t count, const char* what,
                          const char* plural, Farthest& farthest, int64_t f) {
    const char* p = b;
    const bool negative = p < e && *p == '-';
    if (p < e && (*p == '-' || *p == '+')) ++p;
    if (p == e || !std::all_of(p, e, [](char c) { return c >= '0' && c <= '9'; }))
        fail("face", f, std::string("invalid ") + what + " index " + quoted(b, e));
    uint64_t k = 0;
    for (const char* q = p; q < e; ++q) {
        // Saturates far beyond any count, so that huge indices stay out of range.
        if (k < (uint64_t(1) << 40)) k = 10 * k + uint64_t(*q - '0');
    }
    // The index as written, for messages (not built on the common path).
    auto text = [&] {
        return printable(std::string_view(b, size_t(std::min<ptrdiff_t>(e - b, 40))));
    };
    if (k == 0) fail("face", f, std::string(what) + " index 0 (OBJ indices start at 1)");
    if (negative) {
        if (k > count)
            fail("face", f,
                 std::string("relative ") + what + " index " + text() +
                     " points before the first " + what + " (" + std::to_string(count) + " " +
                     plural + " so far)");
        return uint32_t(count - k);
    }
    if (k > kMaxElements)
        fail("face", f,
             std::string(what) + " index " + text() +
                 " out of range (a mesh holds at most 2^32-1 " + plural + ")");
    if (k > farthest.index) farthest = {k, line_, f};
    return uint32_t(k - 1);
}

TriangleMesh ObjParser::build(MeshLoadInfo* info) {
    const uint64_t nv = positions_.size();
    if (nv == 0) fail_at(-1, "", -1, "no vertices (an empty file, or not an OBJ file)");
    if (farthest_v_.index > nv)
        fail_at(farthest_v_.line, "face", farthest_v_.face,
                "vertex index " + std::to_string(farthest_v_.index) + " out of range (" +
                    std::to_string(nv) + " vertices)");
    if (farthest_n_.index > normal_count_)
        fail_at(farthest_n_.line, "face", farthest_n_.face,
                "normal index " + std::to_string(farthest_n_.index) + " out of range (" +
                    std::to_string(normal_count_) + " normals)");
    if (bad_count_ > 0) bad_.resize(size_t(nv), 0);

    TriangleMesh mesh;
    mesh.triangles.reserve(size_t(triangles_));
    const bool use_normals = all_normals_ && triangles_ > 0;
    std::vector<uint32_t> remap;  // file position -> vertex, without normals, when some are dropped
    bool positions_moved = false;
    if (!use_normals) {
        // The file's vertices in file order (unused ones too), minus non-finite ones.
        if (bad_count_ == 0) {
            mesh.positions = std::move(positions_);
            positions_moved = true;
        } else {
            remap.assign(size_t(nv), kNone);
            mesh.positions.reserve(size_t(nv - bad_count_));
            for (size_t v = 0; v < nv; ++v) {
                if (bad_[v]) continue;
                remap[v] = uint32_t(mesh.positions.size());
                mesh.positions.push_back(positions_[v]);
            }
        }
    }
    // With normals: one vertex per distinct (position, normal) pair, in order of first use.
    // Most positions meet a single normal, kept in first_normal/first_vertex; the others go
    // through the map.
    std::vector<uint32_t> first_normal, first_vertex;
    std::unordered_map<uint64_t, uint32_t> split;
    if (use_normals) {
        first_normal.assign(size_t(nv), kNone);
        first_vertex.assign(size_t(nv), 0);
    }
    auto emit = [&](uint32_t v, uint32_t n) {
        if (mesh.positions.size() >= kMaxElements)
            fail_at(-1, "", -1, "more than 2^32-1 distinct (position, normal) pairs");
        mesh.positions.push_back(positions_[v]);
        mesh.normals.push_back(normals_[n]);
        return uint32_t(mesh.positions.size() - 1);
    };
    auto vertex_of = [&](size_t c) -> uint32_t {
        const uint32_t v = corner_v_[c];
        if (!use_normals) return remap.empty() ? v : remap[v];
        const uint32_t n = corner_n_[c];
        if (first_normal[v] == n) return first_vertex[v];
        if (first_normal[v] == kNone) {
            first_normal[v] = n;
            return first_vertex[v] = emit(v, n);
        }
        auto [it, inserted] = split.try_emplace(uint64_t(v) << 32 | n, 0);
        if (inserted) it->second = emit(v, n);
        return it->second;
    };

    uint64_t dropped = 0, degenerate = 0;
    std::vector<uint32_t> sorted;  // scratch for the degenerate test of big polygons
    std::vector<uint32_t> corner_vertex;
    std::vector<Vec3f> corner_pos;
    PolygonScratch scratch;
    // Positions by file index (idx below): moved into the mesh when kept as they are.
    const std::vector<Vec3f>& file_positions = positions_moved ? mesh.positions : positions_;
    size_t c = 0;
    for (const uint32_t n : face_sizes_) {
        if (n == 0) {  // fewer than 3 corners, dropped
            ++dropped;
            continue;
        }
        const uint32_t* idx = corner_v_.data() + c;
        bool is_bad = false;
        for (uint32_t k = 0; k < n && bad_count_ > 0; ++k) is_bad |= bad_[idx[k]] != 0;
        if (is_bad) {
            ++dropped;
            c += n;
            continue;
        }
        bool repeated = false;
        if (n <= 32) {
            for (uint32_t a = 0; a < n && !repeated; ++a)
                for (uint32_t b = a + 1; b < n && !repeated; ++b) repeated = idx[a] == idx[b];
        } else {
            // Big polygons: sort a copy instead of comparing all pairs.
            sorted.assign(idx, idx + n);
            std::sort(sorted.begin(), sorted.end());
            repeated = std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end();
        }
        degenerate += repeated;
        if (n == 3 || (n == 4 && quad_is_convex(file_positions[idx[0]], file_positions[idx[1]],
                                                file_positions[idx[2]], file_positions[idx[3]]))) {
            // The fan, which is what triangulate_polygon gives these.
            const uint32_t v0 = vertex_of(c);
            uint32_t prev = vertex_of(c + 1);
            for (uint32_t k = 2; k < n; ++k) {
                const uint32_t cur = vertex_of(c + k);
                mesh.triangles.emplace_back(v0, prev, cur);
                prev = cur;
            }
            c += n;
            continue;
        }
        // A polygon: its corners' vertices in corner order (vertex_of numbers new ones in
        // order of first use), then triangulate_polygon's split.
        corner_vertex.resize(n);
        corner_pos.resize(n);
        for (uint32_t k = 0; k < n; ++k) {
            corner_vertex[k] = vertex_of(c + k);
            corner_pos[k] = file_positions[idx[k]];
        }
        const size_t first = mesh.triangles.size();
        mesh.triangles.resize(first + n - 2);
        Vec3u* t = mesh.triangles.data() + first;
        triangulate_polygon(corner_pos, t, scratch);
        for (uint32_t k = 0; k + 2 < n; ++k)
            t[k] = Vec3u(corner_vertex[t[k].x], corner_vertex[t[k].y], corner_vertex[t[k].z]);
        c += n;
    }
    if (info) {
        info->format = "obj";
        info->encoding = "text";
        info->gzip = false;
        info->file_bytes = bytes_;
        info->source_faces = face_sizes_.size();
        info->dropped_faces = dropped;
        info->degenerate_faces = degenerate;
    }
    return mesh;
}

}  // namespace

namespace obj {

size_t set_block_bytes(size_t bytes) {
    const size_t old = g_block_bytes;
    g_block_bytes = std::max<size_t>(bytes, 1);
    return old;
}

}  // namespace obj

TriangleMesh read_obj(FileReader& reader, const MeshLoadOptions& options, MeshLoadInfo* info) {
    Timer timer;
    if (reader.gzip()) {
        ErrorLocation w;
        w.path = reader.path();
        throw Error(w, "gzip-compressed OBJ files are not supported");
    }
    try {
        TriangleMesh mesh = ObjParser(reader, options).run(info);
        if (info) info->seconds = timer.seconds();
        return mesh;
    } catch (const std::bad_alloc&) {
        ErrorLocation w;
        w.path = reader.path();
        throw Error(w, "out of memory reading the mesh");
    }
}

TriangleMesh read_obj(const std::string& path, const MeshLoadOptions& options, MeshLoadInfo* info) {
    // Opening through FileReader gives the same missing-file, directory and device messages
    // as for PLY.
    FileReader reader = FileReader::open(path);
    return read_obj(reader, options, info);
}

TriangleMesh read_obj_memory(const void* data, size_t size, const std::string& name,
                             const MeshLoadOptions& options, MeshLoadInfo* info) {
    FileReader reader = FileReader::from_memory(data, size, name);
    return read_obj(reader, options, info);
}

}  // namespace kdt
