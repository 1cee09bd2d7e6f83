// The editable scene: what io loads from JSON (or builds in code) and the UI edits.
// Plain structs; the render session compiles a Scene into an immutable snapshot.
// Depends on core, geometry, io.
#pragma once

#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "renderer/core/math.h"
#include "renderer/geometry/mesh.h"
#include "renderer/light/environment.h"
#include "renderer/material/material.h"

namespace kdt {

struct MeshLoadInfo;

/// One mesh placed in the world. The mesh itself is loaded by load_scene().
struct MeshInstance {
    std::string file;  ///< empty for generated meshes
    Mat4f world_from_object{1.0f};
    MaterialDesc material;
    bool smooth = true;  ///< smooth shading (file normals, else computed)
    std::shared_ptr<const TriangleMesh> mesh;
};

/// Pinhole camera; vfov is the full vertical field of view.
struct CameraDesc {
    Vec3f eye{0.0f, 0.0f, 5.0f};
    Vec3f target{0.0f};
    Vec3f up{0.0f, 1.0f, 0.0f};
    float vfov_degrees = 40.0f;
};

struct Scene {
    std::string name;
    std::vector<MeshInstance> meshes;
    CameraDesc camera;
    EnvironmentDesc environment;
};

/// Where a scene's meshes come from: called with a mesh file's resolved path, or with
/// "builtin:<name>" for a known generated mesh. A kdt::Error it throws is reported naming
/// the scene file and the key.
using SceneMeshSource = std::function<std::shared_ptr<const TriangleMesh>(const std::string&)>;

/// Default limit on a scene's triangles after instancing (each instance counts its mesh's).
inline constexpr uint64_t kDefaultMaxSceneTriangles = 200'000'000;
/// Peak bytes per triangle of a render, after instancing, for the memory budget: measured
/// about 90 on the dragon (flattened mesh, normals, kd-tree, its build), rounded up.
inline constexpr uint64_t kRenderBytesPerTriangle = 100;

/// Options for loading mesh files referenced by a scene.
struct SceneLoadOptions {
    /// A scene file whose instances add up to more triangles than
    /// scene_triangle_budget(max_triangles) is an error (before the render allocates them).
    uint64_t max_triangles = kDefaultMaxSceneTriangles;
    bool drop_invalid = false;  ///< drop faces with non-finite vertices instead of failing
    /// Empty: mesh files are read with load_mesh() and builtins generated. Tests and fuzzers
    /// substitute their own (so that a scene can be checked without its meshes).
    SceneMeshSource mesh_source;
    /// Check that the environment map is a regular file that can be opened (mesh files are
    /// read anyway). Off only for fuzzers, which must not touch the file system.
    bool check_files = true;
    /// Called with each warning, a problem of the file that is not an error (an emissive
    /// material that emits nothing), as one line "warning: FILE: KEY: ...". Empty: written to
    /// stderr after "kdtrace: ".
    std::function<void(const std::string&)> warn;
};

/// Loads a JSON scene file; mesh paths are relative to the scene file. Unknown keys,
/// wrong types and missing files throw kdt::Error naming the file and the key; a material of
/// type emissive whose emission is absent or zero is a warning (options.warn), as black
/// emitters may be meant. Each mesh file and builtin is loaded once and shared by all its
/// instances.
Scene load_scene(const std::string& path, const SceneLoadOptions& options = {});

/// load_scene() on a scene file's text already in memory; `path` names it in messages and
/// is the base of relative mesh paths. For tests and fuzzers.
Scene load_scene_text(const std::string& text, const std::string& path,
                      const SceneLoadOptions& options = {});

/// load_mesh() of one model file (options.drop_invalid as MeshLoadOptions::drop_invalid),
/// warning through options.warn (not failing) about what renders nothing: a file without
/// faces (a point cloud) and the faces drop_invalid dropped. `info` as for load_mesh().
TriangleMesh load_model(const std::string& file, const SceneLoadOptions& options = {},
                        MeshLoadInfo* info = nullptr);

/// A scene around one model file (.ply, .ply.gz, .obj): a camera framing its bounds,
/// a diffuse grey material and a constant white environment.
Scene scene_from_model(const std::string& path, const SceneLoadOptions& options = {});

/// Loads a scene file (.json) or a model file.
Scene load_scene_or_model(const std::string& path, const SceneLoadOptions& options = {});

/// The built-in default scene, generated in code (no download): a displaced, subdivided
/// sphere of a few hundred thousand triangles on a ground plane under a sky.
Scene make_default_scene();

/// Generated meshes (also reachable from scene files as "builtin:<name>").
TriangleMesh make_icosphere(int levels);         ///< unit sphere, 20 * 4^levels triangles
TriangleMesh make_displaced_sphere(int levels);  ///< the default scene's object, radius ~1
TriangleMesh make_ground_plane(float half_size, float height);  ///< two triangles facing +y

/// The triangle budget: max_triangles, or fewer when bytes_per_triangle times it would not
/// fit allocatable_memory_bytes() (the physical memory available now, or what a `ulimit -v`
/// leaves).
uint64_t scene_triangle_budget(uint64_t max_triangles = kDefaultMaxSceneTriangles,
                               uint64_t bytes_per_triangle = kRenderBytesPerTriangle);

/// Bytes this process may still allocate: the physical memory available now (MemAvailable),
/// or less when an address-space limit (`ulimit -v`) leaves less above what the process has
/// mapped; 0 when neither is known.
uint64_t allocatable_memory_bytes();

/// Triangles a render of the scene holds: every instance's mesh counted once per instance.
uint64_t instanced_triangle_count(const Scene& scene);

/// What a command holds per triangle of its model, for check_subdivide(): `bytes` (a render's
/// or build's kRenderBytesPerTriangle by default) and, when a command holds more, what the
/// rest is for (said in the error, e.g. "8 rows' trees and Embree's BVH"); and the most
/// triangles it takes (the kd-tree's limit; a render's scene also kDefaultMaxSceneTriangles).
struct SubdivideMemory {
    uint64_t bytes = kRenderBytesPerTriangle;
    std::string why;
    uint64_t max_triangles = kMaxSubdividedTriangles - 1;
};

/// Refuses --subdivide `levels` of `triangles` when the result would not fit in the memory
/// available (scene_triangle_budget() at memory.bytes per triangle) or memory.max_triangles,
/// before the minutes of work: kdt::Error "--subdivide 3: 200000 triangles become 12800000,
/// more than the ... that fit the kd-tree and the memory available (about 100 bytes each)",
/// after "`model`: " when `model` is not empty.
void check_subdivide(uint64_t triangles, int levels, const SubdivideMemory& memory = {},
                     const std::string& model = {});

/// `mesh` (of the file `model`) split into 4^`levels` triangles each, after check_subdivide().
/// Memory running out on the way (the check counts what is available now and what a ulimit
/// leaves, not what other processes take meanwhile) is an Error naming the model and the flag,
/// "dragon.ply: --subdivide 3: out of memory making 55770496 triangles", not main()'s bare
/// "out of memory".
void subdivide_model(const std::string& model, TriangleMesh& mesh, int levels,
                     const SubdivideMemory& memory = {});

/// Splits every triangle of the scene into 4^`levels` by edge midpoints (subdivide_mesh():
/// the same surface, more triangles; a mesh shared by instances once), after
/// check_subdivide() of the instanced count within a render's budget. Smooth instances keep
/// their shading: a mesh without normals gets its computed vertex normals first, which the
/// subdivision interpolates. Errors as subdivide_model()'s, naming `what` (the scene file;
/// empty for the built-in scene).
void subdivide_scene(Scene& scene, int levels, const std::string& what);

/// The name the tree of `model` after --subdivide `levels` is cached under: "`model`.subK", or
/// `model` itself at 0 levels or for an empty name (the built-in scene). `build`, `bench
/// kdtree` and a render name it alike, so each finds the others' tree.
std::string subdivided_model_key(const std::string& model, int levels);

/// The files a scene reads: its mesh files (not builtins) and its environment map, if any.
std::vector<std::string> scene_input_files(const Scene& scene);

/// Writes a scene as JSON that load_scene() reads back (generated meshes as "builtin:" names).
std::string scene_to_json(const Scene& scene);

/// The values a scene file accepts in a material field (in each component of a colour),
/// compared as the float the field holds: [lo, hi], or (lo, hi] when open_low. The viewer's
/// material edits check through these too, so that every session it saves loads.
struct MaterialRange {
    float lo = 0.0f, hi = 0.0f;
    bool open_low = false;
    constexpr bool contains(float v) const { return (open_low ? v > lo : v >= lo) && v <= hi; }
    bool contains(const Vec3f& c) const { return contains(c.x) && contains(c.y) && contains(c.z); }
    /// For a number typed or parsed as a double: whether the float it becomes lies in the
    /// range (a double beyond float's range does not).
    bool contains_as_float(double v) const {
        return std::fabs(v) <= double(std::numeric_limits<float>::max()) && contains(float(v));
    }
    /// "[0, 1]", "(0, 1]".
    std::string text() const;
};
inline constexpr MaterialRange kAlbedoRange{0.0f, 1.0f};
inline constexpr MaterialRange kRoughnessRange{0.0f, 1.0f, true};
inline constexpr MaterialRange kIorRange{0.0f, 3e38f, true};  ///< positive
inline constexpr MaterialRange kEmissionRange{0.0f, 3e38f};   ///< non-negative

/// One material as a scene file's mesh "material" object (JSON text), and back: the reader
/// checks keys and ranges as scene files do, errors naming `file` and the JSON `where`.
std::string material_to_json(const MaterialDesc& material);
MaterialDesc material_from_json(const std::string& json_text, const std::string& file,
                                const std::string& where);

/// A camera that frames `bounds` from the front-right, above. Throws kdt::Error (naming no
/// file) when the bounds are too large for a camera in float.
CameraDesc frame_bounds(const Bounds3f& bounds, float vfov_degrees = 40.0f);

}  // namespace kdt
