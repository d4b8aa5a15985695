#!/usr/bin/env python3
"""The denoiser against Open Image Denoise (the quality anchor of issue 30).

For SCENE at 120x76 (the preview's size for 120x40 cells) and 16, 64, 256 spp, renders with
`termtrace render --denoise` (the denoised image, the raw EXR and the guides), denoises the
raw EXR with OIDN (albedo and normal guides, HDR) and prints the relative RMSE (pbrt's: the
squared error over reference^2 + 0.01) of the raw image, termtrace's and OIDN's against a
converged reference EXR of the same size (e.g. `termtrace converge SCENE --width 120
--height 76 --reference-spp 16384 --out DIR` writes DIR/reference.exr).

    pip install pyoidn OpenEXR      # OIDN 2.5.1 and an EXR reader, from PyPI
    python3 benches/oidn_compare.py SCENE REFERENCE.exr [TERMTRACE]
"""
import os
import sys
import tempfile
import time

import numpy as np
import pyoidn

from preview_exr import read as read_exr, render


def read(path):
    return read_exr(path, np.float32)


def main():
    scene, reference = sys.argv[1], sys.argv[2]
    termtrace = sys.argv[3] if len(sys.argv) > 3 else "target/release/termtrace"
    ref = read(reference)

    def rel(img):
        return np.sqrt(np.mean((img - ref) ** 2 / (ref ** 2 + 0.01)))

    with tempfile.TemporaryDirectory() as d:
        for spp in (16, 64, 256):
            out = os.path.join(d, f"{scene}{spp}.exr")
            stem = render(termtrace, scene, spp, 3, out)
            raw, albedo, normal = (read(f"{stem}-{k}.exr") for k in ("raw", "albedo", "normal"))
            t = time.time()
            oidn = pyoidn.denoise(raw, albedo, normal, hdr=True)
            took = time.time() - t
            print(f"{scene:9} {spp:4} spp   raw {rel(raw) * 100:6.2f} %   termtrace "
                  f"{rel(read(out)) * 100:6.2f} %   OIDN {rel(oidn) * 100:6.2f} % "
                  f"({took * 1e3:.0f} ms with its setup)")


if __name__ == "__main__":
    main()
