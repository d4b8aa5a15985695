#!/usr/bin/env python3
"""How far the preview's denoiser is from what its filters could give (issue 30's ¼ goal).

For SCENE at 120x76 (the preview's size for 120x40 cells), renders two independent halves of
SPP samples each (`termtrace render --denoise`, seeds 11 and 12: the raw EXRs and the guides),
and applies numpy copies of the shipped filters to each half (src/denoise: the à-trous filter,
filter.rs; the first-order regression, regress.rs; both per half, with the half's own weights),
plus the regression in wider windows. It prints the relative RMSE (pbrt's: the squared error
over reference^2 + 0.01, the reference's own noise not subtracted) of the pooled raw image, of
each filter, of the shipped per-tile choice (16x16 tiles, the best of raw, à-trous and
regression by the halves' estimate), of a per-pixel choice by the same estimate smoothed over
5x5 pixels, and of an ORACLE that picks, per pixel, whichever of the five images is nearest the
reference: not a filter (it reads the answer), a bound on what choosing among them can give.

    pip install OpenEXR numpy
    termtrace converge SCENE --width 120 --height 76 --reference-spp 16384 --out DIR
    python3 benches/denoise_bound.py SCENE DIR/reference.exr [SPP] [TERMTRACE]

The numpy copies follow the Rust code's model and constants, not its every detail (window
edges, the float type), so their figures are near the bench's (`cargo bench --bench denoise`),
not equal to them.
"""
import sys
import tempfile

import numpy as np

from preview_exr import read, render

LW = np.array([0.2126, 0.7152, 0.0722])


def lum(x):
    return x @ LW


def shift(a, dy, dx):
    """a moved by (dy, dx) (out[y, x] = a[y + dy, x + dx]) and where that is inside."""
    h, w = a.shape[:2]
    out = np.zeros_like(a)
    m = np.zeros((h, w), bool)
    ys, yd = slice(max(0, -dy), min(h, h - dy)), slice(max(0, dy), min(h, h + dy))
    xs, xd = slice(max(0, -dx), min(w, w - dx)), slice(max(0, dx), min(w, w + dx))
    out[ys, xs] = a[yd, xd]
    m[ys, xs] = True
    return out, m


def box(v, r):
    """Mean over the (2r+1)^2 window, the window clipped at the image's edges."""
    s, n = np.zeros_like(v), np.zeros_like(v)
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            q, m = shift(v, dy, dx)
            s += q * m
            n += m
    return s / n


def clamp_outliers(c):
    """Fireflies: a luminance above mean + 3 sd of its 24 neighbours is scaled down to it."""
    l = lum(c)
    n, s, s2 = np.zeros_like(l), np.zeros_like(l), np.zeros_like(l)
    for dy in range(-2, 3):
        for dx in range(-2, 3):
            if dy or dx:
                q, m = shift(l, dy, dx)
                n += m
                s += q * m
                s2 += q * q * m
    mean = s / np.maximum(n, 1)
    lim = mean + 3 * np.sqrt(np.maximum(s2 / np.maximum(n, 1) - mean**2, 0))
    return c * np.where((l > lim) & (l > 0), lim / np.where(l > 0, l, 1), 1.0)[..., None]


def guide_weight(alb, nor, dy, dx):
    nn = nor / np.maximum(np.linalg.norm(nor, axis=-1, keepdims=True), 1e-9)
    sky = np.linalg.norm(nor, axis=-1) < 0.1
    qn, m = shift(nn, dy, dx)
    qa, _ = shift(alb, dy, dx)
    qs, _ = shift(sky, dy, dx)
    c = np.maximum((nn * qn).sum(-1), 0) ** 128
    w = np.where(c < 1e-6, 0, c) * np.exp(-((alb - qa) ** 2).sum(-1) / 0.01)
    w = np.where(sky | qs, (sky & qs).astype(float), w)
    return (np.ones_like(w) if dy == 0 and dx == 0 else w) * m


def atrous(c, v, alb, nor, iters=5, sig=4.0):
    """Edge-avoiding à-trous (Dammertz et al. 2010), 3x3 kernel, weights from c itself."""
    k = [0.25, 0.5, 0.25]
    for it in range(iters):
        step = 1 << it
        lp, scale = lum(c), 1 / (sig * np.sqrt(np.maximum(v, 0)) + 1e-6)
        acc, ws, va = np.zeros_like(c), np.zeros(c.shape[:2]), np.zeros(c.shape[:2])
        for j in range(3):
            for i in range(3):
                dy, dx = (j - 1) * step, (i - 1) * step
                qc, _ = shift(c, dy, dx)
                qv, _ = shift(v, dy, dx)
                w = k[j] * k[i] * guide_weight(alb, nor, dy, dx)
                w = w * np.exp(-np.abs(lp - lum(qc)) * scale)
                acc += w[..., None] * qc
                ws += w
                va += w * w * qv
        c, v = acc / ws[..., None], va / ws**2
    return c


def regress(y, wc, v, alb, nn, r=2, sig_s=1.5):
    """First-order regression of y on (1, Δalbedo, Δnormal, Δy, Δx) over a (2r+1)^2 window
    (NFOR's model, Bitterli et al. 2016), weighted by distance and by wc's luminance."""
    h, w = y.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w]
    f = np.concatenate([alb, nn, np.stack([yy / r, xx / r], -1).astype(float)], -1)
    k = f.shape[-1] + 1
    xtx, xty = np.zeros((h, w, k, k)), np.zeros((h, w, k, 3))
    lp = lum(wc)
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            qf, m = shift(f, dy, dx)
            qy, _ = shift(y, dy, dx)
            ql, _ = shift(lp, dy, dx)
            qv, _ = shift(v, dy, dx)
            wt = np.exp(-(dy * dy + dx * dx) / (2 * sig_s**2)) * m
            wt = wt * np.exp(-((lp - ql) ** 2) / (v + qv + 1e-9))
            x = np.concatenate([np.ones((h, w, 1)), qf - f], -1)
            xtx += wt[..., None, None] * x[..., :, None] * x[..., None, :]
            xty += wt[..., None, None] * x[..., :, None] * qy[..., None, :]
    ridge = np.diag(np.r_[0.0, np.full(k - 1, 1e-3)])
    return np.linalg.solve(xtx + ridge * xtx[..., 0:1, 0:1], xty)[..., 0, :]


def main():
    scene, ref_path = sys.argv[1], sys.argv[2]
    spp = sys.argv[3] if len(sys.argv) > 3 else "128"
    exe = sys.argv[4] if len(sys.argv) > 4 else "termtrace"
    ref = read(ref_path)
    with tempfile.TemporaryDirectory() as d:
        a, b = (read(render(exe, scene, spp, seed, f"{d}/h{seed}.png") + "-raw.exr")
                for seed in (11, 12))
        alb, nor = read(f"{d}/h11-albedo.exr"), read(f"{d}/h11-normal.exr")
    scale = 1 / (ref**2 + 0.01)

    def rel(img):
        return 100 * np.sqrt(((img - ref) ** 2 * scale).mean())

    # The halves' estimate of each pixel's squared error (src/denoise/mod.rs).
    def est(da, db):
        e = 0.5 * (da - b) ** 2 + 0.5 * (db - a) ** 2 - 0.5 * (a - b) ** 2 - 0.25 * (da - db) ** 2
        return (e / (np.maximum(a * b, 0) + 0.01)).sum(-1)

    mod = alb + 0.01
    da, db = a / mod, b / mod
    vd = box(0.5 * (lum(da) - lum(db)) ** 2, 3)
    fa = atrous(clamp_outliers(da), vd, alb, nor) * mod
    fb = atrous(clamp_outliers(db), vd, alb, nor) * mod
    v = box(0.5 * (lum(a) - lum(b)) ** 2, 3)
    norm = np.linalg.norm(nor, axis=-1, keepdims=True)
    nn = nor / np.maximum(norm, 1e-9) * (norm > 0.1)
    ca, cb = clamp_outliers(a), clamp_outliers(b)
    pooled = 0.5 * (a + b)
    raw_est = ((a - b) ** 2 * 0.25 / (np.maximum(a * b, 0) + 0.01)).sum(-1)
    cands = [("raw", pooled, raw_est), ("à-trous", 0.5 * (fa + fb), est(fa, fb))]
    for r, s in [(2, 1.5), (3, 2.5), (4, 3.5)]:
        ra, rb = regress(ca, fa, v, alb, nn, r, s), regress(cb, fb, v, alb, nn, r, s)
        cands.append((f"regression {2 * r + 1}x{2 * r + 1}", 0.5 * (ra + rb), est(ra, rb)))
    imgs = np.stack([c[1] for c in cands])
    h, w = a.shape[:2]

    def pick(choice):
        return np.take_along_axis(imgs, choice[None, ..., None].repeat(3, -1), 0)[0]

    print(f"{scene}, {spp} + {spp} spp, relative RMSE against {ref_path}")
    for name, img, _ in cands:
        print(f"  {name:32} {rel(img):6.2f} %")
    tiles = np.zeros((3, h, w), int)
    for ty in range(0, h, 16):
        for tx in range(0, w, 16):
            t = [c[2][ty:ty + 16, tx:tx + 16].sum() for c in cands[:3]]
            tiles[:, ty:ty + 16, tx:tx + 16] = int(np.argmin(t))
    print(f"  {'shipped: per 16x16 tile, of 3':32} {rel(pick(tiles[0])):6.2f} %")
    smooth = np.argmin(np.stack([box(c[2], 2) for c in cands]), 0)
    print(f"  {'per pixel (5x5 estimate), of 5':32} {rel(pick(smooth)):6.2f} %")
    true = np.stack([((c[1] - ref) ** 2 * scale).sum(-1) for c in cands])
    print(f"  {'ORACLE per pixel, of 5':32} {rel(pick(np.argmin(true, 0))):6.2f} %")


if __name__ == "__main__":
    main()
