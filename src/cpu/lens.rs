//! The map's light as a clear glass sphere refracts it onto a point (next-event estimation
//! through a glass ball, the sun's caustic; docs/MODEL-NOTES.md "The map through a glass
//! ball"): the paths that enter the sphere and leave it by refraction, toward a direction's
//! light, and how much the sphere spreads that light. Twin: shaders/common/lens.wgsl
//! (tests/twins.rs keeps their functions paired).
//!
//! The path is the one manifold next-event estimation solves for (Hanika, Droske &
//! Fascione, "Manifold Next Event Estimation", EGSR 2015) with two refractive vertices; on
//! a sphere it lies in the plane of the centre, the point and the light's direction, and by
//! the path's reversibility it is the ray from the point traced through the sphere, one
//! unknown: its sine of incidence s. The ray from p at angle ψ from the centre (sin ψ = s r /
//! D) is turned toward the centre by i − r′ at each interface (sin i = s, sin r′ = s / n),
//! so it leaves at angle β(s) = ψ − 2 (i − r′) (the ball lens's deviation: the rainbow's
//! geometry, Descartes' ray through a drop, without its inner reflection).
//! With one reflection inside (`Frame::inner`), the ray turns by π − 2r′ more at the sphere's
//! far side, so β(s) = ψ − 2 (i − r′) + π + 2r′ (mod 2π; Descartes' primary rainbow, whose
//! total deviation is π + 2i − 4r′): the sun's image a glass ball shows on the sun's side, and
//! the ring of light it throws back.
//! β(s) = β_w has up to three roots (three rays through a point inside the caustic behind the
//! ball, one outside it); they are bracketed between β's folds (`folds`) and refined by
//! safeguarded Newton steps. A root the bracketing misses (two folds within one of the
//! intervals β′'s sign is read at) is left to scattering, and `spread_of` finds no density
//! for it, so the weights stay exact.

use super::material::schlick;
use glam::Vec3A;
use std::f32::consts::{FRAC_PI_2, PI, TAU};

/// Intervals of s ∈ [0, 1] β′'s sign is read at to bracket β's folds: its points are 0,
/// 1 / HALF, …, 1.
const HALF: usize = 8;
/// The most roots a point has (three inside the caustic).
pub const MAX_ROOTS: usize = 3;
/// The most safeguarded Newton steps per root; it stops at a step under 10⁻⁷.
const STEPS: u32 = 24;
/// The least cosine of incidence of a path `path` returns.
const GRAZING: f32 = 1e-2;
/// How near (in s) the root `spread_of` matches to a path's own must be.
const MATCH: f32 = 1e-3;
/// The most folds of β on s ∈ (0, 1): without a reflection inside one (where the point is
/// near enough, k > 2 − 2/n), with one one where n < 2.
const MAX_FOLDS: usize = 2;

/// The plane of a point, a glass sphere and a light's direction.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    /// Unit direction from the point to the centre.
    pub a: Vec3A,
    /// Unit direction in the plane, perpendicular to `a`, on the light's side.
    pub e2: Vec3A,
    /// r / D, the sine of the sphere's half-angle seen from the point.
    pub k: f32,
    /// The light's angle from `a` (in [0, π]).
    pub beta: f32,
    /// The sphere's index of refraction (above 1).
    pub ior: f32,
    /// Reflections inside the sphere between the refractions in and out: 0 or 1.
    pub inner: u32,
}

/// One path from the point through the sphere to the light.
#[derive(Clone, Copy, Debug)]
pub struct Refraction {
    /// Unit direction from the point to where it enters the sphere.
    pub dir: Vec3A,
    /// Distance from the point to the entry point.
    pub dist: f32,
    /// Where it reflects inside the sphere (with `Frame::inner` 1), else where it leaves.
    pub turn: Vec3A,
    /// Where it leaves the sphere.
    pub exit: Vec3A,
    /// The sphere's outward normal there.
    pub exit_normal: Vec3A,
    /// Cosines of incidence at the entry (outside) and at the exit (inside).
    pub cos_i: f32,
    pub cos_r: f32,
    /// The solid angle the point sees the light's image subtend, per unit solid angle of the
    /// light: sin ψ |dψ / dβ| / sin β.
    pub spread: f32,
}

/// The plane of `p`, the sphere (centre `c`, radius `r`, index `ior` > 1) and the light's
/// direction `w` (unit, toward it), or None where `p` is inside the sphere or `w` is (within
/// 10⁻⁶) along the line through p and the centre, where the plane is not defined. Its paths
/// refract in and out; `Frame { inner: 1, ..f }` gives those that reflect once inside.
pub fn frame(p: Vec3A, c: Vec3A, r: f32, ior: f32, w: Vec3A) -> Option<Frame> {
    let to_c = c - p;
    let d = to_c.length();
    if d.is_nan() || d <= r * 1.0001 {
        return None;
    }
    let a = to_c / d;
    let ca = w.dot(a).clamp(-1.0, 1.0);
    // w's part across a, as a × (w × a): square to a to rounding however near w is to a
    // (w − (w·a) a loses that where w is within a degree of a, behind the ball).
    let perp = a.cross(w.cross(a));
    let sb = perp.length();
    if sb.is_nan() || sb < 1e-6 {
        return None;
    }
    Some(Frame {
        a,
        e2: perp / sb,
        k: r / d,
        beta: sb.atan2(ca),
        ior,
        inner: 0,
    })
}

/// β(s): the angle from the centre's direction at which the ray of sine of incidence `s`
/// leaves (with a reflection inside, in (0, 2π): the light's side is below π); β(−s) =
/// 2π · inner − β(s).
#[inline(always)]
fn deviation(f: &Frame, s: f32) -> f32 {
    let r = (s / f.ior).asin();
    let b = (f.k * s).asin() - 2.0 * (s.asin() - r);
    if f.inner == 0 { b } else { b + PI + 2.0 * r }
}

/// β(s) − β_w: the angle from the light of the ray of sine of incidence `s`, as it leaves.
#[inline(always)]
fn offset(f: &Frame, s: f32) -> f32 {
    deviation(f, s) - f.beta
}

/// dβ / ds.
#[inline(always)]
fn slope(f: &Frame, s: f32) -> f32 {
    let ks = f.k * s;
    let sn = s / f.ior;
    let refracted = 2.0 / (f.ior * (1.0 - sn * sn).sqrt());
    f.k / (1.0 - ks * ks).sqrt() - 2.0 / (1.0 - s * s).sqrt() + refracted * (1 + f.inner) as f32
}

/// The derivative in s of a / √(1 − a² s²): a³ s / (1 − a² s²)^{3/2}.
#[inline(always)]
fn cubed(a: f32, s: f32) -> f32 {
    let q = 1.0 / (1.0 - a * s * a * s).sqrt();
    a * a * a * s * q * q * q
}

/// d²β / ds²: `slope`'s terms differentiated (`cubed`).
#[inline(always)]
fn curvature(f: &Frame, s: f32) -> f32 {
    cubed(f.k, s) - 2.0 * cubed(1.0, s) + 2.0 * (1 + f.inner) as f32 * cubed(f.ior.recip(), s)
}

/// Whether the frame's light is within the angles its paths leave at. Without a reflection
/// inside, β = ψ − 2 (i − r′) on s ∈ [0, 1], where ψ rises to asin k and 2 (i − r′) to
/// 2 (π/2 − asin(1/n)), so β lies in [−2 (π/2 − asin(1/n)), asin k], and β(−s) = −β(s):
/// |β| is at most the larger of the two (most of a point's lights, on its lit side, are
/// beyond). With one, β = π + ψ + 4r′ − 2i. On s ∈ [0, 1], 4r′ − 2i rises from 0 to its
/// maximum at s² = (4 − n²)/3 where n < 2 (the rainbow's angle from the antisolar point:
/// Descartes' ray of least deviation) and falls to 4 asin(1/n) − π at s = 1; so on s ≥ 0,
/// β ≥ π − max(0, π − 4 asin(1/n)), and on s < 0, where β(−s) = 2π − β(s), β ≥ π − asin k −
/// that maximum.
#[inline(always)]
fn reaches(f: &Frame) -> bool {
    if f.inner == 0 {
        return f.beta <= f.k.asin().max(2.0 * (FRAC_PI_2 - f.ior.recip().asin()));
    }
    let s2 = (4.0 - f.ior * f.ior) / 3.0;
    let bow = if s2 > 0.0 {
        let s = s2.sqrt();
        4.0 * (s / f.ior).asin() - 2.0 * s.asin()
    } else {
        0.0
    };
    let edge = PI - 4.0 * f.ior.recip().asin();
    // A margin for the rounding of the solver's own arithmetic.
    f.beta >= PI - (f.k.asin() + bow).max(edge) - 1e-4
}

/// The zero in [lo, hi] of the function whose value and derivative at s `eval` gives,
/// negative at `lo` where `lo_negative` (else not): safeguarded Newton steps from `start`,
/// each kept in the shrinking bracket, else halving it; and the steps it took (for the
/// tests). The roots (`refine`, on β) and the folds (`fold`, on β′) are both found by it.
fn newton(
    mut lo: f32,
    mut hi: f32,
    start: f32,
    lo_negative: bool,
    eval: impl Fn(f32) -> (f32, f32),
) -> (f32, u32) {
    let mut s = start;
    for taken in 1..=STEPS {
        let (g, dg) = eval(s);
        if (g < 0.0) == lo_negative {
            lo = s;
        } else {
            hi = s;
        }
        let next = s - g / dg;
        // A Newton step that rounds back to s has converged: s is then an end of the
        // bracket, and taken as outside it, the step became a halving, and the halvings ran
        // to the bracket's width, up to all STEPS (measured on `glass` and `outdoor-caustics`:
        // 10 and 12 steps on average, 6 % and 13 % of the roots all 24, where Newton's own
        // steps settle in about 5).
        let to = if (next > lo && next < hi) || next == s {
            next
        } else {
            0.5 * (lo + hi)
        };
        let step = (to - s).abs();
        s = to;
        if step < 1e-7 {
            return (s, taken);
        }
    }
    (s, STEPS)
}

/// The root in [lo, hi], whose offsets `glo` and `ghi` differ in sign: Newton steps on β from
/// the chord's root; and the steps it took.
fn refine(f: &Frame, lo: f32, hi: f32, glo: f32, ghi: f32) -> (f32, u32) {
    let start = (lo + (hi - lo) * glo / (glo - ghi)).clamp(lo, hi);
    newton(lo, hi, start, glo < 0.0, |s| (offset(f, s), slope(f, s)))
}

/// The fold of β in [lo, hi], where β′ turns from the sign it has at `lo` (`rising`: ≥ 0)
/// to the other: Newton's steps on β′ (with `curvature`) from the interval's middle; and the
/// steps it took. Twenty halvings found it before (to 2⁻²³ of the interval); Newton's steps
/// settle in about five.
fn fold(f: &Frame, lo: f32, hi: f32, rising: bool) -> (f32, u32) {
    newton(lo, hi, 0.5 * (lo + hi), !rising, |s| {
        (slope(f, s), curvature(f, s))
    })
}

/// The folds of β on s ∈ (0, 1): where β′ changes sign between the points 0, 1 / HALF, …, 1
/// (β′ is even, so −s is a fold too). Between folds β is monotonic. At a fold two paths
/// merge: with a reflection inside, the rainbow's angle (Descartes' ray of least deviation);
/// without one, the caustic behind the ball, where a point inside it has three paths.
fn folds(f: &Frame) -> ([f32; MAX_FOLDS], usize, u32) {
    let (mut out, mut count, mut steps) = ([0.0; MAX_FOLDS], 0, 0);
    let (mut lo, mut rising) = (0.0, slope(f, 0.0) >= 0.0);
    for m in 1..=HALF {
        let hi = m as f32 / HALF as f32;
        // β′(1) is −∞ (the ray grazes in), not computed: WGSL may assume floats finite.
        let up = m < HALF && slope(f, hi) >= 0.0;
        if up != rising && count < MAX_FOLDS {
            let (s, taken) = fold(f, lo, hi, rising);
            (out[count], count, steps) = (s, count + 1, steps + taken);
            rising = !rising;
        }
        lo = hi;
    }
    (out, count, steps)
}

/// The sines of incidence of the paths from the frame's point through the sphere to its
/// light, in increasing order, how many there are (at most `MAX_ROOTS`), and the Newton steps
/// taken on the folds and on the roots (for the tests): bracketed
/// between β's folds and the ends, where each interval holds one root at most. β is
/// evaluated at the folds and at 1 only, β(−s) being 2π · inner − β(s). (A fixed grid of 16
/// intervals, used before without a reflection inside, took nine evaluations and missed two
/// roots that shared an interval near the caustic; with one, 7 % of the test's cases.)
pub fn roots(f: &Frame) -> ([f32; MAX_ROOTS], usize, [u32; 2]) {
    let (mut out, mut count, mut steps) = ([0.0; MAX_ROOTS], 0, 0);
    if !reaches(f) {
        return (out, 0, [0; 2]);
    }
    let (fold, n, fold_steps) = folds(f);
    // −1, the folds' mirror images, the folds, 1; and β − β_w there.
    let mirrored = TAU * f.inner as f32;
    let (mut cuts, mut at) = ([0.0; 2 * MAX_FOLDS + 2], [0.0; 2 * MAX_FOLDS + 2]);
    let end = deviation(f, 1.0);
    (cuts[0], at[0]) = (-1.0, mirrored - end - f.beta);
    for j in 0..n {
        let (s, b) = (fold[n - 1 - j], deviation(f, fold[n - 1 - j]));
        (cuts[1 + j], at[1 + j]) = (-s, mirrored - b - f.beta);
        (cuts[2 * n - j], at[2 * n - j]) = (s, b - f.beta);
    }
    (cuts[1 + 2 * n], at[1 + 2 * n]) = (1.0, end - f.beta);
    for j in 0..=2 * n {
        let (glo, ghi) = (at[j], at[j + 1]);
        if (glo < 0.0) != (ghi < 0.0) && count < MAX_ROOTS {
            let (s, taken) = refine(f, cuts[j], cuts[j + 1], glo, ghi);
            (out[count], count, steps) = (s, count + 1, steps + taken);
        }
    }
    (out, count, [fold_steps, steps])
}

/// The path of sine of incidence `s` from `p` through the sphere (centre `c`, radius `r`).
pub fn path(f: &Frame, p: Vec3A, c: Vec3A, r: f32, s: f32) -> Option<Refraction> {
    let sin_psi = f.k * s;
    let cos_psi = (1.0 - sin_psi * sin_psi).max(0.0).sqrt();
    let dir = cos_psi * f.a + sin_psi * f.e2;
    let cos_i = (1.0 - s * s).max(0.0).sqrt();
    let sn = s / f.ior;
    let cos_r = (1.0 - sn * sn).max(0.0).sqrt();
    let dist = r * (cos_psi / f.k - cos_i);
    let entry = p + dir * dist;
    let n1 = (entry - c) / r;
    // Refracted in (material::refract_dir's Snell's law), across the chord of length
    // 2r cos r′, and with a reflection inside, mirrored there across another as long.
    let inside = ((dir + cos_i * n1) / f.ior - cos_r * n1).normalize();
    let chord = 2.0 * r * cos_r;
    let turn = entry + inside * chord;
    let exit = if f.inner == 0 {
        turn
    } else {
        let n2 = (turn - c) / r;
        turn + (inside - 2.0 * inside.dot(n2) * n2) * chord
    };
    // sin ψ |dψ/dβ| / sin β, with dψ/ds = k / cos ψ: k² |s| / (cos ψ |β′(s)| sin β).
    let spread = f.k * f.k * s.abs() / (cos_psi * slope(f, s).abs() * f.beta.sin());
    // (Grazing paths, which carry next to no light, are left to scattering: their entry
    // point is too ill-conditioned to trace to.)
    if !(spread > 0.0 && spread.is_finite() && dist > 0.0 && cos_i > GRAZING) {
        return None;
    }
    Some(Refraction {
        dir,
        dist,
        turn,
        exit,
        exit_normal: (exit - c) / r,
        cos_i,
        cos_r,
        spread,
    })
}

/// The spread of the path whose first leg has direction `dir` from the frame's point (a ray
/// the point's lobe drew, which went through the sphere and left it toward the frame's light),
/// where `roots` finds that path, else None: light sampling would not have found it.
pub fn spread_of(f: &Frame, p: Vec3A, c: Vec3A, r: f32, dir: Vec3A) -> Option<f32> {
    let s = dir.dot(f.e2) / f.k;
    let (found, count, _) = roots(f);
    let mut best = None;
    let mut gap = MATCH;
    for &root in &found[..count] {
        if (root - s).abs() < gap {
            gap = (root - s).abs();
            best = Some(root);
        }
    }
    path(f, p, c, r, best?).map(|x| x.spread)
}

/// The probability that `material::scatter_dielectric` takes a ray through the sphere on the
/// path: refracted in at incidence cos i, reflected `inner` times inside and refracted out,
/// each at cos r′ (Schlick's Fresnel).
pub fn transmittance(ior: f32, cos_i: f32, cos_r: f32, inner: u32) -> f32 {
    let through = (1.0 - schlick(cos_i, 1.0 / ior)) * (1.0 - schlick(cos_r, ior));
    if inner == 0 {
        through
    } else {
        through * schlick(cos_r, ior)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::lcg::Lcg;

    /// `refine` settles a root, and `fold` a fold, in Newton's few steps: over the frames of
    /// `the_paths_refract_to_the_light` (through the sphere and with a reflection inside), at
    /// most 7.5 steps per root and 6 per fold on average (measured: 6.9 and 4.8). The brackets
    /// between folds are wider than the 16-interval grid's that bracketed the roots without a
    /// reflection inside before (5.1 steps a root there), and spare seven evaluations of β a
    /// frame. Before a step that rounds back to its start counted as converged, such a step
    /// became a halving, and the halvings ran to the bracket's width: 11.0 steps a root on the
    /// grid, 10–12 in the shipped scenes (BENCHMARKS.md, "Newton's steps, fixed"); the folds
    /// were bisected in 20.
    #[test]
    fn newton_settles_roots_and_folds_in_few_steps() {
        let mut rng = Lcg(11);
        let (mut roots_seen, mut folds_seen) = (0u32, 0u32);
        let (mut root_steps, mut fold_steps) = (0u32, 0u32);
        for case in 0..4000 {
            let c = Vec3A::new(rng.f(), rng.f(), rng.f()) * 2.0 - 1.0;
            let r = 0.1 + rng.f();
            let ior = 1.2 + 0.8 * rng.f();
            let p = c + rng.unit() * r * (1.01 + 4.0 * rng.f());
            let Some(f) = frame(p, c, r, ior, rng.unit()) else {
                continue;
            };
            let f = Frame {
                inner: case % 2,
                ..f
            };
            let (_, count, [fs, rs]) = roots(&f);
            roots_seen += count as u32;
            root_steps += rs;
            if reaches(&f) {
                folds_seen += folds(&f).1 as u32;
                fold_steps += fs;
            }
        }
        let per_root = root_steps as f64 / roots_seen as f64;
        let per_fold = fold_steps as f64 / folds_seen as f64;
        assert!(
            roots_seen > 1000 && folds_seen > 500,
            "{roots_seen} roots, {folds_seen} folds"
        );
        assert!(
            per_root <= 7.5 && per_fold <= 6.0,
            "{per_root:.2} steps per root, {per_fold:.2} per fold on average"
        );
    }

    /// Snell's law in vector form (PBRT 4th ed. §9.3), `n` facing `d`: None at total internal
    /// reflection. An implementation apart from the solver's angles.
    fn refract(d: Vec3A, n: Vec3A, eta: f32) -> Option<Vec3A> {
        let cos_i = -d.dot(n);
        let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
        (k >= 0.0).then(|| (eta * d + (eta * cos_i - k.sqrt()) * n).normalize())
    }

    /// Where a ray from inside or outside meets the sphere (the far side from inside).
    fn meet(o: Vec3A, d: Vec3A, c: Vec3A, r: f32, inside: bool) -> Option<Vec3A> {
        let oc = o - c;
        let b = oc.dot(d);
        let disc = b * b - (oc.dot(oc) - r * r);
        if disc < 0.0 {
            return None;
        }
        let t = if inside {
            -b + disc.sqrt()
        } else {
            -b - disc.sqrt()
        };
        (t > 0.0).then(|| o + t * d)
    }

    /// The light's direction as a ray from `p` along `dir` leaves the sphere after `inner`
    /// reflections inside, traced apart.
    fn trace_through(
        p: Vec3A,
        dir: Vec3A,
        c: Vec3A,
        r: f32,
        ior: f32,
        inner: u32,
    ) -> Option<Vec3A> {
        let e = meet(p, dir, c, r, false)?;
        let mut inside = refract(dir, (e - c) / r, 1.0 / ior)?;
        let mut x = meet(e, inside, c, r, true)?;
        for _ in 0..inner {
            let n = (x - c) / r;
            inside = inside - 2.0 * inside.dot(n) * n;
            x = meet(x, inside, c, r, true)?;
        }
        refract(inside, -(x - c) / r, ior)
    }

    /// Every path `roots` finds leaves the sphere toward the light (traced apart, by vector
    /// Snell: within 0.2° where the exit's Jacobian is not extreme); `path` lands on the
    /// sphere where it says; and the number of paths is a dense scan's (f64, 20 000 steps of
    /// s) on all but the configurations where two roots share a grid interval (under 1 %):
    /// through the sphere, and with one reflection inside.
    #[test]
    fn the_paths_refract_to_the_light() {
        for reflections in [0, 1] {
            paths_refract_to_the_light(reflections);
        }
    }

    fn paths_refract_to_the_light(reflections: u32) {
        let mut rng = Lcg(3 + reflections as u64);
        let (mut paths, mut missed, mut cases, mut inner) = (0, 0, 0, 0);
        for _ in 0..4000 {
            let c = Vec3A::new(rng.f(), rng.f(), rng.f()) * 2.0 - 1.0;
            let r = 0.1 + rng.f();
            let ior = 1.2 + 0.8 * rng.f();
            let (p, w) = if reflections > 0 {
                // A light a reflection inside can bring back is behind the point.
                let p = c + rng.unit() * r * (1.01 + 4.0 * rng.f());
                (p, ((p - c).normalize() + 0.8 * rng.unit()).normalize())
            } else if cases % 2 == 0 {
                (c + rng.unit() * r * (1.01 + 4.0 * rng.f()), rng.unit())
            } else {
                // Behind the sphere and near it, where three paths may meet.
                let p = c + rng.unit() * r * (1.01 + 0.5 * rng.f());
                (
                    p,
                    ((c - p).normalize() + 0.3 * rng.f() * rng.unit()).normalize(),
                )
            };
            let Some(f) = frame(p, c, r, ior, w) else {
                continue;
            };
            let f = Frame {
                inner: reflections,
                ..f
            };
            cases += 1;
            let (found, count, _) = roots(&f);
            // The dense scan, in f64: with a reflection inside, β(s) = ψ + π − 2i + 4r′.
            let (k, b, n) = (f.k as f64, f.beta as f64, ior as f64);
            let m = reflections as f64;
            let g = |s: f64| {
                let rr = (s / n).asin();
                (k * s).asin() - 2.0 * (s.asin() - rr) + m * (std::f64::consts::PI + 2.0 * rr) - b
            };
            let steps = 20000;
            let dense = (0..steps)
                .filter(|&j| {
                    let lo = -1.0 + 2.0 * j as f64 / steps as f64;
                    let hi = -1.0 + 2.0 * (j + 1) as f64 / steps as f64;
                    (g(lo) < 0.0) != (g(hi) < 0.0)
                })
                .count();
            if dense != count {
                missed += 1;
            }
            if dense == 3 {
                inner += 1;
            }
            for &s in &found[..count] {
                let Some(x) = path(&f, p, c, r, s) else {
                    continue;
                };
                let entry = p + x.dir * x.dist;
                assert!(
                    ((entry - c).length() - r).abs() < 1e-4 * (1.0 + r),
                    "p {p} c {c} r {r} ior {ior} s {s} k {} dist {} off {}",
                    f.k,
                    x.dist,
                    (entry - c).length() - r
                );
                assert!(((x.turn - c).length() - r).abs() < 1e-3 * (1.0 + r));
                assert!(((x.exit - c).length() - r).abs() < 1e-3 * (1.0 + r));
                let out = trace_through(p, x.dir, c, r, ior, reflections)
                    .unwrap_or_else(|| panic!("p {p} c {c} r {r} ior {ior} w {w} s {s}: no path"));
                if x.spread < 100.0 {
                    assert!(
                        out.dot(w) > 1.0 - 6e-6,
                        "p {p} c {c} r {r} ior {ior} w {w} s {s}: {}° off",
                        out.dot(w).min(1.0).acos().to_degrees()
                    );
                }
                paths += 1;
            }
        }
        eprintln!(
            "{reflections} inside: {paths} paths, {inner} with three, {missed} of {cases} missed"
        );
        assert!(
            paths > 2000 && inner > 100,
            "{paths} paths, {inner} points with three"
        );
        assert!(
            (missed as f64) < 0.01 * cases as f64,
            "{missed} of {cases} counted apart from the dense scan"
        );
    }

    /// `spread` is the ratio of solid angles the solver's own map from light directions to
    /// directions at p gives, measured by finite differences (to 1 %), in and out of the
    /// caustic, with and without a reflection inside; and `spread_of` finds it again from a
    /// path's first direction, and nothing from a direction no path has.
    #[test]
    fn the_spread_is_the_jacobian_of_the_refraction() {
        for reflections in [0, 1] {
            spread_is_the_jacobian(reflections);
        }
        // A direction the sphere does not bend any path into.
        let f = frame(Vec3A::new(0.0, 0.0, 3.0), Vec3A::ZERO, 0.5, 1.5, Vec3A::X).unwrap();
        assert_eq!(roots(&f).1, 0);
        assert!(spread_of(&f, Vec3A::new(0.0, 0.0, 3.0), Vec3A::ZERO, 0.5, -Vec3A::Z).is_none());
        // Nor, with a reflection inside, a direction away from the point's side.
        let f = Frame {
            inner: 1,
            ..frame(
                Vec3A::new(0.0, 0.0, 3.0),
                Vec3A::ZERO,
                0.5,
                1.5,
                -Vec3A::Z + 0.1 * Vec3A::X,
            )
            .unwrap()
        };
        assert_eq!(roots(&f).1, 0);
    }

    fn spread_is_the_jacobian(reflections: u32) {
        let mut rng = Lcg(5 + reflections as u64);
        let mut checked = 0;
        for _ in 0..10000 {
            let (c, r) = (Vec3A::ZERO, 0.5);
            let ior = 1.3 + 0.6 * rng.f();
            let p = rng.unit() * r * (1.05 + 5.0 * rng.f());
            // A light a reflection inside can bring back is behind the point.
            let w = match reflections {
                0 => rng.unit(),
                _ => (p.normalize() + 0.8 * rng.unit()).normalize(),
            };
            let Some(f) = frame(p, c, r, ior, w) else {
                continue;
            };
            let f = Frame {
                inner: reflections,
                ..f
            };
            let (found, count, _) = roots(&f);
            for &s in &found[..count] {
                let Some(x) = path(&f, p, c, r, s) else {
                    continue;
                };
                assert_eq!(spread_of(&f, p, c, r, x.dir), Some(x.spread));
                // Finite differences hold away from the fold (two roots merging, where the
                // rainbow is) and grazing paths.
                let away = slope(&f, s).abs() > 0.5 && s.abs() < 0.9 && s.abs() > 0.05;
                if !(x.spread > 1e-3 && x.spread < 10.0 && away) {
                    continue;
                }
                let t1 = w.any_orthonormal_vector();
                let t2 = w.cross(t1);
                let h = 1e-3;
                // The path near this one for a nearby light direction.
                let dir_at = |dw: Vec3A| {
                    let g = Frame {
                        inner: reflections,
                        ..frame(p, c, r, ior, (w + dw).normalize())?
                    };
                    let (near, n, _) = roots(&g);
                    near[..n]
                        .iter()
                        .filter_map(|&t| path(&g, p, c, r, t))
                        .min_by(|a, b| {
                            let da = (a.dir - x.dir).length();
                            let db = (b.dir - x.dir).length();
                            da.total_cmp(&db)
                        })
                        .map(|y| y.dir)
                };
                let (Some(a1), Some(b1), Some(a2), Some(b2)) = (
                    dir_at(t1 * h),
                    dir_at(-t1 * h),
                    dir_at(t2 * h),
                    dir_at(-t2 * h),
                ) else {
                    continue;
                };
                let seen = (a1 - b1).cross(a2 - b2).dot(x.dir).abs();
                let source = (2.0 * h) * (2.0 * h);
                assert!(
                    (seen / source / x.spread - 1.0).abs() < 0.01,
                    "p {p} ior {ior} w {w} s {s}: measured {} against {}",
                    seen / source,
                    x.spread
                );
                checked += 1;
            }
        }
        assert!(checked > 1000, "{reflections} inside: {checked}");
    }

    /// A path through the sphere's centre passes unbent, and Schlick's Fresnel lets through
    /// (1 − r0)² of it, and r0 (1 − r0)² back after a reflection at the far side; at grazing
    /// incidence nothing enters.
    #[test]
    fn head_on_the_sphere_passes_the_light_through() {
        let r0 = (0.5f32 / 2.5).powi(2);
        assert!((transmittance(1.5, 1.0, 1.0, 0) - (1.0 - r0) * (1.0 - r0)).abs() < 1e-6);
        assert!((transmittance(1.5, 1.0, 1.0, 1) - r0 * (1.0 - r0) * (1.0 - r0)).abs() < 1e-7);
        assert_eq!(transmittance(1.5, 0.0, 0.7, 0), 0.0);
        // Head on, a point sees the light behind it reflected straight back.
        let p = Vec3A::new(0.0, 0.0, 3.0);
        let f = frame(
            p,
            Vec3A::ZERO,
            0.5,
            1.5,
            Vec3A::new(0.0, 0.01, 1.0).normalize(),
        )
        .unwrap();
        let (found, count, _) = roots(&Frame { inner: 1, ..f });
        assert!(found[..count].iter().any(|s| s.abs() < 0.05), "{found:?}");
    }
}
