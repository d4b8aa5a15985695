#!/usr/bin/env python3
"""The raw image's error estimate, as the preview makes it and as it could be made.

The preview estimates the raw image's relative MSE from its two halves A and B without a
reference: each pixel's (A - B)^2 / 4, over an estimate of reference^2 (+ 0.01, pbrt's).
Today that estimate is A*B (src/render/snapshot.rs, shaders/resolve.wgsl): unbiased for
reference^2, but a firefly in one half makes A*B huge, so the pixel's error is counted as
small. This script renders PAIRS pairs of independent halves of SPP samples (`termtrace
render --denoise`, seeds 11, 12, ...) at 120x76 and prints, per pair, each candidate
estimate over the true error against REFERENCE (relative RMSE, the reference's own noise not
subtracted):

  A*B          what ships
  min^2        min(A, B)^2
  box*box      the product of the halves' 3x3 means
  minbox^2     the smaller of the halves' 3x3 means, squared

    pip install OpenEXR numpy
    python3 benches/estimate_check.py SCENE REFERENCE.exr [SPP] [PAIRS] [TERMTRACE]
"""
import sys
import tempfile

import numpy as np

from preview_exr import read, render


def box3(a):
    """Each pixel's 3x3 mean, the window clipped at the image's edges."""
    h, w = a.shape[:2]
    p = np.pad(a, ((1, 1), (1, 1), (0, 0)))
    n = np.pad(np.ones((h, w)), 1)
    s = sum(p[1 + dy:1 + dy + h, 1 + dx:1 + dx + w] for dy in (-1, 0, 1) for dx in (-1, 0, 1))
    c = sum(n[1 + dy:1 + dy + h, 1 + dx:1 + dx + w] for dy in (-1, 0, 1) for dx in (-1, 0, 1))
    return s / c[..., None]


def main():
    scene, ref_path = sys.argv[1], sys.argv[2]
    spp = sys.argv[3] if len(sys.argv) > 3 else "64"
    pairs = int(sys.argv[4]) if len(sys.argv) > 4 else 5
    exe = sys.argv[5] if len(sys.argv) > 5 else "termtrace"
    ref = read(ref_path)
    names = ["A*B", "min^2", "box*box", "minbox^2"]
    ratios = {k: [] for k in names}
    trues = []
    with tempfile.TemporaryDirectory() as d:
        for i in range(pairs):
            halves = [read(render(exe, scene, spp, seed, f"{d}/h{seed}.png") + "-raw.exr")
                      for seed in (11 + 2 * i, 12 + 2 * i)]
            a, b = halves
            d2 = 0.25 * (a - b) ** 2
            true = (((a + b) / 2 - ref) ** 2 / (ref**2 + 0.01)).mean()
            ba, bb = box3(a), box3(b)
            proxies = {
                "A*B": np.maximum(a * b, 0),
                "min^2": np.minimum(a, b) ** 2,
                "box*box": np.maximum(ba * bb, 0),
                "minbox^2": np.minimum(ba, bb) ** 2,
            }
            trues.append(true)
            for k in names:
                ratios[k].append(np.sqrt((d2 / (proxies[k] + 0.01)).mean() / true))
    print(f"{scene}, {spp} spp a half, {pairs} pairs: true relative RMSE",
          " ".join(f"{100 * np.sqrt(t):.1f} %" for t in trues))
    for k in names:
        print(f"  {k:9} estimate / true:", " ".join(f"{r:.2f}" for r in ratios[k]))


if __name__ == "__main__":
    main()
