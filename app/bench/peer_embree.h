// Embree 3 as a benchmark peer: one triangle-mesh scene, single-ray closest-hit and any-hit
// queries with kdtrace's Ray/Hit types. Only the app links Embree; the renderer never does.
// Compiled only with KDT_HAVE_EMBREE (the CMake option KDT_WITH_EMBREE found Embree).
#pragma once

#ifdef KDT_HAVE_EMBREE

#include <cstddef>
#include <cstdint>

#include "renderer/accel/kdtree.h"
#include "renderer/core/math.h"
#include "renderer/geometry/mesh.h"

namespace kdt::app {

struct EmbreePeerParams {
    int threads = 0;            ///< build threads ("threads=N"); 0 = Embree's default (all)
    bool robust = false;        ///< RTC_SCENE_FLAG_ROBUST: watertight-ish, slower traversal
    bool high_quality = false;  ///< RTC_BUILD_QUALITY_HIGH (spatial splits) instead of medium
};

/// An Embree device and committed scene over a copy of `mesh` (Embree's own buffers).
/// Queries are thread-safe and mirror KdTree::intersect / occluded: same ray interval,
/// Hit::u/v are the barycentrics of vertices 1 and 2, prim is the triangle index.
class EmbreePeer {
public:
    EmbreePeer(const TriangleMesh& mesh, const EmbreePeerParams& params);
    ~EmbreePeer();
    EmbreePeer(const EmbreePeer&) = delete;
    EmbreePeer& operator=(const EmbreePeer&) = delete;

    bool intersect(const Ray& ray, Hit& hit) const;
    bool occluded(const Ray& ray) const;
    /// Stream queries (rtcIntersect1M / rtcOccluded1M) over n rays; `coherent` sets
    /// RTC_INTERSECT_CONTEXT_FLAG_COHERENT (camera rays), else the incoherent flag.
    void intersect(const Ray* rays, size_t n, Hit* hits, bool coherent) const;
    void occluded(const Ray* rays, size_t n, uint8_t* occluded, bool coherent) const;

    /// Wall time of rtcCommitScene (the BVH build), seconds.
    double build_seconds() const { return build_seconds_; }
    /// Bytes Embree allocated during the commit (the BVH; vertex and index buffers excluded).
    size_t bvh_bytes() const { return bvh_bytes_; }
    /// Largest net allocation seen during the commit (BVH plus build scratch), bytes.
    size_t peak_build_bytes() const { return peak_build_bytes_; }

private:
    void* device_ = nullptr;  // RTCDevice
    void* scene_ = nullptr;   // RTCScene
    double build_seconds_ = 0.0;
    size_t bvh_bytes_ = 0;
    size_t peak_build_bytes_ = 0;
};

}  // namespace kdt::app

#endif  // KDT_HAVE_EMBREE
