// Binary PLY elements: fixed-size vertex records in batches, "3 a b c" faces in runs, and
// any other record property by property.
#include <algorithm>
#include <bit>
#include <charconv>
#include <string>
#include <vector>

#include "renderer/io/ply_binary_decode.h"
#include "renderer/io/ply_parser.h"

namespace kdt::ply {

// Vertex element of scalars only: fixed-size records, decoded in whole-buffer batches and
// appended to the positions (reserved, not sized: no zero fill before the real values).
template <bool Swap>
void PlyParser::read_binary_vertices_fixed(Element& el) {
    struct Plan {
        size_t offset;
        PlyType type;
        int slot;
        float scale;
    };
    std::vector<Plan> plan;
    size_t off = 0;
    for (const Property& p : el.props) {
        if (p.slot != kSkip) plan.push_back({off, p.type, p.slot, p.scale});
        off += type_size(p.type);
    }
    const size_t rec = el.scalar_bytes;
    // Common case: x, y, z as consecutive floats first in the record and nothing else kept.
    const bool xyz_only = plan.size() == 3 && plan[0].slot == kPosX && plan[1].slot == kPosY &&
                          plan[2].slot == kPosZ && plan[0].offset + 4 == plan[1].offset &&
                          plan[1].offset + 4 == plan[2].offset && plan[0].type == PlyType::f32 &&
                          plan[1].type == PlyType::f32 && plan[2].type == PlyType::f32;
    constexpr size_t kRun = 1024;  // 12 KiB of positions, in L1
    Vec3f run[kRun + 1];           // + 1: decode_positions writes past the last
    uint64_t i = 0;
    float v[9] = {};
    while (i < el.count) {
        record_offset_ = in_.offset();
        need(el, i, rec);
        uint64_t n = std::min<uint64_t>(el.count - i, in_.avail() / rec);
        const char* base = in_.pos();
        if (xyz_only && bad_vertex_.empty()) {
            // Runs of finite positions through a small array and one insert each; a
            // non-finite one goes to store_vertex (an error, or flagged with drop_invalid).
            n = std::min<uint64_t>(n, kRun);
            grow_capacity(mesh_.positions, i + n, el);
            const char* r = base + plan[0].offset;
            uint64_t k = decode_positions<Swap>(r, size_t(n), rec, run);
            mesh_.positions.insert(mesh_.positions.end(), run, run + k);
            if (k < n) {
                r += k * rec;
                record_offset_ = in_.offset() + k * rec;
                v[0] = std::bit_cast<float>(load_uint<Swap, uint32_t>(r));
                v[1] = std::bit_cast<float>(load_uint<Swap, uint32_t>(r + 4));
                v[2] = std::bit_cast<float>(load_uint<Swap, uint32_t>(r + 8));
                mesh_.positions.emplace_back();
                store_vertex(el, i + k, v);
                ++k;
            }
            n = k;
        } else {
            grow_vertices(el, i + n);
            for (uint64_t k = 0; k < n; ++k) {
                const char* r = base + k * rec;
                for (const Plan& pl : plan)
                    v[pl.slot] = load_float<Swap>(r + pl.offset, pl.type) * pl.scale;
                record_offset_ = in_.offset() + k * rec;
                store_vertex(el, i + k, v);
            }
        }
        in_.advance(size_t(n * rec));
        i += n;
    }
}

// Index `p` of record i of el, of item type t: integer types as they are, float and double
// through real_index (the value named as the shortest text that reads back to it).
template <bool Swap>
int64_t PlyParser::load_index(const Element& el, uint64_t i, const char* p, PlyType t) const {
    if (is_integer(t)) return load_int<Swap>(p, t);
    char text[32];
    std::to_chars_result r;
    double x;
    if (t == PlyType::f32) {
        const float f = std::bit_cast<float>(load_uint<Swap, uint32_t>(p));
        r = std::to_chars(text, text + sizeof(text), f);
        x = double(f);
    } else {
        x = std::bit_cast<double>(load_uint<Swap, uint64_t>(p));
        r = std::to_chars(text, text + sizeof(text), x);
    }
    return real_index(el, i, x, std::string(text, r.ptr));
}

// One record of any element, property by property (lists included).
template <bool Swap>
void PlyParser::read_binary_record(Element& el, uint64_t i) {
    const bool is_vertex = &el == &elements_[size_t(vertex_el_)];
    float v[9] = {};
    record_offset_ = in_.offset();
    bool have_face = false, face_kept = true;
    for (const Property& p : el.props) {
        if (!p.is_list()) {
            size_t sz = type_size(p.type);
            need(el, i, sz);
            if (p.slot >= 0) v[p.slot] = load_float<Swap>(in_.pos(), p.type) * p.scale;
            in_.advance(sz);
            continue;
        }
        size_t csz = type_size(p.count_type), isz = type_size(p.type);
        need(el, i, csz);
        int64_t count = load_int<Swap>(in_.pos(), p.count_type);
        in_.advance(csz);
        if (count < 0)
            fail_at(el, i,
                    "negative list count " + std::to_string(count) + " in " + excerpt(p.name));
        if (p.slot != kIndices) {
            if (!in_.skip(uint64_t(count) * isz))
                fail_data(el, i, -1, int64_t(in_.offset()),
                          "unexpected end of data (file truncated?)");
            continue;
        }
        face_kept = check_face_size(el, i, count);
        poly_.clear();
        if (uint64_t(count) * isz <= kBlockBytes) {
            need(el, i, size_t(count) * isz);
            const char* q = in_.pos();
            if (is_integer(p.type)) {
                for (int64_t k = 0; k < count; ++k)
                    poly_.push_back(load_int<Swap>(q + k * isz, p.type));
            } else {
                for (int64_t k = 0; k < count; ++k)
                    poly_.push_back(load_index<Swap>(el, i, q + k * isz, p.type));
            }
            in_.advance(size_t(count) * isz);
        } else {
            // A huge polygon: stream it; poly_ grows only as real data arrives.
            for (int64_t k = 0; k < count; ++k) {
                need(el, i, isz);
                poly_.push_back(load_index<Swap>(el, i, in_.pos(), p.type));
                in_.advance(isz);
            }
        }
        have_face = true;
    }
    if (is_vertex) store_vertex(el, i, v);
    if (have_face && !face_kept) return;
    if (have_face && is_strip(el))
        emit_strip(el, i, poly_.data(), poly_.size());
    else if (have_face)
        emit_face(el, i, poly_.data(), poly_.size());
}

// Face element holding only the index list with uchar count: the layout of nearly every
// scanned mesh. Decoded straight from the buffer: runs of valid triangles with 4-byte indices
// are collected in a small array (in L1) and appended by one insert each, so the loop keeps
// its state in registers and checks no capacity per triangle; any other record (a polygon,
// an invalid or degenerate face, one cut by the window end, other index types) takes the
// record-by-record path.
template <bool Swap>
void PlyParser::read_binary_faces_fast(Element& el) {
    const Property& p = el.props[0];
    const size_t isz = type_size(p.type);
    constexpr size_t kRun = 1024;  // 12 KiB of triangles
    Vec3u run[kRun + 1];           // + 1: decode_triangles writes past the last
    // Signed indices are valid below 2^31 however many vertices the header declares.
    const uint32_t limit =
        uint32_t(p.type == PlyType::i32 ? std::min<uint64_t>(vertex_count_, uint64_t(INT32_MAX) + 1)
                                        : vertex_count_);
    const bool runs = isz == 4;
    int64_t idx[3];
    for (uint64_t i = 0; i < el.count;) {
        if (runs && bad_vertex_.empty()) {
            const size_t n = size_t(std::min<uint64_t>(
                {el.count - i, uint64_t(in_.avail() / kTriangleRecord), uint64_t(kRun)}));
            const size_t k = decode_triangles<Swap>(in_.pos(), n, limit, run);
            grow_capacity(mesh_.triangles, mesh_.triangles.size() + k, el);
            mesh_.triangles.insert(mesh_.triangles.end(), run, run + k);
            source_faces_ += k;
            in_.advance(k * kTriangleRecord);
            i += k;
            if (k == kRun) continue;
            if (i == el.count) break;
        }
        record_offset_ = in_.offset();
        // Fewer bytes than a triangle left: the record path reads what there is and says
        // what is wrong with it (a short face, or data cut short).
        if (in_.avail() < 1 + 3 * isz && !in_.fill(1 + 3 * isz)) {
            read_binary_record<Swap>(el, i++);
            continue;
        }
        const char* r = in_.pos();
        if (uint8_t(*r) != 3) {
            read_binary_record<Swap>(el, i++);
            continue;
        }
        for (int k = 0; k < 3; ++k) idx[k] = load_int<Swap>(r + 1 + isz * k, p.type);
        in_.advance(1 + 3 * isz);
        emit_face(el, i++, idx, 3);
    }
}

template <bool Swap>
void PlyParser::read_binary_element(Element& el) {
    const bool is_vertex = &el == &elements_[size_t(vertex_el_)];
    const bool is_face = face_el_ >= 0 && &el == &elements_[size_t(face_el_)];
    if (is_vertex && !el.has_lists) {
        read_binary_vertices_fixed<Swap>(el);
    } else if (is_face && el.props.size() == 1 && el.props[0].count_type == PlyType::u8 &&
               is_integer(el.props[0].type)) {
        read_binary_faces_fast<Swap>(el);
    } else if (!is_vertex && !is_face && !el.has_lists) {
        record_offset_ = in_.offset();
        if (!in_.skip(el.count * el.scalar_bytes))
            fail_data(el, (in_.offset() - record_offset_) / std::max<size_t>(el.scalar_bytes, 1),
                      -1, int64_t(in_.offset()), "unexpected end of data (file truncated?)");
    } else {
        for (uint64_t i = 0; i < el.count; ++i) read_binary_record<Swap>(el, i);
    }
}

template void PlyParser::read_binary_element<false>(Element& el);
template void PlyParser::read_binary_element<true>(Element& el);

}  // namespace kdt::ply
