// Temporary stand-in so kdt_accel links until the SAH builder (branch sah) lands.
#include "renderer/accel/builder.h"
#include "renderer/core/error.h"

namespace kdt {

KdBuildOutput build_sah_tree(const TriangleMesh&, const KdTreeParams&) {
    throw Error("SAH builder not built yet");
}

}  // namespace kdt
