"""What the Python benches share: reading termtrace's EXRs, and rendering a scene at the
preview's size (120x76, 120x40 cells) with `render --denoise`, which writes the raw EXR and
the guides beside the image. Imported by denoise_bound.py, estimate_check.py and
oidn_compare.py (run from anywhere: Python puts a script's own folder on its path)."""
import os
import subprocess
import sys

import numpy as np
import OpenEXR


def read(path, dtype=np.float64):
    """An EXR's RGB as an (height, width, 3) array of `dtype`."""
    with OpenEXR.File(path) as f:
        ch = f.channels()
        if "RGB" in ch:
            return np.ascontiguousarray(ch["RGB"].pixels, dtype=dtype)
        return np.ascontiguousarray(np.stack([ch[c].pixels for c in "RGB"], -1), dtype=dtype)


def render(exe, scene, spp, seed, out):
    """`termtrace render SCENE --denoise` at 120x76 to `out` (a .png or .exr); returns the
    name without its extension, to which `-raw.exr`, `-albedo.exr` and `-normal.exr` add.
    Exits with termtrace's message if it fails."""
    run = subprocess.run([exe, "render", scene, "--width", "120", "--height", "76", "--spp",
                          str(spp), "--seed", str(seed), "--denoise", "-q", "-o", out],
                         capture_output=True, text=True)
    if run.returncode != 0:
        sys.exit(f"termtrace render failed:\n{run.stderr}")
    return os.path.splitext(out)[0]
