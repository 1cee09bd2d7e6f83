// libFuzzer target for the JSON scene reader: any input must load or throw a kdt::Error
// naming the file, never crash, leak, hang or trip a sanitizer. Meshes are not read: every
// mesh file and builtin resolves to one small triangle (SceneLoadOptions::mesh_source), so
// inputs cannot reach the disk and the scene's own checks are what gets fuzzed.
// Built by tests/fuzz/tests.cmake.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>

#include "renderer/core/error.h"
#include "renderer/scene/scene.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    static const auto triangle = [] {
        auto mesh = std::make_shared<kdt::TriangleMesh>();
        mesh->positions = {kdt::Vec3f(0.0f), kdt::Vec3f(1.0f, 0.0f, 0.0f),
                           kdt::Vec3f(0.0f, 1.0f, 0.0f)};
        mesh->triangles = {kdt::Vec3u(0, 1, 2)};
        return std::shared_ptr<const kdt::TriangleMesh>(mesh);
    }();
    kdt::SceneLoadOptions options;
    options.drop_invalid = size % 2 == 1;
    options.mesh_source = [](const std::string&) { return triangle; };
    options.check_files = false;
    options.warn = [](const std::string&) {};  // warnings are input too, not findings
    const std::string text(reinterpret_cast<const char*>(data), size);
    try {
        kdt::Scene scene = kdt::load_scene_text(text, "fuzz.json", options);
        if (scene.meshes.empty()) __builtin_trap();
        for (const kdt::MeshInstance& m : scene.meshes) {
            if (!m.mesh) __builtin_trap();
        }
        if (!kdt::is_finite(scene.camera.eye) || !kdt::is_finite(scene.camera.target) ||
            !std::isfinite(scene.camera.vfov_degrees))
            __builtin_trap();
        // What load_scene reads, scene_to_json must write and load_scene read back.
        kdt::Scene again = kdt::load_scene_text(kdt::scene_to_json(scene), "fuzz.json", options);
        if (again.meshes.size() != scene.meshes.size()) __builtin_trap();
    } catch (const kdt::Error& e) {
        if (std::strncmp(e.what(), "fuzz.json: ", 11) != 0) {
            std::fprintf(stderr, "error without the file name: %s\n", e.what());
            __builtin_trap();
        }
    }
    return 0;
}
