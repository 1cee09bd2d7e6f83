#include "app/bench/peer_embree.h"

#ifdef KDT_HAVE_EMBREE

#include <algorithm>
#include <atomic>
#include <cstring>
#include <string>

#include <embree3/rtcore.h>

#include "renderer/core/error.h"
#include "renderer/core/timer.h"

namespace kdt::app {
namespace {

// Net bytes Embree holds, updated by its memory monitor from any build thread.
struct MemoryMonitor {
    std::atomic<int64_t> current{0};
    std::atomic<int64_t> peak{0};
};

bool monitor_callback(void* user, ssize_t bytes, bool /*post*/) {
    auto* m = static_cast<MemoryMonitor*>(user);
    int64_t now = m->current.fetch_add(int64_t(bytes)) + int64_t(bytes);
    int64_t peak = m->peak.load();
    while (now > peak && !m->peak.compare_exchange_weak(peak, now)) {
    }
    return true;
}

// One monitor per process is enough: the bench keeps one peer alive at a time.
MemoryMonitor g_monitor;

void check_device(RTCDevice device, const char* what) {
    RTCError err = rtcGetDeviceError(device);
    if (err != RTC_ERROR_NONE) {
        throw Error(std::string("Embree: ") + what + " failed (error " + std::to_string(int(err)) +
                    ")");
    }
}

void to_embree(const Ray& ray, RTCRay& r) {
    r.org_x = ray.origin.x;
    r.org_y = ray.origin.y;
    r.org_z = ray.origin.z;
    r.tnear = ray.tmin;
    r.dir_x = ray.dir.x;
    r.dir_y = ray.dir.y;
    r.dir_z = ray.dir.z;
    r.time = 0.0f;
    r.tfar = ray.tmax;
    r.mask = 0xffffffffu;
    r.id = 0;
    r.flags = 0;
}

// A ray and an empty hit record, ready for rtcIntersect*.
void to_embree(const Ray& ray, RTCRayHit& rh) {
    to_embree(ray, rh.ray);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
}

// The context of the stream queries, with Embree's hint for coherent or incoherent rays.
RTCIntersectContext stream_context(bool coherent) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags =
        coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
    return context;
}

// Our Hit from an RTCRayHit after rtcIntersect*: false (and a miss) when nothing was hit.
bool from_embree(const RTCRayHit& rh, Hit& hit) {
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) {
        hit = Hit{};
        return false;
    }
    hit.t = rh.ray.tfar;
    hit.u = rh.hit.u;
    hit.v = rh.hit.v;
    hit.prim = rh.hit.primID;
    return true;
}

// Rays per rtcIntersect1M call: Embree's stream code works on small groups anyway.
constexpr size_t kStream = 64;

}  // namespace

EmbreePeer::EmbreePeer(const TriangleMesh& mesh, const EmbreePeerParams& params) {
    const std::string config =
        params.threads > 0 ? "threads=" + std::to_string(params.threads) : std::string();
    RTCDevice device = rtcNewDevice(config.c_str());
    if (!device) throw Error("Embree: rtcNewDevice failed");
    device_ = device;
    rtcSetDeviceMemoryMonitorFunction(device, monitor_callback, &g_monitor);

    RTCScene scene = rtcNewScene(device);
    scene_ = scene;
    rtcSetSceneFlags(scene, params.robust ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE);
    rtcSetSceneBuildQuality(
        scene, params.high_quality ? RTC_BUILD_QUALITY_HIGH : RTC_BUILD_QUALITY_MEDIUM);
    RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    // Embree's own buffers are padded for its 16-byte vertex loads; copying also keeps the
    // peer independent of the mesh's lifetime.
    auto* vertices = static_cast<float*>(
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                3 * sizeof(float), mesh.vertex_count()));
    auto* triangles = static_cast<uint32_t*>(
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                3 * sizeof(uint32_t), mesh.triangle_count()));
    check_device(device, "buffer allocation");
    if (mesh.vertex_count()) {
        std::memcpy(vertices, mesh.positions.data(), mesh.vertex_count() * 3 * sizeof(float));
    }
    if (mesh.triangle_count()) {
        std::memcpy(triangles, mesh.triangles.data(), mesh.triangle_count() * 3 * sizeof(uint32_t));
    }
    rtcCommitGeometry(geom);
    rtcAttachGeometry(scene, geom);
    rtcReleaseGeometry(geom);

    const int64_t before = g_monitor.current.load();
    g_monitor.peak.store(before);
    Timer timer;
    rtcCommitScene(scene);
    build_seconds_ = timer.seconds();
    check_device(device, "rtcCommitScene");
    bvh_bytes_ = size_t(std::max<int64_t>(0, g_monitor.current.load() - before));
    peak_build_bytes_ = size_t(std::max<int64_t>(0, g_monitor.peak.load() - before));
}

EmbreePeer::~EmbreePeer() {
    if (scene_) rtcReleaseScene(static_cast<RTCScene>(scene_));
    if (device_) rtcReleaseDevice(static_cast<RTCDevice>(device_));
}

bool EmbreePeer::intersect(const Ray& ray, Hit& hit) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit rh;
    to_embree(ray, rh);
    rtcIntersect1(static_cast<RTCScene>(scene_), &context, &rh);
    return from_embree(rh, hit);
}

bool EmbreePeer::occluded(const Ray& ray) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRay r;
    to_embree(ray, r);
    rtcOccluded1(static_cast<RTCScene>(scene_), &context, &r);
    // Embree marks an occluded ray by setting tfar to -inf.
    return r.tfar < 0.0f;
}

void EmbreePeer::intersect(const Ray* rays, size_t n, Hit* hits, bool coherent) const {
    RTCIntersectContext context = stream_context(coherent);
    RTCRayHit rh[kStream];
    for (size_t begin = 0; begin < n; begin += kStream) {
        const size_t m = std::min(kStream, n - begin);
        for (size_t i = 0; i < m; ++i) to_embree(rays[begin + i], rh[i]);
        rtcIntersect1M(static_cast<RTCScene>(scene_), &context, rh, unsigned(m), sizeof(RTCRayHit));
        for (size_t i = 0; i < m; ++i) from_embree(rh[i], hits[begin + i]);
    }
}

void EmbreePeer::occluded(const Ray* rays, size_t n, uint8_t* occluded, bool coherent) const {
    RTCIntersectContext context = stream_context(coherent);
    RTCRay r[kStream];
    for (size_t begin = 0; begin < n; begin += kStream) {
        const size_t m = std::min(kStream, n - begin);
        for (size_t i = 0; i < m; ++i) to_embree(rays[begin + i], r[i]);
        rtcOccluded1M(static_cast<RTCScene>(scene_), &context, r, unsigned(m), sizeof(RTCRay));
        for (size_t i = 0; i < m; ++i) occluded[begin + i] = r[i].tfar < 0.0f ? 1 : 0;
    }
}

}  // namespace kdt::app

#endif  // KDT_HAVE_EMBREE
