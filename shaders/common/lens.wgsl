// #include "common/material.wgsl"
// Twin: src/cpu/lens.rs (tests/twins.rs keeps their functions paired).
// The map's light as a clear glass sphere refracts it onto a point (next-event estimation
// through a glass ball, the sun's caustic; docs/MODEL-NOTES.md "The map through a glass
// ball"): the paths from the point through the sphere toward a direction's light, the roots
// of β(s) = ψ − 2 (i − r′) = β_w (+ π + 2r′ with a reflection inside: Descartes' rainbow ray)
// in the plane of the point, the centre and the light (the
// specular chain of manifold next-event estimation, Hanika, Droske & Fascione, EGSR 2015),
// bracketed between β's folds and refined by safeguarded Newton steps, and how much the
// sphere spreads the light. The arithmetic is src/cpu/lens.rs's, which derives it.

// Intervals of s ∈ [0, 1] β′'s sign is read at to bracket β's folds; the most roots; the most
// Newton steps per root or fold; the least cosine of incidence of a path; how near (in s)
// lens_spread_of's root must be to a path's own.
const LENS_HALF: u32 = 8u;
const LENS_MAX_ROOTS: u32 = 3u;
const LENS_STEPS: u32 = 24u;
const LENS_GRAZING: f32 = 1e-2;
const LENS_MATCH: f32 = 1e-3;
// The most folds of β on s ∈ (0, 1).
const LENS_MAX_FOLDS: u32 = 2u;

// The plane of a point, a glass sphere and a light's direction: a (point to centre), e2 (in
// the plane, on the light's side), k = r / D, the light's angle beta from a, the index, and
// the paths' reflections inside (0 or 1).
struct LensFrame {
    a: vec3f,
    e2: vec3f,
    k: f32,
    beta: f32,
    ior: f32,
    ok: bool,
    inner: u32,
}

// The sines of incidence of the paths (the first `count` of s), in increasing order.
struct LensRoots {
    s: vec3f,
    count: u32,
}

// One path: its first leg's direction and length, where it reflects inside (else where it
// leaves), where it leaves the sphere and the normal there, its cosines of incidence at the
// entry and the exit, and its spread.
struct LensPath {
    dir: vec3f,
    dist: f32,
    turn: vec3f,
    exit: vec3f,
    cos_i: f32,
    exit_normal: vec3f,
    cos_r: f32,
    spread: f32,
    ok: bool,
}

// The plane of p, the sphere (centre c, radius r, index ior > 1) and the light's direction w;
// not ok where p is inside the sphere or w along the line through p and the centre.
fn lens_frame(p: vec3f, c: vec3f, r: f32, ior: f32, w: vec3f) -> LensFrame {
    var out = LensFrame(vec3f(0.0), vec3f(0.0), 0.0, 0.0, ior, false, 0u);
    let to_c = c - p;
    let d = length(to_c);
    if !(d > r * 1.0001) {
        return out;
    }
    let a = to_c / d;
    let ca = clamp(dot(w, a), -1.0, 1.0);
    // w's part across a, as a × (w × a): square to a to rounding however near w is to a.
    let perp = cross(a, cross(w, a));
    let sb = length(perp);
    if !(sb >= 1e-6) {
        return out;
    }
    out = LensFrame(a, perp / sb, r / d, atan2(sb, ca), ior, true, 0u);
    return out;
}

// β(s): the angle from the centre's direction at which the ray of sine of incidence s
// leaves (with a reflection inside, in (0, 2π)); β(−s) = 2π · inner − β(s).
fn lens_deviation(f: LensFrame, s: f32) -> f32 {
    let r = asin(s / f.ior);
    let b = asin(f.k * s) - 2.0 * (asin(s) - r);
    if f.inner == 0u {
        return b;
    }
    return b + PI + 2.0 * r;
}

// β(s) − β_w.
fn lens_offset(f: LensFrame, s: f32) -> f32 {
    return lens_deviation(f, s) - f.beta;
}

// dβ / ds.
fn lens_slope(f: LensFrame, s: f32) -> f32 {
    let ks = f.k * s;
    let sn = s / f.ior;
    let refracted = 2.0 / (f.ior * sqrt(1.0 - sn * sn));
    return f.k / sqrt(1.0 - ks * ks) - 2.0 / sqrt(1.0 - s * s) + refracted * f32(1u + f.inner);
}

// The derivative in s of a / √(1 − a² s²): a³ s / (1 − a² s²)^{3/2}.
fn lens_cubed(a: f32, s: f32) -> f32 {
    let q = 1.0 / sqrt(1.0 - a * s * a * s);
    return a * a * a * s * q * q * q;
}

// d²β / ds².
fn lens_curvature(f: LensFrame, s: f32) -> f32 {
    return lens_cubed(f.k, s) - 2.0 * lens_cubed(1.0, s) + 2.0 * f32(1u + f.inner) * lens_cubed(1.0 / f.ior, s);
}

// Whether the frame's light is within the angles its paths leave at (src/cpu/lens.rs:
// reaches, which derives the bounds).
fn lens_reaches(f: LensFrame) -> bool {
    if f.inner == 0u {
        return f.beta <= max(asin(f.k), 2.0 * (0.5 * PI - asin(1.0 / f.ior)));
    }
    let s2 = (4.0 - f.ior * f.ior) / 3.0;
    var bow = 0.0;
    if s2 > 0.0 {
        let s = sqrt(s2);
        bow = 4.0 * asin(s / f.ior) - 2.0 * asin(s);
    }
    let edge = PI - 4.0 * asin(1.0 / f.ior);
    return f.beta >= PI - max(asin(f.k) + bow, edge) - 1e-4;
}

// The zero in [lo, hi] of β′ (on_slope) or of β − β_w, negative at lo where lo_negative:
// safeguarded Newton steps from start, kept in the shrinking bracket (src/cpu/lens.rs: newton).
// One loop for the roots and the folds: one copy of the steps in the kernel.
fn lens_newton(f: LensFrame, lo_in: f32, hi_in: f32, start: f32, lo_negative: bool, on_slope: bool) -> f32 {
    var lo = lo_in;
    var hi = hi_in;
    var s = start;
    for (var i = 0u; i < LENS_STEPS; i++) {
        // β′ is the value on the folds and the derivative on the roots.
        let d = lens_slope(f, s);
        var g = d;
        var dg: f32;
        if on_slope {
            dg = lens_curvature(f, s);
        } else {
            g = lens_offset(f, s);
            dg = d;
        }
        if (g < 0.0) == lo_negative {
            lo = s;
        } else {
            hi = s;
        }
        let next = s - g / dg;
        // A Newton step that rounds back to s has converged (src/cpu/lens.rs: newton).
        let to = select(0.5 * (lo + hi), next, (next > lo && next < hi) || next == s);
        let step = abs(to - s);
        s = to;
        if step < 1e-7 {
            break;
        }
    }
    return s;
}

// The fold of β in [lo, hi], where β′ turns from its sign at lo (rising: ≥ 0) to the other:
// Newton's steps on β′ from the interval's middle (src/cpu/lens.rs: fold).
fn lens_fold(f: LensFrame, lo: f32, hi: f32, rising: bool) -> f32 {
    return lens_newton(f, lo, hi, 0.5 * (lo + hi), !rising, true);
}

// The folds of β on s ∈ (0, 1) (the first `count` of s), where β′ changes sign between the
// points 0, 1 / LENS_HALF, …, 1 (src/cpu/lens.rs: folds).
fn lens_folds(f: LensFrame) -> LensRoots {
    var out = LensRoots(vec3f(0.0), 0u);
    var lo = 0.0;
    var rising = lens_slope(f, 0.0) >= 0.0;
    for (var m = 1u; m <= LENS_HALF; m++) {
        let hi = f32(m) / f32(LENS_HALF);
        // β′(1) is −∞ (the ray grazes in), not computed: WGSL may assume floats finite.
        let up = m < LENS_HALF && lens_slope(f, hi) >= 0.0;
        if up != rising && out.count < LENS_MAX_FOLDS {
            out.s[out.count] = lens_fold(f, lo, hi, rising);
            out.count += 1u;
            rising = !rising;
        }
        lo = hi;
    }
    return out;
}

// The root in [lo, hi], whose offsets glo and ghi differ in sign: Newton's steps on β from
// the chord's root (src/cpu/lens.rs: refine).
fn lens_refine(f: LensFrame, lo: f32, hi: f32, glo: f32, ghi: f32) -> f32 {
    let start = clamp(lo + (hi - lo) * glo / (glo - ghi), lo, hi);
    return lens_newton(f, lo, hi, start, glo < 0.0, false);
}

// The sines of incidence of the paths from the frame's point through the sphere to its light,
// bracketed between β's folds and the ends (src/cpu/lens.rs: roots), β evaluated at the folds
// and at 1 only. One loop over the cut points and one call of lens_refine, with nothing in
// local memory: the same numbers as src/cpu/lens.rs's roots, one copy of the Newton steps in
// the kernel (BENCHMARKS.md, "Glass on the GPU").
fn lens_roots(f: LensFrame) -> LensRoots {
    var out = LensRoots(vec3f(0.0), 0u);
    if !lens_reaches(f) {
        return out;
    }
    // −1, the folds' mirror images, the folds, 1 (2n + 1 intervals); β(−s) = 2π · inner − β(s).
    let fold = lens_folds(f);
    let n = fold.count;
    let mirrored = 2.0 * PI * f32(f.inner);
    let end = lens_deviation(f, 1.0);
    var b0 = 0.0;
    var b1 = 0.0;
    if n > 0u {
        b0 = lens_deviation(f, fold.s.x);
    }
    if n > 1u {
        b1 = lens_deviation(f, fold.s.y);
    }
    var lo = -1.0;
    var glo = 0.0;
    for (var j = 0u; j <= 2u * n + 1u; j++) {
        // The cut's s, β at |s|, and whether s < 0.
        var hi = 1.0;
        var b = end;
        let below = j <= n;
        if j == 0u {
            hi = -1.0;
        } else if j <= 2u * n {
            let m = select(j - n - 1u, n - j, below);
            hi = select(fold.s[m], -fold.s[m], below);
            b = select(b0, b1, m == 1u);
        }
        let ghi = select(b, mirrored - b, below) - f.beta;
        if j > 0u && (glo < 0.0) != (ghi < 0.0) && out.count < LENS_MAX_ROOTS {
            out.s[out.count] = lens_refine(f, lo, hi, glo, ghi);
            out.count += 1u;
        }
        lo = hi;
        glo = ghi;
    }
    return out;
}

// The path of sine of incidence s from p through the sphere (centre c, radius r).
fn lens_path(f: LensFrame, p: vec3f, c: vec3f, r: f32, s: f32) -> LensPath {
    let sin_psi = f.k * s;
    let cos_psi = sqrt(max(1.0 - sin_psi * sin_psi, 0.0));
    let dir = cos_psi * f.a + sin_psi * f.e2;
    let cos_i = sqrt(max(1.0 - s * s, 0.0));
    let sn = s / f.ior;
    let cos_r = sqrt(max(1.0 - sn * sn, 0.0));
    let dist = r * (cos_psi / f.k - cos_i);
    let entry = p + dir * dist;
    let n1 = (entry - c) / r;
    let inside = normalize((dir + cos_i * n1) / f.ior - cos_r * n1);
    let chord = 2.0 * r * cos_r;
    let turn = entry + inside * chord;
    var exit = turn;
    if f.inner != 0u {
        let n2 = (turn - c) / r;
        exit = turn + (inside - 2.0 * dot(inside, n2) * n2) * chord;
    }
    let spread = f.k * f.k * abs(s) / (cos_psi * abs(lens_slope(f, s)) * sin(f.beta));
    let ok = spread > 0.0 && spread < 3.0e38 && dist > 0.0 && cos_i > LENS_GRAZING;
    return LensPath(dir, dist, turn, exit, cos_i, (exit - c) / r, cos_r, spread, ok);
}

// The spread of the path whose first leg has direction dir from the frame's point, where
// lens_roots finds that path, else 0.
fn lens_spread_of(f: LensFrame, p: vec3f, c: vec3f, r: f32, dir: vec3f) -> f32 {
    let s = dot(dir, f.e2) / f.k;
    let found = lens_roots(f);
    var gap = LENS_MATCH;
    var best = 0.0;
    var any = false;
    for (var k = 0u; k < found.count; k++) {
        let root = found.s[k];
        if abs(root - s) < gap {
            gap = abs(root - s);
            best = root;
            any = true;
        }
    }
    if !any {
        return 0.0;
    }
    let x = lens_path(f, p, c, r, best);
    return select(0.0, x.spread, x.ok);
}

// The probability that scatter_dielectric takes a ray through the sphere on the path:
// refracted in at incidence cos_i, reflected `inner` times inside and refracted out, each at
// cos_r (Schlick's Fresnel).
fn lens_transmittance(ior: f32, cos_i: f32, cos_r: f32, inner: u32) -> f32 {
    let through = (1.0 - schlick(cos_i, 1.0 / ior)) * (1.0 - schlick(cos_r, ior));
    if inner == 0u {
        return through;
    }
    return through * schlick(cos_r, ior);
}
