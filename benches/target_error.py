#!/usr/bin/env python3
"""Where `render --target-error E` stops, against the true error (issue 45, item 3).

For each shipped scene at 96x54, renders a reference (`converge --reference-spp 4096`, cached)
and then `render --target-error E` with seeds 1..RUNS, and prints each run's true relative
RMSE (pbrt's: squared error over reference^2 + 0.01, the reference's own noise left in) over
E. A stop within 25 % of E reads 0.75-1.25.

    pip install OpenEXR numpy
    python3 benches/target_error.py [E] [RUNS] [TERMTRACE] [SCENE ...]
"""
import subprocess
import sys
import tempfile

import numpy as np

from preview_exr import read

SCENES = ["showcase", "basic", "metal", "fuzz", "specular", "emissive", "dielectric", "spheres",
          "dof", "cornell", "weekend", "mesh", "lamp", "outdoor", "outdoor-caustics", "pbr",
          "glass"]


def main():
    e = float(sys.argv[1]) if len(sys.argv) > 1 else 0.05
    runs = int(sys.argv[2]) if len(sys.argv) > 2 else 3
    exe = sys.argv[3] if len(sys.argv) > 3 else "termtrace"
    scenes = sys.argv[4:] or SCENES
    size = ["--width", "96", "--height", "54"]
    with tempfile.TemporaryDirectory() as d:
        for scene in scenes:
            subprocess.run([exe, "converge", scene, *size, "--reference-spp", "4096",
                            "--time", "0.1", "--out", f"{d}/{scene}", "-q"], check=True,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            ref = read(f"{d}/{scene}/reference.exr")
            ratios = []
            for seed in range(1, runs + 1):
                out = f"{d}/{scene}-{seed}.exr"
                subprocess.run([exe, "render", scene, *size, "--spp", "65536", "--seed",
                                str(seed), "--target-error", str(e), "-o", out, "-q"],
                               check=True, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
                img = read(out)
                true = np.sqrt(((img - ref) ** 2 / (ref ** 2 + 0.01)).mean())
                ratios.append(true / e)
            print(f"{scene:18} true / E: " + " ".join(f"{r:.2f}" for r in ratios), flush=True)


if __name__ == "__main__":
    main()
