#!/usr/bin/env python3
"""termtrace's native CPU tracer against Mitsuba 3's CPU renderer (`llvm_ad_rgb`), on the same
scenes at the same size, depth and Russian roulette (issue 47).

For each scene (a termtrace TOML file, translated here into the Mitsuba scene Mitsuba reads,
for the subset both renderers compute alike: Lambertian, perfect mirrors, smooth glass, area
lights, a gradient or uniform sky, an HDR map, a textured OBJ with its material made
Lambertian) it prints:

- samples/s of both: termtrace's from `render --time`'s summary; Mitsuba's from a timed
  `mi.render` after a warm-up render of the same spp (its kernel compiled and cached: the
  steady state, which favours Mitsuba);
- relative RMSE (pbrt's relMSE, ε = 0.01, as `converge` computes it) at equal time (1 s and
  4 s by default), each renderer against its own reference (the same number of seconds for
  both: `--reference-seconds`);
- the two references' relative RMSE against each other: the check that the translation
  gives the same image (it is the references' own noise where it does).

With `--common-reference` both renderers' runs are measured against termtrace's reference. On a
scene of caustics that a renderer finds as fireflies (mirror balls under a sunny map), its own
reference of a few thousand samples holds most of its runs' error, and measuring a run against
it reads low; the common reference is the one of the two with the least noise (the
`refs apart` column still says how far the other lies from it).

Needs `pip install mitsuba` (3.9) and LLVM for Dr.Jit: on Debian `apt-get install libllvm19`
and `DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1` (set here when unset and
the file exists). Run from the repository root after `cargo build --release`:

    python3 benches/mitsuba_peer.py                      # the five scenes of issue 47
    python3 benches/mitsuba_peer.py scenes/cornell.toml --size 160x96 --times 1,4
"""

import argparse
import math
import os
import re
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

LLVM = "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1"
if "DRJIT_LIBLLVM_PATH" not in os.environ and os.path.exists(LLVM):
    os.environ["DRJIT_LIBLLVM_PATH"] = LLVM

import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402

SCENES = [
    "scenes/cornell.toml",
    "scenes/lamp.toml",
    "scenes/basic.toml",
    "benches/peer/map-mirror.toml",
    "benches/peer/map-dog.toml",
]
EPSILON = 0.01  # converge's relMSE ε (src/common/estimate.rs: REL_MSE_EPSILON)
# termtrace starts Russian roulette after 3 bounces (docs/MODEL-NOTES.md); Mitsuba counts
# depth from the camera ray's first hit as 1, so its rr_depth 4 is the same vertex.
RR_DEPTH = 4


def srgb_to_linear(c):
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def color(v, where):
    """A termtrace colour (`[r, g, b]` linear, or `"#rrggbb"` sRGB) as linear RGB."""
    if isinstance(v, str):
        m = re.fullmatch(r"#([0-9a-fA-F]{6})", v)
        if not m:
            sys.exit(f"{where}: colour {v!r} is not #rrggbb")
        return [srgb_to_linear(int(v[i : i + 2], 16) / 255) for i in (1, 3, 5)]
    return [float(x) for x in v]


def rgb(c):
    return {"type": "rgb", "value": c}


def unsupported(where, what):
    sys.exit(f"{where}: {what} has no Mitsuba twin in this benchmark")


def bsdf(obj, materials, where):
    """The Mitsuba BSDF of a termtrace object's lecture material (MODEL.md): reflecting on
    both faces, as termtrace's surfaces do (Mitsuba's reflect on the front alone)."""
    b = one_sided_bsdf(obj, materials, where)
    return b if b["type"] == "dielectric" else {"type": "twosided", "bsdf": b}


def one_sided_bsdf(obj, materials, where):
    m = dict(materials.get(obj.get("material"), {})) if "material" in obj else {}
    m.update({k: v for k, v in obj.items() if k not in ("material",)})
    if m.get("model", "lecture") != "lecture":
        unsupported(where, f"material model {m['model']!r}")
    c = color(m.get("color", [0.8, 0.8, 0.8]), where)
    smooth = float(m.get("smoothness", 0))
    spec = float(m.get("specular", 0))
    if float(m.get("light", 0)) > 0:
        # An emitter ends the path (MODEL.md): it reflects nothing.
        return {"type": "diffuse", "reflectance": rgb([0, 0, 0])}
    if smooth < 0:
        ior = float(m.get("ior", 1.5))
        return {
            "type": "dielectric",
            "int_ior": ior,
            "ext_ior": 1.0,
            "specular_transmittance": rgb(c),
        }
    if spec == 0:
        return {"type": "diffuse", "reflectance": rgb(c)}
    if spec == 1 and smooth == 1:
        tint = color(m["specular_color"], where) if "specular_color" in m else c
        return {"type": "conductor", "material": "none", "specular_reflectance": rgb(tint)}
    unsupported(where, f"smoothness {smooth} with specular {spec} (a glossy lobe)")


def emitter(obj, where):
    light = float(obj.get("light", 0))
    if light <= 0:
        return None
    c = color(obj.get("color", [0.8, 0.8, 0.8]), where)
    return {"type": "area", "radiance": rgb([x * light for x in c])}


def shape(kind, obj, materials, where):
    T = mi.ScalarTransform4f
    if kind == "sphere":
        if obj["radius"] <= 0:
            unsupported(where, "a hollow sphere")
        s = {"type": "sphere", "center": obj["center"], "radius": obj["radius"]}
    elif kind == "quad":
        q, u, v = (np.array(obj[k], float) for k in ("q", "u", "v"))
        n = np.cross(u, v)
        n /= np.linalg.norm(n)
        c = q + u / 2 + v / 2
        m = np.identity(4)
        m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = u / 2, v / 2, n, c
        s = {"type": "rectangle", "to_world": T(m.tolist())}
    elif kind == "box":
        rx, ry, rz = obj.get("rotation", [0, 0, 0])
        # Euler X then Y then Z (src/scene/model.rs): R = Rz·Ry·Rx.
        r = T().rotate([0, 0, 1], rz) @ T().rotate([0, 1, 0], ry) @ T().rotate([1, 0, 0], rx)
        s = {
            "type": "cube",
            "to_world": T().translate(obj["center"]) @ r @ T().scale(obj["half_extents"]),
        }
    else:
        unsupported(where, kind)
    s["bsdf"] = bsdf(obj, materials, where)
    e = emitter(obj, where)
    if not e:
        return [s]
    s["emitter"] = e
    if kind != "quad":
        return [s]
    # Both faces of a termtrace emitter emit (MODEL.md); Mitsuba's front alone: a second
    # rectangle facing the other way (v and the normal flipped), a hair behind the first so
    # that each face is hit from its own side.
    back = dict(s)
    back["to_world"] = T().translate((-1e-5 * np.linalg.norm(u + v) * n).tolist()) @ (
        s["to_world"] @ T().scale([1, -1, -1])
    )
    back["emitter"] = dict(e)
    return [s, back]


def obj_model(entry, scene_dir, where):
    """A `[[gltf]]` OBJ whose every material is overridden as Lambertian: an `obj` shape per
    MTL material is more than the benchmark needs, so one material, its map_Kd as a bitmap."""
    path = (scene_dir / entry["file"]).resolve()
    if path.suffix.lower() != ".obj":
        unsupported(where, f"{path.name} (only OBJ models)")
    overrides = entry.get("materials", {})
    if len(overrides) != 1:
        unsupported(where, "an OBJ whose materials are not one Lambertian override")
    (name, m), = overrides.items()
    if m.get("model") != "lecture" or float(m.get("specular", 1)) != 0:
        unsupported(where, f"material {name!r} unless model = \"lecture\" and specular = 0")
    mtl = path.with_suffix(".mtl").read_text()
    kd = re.search(r"^\s*map_Kd\s+(\S+)\s*$", mtl, re.M)
    c = color(m.get("color", [1, 1, 1]), where)
    refl = rgb(c)
    if kd:
        refl = {
            "type": "bitmap",
            "filename": str(path.parent / kd.group(1)),
            "filter_type": "bilinear",
        }
        if c != [1.0, 1.0, 1.0]:
            unsupported(where, "a tinted colour map")
    return {
        "type": "obj",
        "filename": str(path),
        "bsdf": {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": refl}},
    }


def sky(t, scene_dir, where):
    s = t.get("sky", {})
    if "map" in s:
        # termtrace's u = atan2(−x, z)/2π − rotation/2π (src/scene/envmap_sampling.rs);
        # Mitsuba's u = atan2(x, −z)/2π in the emitter's frame: half a turn apart, and the
        # rotation the other way.
        rot = 180.0 - float(s.get("rotation", 0))
        if not s.get("visible", True):
            unsupported(where, "a map the camera does not see")
        return {
            "type": "envmap",
            "filename": str((scene_dir / s["map"]).resolve()),
            "scale": float(s.get("intensity", 1)),
            "to_world": mi.ScalarTransform4f().rotate([0, 1, 0], rot),
        }
    if "uniform" in s:
        c = color(s["uniform"], where)
        return None if max(c) == 0 else {"type": "constant", "radiance": rgb(c)}
    # The lecture's gradient, lerp(bottom, top, (y + 1)/2): rows of an equirectangular map
    # (v = acos(y)/π), fine enough that the bilinear lookup is the line to 1e-5.
    bottom = np.array(color(s.get("bottom", [1, 1, 1]), where))
    top = np.array(color(s.get("top", [0.5, 0.7, 1.0]), where))
    h, w = 2048, 8
    y = np.cos(np.pi * (np.arange(h) + 0.5) / h)
    t_ = ((y + 1) / 2)[:, None]
    rows = (1 - t_) * bottom + t_ * top
    img = np.repeat(rows[:, None, :], w, axis=1).astype(np.float32)
    return {"type": "envmap", "bitmap": mi.Bitmap(img)}


def mitsuba_scene(path, width, height):
    t = tomllib.loads(path.read_text())
    where = str(path)
    cam = t["camera"]
    if float(cam.get("aperture", 0)) > 0:
        unsupported(where, "a thin lens")
    render = t.get("render", {})
    bounces = int(render.get("max_bounces", 10))
    T = mi.ScalarTransform4f
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": bounces + 1, "rr_depth": RR_DEPTH},
        "sensor": {
            "type": "perspective",
            "fov": float(cam.get("vfov", 90)),
            "fov_axis": "y",
            "to_world": T().look_at(
                origin=cam["look_from"], target=cam["look_at"], up=cam.get("up", [0, 1, 0])
            ),
            "film": {
                "type": "hdrfilm",
                "width": width,
                "height": height,
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
            },
            "sampler": {"type": "independent"},
        },
    }
    e = sky(t, path.parent, where)
    if e:
        d["sky"] = e
    materials = t.get("materials", {})
    i = 0
    for kind in ("sphere", "quad", "box"):
        for obj in t.get(kind, []):
            for part in shape(kind, obj, materials, f"{where}: {kind} {obj.get('name', i)}"):
                d[f"shape{i}"] = part
                i += 1
    for entry in t.get("gltf", []):
        d[f"shape{i}"] = obj_model(entry, path.parent, where)
        i += 1
    for k in t:
        if k not in ("camera", "render", "sky", "materials", "sphere", "quad", "box", "gltf"):
            unsupported(where, f"[{k}]")
    return mi.load_dict(d), bounces


def read_exr(path):
    return np.array(mi.Bitmap(str(path)), dtype=np.float64)[..., :3]


def rel_rmse(img, ref):
    return math.sqrt(float(np.mean((img - ref) ** 2 / (ref**2 + EPSILON))))


class Termtrace:
    def __init__(self, exe, scene, width, height, threads, tmp):
        self.exe, self.scene, self.size, self.threads, self.tmp = exe, scene, (width, height), threads, tmp

    def render(self, seconds, seed):
        out = Path(self.tmp) / f"tt-{seed}.exr"
        cmd = [
            self.exe, "render", str(self.scene), "--adapter", "cpu-native",
            "--threads", str(self.threads), "--width", str(self.size[0]),
            "--height", str(self.size[1]), "--time", str(seconds), "--seed", str(seed),
            "-o", str(out),
        ]  # fmt: skip
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit(f"termtrace failed: {' '.join(cmd)}\n{r.stderr}")
        m = re.search(r"(\d+) spp, ([\d.]+) s, ([\d.]+) ([kMG])samples/s", r.stderr)
        scale = {"k": 1e3, "M": 1e6, "G": 1e9}[m.group(4)]
        return read_exr(out), float(m.group(3)) * scale, int(m.group(1))


class Mitsuba:
    def __init__(self, scene, width, height):
        self.scene, self.pixels = scene, width * height
        self.rate = None

    def render_spp(self, spp, seed):
        start = time.perf_counter()
        img = mi.render(self.scene, spp=spp, seed=seed)
        dr.eval(img)
        dr.sync_thread()
        return np.array(img, dtype=np.float64)[..., :3], time.perf_counter() - start

    def measure_rate(self):
        # A quarter second's worth, twice: the first compiles the kernel.
        spp = 4
        while True:
            self.render_spp(spp, 0)
            _, t = self.render_spp(spp, 1)
            if t >= 0.25 or spp >= 1 << 16:
                break
            spp = max(spp * 2, int(spp * 0.3 / max(t, 1e-3)))
        self.rate = spp * self.pixels / t
        return self.rate

    def render(self, seconds, seed, timed=True):
        spp = max(1, round(self.rate * seconds / self.pixels))
        # Mitsuba compiles a kernel per spp: render once to compile, then time the same spp
        # (a reference needs no timing).
        if timed:
            self.render_spp(spp, seed + 1000)
        img, t = self.render_spp(spp, seed)
        return img, spp * self.pixels / t, spp


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="*", default=SCENES)
    ap.add_argument("--termtrace", default="target/release/termtrace")
    ap.add_argument("--size", default="320x192", help="WIDTHxHEIGHT (default 320x192)")
    ap.add_argument("--times", default="1,4", help="equal-time checkpoints in seconds")
    ap.add_argument("--reference-seconds", type=float, default=60.0)
    ap.add_argument("--runs", type=int, default=2, help="runs per checkpoint, averaged")
    ap.add_argument("--threads", type=int, default=os.cpu_count())
    ap.add_argument("--common-reference", action="store_true",
                    help="measure both renderers' runs against termtrace's reference")
    ap.add_argument("--save-references", metavar="DIR",
                    help="write both references there (SCENE-termtrace.exr, SCENE-mitsuba.exr)")
    a = ap.parse_args()
    width, height = (int(x) for x in a.size.split("x"))
    times = [float(x) for x in a.times.split(",")]
    mi.set_variant("llvm_ad_rgb")
    dr.set_thread_count(a.threads)
    print(f"machine: {os.cpu_count()} cores; threads {a.threads}; Mitsuba {mi.__version__} "
          f"llvm_ad_rgb; {width}x{height}; references {a.reference_seconds:g} s each"
          + ("; both against termtrace's" if a.common_reference else "")
          + f"; {a.runs} runs a checkpoint")
    header = "| scene | Msamples/s termtrace / Mitsuba (termtrace ÷ Mitsuba) | refs apart |" + "".join(
        f" rel. RMSE at {t:g} s termtrace / Mitsuba (Mitsuba ÷ termtrace) |" for t in times
    )
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for s in a.scenes:
            path = Path(s)
            scene, _ = mitsuba_scene(path, width, height)
            tt = Termtrace(a.termtrace, path, width, height, a.threads, tmp)
            mt = Mitsuba(scene, width, height)
            mt.measure_rate()
            ref_tt, _, ref_tt_spp = tt.render(a.reference_seconds, 1_000_000)
            ref_mt, _, ref_mt_spp = mt.render(a.reference_seconds, 1_000_000, timed=False)
            apart = rel_rmse(ref_mt, ref_tt)
            if a.save_references:
                out = Path(a.save_references)
                out.mkdir(parents=True, exist_ok=True)
                for name, img in (("termtrace", ref_tt), ("mitsuba", ref_mt)):
                    mi.Bitmap(img.astype(np.float32)).write(str(out / f"{path.stem}-{name}.exr"))
            rates_tt, rates_mt, cells = [], [], []
            for t in times:
                e_tt, e_mt = [], []
                for run in range(a.runs):
                    img, rate, _ = tt.render(t, run + 1)
                    e_tt.append(rel_rmse(img, ref_tt))
                    rates_tt.append(rate)
                    img, rate, _ = mt.render(t, run + 1)
                    e_mt.append(rel_rmse(img, ref_tt if a.common_reference else ref_mt))
                    rates_mt.append(rate)
                et, em = float(np.mean(e_tt)), float(np.mean(e_mt))
                cells.append(f" {et:.4f} / {em:.4f} ({em / et:.2f}×) |")
            rt, rm = float(np.median(rates_tt)), float(np.median(rates_mt))
            row = (f"| {path.stem} | {rt / 1e6:.2f} / {rm / 1e6:.2f} ({rt / rm:.2f}×) | "
                   f"{apart:.4f} |" + "".join(cells))
            print(f"{path.stem}: references {ref_tt_spp} / {ref_mt_spp} spp", file=sys.stderr)
            print(row, file=sys.stderr)
            rows.append(row)
    print(header)
    print("|---|---|---|" + "---|" * len(times))
    for r in rows:
        print(r)


if __name__ == "__main__":
    main()
