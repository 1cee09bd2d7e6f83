// The PLY header: keywords, elements and properties, their roles, and counts the input
// cannot hold.
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

#include "renderer/io/ply_numbers.h"
#include "renderer/io/ply_parser.h"

namespace kdt::ply {

void PlyParser::parse_header() {
    // One bound for the whole header: a line may run only to the header's 4 MiB.
    auto too_long = [&] {
        ++line_;  // the line being read
        fail_header("no end_header in the first 4 MiB (missing end_header?)");
    };
    const char* b;
    const char* e;
    auto split = [](const char* p, const char* end, std::vector<std::string_view>& out) {
        out.clear();
        for (;;) {
            p = skip_blanks(p, end);
            if (p == end) break;
            const char* t = skip_token(p, end);
            out.emplace_back(p, size_t(t - p));
            p = t;
        }
    };
    std::vector<std::string_view> tok;

    // CR-only line ends (old Mac) would make the whole header one line. The data parsers
    // split lines at LF (CRLF is LF with a CR before it), so such a file is refused, by name.
    if (in_.fill(5) && std::memcmp(in_.pos(), "ply\r", 4) == 0 && in_.pos()[4] != '\n') {
        line_ = 1;
        fail_header(
            "line ends are CR only (old Mac); PLY files are read with LF or CRLF line ends: "
            "convert them first (for an ascii PLY: tr '\\r' '\\n' < IN > OUT)");
    }
    if (!in_.next_line(b, e, too_long, kMaxHeaderBytes)) {
        line_ = 1;
        fail_header("empty file (not a PLY file)");
    }
    ++line_;
    split(b, e, tok);
    if (tok.size() != 1 || tok[0] != "ply")
        fail_header("not a PLY file (the first line must be 'ply')");

    bool have_format = false, have_end = false;
    while (!have_end) {
        if (in_.offset() >= kMaxHeaderBytes) too_long();
        if (!in_.next_line(b, e, too_long, kMaxHeaderBytes - size_t(in_.offset()))) {
            fail_header("missing end_header (the file ends inside the header)");
        }
        ++line_;
        split(b, e, tok);
        if (tok.empty()) continue;
        std::string_view kw = tok[0];
        if (kw == "format") {
            if (have_format) fail_header("second format line");
            if (tok.size() != 3)
                fail_header(
                    "unknown format line '" + excerpt(std::string_view(b, size_t(e - b))) +
                    "' (expected 'format ascii|binary_little_endian|binary_big_endian 1.0')");
            check_version(tok[2]);
            if (tok[1] == "ascii")
                encoding_ = PlyEncoding::ascii;
            else if (tok[1] == "binary_little_endian")
                encoding_ = PlyEncoding::binary_little_endian;
            else if (tok[1] == "binary_big_endian")
                encoding_ = PlyEncoding::binary_big_endian;
            else
                fail_header("unknown format '" + excerpt(tok[1]) + "'");
            have_format = true;
        } else if (kw == "element") {
            if (tok.size() != 3)
                fail_header("malformed element line (expected 'element NAME COUNT')");
            Element el;
            el.name = std::string(tok[1]);
            el.line = line_;
            const char* p = tok[2].data();
            int64_t count = 0;
            IntResult r = parse_int(p, tok[2].data() + tok[2].size(), count);
            if (r == IntResult::invalid)
                fail_header("element " + excerpt(el.name) + ": count '" + excerpt(tok[2]) +
                            "' is not an integer");
            if (r == IntResult::overflow || count > int64_t(1) << 48)
                fail_header("element " + excerpt(el.name) + ": count " + excerpt(tok[2]) +
                            " is too large");
            if (count < 0)
                fail_header("element " + excerpt(el.name) + ": negative count " +
                            std::to_string(count));
            el.count = uint64_t(count);
            for (const Element& other : elements_)
                if (other.name == el.name)
                    fail_header("second element named '" + excerpt(el.name) + "'");
            elements_.push_back(std::move(el));
        } else if (kw == "property") {
            if (elements_.empty()) fail_header("property before any element");
            Element& el = elements_.back();
            Property prop;
            if (tok.size() >= 2 && tok[1] == "list") {
                if (tok.size() != 5)
                    fail_header(
                        "malformed list property (expected 'property list COUNT_TYPE ITEM_TYPE "
                        "NAME')");
                prop.count_type = parse_type(tok[2]);
                prop.type = parse_type(tok[3]);
                if (prop.count_type == PlyType::none)
                    fail_header("unknown property type '" + excerpt(tok[2]) + "'");
                if (prop.type == PlyType::none)
                    fail_header("unknown property type '" + excerpt(tok[3]) + "'");
                if (!is_integer(prop.count_type))
                    fail_header("list count type '" + excerpt(tok[2]) + "' is not an integer type");
                prop.name = std::string(tok[4]);
                el.has_lists = true;
            } else {
                if (tok.size() != 3)
                    fail_header("malformed property line (expected 'property TYPE NAME')");
                prop.type = parse_type(tok[1]);
                if (prop.type == PlyType::none)
                    fail_header("unknown property type '" + excerpt(tok[1]) + "'");
                prop.name = std::string(tok[2]);
                el.scalar_bytes += type_size(prop.type);
            }
            for (const Property& other : el.props)
                if (other.name == prop.name)
                    fail_header("element " + excerpt(el.name) + ": second property named '" +
                                excerpt(prop.name) + "'");
            el.props.push_back(std::move(prop));
        } else if (kw == "end_header") {
            have_end = true;
        }
        // comment, obj_info and unknown keywords: ignored (see ply_reader.h).
    }
    if (!have_format) fail_header("missing format line");
    ascii_ = encoding_ == PlyEncoding::ascii;
    swap_ = encoding_ == PlyEncoding::binary_big_endian;
    data_offset_ = in_.offset();
    header_lines_ = line_;
}

// Only version 1.0 is specified. Writers that say 1.1 and the like (Assimp reads them) write
// the same layout, so any 1.x is read as 1.0, with a warning; another major is refused.
void PlyParser::check_version(std::string_view v) {
    if (v == "1" || v == "1.0") return;
    bool minor = v.size() > 2 && v.substr(0, 2) == "1.";
    for (size_t k = 2; k < v.size() && minor; ++k) minor = is_digit(v[k]);
    if (!minor)
        fail_header("PLY version '" + excerpt(v) +
                    "' is not supported (versions 1.x are read, as 1.0)");
    if (v.find_first_not_of('0', 2) == std::string_view::npos) return;  // 1.00
    ErrorLocation w;
    w.path = reader_.path();
    w.element = "header";
    w.line = line_;
    warnings_.push_back(
        Error(w, "format version " + excerpt(v) + ": only PLY 1.0 is specified; read as 1.0")
            .what());
}

void PlyParser::plan_elements() {
    for (size_t k = 0; k < elements_.size(); ++k) {
        if (elements_[k].name == "vertex") vertex_el_ = int(k);
        if (elements_[k].name == "face") face_el_ = int(k);
        if (elements_[k].name == "tristrips") strip_el_ = int(k);
    }
    if (vertex_el_ < 0) {
        line_ = -1;
        fail_header("no 'element vertex' in the header");
    }
    Element& v = elements_[size_t(vertex_el_)];
    line_ = v.line;
    struct Name {
        std::string_view name;
        int slot;
    };
    static constexpr Name kNames[] = {
        {"x", kPosX},
        {"y", kPosY},
        {"z", kPosZ},
        {"nx", kNormX},
        {"ny", kNormY},
        {"nz", kNormZ},
        {"normal_x", kNormX},
        {"normal_y", kNormY},
        {"normal_z", kNormZ},
        {"red", kColR},
        {"green", kColG},
        {"blue", kColB},
        {"r", kColR},
        {"g", kColG},
        {"b", kColB},
        {"diffuse_red", kColR},
        {"diffuse_green", kColG},
        {"diffuse_blue", kColB},
    };
    int found[9] = {};
    for (Property& p : v.props) {
        if (p.is_list()) continue;
        for (const Name& n : kNames) {
            if (n.name == p.name && found[n.slot] == 0) {
                p.slot = n.slot;
                found[n.slot] = 1;
                break;
            }
        }
    }
    for (int s = kPosX; s <= kPosZ; ++s)
        if (!found[s]) fail_header(std::string("element vertex has no property ") + "xyz"[s]);
    for (const Property& p : v.props)
        if (p.is_list() && (p.name == "x" || p.name == "y" || p.name == "z"))
            fail_header("vertex property " + p.name + " is a list");
    has_normals_ = options_.keep_normals && found[kNormX] && found[kNormY] && found[kNormZ];
    has_colors_ = options_.keep_colors && found[kColR] && found[kColG] && found[kColB];
    for (Property& p : v.props) {
        if ((p.slot >= kNormX && p.slot <= kNormZ && !has_normals_) ||
            (p.slot >= kColR && p.slot <= kColB && !has_colors_))
            p.slot = kSkip;
        if (p.slot >= kColR && p.slot <= kColB && is_integer(p.type))
            p.scale = float(1.0 / double(type_max(p.type)));
    }
    xyz_only_ = v.props.size() == 3;
    for (size_t k = 0; k < v.props.size() && xyz_only_; ++k)
        xyz_only_ = v.props[k].slot == int(k) && v.props[k].type == PlyType::f32;
    if (v.count > uint64_t(UINT32_MAX))
        fail_header("element vertex: " + std::to_string(v.count) +
                    " vertices exceed the 32-bit index limit");
    vertex_count_ = v.count;

    for (int k : {face_el_, strip_el_}) {
        if (k < 0) continue;
        Element& f = elements_[size_t(k)];
        line_ = f.line;
        for (Property& p : f.props) {
            // Float and double indices are read too (Assimp reads them), each value checked
            // to be an integer (real_index).
            if (p.is_list() && (p.name == "vertex_indices" || p.name == "vertex_index")) {
                p.slot = kIndices;
                break;
            }
        }
        bool have = false;
        for (const Property& p : f.props) have |= p.slot == kIndices;
        if (!have) fail_header("element " + f.name + " has no list property vertex_indices");
    }
}

// Least bytes one record of el takes: binary records their scalar bytes plus list counts;
// ascii at least two bytes (digit and separator) per value. With `full_faces`, a face's
// index list holds at least three indices, as a valid face's does.
uint64_t PlyParser::min_record_bytes(const Element& el, bool full_faces) const {
    uint64_t min_bytes = 0;
    for (const Property& p : el.props) {
        // A strip may be empty.
        const bool indices = full_faces && p.slot == kIndices && !is_strip(el);
        if (ascii_) {
            min_bytes += indices ? 8 : 2;
        } else if (p.is_list()) {
            min_bytes += type_size(p.type) * (indices ? 3 : 0) + type_size(p.count_type);
        } else {
            min_bytes += type_size(p.type);
        }
    }
    return min_bytes;
}

// Rejects counts the input cannot hold before anything is allocated for them, the file's
// last ascii value needing no separator. Lists may be empty here, so a face of fewer than
// three indices is reported as such when it is read; the triangle array reserved up front
// is bounded by faces of three (face_records_bound_).
void PlyParser::check_counts() {
    const uint64_t bound = reader_.size_bound();
    const uint64_t remaining = (bound > data_offset_ ? bound - data_offset_ : 0) + (ascii_ ? 1 : 0);
    unsigned __int128 total = 0;
    for (const Element& el : elements_) {
        const unsigned __int128 need = (unsigned __int128)el.count * min_record_bytes(el, false);
        total += need;
        if (total > remaining) {
            line_ = el.line;
            auto bytes = [](unsigned __int128 b) {
                return b > UINT64_MAX ? std::string("2^64") : std::to_string(uint64_t(b));
            };
            // Name the running total when earlier elements took part of the file.
            const std::string with_before =
                total == need ? "" : " (" + bytes(total) + " with the elements before it)";
            fail_header("element " + excerpt(el.name) + ": count " + std::to_string(el.count) +
                        " needs at least " + bytes(need) + " bytes" + with_before +
                        ", more than the " + std::to_string(remaining - (ascii_ ? 1 : 0)) +
                        (reader_.gzip() ? " bytes this compressed file may inflate to (gzip "
                                          "data is read up to " +
                                              std::to_string(kMaxInflationRatio) + ":1)"
                                        : " bytes of data in the file"));
        }
    }
    if (face_el_ >= 0) {
        const Element& f = elements_[size_t(face_el_)];
        face_records_bound_ = std::min<uint64_t>(
            f.count, remaining / std::max<uint64_t>(min_record_bytes(f, true), 1));
    }
}

}  // namespace kdt::ply
