//! The environment map in lanes: the direction of map coordinates and back, the sampling
//! distribution's two inversions (gathers from its CDFs and guide tables) and its density,
//! and the bilinear lookup; `envmap_sampling`'s arithmetic operation for operation, so that
//! each lane's values are the scalar tracer's bit for bit (tested with the paths,
//! `lanes_trace_the_scalar_paths_bit_for_bit`, and here on their own).

use super::trig::{acos_over_pi, atan2_turns, sin_cos_turns};
use crate::cpu::simd::{F, I, Isa, M, MAX_LANES, Make, V3, lanes_of, rows};
use crate::scene::envmap::EnvMap;
use crate::scene::envmap_sampling::Distribution;
use crate::scene::trig::FRAC_1_TAU;
use glam::Vec3A;
use std::arch::x86_64::{_CMP_EQ_OQ, _CMP_UNORD_Q};
use std::f32::consts::PI;

/// `envmap_sampling::coordinates` of directions `d` in lanes, and the lanes where a component
/// of `d` is NaN, whose coordinates are not the scalar function's (its min and max differ
/// from the vector ones there): the caller looks those up with the scalar code.
#[inline(always)]
pub(super) fn coordinates<S: Isa>(s: S, d: V3<S>, rotation: f32) -> ((F<S>, F<S>), M<S>) {
    let (zero, one) = (s.zero(), s.splat(1.0));
    let v = acos_over_pi(s, d[1].max(s.splat(-1.0)).min(one));
    let turns = atan2_turns(s, -d[0], d[2]) - s.splat(rotation) * s.splat(FRAC_1_TAU);
    let u = turns - floor(s, turns);
    let nan = d[0].cmp::<_CMP_UNORD_Q>(d[1]) | d[2].cmp::<_CMP_UNORD_Q>(d[2]);
    ((u.blend(zero, u.ge(one)), v), nan)
}

/// `envmap_sampling::direction_and_sin` in lanes.
#[inline(always)]
pub(super) fn direction_and_sin<S: Isa>(s: S, u: F<S>, v: F<S>, rotation: f32) -> (V3<S>, F<S>) {
    let (sin_t, cos_t) = sin_cos_turns(s, s.splat(0.5) * v);
    let phi = u + s.splat(rotation) * s.splat(FRAC_1_TAU);
    let (sin_p, cos_p) = sin_cos_turns(s, phi - floor(s, phi));
    ([-sin_t * sin_p, cos_t, sin_t * cos_p], sin_t)
}

/// A map's CDFs and guide tables as words, for gathers.
pub(super) struct Tables<'a> {
    marginal: &'a [u32],
    conditional: &'a [u32],
    guide_marginal: &'a [u32],
    guide_conditional: &'a [u32],
    /// Buckets of each row's guide table.
    buckets: i32,
}

impl<'a> Tables<'a> {
    pub(super) fn of(d: &'a Distribution) -> Tables<'a> {
        let (guide_marginal, guide_conditional, buckets) = d.guides();
        Tables {
            marginal: bytemuck::cast_slice(&d.marginal),
            conditional: bytemuck::cast_slice(&d.conditional),
            guide_marginal,
            guide_conditional,
            buckets: buckets as i32,
        }
    }
}

/// Directions drawn from the map, in lanes (`envmap_sampling::Sample`).
pub(super) struct Drawn<S: Isa> {
    pub(super) dir: V3<S>,
    /// The density with respect to solid angle.
    pub(super) pdf: F<S>,
    /// The map coordinates (u, v) the directions were made from.
    pub(super) uv: (F<S>, F<S>),
}

/// `Distribution::sample` in lanes, for draws (u1, u2) in [0, 1).
#[inline(always)]
pub(super) fn sample<S: Isa>(
    s: S,
    d: &Distribution,
    t: &Tables,
    (u1, u2): (F<S>, F<S>),
    rotation: f32,
) -> Drawn<S> {
    let (w, h) = (d.width as i32, d.height as i32);
    let zero = s.int(0);
    let mbuckets = t.guide_marginal.len() as i32 - 1;
    let (y, ty) = invert(
        s,
        (t.marginal, zero, h),
        (t.guide_marginal, zero, mbuckets),
        u2,
    );
    let (row, guide) = (y * s.int(w + 1), y * s.int(t.buckets + 1));
    let (x, tx) = invert(
        s,
        (t.conditional, row, w),
        (t.guide_conditional, guide, t.buckets),
        u1,
    );
    let u = (x.to_float() + tx) / s.splat(d.width as f32);
    let v = (y.to_float() + ty) / s.splat(d.height as f32);
    let (dir, sin_t) = direction_and_sin(s, u, v, rotation);
    let pdf = if d.integral > 0.0 {
        density(s, d, t, x, y, row) / (s.splat(2.0 * PI * PI) * sin_t)
    } else {
        s.zero()
    };
    Drawn {
        dir,
        pdf: pdf.keep(sin_t.gt(s.zero())),
        uv: (u, v),
    }
}

/// `Distribution::pdf_at` in lanes, at coordinates (u, v) in [0, 1] (not NaN).
#[inline(always)]
pub(super) fn pdf_at<S: Isa>(s: S, d: &Distribution, t: &Tables, u: F<S>, v: F<S>) -> F<S> {
    if d.integral <= 0.0 {
        return s.zero();
    }
    let x = texel(s, u * s.splat(d.width as f32), d.width);
    let y = texel(s, v * s.splat(d.height as f32), d.height);
    let sin_t = sin_cos_turns(s, s.splat(0.5) * v).0;
    let row = y * s.int(d.width as i32 + 1);
    (density(s, d, t, x, y, row) / (s.splat(2.0 * PI * PI) * sin_t)).keep(sin_t.gt(s.zero()))
}

/// `Distribution::texel_at`'s index of coordinate c scaled by `n` texels: the truncation, at
/// most the last texel.
#[inline(always)]
fn texel<S: Isa>(s: S, c: F<S>, n: u32) -> I<S> {
    let i = c.truncate();
    let last = s.int(n as i32 - 1);
    i.blend(last, i.gt(last))
}

/// Word `i` of `table` as a float, in lanes.
#[inline(always)]
fn word<S: Isa>(table: &[u32], i: I<S>) -> F<S> {
    I::gather(table, i).float_of_bits()
}

/// `Distribution::density_uv` of texels (x, y) in lanes (`row`: row y's first CDF word).
#[inline(always)]
fn density<S: Isa>(s: S, d: &Distribution, t: &Tables, x: I<S>, y: I<S>, row: I<S>) -> F<S> {
    let one = s.int(1);
    let dm = word(t.marginal, y + one) - word(t.marginal, y);
    let dr = word(t.conditional, row + x + one) - word(t.conditional, row + x);
    ((dm * s.splat(d.height as f32)) * dr) * s.splat(d.width as f32)
}

/// `invert_guided` in lanes: the interval of the CDF of `n` intervals at word `base` of `cdf`
/// that u falls in, and u's place in it, searched between the bounds its bucket of the guide
/// table at word `gbase` of `guide` (`buckets` buckets) gives: bisection with gathers until
/// every lane's bounds meet.
#[inline(always)]
fn invert<S: Isa>(
    s: S,
    (cdf, base, n): (&[u32], I<S>, i32),
    (guide, gbase, buckets): (&[u32], I<S>, i32),
    u: F<S>,
) -> (I<S>, F<S>) {
    let one = s.int(1);
    let k = (u * s.splat(buckets as f32)).truncate();
    let k = k.blend(s.int(buckets - 1), k.gt(s.int(buckets - 1)));
    let mut lo = I::gather(guide, gbase + k);
    let hi = I::gather(guide, gbase + k + one) + one;
    let mut hi = hi.blend(s.int(n), hi.gt(s.int(n)));
    loop {
        let open = (hi - lo).gt(one);
        if !open.any() {
            break;
        }
        let mid = (lo + hi).shr(1);
        let below = word(cdf, base + mid).le(u);
        lo = lo.blend(mid, open & below);
        hi = hi.blend(mid, open.without(below));
    }
    let c0 = word(cdf, base + lo);
    let width = word(cdf, base + lo + one) - c0;
    let t = ((u - c0) / width).max(s.zero()).min(s.splat(1.0));
    (lo, t.blend(s.splat(0.5), !width.gt(s.zero())))
}
/// `EnvMap::radiance_at` at map coordinates (u, v) in the lanes of `lanes`, times the map's
/// intensity (0 in the other lanes): the four texels gathered in lanes and decoded and
/// blended in `envmap_sampling::bilinear`'s and `rgbe_unpack`'s order, so that each lane's
/// radiance is the scalar lookup's bit for bit. A lane whose coordinates fall outside the
/// map (NaN: `bilinear` wraps them by `rem_euclid`) or whose texels hold an exponent below 10
/// (none does: `rgbe_pack` writes 29 or more) is looked up by the scalar code.
#[inline(always)]
pub(super) fn map_radiance<S: Isa>(
    s: S,
    (map, intensity): (&EnvMap, f32),
    (u, v): (F<S>, F<S>),
    lanes: M<S>,
) -> V3<S> {
    let (zero, one) = (s.zero(), s.splat(1.0));
    let (w, h) = (map.width as f32, map.height as f32);
    let fx = u.keep(lanes) * s.splat(w) - s.splat(0.5);
    let fy = (v.keep(lanes) * s.splat(h) - s.splat(0.5)).max(zero);
    let (x0f, y0f) = (floor(s, fx), floor(s, fy));
    let (tx, ty) = (fx - x0f, fy - y0f);
    // Wrapped in u (x0 = −1 is the last column); clamped at the poles in v.
    let inside = x0f.ge(s.splat(-1.0)) & x0f.le(s.splat(w - 1.0));
    let x0f = x0f.blend(s.splat(w - 1.0), x0f.lt(zero));
    let x1f = (x0f + one).blend(zero, (x0f + one).cmp::<_CMP_EQ_OQ>(s.splat(w)));
    let y0f = y0f.min(s.splat(h - 1.0));
    let y1f = (y0f + one).min(s.splat(h - 1.0));
    let (x0, x1) = (x0f.truncate(), x1f.truncate());
    let width = s.int(map.width as i32);
    let (row0, row1) = (y0f.truncate() * width, y1f.truncate() * width);
    let (t00, odd00) = rgbe_unpack(s, I::gather(&map.rgbe, row0 + x0));
    let (t10, odd10) = rgbe_unpack(s, I::gather(&map.rgbe, row0 + x1));
    let (t01, odd01) = rgbe_unpack(s, I::gather(&map.rgbe, row1 + x0));
    let (t11, odd11) = rgbe_unpack(s, I::gather(&map.rgbe, row1 + x1));
    let odd = lanes & (!inside | ((odd00 | odd10) | (odd01 | odd11)));
    let mut out: V3<S> = each!(|c| {
        let top = lerp(t00[c], t10[c], tx);
        let bottom = lerp(t01[c], t11[c], tx);
        (lerp(top, bottom, ty) * s.splat(intensity)).keep(lanes)
    });
    if odd.any() {
        let mut rows = rows(out);
        let (mut us, mut vs) = ([0.0; MAX_LANES], [0.0; MAX_LANES]);
        u.store(&mut us);
        v.store(&mut vs);
        for k in lanes_of(odd.bits()) {
            let l = Vec3A::from_array(map.radiance_at(us[k], vs[k])) * intensity;
            for (c, row) in rows.iter_mut().enumerate() {
                row[k] = l[c];
            }
        }
        out = each!(|c| s.load(&rows[c]));
    }
    out
}

/// Asks the cache for the texels `map_radiance` reads at (u, v) in the lanes of `lanes`
/// (rows y and y + 1 of column x; a hint, which changes no value) before any is looked up, so
/// that the lanes' misses overlap: a lookup was 30 % of `outdoor`'s time in lanes, most of it
/// waiting on them. The texels' indices are made in lanes, then asked for one by one.
#[inline(always)]
pub(super) fn prefetch<S: Isa>(s: S, map: &EnvMap, (u, v): (F<S>, F<S>), lanes: M<S>) {
    let (w, h) = (map.width as i32, map.height as i32);
    let half = s.splat(0.5);
    // (max first: a NaN coordinate becomes 0.)
    let x = (u * s.splat(w as f32) - half).max(s.zero()).truncate();
    let y = (v * s.splat(h as f32) - half).max(s.zero()).truncate();
    let (x, y) = (
        x.blend(s.int(w - 1), x.gt(s.int(w - 1))),
        y.blend(s.int(h - 1), y.gt(s.int(h - 1))),
    );
    let below = (y + s.int(1)).blend(s.int(h - 1), y.gt(s.int(h - 2)));
    let (mut top, mut bottom) = ([0; MAX_LANES], [0; MAX_LANES]);
    (y * s.int(w) + x).store(&mut top);
    (below * s.int(w) + x).store(&mut bottom);
    // (A huge coordinate truncates to a negative index: clamped into the map.)
    let last = map.rgbe.len() - 1;
    for k in lanes_of(lanes.bits()) {
        let (a, b) = (top[k].max(0) as usize, bottom[k].max(0) as usize);
        crate::scene::envmap_sampling::prefetch(&map.rgbe[a.min(last)]);
        crate::scene::envmap_sampling::prefetch(&map.rgbe[b.min(last)]);
    }
}

/// `envmap_sampling::floor` in lanes: the truncation, one less where it rounded up.
#[inline(always)]
pub(super) fn floor<S: Isa>(s: S, x: F<S>) -> F<S> {
    let t = x.trunc();
    t.blend(t - s.splat(1.0), t.gt(x))
}

/// a + t (b − a), `bilinear`'s step.
#[inline(always)]
fn lerp<S: Isa>(a: F<S>, b: F<S>, t: F<S>) -> F<S> {
    a + t * (b - a)
}

/// `envmap_sampling::rgbe_unpack` of texels `w` in lanes: m × 2^(e − 136), the power built
/// from its bits, black at e = 0; and the lanes of an exponent from 1 to 9, which this does
/// not decode (a subnormal power).
#[inline(always)]
fn rgbe_unpack<S: Isa>(s: S, w: I<S>) -> (V3<S>, M<S>) {
    let e = w.shr(24);
    let black = e.eq(s.int(0));
    let f = ((e - s.int(9)) * s.int(1 << 23)).float_of_bits();
    let c: V3<S> = each!(|c| {
        let m = w.shr(8 * c as i32).and(s.int(0xff)).to_float();
        (m * f).blend(s.zero(), black)
    });
    (c, s.int(10).gt(e).without(black))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::simd::{Avx2, Avx512, Row};
    use crate::scene::envmap_sampling as scalar;

    fn row<S: Isa>(f: F<S>) -> Row {
        let mut r = [0.0; MAX_LANES];
        f.store(&mut r);
        r
    }

    /// Draws and directions in lanes against the scalar functions, bit for bit.
    fn agree<S: Isa>(s: S, d: &Distribution, rotation: f32) {
        let t = Tables::of(d);
        let n = S::N;
        let mut rng = crate::cpu::rng::Rng::new(7, 11, 3);
        for _ in 0..20_000 / n {
            let (mut a, mut b) = ([0.0; MAX_LANES], [0.0; MAX_LANES]);
            for k in 0..n {
                (a[k], b[k]) = rng.rand2();
            }
            // The draws' edges: 0 and the largest below 1.
            (a[0], b[1]) = (0.0, 1.0 - f32::EPSILON / 2.0);
            let Drawn {
                dir,
                pdf,
                uv: (u, v),
            } = sample(s, d, &t, (s.load(&a), s.load(&b)), rotation);
            let (dir, pdf, us, vs) = (dir.map(row), row(pdf), row(u), row(v));
            let density = row(pdf_at(s, d, &t, u, v));
            let ((cu, cv), nan) = coordinates(s, dir.map(|c| s.load(&c)), rotation);
            assert_eq!(nan.bits(), 0);
            let (cu, cv) = (row(cu), row(cv));
            for k in 0..n {
                let want = d.sample(a[k], b[k], rotation);
                let got = (
                    Vec3A::new(dir[0][k], dir[1][k], dir[2][k]),
                    pdf[k],
                    (us[k], vs[k]),
                );
                let bits = |(dir, pdf, (u, v)): (Vec3A, f32, (f32, f32))| {
                    (
                        dir.to_array().map(f32::to_bits),
                        pdf.to_bits(),
                        u.to_bits(),
                        v.to_bits(),
                    )
                };
                let wanted = (Vec3A::from(want.dir), want.pdf, want.uv);
                assert_eq!(
                    bits(got),
                    bits(wanted),
                    "draws ({}, {}) in {n} lanes",
                    a[k],
                    b[k]
                );
                let (u, v) = want.uv;
                assert_eq!(density[k].to_bits(), d.pdf_at(u, v).to_bits(), "({u}, {v})");
                let back = scalar::coordinates(want.dir, rotation);
                assert_eq!(
                    (cu[k].to_bits(), cv[k].to_bits()),
                    (back.0.to_bits(), back.1.to_bits())
                );
            }
        }
    }

    #[test]
    fn lanes_sample_and_look_up_the_map_as_the_scalar_code() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/maps/quarry_01_1k.hdr");
        let map = EnvMap::load(std::path::Path::new(path)).expect("the shipped map");
        // Rotations either side of zero and past a turn: φ's reduction.
        for rotation in [0.0, 3.49, -1.0, 7.5] {
            if let Some(s) = Avx2::new() {
                agree(s, &map.distribution, rotation);
            }
            if let Some(s) = Avx512::new() {
                agree(s, &map.distribution, rotation);
            }
        }
    }
}
