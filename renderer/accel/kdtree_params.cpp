// The range table of KdTreeParams: the one place its limits, flags and help live.
#include "renderer/accel/kdtree.h"

namespace kdt {

namespace {

using P = KdTreeParams;

const Field<P> kTreeFields[] = {
    KDT_FIELD(P, builder, "--builder",
              "kd-tree builder: thesis (the thesis's cost function) or sah", 0, 1, false,
              kKdBuilderNames),
    KDT_FIELD(P, q, "--q",
              "Leaf cost correction q (both builders): a leaf of n > n0 triangles costs "
              "f(n) = (n - n0)^(1 + log2 q) + n0",
              0.0, 1.0, true),
    KDT_FIELD(P, n0, "--n0",
              "Leaf cost correction n0 (both builders): a leaf of up to n0 triangles costs n", 0,
              1000000),
    KDT_FIELD(P, max_depth, "--depth", "kd-tree maximum depth (0 = automatic, 8 + 1.3 log2 N)", 0,
              kMaxTreeDepth),
    KDT_FIELD(P, use_median_split, "--no-median",
              "Thesis builder: no median-vertex split candidates"),
    KDT_FIELD(P, use_center_split, "--no-center",
              "Thesis builder: no spatial-middle split candidates"),
    KDT_FIELD(P, use_cutoff_split, "--no-cutoff",
              "Thesis builder: no cut-off-empty-space split candidates"),
    KDT_FIELD(P, thesis_all_axes, "--all-axes",
              "Thesis builder: try x, y and z at every node instead of alternating by depth"),
    KDT_FIELD(P, traversal_cost, "--sah-traversal-cost",
              "SAH builder: cost of an inner node relative to a triangle test", 0.0, 3e38, true),
    KDT_FIELD(P, intersect_cost, "--sah-intersect-cost", "SAH builder: cost of a triangle test",
              0.0, 3e38, true),
    KDT_FIELD(P, empty_bonus, "--sah-empty-bonus",
              "SAH builder: cost reduction for cutting off empty space", 0.0, 1.0),
    KDT_FIELD(P, threads, "--threads", "Threads (0 = all)", 0, 1024),
};

}  // namespace

std::span<const Field<KdTreeParams>> kd_tree_fields() { return kTreeFields; }

bool kd_tree_field_applies(const KdTreeParams& params, std::string_view name) {
    const bool thesis_only = name == "use_median_split" || name == "use_center_split" ||
                             name == "use_cutoff_split" || name == "thesis_all_axes";
    const bool sah_only =
        name == "traversal_cost" || name == "intersect_cost" || name == "empty_bonus";
    if (thesis_only) return params.builder == KdBuilder::thesis;
    if (sah_only) return params.builder == KdBuilder::sah;
    return true;
}

}  // namespace kdt
