// `kdtrace scene`: checks a scene file (or model) and prints what it holds, or writes the
// built-in default scene as JSON so it can be edited and rendered elsewhere.
#include <cstdint>
#include <cstdio>
#include <string>

#include "app/commands.h"
#include "app/options_cli.h"
#include "renderer/core/error.h"
#include "renderer/core/interrupt.h"
#include "renderer/core/output_path.h"
#include "renderer/core/temp_file.h"
#include "renderer/light/environment.h"
#include "renderer/scene/scene.h"

namespace kdt::app {

namespace {
/// The longest scene name printed whole; a longer one is shown by its head and size.
constexpr size_t kMaxNameBytes = 200;
}  // namespace

void add_scene_command(CLI::App& parent) {
    auto* cmd =
        parent.add_subcommand("scene", "Check a scene file, or export the built-in default scene");
    static std::string input, output;
    static bool drop_invalid = false;
    non_empty_file_name(cmd->add_option("SCENE", input,
                                        "Scene (.json) or model file; omitted = the built-in "
                                        "default scene"),
                        "SCENE", " (omit SCENE for the built-in scene)");
    // A scene file is read as JSON by its extension (load_scene_or_model()): another one
    // would come back as a model.
    file_extension(non_empty_file_name(cmd->add_option("-o,--output", output,
                                                       "Write the scene as JSON to this .json "
                                                       "file (- = standard output)"),
                                       "-o"),
                   "-o", ".json", "the scene is written as JSON (- for standard output)", {"-"});
    cmd->add_flag("--drop-invalid", drop_invalid,
                  "Drop faces with non-finite vertices or fewer than 3 indices");
    static uint64_t max_triangles = kDefaultMaxSceneTriangles;
    cmd->add_option("--max-triangles", max_triangles,
                    "Refuse a scene (its instances counted), model or built-in scene of more "
                    "triangles (also bounded by the memory available)")
        ->capture_default_str()
        ->check(in_range(1.0, 18446744073709551615.0));
    cmd->callback([] {
        interrupt::install();
        // Fail before loading, not after; the files the scene references are checked below.
        const bool to_stdout = output == "-";
        if (!output.empty() && !to_stdout) check_output(output, {input}, "the scene");
        // With -o -, standard output holds the JSON alone and the summary goes to stderr.
        std::FILE* report = to_stdout ? stderr : stdout;
        SceneLoadOptions opts;
        opts.drop_invalid = drop_invalid;
        opts.max_triangles = max_triangles;
        Scene scene = input.empty() ? make_default_scene() : load_scene_or_model(input, opts);
        // A scene file's instances are bounded as it is read; a model and the built-in scene
        // are bounded here, by the same budget.
        const uint64_t instanced = instanced_triangle_count(scene);
        if (const uint64_t budget = scene_triangle_budget(max_triangles); instanced > budget) {
            throw Error((input.empty() ? std::string("the built-in scene") : input) + ": " +
                        std::to_string(instanced) + " triangles, more than " +
                        (budget < max_triangles
                             ? "the " + std::to_string(budget) + " that fit the memory available"
                             : "--max-triangles " + std::to_string(max_triangles)));
        }
        // The environment is checked as `render` would (the meshes were read above): a map
        // decoded, a constant colour's radiance bounded.
        try {
            make_environment_light(scene.environment);
        } catch (const Error& e) {
            throw Error(ErrorLocation{input, scene.environment.file.empty() ? "environment"
                                                                            : "environment/file"},
                        e.what());
        }
        size_t tris = 0, verts = 0;
        for (const MeshInstance& m : scene.meshes) {
            tris += m.mesh->triangle_count();
            verts += m.mesh->vertex_count();
        }
        // Names come from files: printable() keeps their bytes from driving the terminal or
        // cutting the line short (a NUL); a scene name, which nothing bounds, is cut short.
        std::fprintf(report, "scene %s: %zu meshes, %zu vertices, %zu triangles\n",
                     excerpt(scene.name, kMaxNameBytes).c_str(), scene.meshes.size(), verts, tris);
        for (const MeshInstance& m : scene.meshes) {
            std::fprintf(report, "  %s: %zu triangles, %s, %s shading\n", printable(m.file).c_str(),
                         m.mesh->triangle_count(), kMaterialTypeNames[size_t(m.material.type)],
                         m.smooth ? "smooth" : "flat");
        }
        const CameraDesc& c = scene.camera;
        std::fprintf(report, "camera: eye (%g %g %g) target (%g %g %g) up (%g %g %g) vfov %g deg\n",
                     c.eye.x, c.eye.y, c.eye.z, c.target.x, c.target.y, c.target.z, c.up.x, c.up.y,
                     c.up.z, c.vfov_degrees);
        const EnvironmentDesc& e = scene.environment;
        if (e.file.empty()) {
            std::fprintf(report, "environment: constant (%g %g %g) x %g\n", e.color.x, e.color.y,
                         e.color.z, e.intensity);
        } else {
            std::fprintf(report, "environment: %s (%s), rotation %g deg, intensity %g\n",
                         printable(e.file).c_str(), kEnvMappingNames[size_t(e.mapping)],
                         e.rotation_degrees, e.intensity);
        }
        if (to_stdout) {
            const std::string text = scene_to_json(scene);
            // A failed write (a full disk, a closed pipe) is reported by main()'s
            // finish_stdout(), with status 1.
            std::fwrite(text.data(), 1, text.size(), stdout);
        } else if (!output.empty()) {
            check_output(output, scene_input_files(scene), "the scene");
            const std::string text = scene_to_json(scene);
            write_file_atomically(output, text.data(), text.size());
            std::fprintf(report, "wrote %s\n", printable(output).c_str());
        }
    });
}

}  // namespace kdt::app
