//! The path loop in eight AVX lanes, one path a lane, for scenes of a few primitives
//! (spheres, quads, boxes: at most eight) of the lecture's certain lobes under the sky, lit
//! by the sky and at most one light, with or without light sampling: `Tracer::trace_path`'s
//! arithmetic for those scenes, operation for operation in the same order (glam's dot is
//! (x·x′ + y·y′) + z·z′, its cross the textbook one, its normalize a division by the square
//! root, nothing fused), so that each lane's path is the scalar one bit for bit; tested
//! against it on every lane. The scalar loop runs one path's dependent chain of divisions
//! and square roots at a time; here eight run side by side, every primitive tested against
//! eight rays at once (the wavefront of Laine, Karras and Aila, "Megakernels Considered
//! Harmful", HPG 2013, kept in one kernel as Mitsuba 3's LLVM backend keeps it, sixteen lanes
//! wide there). A lane whose path has ended starts its pixel's next sample (`Lanes::trace`).
//! The draws stay each lane's own sampler's, taken in the order the scalar path takes them.
//!
//! The one difference a path can show: where two primitives are hit at the same distance (a
//! ray through the edge two quads share), the scalar walk keeps the one its BVH order tests
//! first, and this the first in the scene's order (spheres, quads, boxes).

use super::intersect::{LANES, NO_HIT};
use super::rng::Rng;
use super::scene::CpuScene;
use super::trace::T_FAR;
use super::trace::Tracer;
use crate::common::Features;
use crate::common::arrays::REF_INDEX;
use glam::Vec3A;
use std::arch::x86_64::*;
use std::f32::consts::PI;

/// The most primitives a scene may have here: their parameters are permuted into the lanes
/// from one register of eight.
pub const MAX_PRIMITIVES: usize = 8;

/// Russian roulette as `trace_path` plays it (with light sampling only).
const RR_START: u32 = 3;
const RR_MAX_SURVIVAL: f32 = 0.95;

/// No primitive (a lane's index where it hit none, or leaves none behind).
const NONE: i32 = -1;

/// A primitive's kind, as its reference's top bits say.
#[derive(Clone, Copy, PartialEq)]
enum Kind {
    Sphere = 0,
    Quad = 1,
    Box = 2,
}

type Table = [f32; 8];
type Tables3 = [Table; 3];

/// The scene as the lanes read it: per primitive (in the scene's order, spheres, quads,
/// boxes), its shape's parameters and its material's, as tables of eight that a lane's
/// primitive index permutes. Built per row from the scene (a few primitives: nothing to keep
/// in step with edits).
pub struct Lanes {
    kinds: Vec<Kind>,
    /// Per kind (sphere, quad, box), whether each primitive is of it (1.0 or 0.0).
    of_kind: [Table; 3],
    /// Spheres: the anchor, the anchor normal, |radius| times it (`hit_sphere`'s r·n, the
    /// product of the same two floats), |radius|, 2·|radius|, and whether the radius is
    /// positive (the outside is where the normal points) or negative (the normal turned
    /// inward), as 1.0 or 0.0.
    anchor: Tables3,
    normal: Tables3,
    r_normal: Tables3,
    r: Table,
    two_r: Table,
    outward: Table,
    inward: Table,
    /// Quads: the corner, the edges, the normal and w (`Quad`).
    quad: [Tables3; 5],
    /// Boxes: the centre, the half extents and the three axes.
    center: Tables3,
    half: Tables3,
    axes: [Tables3; 3],
    /// The material: whether it emits (1.0 or 0.0), its colour and light, whether its lobe
    /// is the specular one, its smoothness s and 1 − s, the specular lobe's fuzz (its
    /// `absorption`; 0 for the diffuse lobe), the lobe's tint, and whether light sampling
    /// weighs the lobe (the cosine lobe: `trace_path`'s `light_lobe`).
    emits: Table,
    color: Tables3,
    light: Table,
    spec: Table,
    smooth: Table,
    rough: Table,
    fuzz: Table,
    tint: Tables3,
    sampled: Table,
    /// The one light (`GpuLight`), where the scene has one and light sampling runs.
    lamp: Option<Lamp>,
    sky_uniform: bool,
    sky_bottom: [f32; 3],
    sky_top: [f32; 3],
    max_bounces: u32,
}

/// The light that light sampling draws from: its primitive, its shape, and its material's
/// colour times its light.
struct Lamp {
    index: usize,
    shape: LampShape,
    radiance: [f32; 3],
}

/// What sampling a light needs of its shape.
enum LampShape {
    /// The centre (`sphere_center`) and radius².
    Sphere { center: [f32; 3], r2: f32 },
    /// The corner, the edges and the normal, and the area (`GpuLight::area`).
    Quad { q: [[f32; 3]; 4], area: f32 },
}

/// One lane's path: its radiance and its segments.
pub type Traced = (Vec3A, u32);

impl Lanes {
    /// The lanes for `s` traced with features `f`, where they apply: a CPU with AVX2, one to
    /// `MAX_PRIMITIVES` spheres, quads and boxes (no triangles), every material an emitter
    /// or the lecture's surface with a certain lobe (no draw picks it; the specular one may
    /// be fuzzed), at most one light and no map, no glossy lobe that light sampling weighs,
    /// and the sky without its sun. The camera rays, a lens's included, are the caller's.
    pub fn of(s: &CpuScene, f: Features) -> Option<Lanes> {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return None;
        }
        let plain = !(f.triangles
            || f.instances
            || f.dielectrics
            || f.sun
            || f.textures
            || f.env_map
            || f.pbr
            || f.mirror_nee
            || f.lens_nee
            || f.gloss_nee);
        let count = s.spheres.len() + s.quads.len() + s.boxes.len();
        if !plain
            || !s.triangles.is_empty()
            || !s.instances.is_empty()
            || count == 0
            || count > MAX_PRIMITIVES
            || s.u.n_lights > 1
            || s.env.is_some()
            || s.shading_normals()
        {
            return None;
        }
        let mut l = Lanes {
            kinds: Vec::with_capacity(count),
            of_kind: [[0.0; 8]; 3],
            anchor: [[0.0; 8]; 3],
            normal: [[0.0; 8]; 3],
            r_normal: [[0.0; 8]; 3],
            r: [0.0; 8],
            two_r: [0.0; 8],
            outward: [0.0; 8],
            inward: [0.0; 8],
            quad: [[[0.0; 8]; 3]; 5],
            center: [[0.0; 8]; 3],
            half: [[0.0; 8]; 3],
            axes: [[[0.0; 8]; 3]; 3],
            emits: [0.0; 8],
            color: [[0.0; 8]; 3],
            light: [0.0; 8],
            spec: [0.0; 8],
            smooth: [0.0; 8],
            rough: [0.0; 8],
            fuzz: [0.0; 8],
            tint: [[0.0; 8]; 3],
            sampled: [0.0; 8],
            lamp: None,
            sky_uniform: s.u.sky_uniform,
            sky_bottom: s.u.sky_bottom.to_array(),
            sky_top: s.u.sky_top.to_array(),
            max_bounces: s.u.max_bounces,
        };
        let flag = |b: bool| if b { 1.0 } else { 0.0 };
        let mut materials = Vec::with_capacity(count);
        for (k, sp) in s.spheres.iter().enumerate() {
            let r = sp.radius.abs();
            for c in 0..3 {
                l.anchor[c][k] = sp.anchor[c];
                l.normal[c][k] = sp.anchor_normal[c];
                l.r_normal[c][k] = (r * sp.anchor_normal)[c];
            }
            l.r[k] = r;
            l.two_r[k] = 2.0 * r;
            l.outward[k] = flag(sp.radius > 0.0);
            l.inward[k] = flag(sp.radius < 0.0);
            l.kinds.push(Kind::Sphere);
            materials.push(sp.material);
        }
        for q in &s.quads {
            let k = l.kinds.len();
            for (t, v) in l.quad.iter_mut().zip([q.q, q.u, q.v, q.normal, q.w]) {
                for c in 0..3 {
                    t[c][k] = v[c];
                }
            }
            l.kinds.push(Kind::Quad);
            materials.push(q.material);
        }
        for b in &s.boxes {
            let k = l.kinds.len();
            for c in 0..3 {
                l.center[c][k] = b.center[c];
                l.half[c][k] = b.half_extents[c];
                for a in 0..3 {
                    l.axes[a][c][k] = b.axes[a][c];
                }
            }
            l.kinds.push(Kind::Box);
            materials.push(b.material);
        }
        for (k, &kind) in l.kinds.iter().enumerate() {
            l.of_kind[kind as usize][k] = 1.0;
        }
        for (k, &mat) in materials.iter().enumerate() {
            let m = s.materials.get(mat as usize)?;
            if m.pbr {
                return None;
            }
            for c in 0..3 {
                l.color[c][k] = m.color[c];
            }
            l.light[k] = m.light;
            if f.emitters && m.light > 0.0 {
                // An emitter ends the path where it is met, whatever its other keys.
                l.emits[k] = 1.0;
                continue;
            }
            // The lobe is certain (no draw picks it).
            let spec = m.specular >= 1.0;
            if m.smoothness < 0.0 || !(spec || m.specular == 0.0) {
                return None;
            }
            for c in 0..3 {
                l.tint[c][k] = if spec {
                    m.specular_color[c]
                } else {
                    m.color[c]
                };
            }
            l.spec[k] = flag(spec);
            l.smooth[k] = m.smoothness;
            l.rough[k] = 1.0 - m.smoothness;
            l.fuzz[k] = if spec { m.absorption } else { 0.0 };
            l.sampled[k] = flag(!spec || m.smoothness == 0.0);
        }
        // Light sampling runs where the scene has a light and the settings ask for it
        // (`trace_path`'s `nee`).
        if f.nee && s.u.n_lights == 1 {
            let light = s.lights[0];
            let i = (light.prim & REF_INDEX) as usize;
            let (index, shape, material) = match light.prim >> 30 {
                0 => {
                    let sp = &s.spheres[i];
                    let center = super::trace::sphere_center(sp).to_array();
                    let r2 = sp.radius * sp.radius;
                    (i, LampShape::Sphere { center, r2 }, sp.material)
                }
                1 => {
                    let q = &s.quads[i];
                    let corners = [q.q, q.u, q.v, q.normal].map(|v| v.to_array());
                    let shape = LampShape::Quad {
                        q: corners,
                        area: light.area,
                    };
                    (s.spheres.len() + i, shape, q.material)
                }
                _ => return None,
            };
            let m = &s.materials[material as usize];
            l.lamp = Some(Lamp {
                index,
                shape,
                radiance: (m.color * m.light).to_array(),
            });
        }
        Some(l)
    }
}

/// Eight lanes of a 3-vector, by component.
type V3 = [__m256; 3];

/// The paths in flight, one a lane: what `Tracer::trace_path` keeps between bounces.
struct Paths {
    o: V3,
    d: V3,
    throughput: V3,
    radiance: V3,
    segments: __m256i,
    bounce: __m256i,
    /// The primitive the ray leaves, where it cannot meet it again.
    skip: __m256i,
    /// The last bounce's lobe density where light sampling weighs it (else 0), and where it
    /// was drawn: what an emitter met next is weighed against.
    prev_pdf: __m256,
    prev_point: V3,
    prev_normal: V3,
}

impl Paths {
    /// New paths in lanes `m` along camera rays (o, d).
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    fn start(&mut self, m: __m256, o: V3, d: V3) {
        let mi = _mm256_castps_si256(m);
        let blend_i = |a: __m256i, b: __m256i| {
            _mm256_castps_si256(_mm256_blendv_ps(
                _mm256_castsi256_ps(a),
                _mm256_castsi256_ps(b),
                _mm256_castsi256_ps(mi),
            ))
        };
        let (zero, one) = (_mm256_setzero_ps(), set(1.0));
        let up = [zero, one, zero];
        for c in 0..3 {
            self.o[c] = _mm256_blendv_ps(self.o[c], o[c], m);
            self.d[c] = _mm256_blendv_ps(self.d[c], d[c], m);
            self.throughput[c] = _mm256_blendv_ps(self.throughput[c], one, m);
            self.radiance[c] = _mm256_blendv_ps(self.radiance[c], zero, m);
            self.prev_point[c] = _mm256_blendv_ps(self.prev_point[c], o[c], m);
            self.prev_normal[c] = _mm256_blendv_ps(self.prev_normal[c], up[c], m);
        }
        self.segments = blend_i(self.segments, _mm256_setzero_si256());
        self.bounce = blend_i(self.bounce, _mm256_setzero_si256());
        self.skip = blend_i(self.skip, _mm256_set1_epi32(NONE));
        self.prev_pdf = _mm256_blendv_ps(self.prev_pdf, zero, m);
    }
}

/// Samples a lane's pixel takes in turn before the next pixel group's samplers are made: the
/// lanes' samplers are made eight pixels at once (`Rng::group`) for this many samples ahead.
const CHUNK: u32 = 16;

impl Lanes {
    /// Traces samples `samples` of the `n` (up to eight) pixels of row `y` (of `width`) from
    /// column `x0`, one pixel a lane, as `Tracer::trace_path` traces each path, and hands
    /// each path to `done` when it ends: its lane (the pixel x0 + lane), its sample, its radiance and segments,
    /// and its sampler (`Rng::taken`). A lane whose path ends starts its pixel's next sample
    /// at once (path regeneration: Novák, Havran and Dachsbacher, "Path Regeneration for
    /// Interactive Path Tracing", Eurographics 2010), so the lanes stay busy while the
    /// paths' lengths differ. Returns the primitive tests made.
    ///
    /// # Safety
    /// The CPU must have AVX2 (`of` checks it).
    #[allow(clippy::too_many_arguments)]
    #[target_feature(enable = "avx,avx2")]
    pub unsafe fn trace(
        &self,
        tracer: &Tracer,
        (x0, y, width): (u32, u32, u32),
        n: usize,
        samples: std::ops::Range<u32>,
        (seed, ahead): (u32, usize),
        mut done: impl FnMut(usize, u32, Traced, &Rng),
    ) -> u64 {
        let zero = _mm256_setzero_ps();
        let one = set(1.0);
        let pixels: [u32; LANES] = std::array::from_fn(|k| y * width + x0 + k as u32);
        let mut tests = 0u64;
        let mut p = Paths {
            o: [zero; 3],
            d: [zero, zero, one],
            throughput: [one; 3],
            radiance: [zero; 3],
            segments: _mm256_setzero_si256(),
            bounce: _mm256_setzero_si256(),
            skip: _mm256_set1_epi32(NONE),
            prev_pdf: zero,
            prev_point: [zero; 3],
            prev_normal: [zero, one, zero],
        };
        let mut start = samples.start;
        while start < samples.end {
            let end = (start + CHUNK).min(samples.end);
            let groups: Vec<[Rng; LANES]> = (start..end)
                .map(|s| Rng::group(&pixels, s, seed, ahead))
                .collect();
            let mut rngs = groups[0];
            let mut next = [start; LANES];
            let mut sample_of = [start; LANES];
            let mut active = 0u32;
            loop {
                // Each idle lane starts its pixel's next sample: its camera ray.
                let mut starts = 0u32;
                let (mut o, mut d) = ([[0.0f32; 8]; 3], [[0.0f32; 8]; 3]);
                for k in 0..n {
                    if active >> k & 1 != 0 || next[k] >= end {
                        continue;
                    }
                    rngs[k] = groups[(next[k] - start) as usize][k];
                    sample_of[k] = next[k];
                    next[k] += 1;
                    let ray = tracer.camera_ray(x0 + k as u32, y, &mut rngs[k]);
                    for c in 0..3 {
                        o[c][k] = ray.origin[c];
                        d[c][k] = ray.dir[c];
                    }
                    starts |= 1 << k;
                }
                if starts != 0 {
                    p.start(lane_mask(starts), o.map(|a| load(&a)), d.map(|a| load(&a)));
                    active |= starts;
                }
                if active == 0 {
                    break;
                }
                let before = active;
                active = self.step(&mut p, active, &mut rngs, &mut tests);
                let ended = before & !active;
                if ended != 0 {
                    let mut out = [[0.0f32; 8]; 3];
                    let mut segs = [0u32; 8];
                    // SAFETY: unaligned stores of eight lanes into arrays of eight.
                    unsafe {
                        for (o, r) in out.iter_mut().zip(p.radiance) {
                            _mm256_storeu_ps(o.as_mut_ptr(), r);
                        }
                        _mm256_storeu_si256(segs.as_mut_ptr() as *mut __m256i, p.segments);
                    }
                    for k in (0..n).filter(|k| ended >> k & 1 != 0) {
                        let radiance = Vec3A::new(out[0][k], out[1][k], out[2][k]);
                        done(k, sample_of[k], (radiance, segs[k]), &rngs[k]);
                    }
                }
            }
            start = end;
        }
        tests
    }

    /// One bounce of the paths in lanes `active` (`trace_path`'s loop body); returns the
    /// lanes whose paths go on.
    #[target_feature(enable = "avx,avx2")]
    fn step(&self, p: &mut Paths, active: u32, rngs: &mut [Rng; LANES], tests: &mut u64) -> u32 {
        let zero = _mm256_setzero_ps();
        let one = set(1.0);
        let nee = self.lamp.is_some();
        let Paths {
            o,
            d,
            throughput,
            radiance,
            ..
        } = p;
        let live = lane_mask(active);
        p.segments = _mm256_sub_epi32(p.segments, _mm256_castps_si256(live));
        *tests += (active.count_ones() as u64) * self.kinds.len() as u64;
        let (best, index) = self.closest(*o, *d, p.skip);
        let found = _mm256_castsi256_ps(_mm256_cmpgt_epi32(index, _mm256_set1_epi32(NONE)));
        let missed = _mm256_andnot_ps(found, live);
        if _mm256_movemask_ps(missed) != 0 {
            let sky = self.sky(d[1]);
            for c in 0..3 {
                let add = _mm256_add_ps(radiance[c], _mm256_mul_ps(throughput[c], sky[c]));
                radiance[c] = _mm256_blendv_ps(radiance[c], add, missed);
            }
        }
        let mut hit = _mm256_and_ps(found, live);
        if _mm256_movemask_ps(hit) == 0 {
            return 0;
        }
        let idx = _mm256_max_epi32(index, _mm256_setzero_si256());
        let pick = |t: &Table| pick(t, idx);
        let pick3 = |t: &Tables3| pick3(t, idx);
        let (position, n_out) = self.surface(*o, *d, best, idx);
        // An emitter: its light, weighed against light sampling where the last lobe's
        // density is known, and the path ends.
        let emits = _mm256_and_ps(flagged(&self.emits, idx), hit);
        if _mm256_movemask_ps(emits) != 0 {
            let mut w = one;
            if nee {
                let pl = self.light_pdf(idx, p.prev_point, position);
                let weigh = _mm256_cmp_ps::<_CMP_GT_OQ>(p.prev_pdf, zero);
                w = _mm256_blendv_ps(one, power_heuristic(p.prev_pdf, pl), weigh);
            }
            let (color, light) = (pick3(&self.color), pick(&self.light));
            for c in 0..3 {
                let e = _mm256_mul_ps(
                    _mm256_mul_ps(_mm256_mul_ps(throughput[c], color[c]), light),
                    w,
                );
                radiance[c] = _mm256_blendv_ps(radiance[c], _mm256_add_ps(radiance[c], e), emits);
            }
            hit = _mm256_andnot_ps(emits, hit);
        }
        // The paths at the bounce limit end here.
        let last = _mm256_castsi256_ps(_mm256_cmpeq_epi32(
            p.bounce,
            _mm256_set1_epi32(self.max_bounces as i32),
        ));
        hit = _mm256_andnot_ps(last, hit);
        let on = _mm256_movemask_ps(hit) as u32;
        if on == 0 {
            return 0;
        }
        // The facing normal.
        let front = _mm256_cmp_ps::<_CMP_LT_OQ>(dot(*d, n_out), zero);
        let nf = n_out.map(|x| _mm256_blendv_ps(neg(x), x, front));
        let tint = pick3(&self.tint);
        let sampled = _mm256_and_ps(flagged(&self.sampled, idx), hit);
        // Light sampling at the lobes it weighs: the shadow ray leaves on the facing side, and
        // cannot meet the primitive it leaves (`leaving(hit, front)`).
        if let Some(lamp) = self
            .lamp
            .as_ref()
            .filter(|_| _mm256_movemask_ps(sampled) != 0)
        {
            let from = self.leaving(idx, front);
            let (l, t) = self.sample_light(lamp, position, nf, from, sampled, rngs);
            *tests += t;
            for c in 0..3 {
                let add = _mm256_mul_ps(_mm256_mul_ps(throughput[c], tint[c]), l[c]);
                radiance[c] =
                    _mm256_blendv_ps(radiance[c], _mm256_add_ps(radiance[c], add), sampled);
            }
        }
        // The lobe's direction (`scatter_surface`): the diffuse one, or blended toward the
        // mirror direction (fuzzed by a second draw where the lobe has fuzz) by the
        // smoothness (`Vec3A::lerp`) and normalized again.
        let (u, v) = draw2(rngs, on);
        let unit = random_unit_vector(u, v);
        let diffuse = normalize_or(std::array::from_fn(|c| _mm256_add_ps(nf[c], unit[c])), nf);
        let spec = _mm256_and_ps(flagged(&self.spec, idx), hit);
        let dir = if _mm256_movemask_ps(spec) != 0 {
            let dn = _mm256_mul_ps(set(2.0), dot(*d, nf));
            let (s, rough) = (pick(&self.smooth), pick(&self.rough));
            let mut mirror: V3 =
                std::array::from_fn(|c| _mm256_sub_ps(d[c], _mm256_mul_ps(dn, nf[c])));
            let fuzz = pick(&self.fuzz);
            let fuzzed = _mm256_and_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(fuzz, zero), spec);
            let fuzzy = _mm256_movemask_ps(fuzzed) as u32;
            if fuzzy != 0 {
                let (u, v) = draw2(rngs, fuzzy);
                let unit = random_unit_vector(u, v);
                let moved =
                    std::array::from_fn(|c| _mm256_add_ps(mirror[c], _mm256_mul_ps(fuzz, unit[c])));
                let moved = normalize_or(moved, nf);
                for c in 0..3 {
                    mirror[c] = _mm256_blendv_ps(mirror[c], moved[c], fuzzed);
                }
            }
            let blend: V3 = std::array::from_fn(|c| {
                _mm256_add_ps(
                    _mm256_mul_ps(diffuse[c], rough),
                    _mm256_mul_ps(mirror[c], s),
                )
            });
            let specular = normalize_or(blend, nf);
            std::array::from_fn(|c| _mm256_blendv_ps(diffuse[c], specular[c], spec))
        } else {
            diffuse
        };
        // Absorbed where dir·n <= 0 (a NaN goes on, as in `scatter_surface`).
        let mut kept = _mm256_and_ps(_mm256_cmp_ps::<_CMP_NLE_UQ>(dot(dir, nf), zero), hit);
        if nee {
            let cosine = _mm256_div_ps(_mm256_max_ps(dot(dir, nf), zero), set(PI));
            p.prev_pdf = _mm256_blendv_ps(p.prev_pdf, _mm256_and_ps(cosine, sampled), hit);
            for (prev, n) in p.prev_normal.iter_mut().zip(nf) {
                *prev = _mm256_blendv_ps(*prev, n, sampled);
            }
        }
        for c in 0..3 {
            throughput[c] =
                _mm256_blendv_ps(throughput[c], _mm256_mul_ps(throughput[c], tint[c]), kept);
            p.prev_point[c] = _mm256_blendv_ps(p.prev_point[c], position[c], kept);
        }
        // Russian roulette, with light sampling only, from bounce RR_START.
        if nee {
            let late = _mm256_castsi256_ps(_mm256_cmpgt_epi32(
                p.bounce,
                _mm256_set1_epi32(RR_START as i32 - 1),
            ));
            let plays = _mm256_and_ps(kept, late);
            let playing = _mm256_movemask_ps(plays) as u32;
            if playing != 0 {
                let (x, y, z) = (throughput[0], throughput[1], throughput[2]);
                let q = _mm256_min_ps(_mm256_max_ps(_mm256_max_ps(x, z), y), set(RR_MAX_SURVIVAL));
                let u = draw(rngs, playing);
                let lost = _mm256_andnot_ps(_mm256_cmp_ps::<_CMP_NGE_UQ>(u, q), plays);
                kept = _mm256_andnot_ps(lost, kept);
                let divided = _mm256_andnot_ps(lost, plays);
                for t in throughput.iter_mut() {
                    *t = _mm256_blendv_ps(*t, _mm256_div_ps(*t, q), divided);
                }
            }
        }
        // The side the ray leaves by, the primitive it cannot meet next (`leaving`), and its
        // origin moved off the surface (`offset_ray`).
        let out = _mm256_cmp_ps::<_CMP_GT_OQ>(dot(dir, n_out), zero);
        let side = n_out.map(|x| _mm256_blendv_ps(neg(x), x, out));
        let skip = self.leaving(idx, out);
        p.skip = _mm256_castps_si256(_mm256_blendv_ps(
            _mm256_castsi256_ps(p.skip),
            _mm256_castsi256_ps(skip),
            kept,
        ));
        let moved = offset_ray(position, side);
        for c in 0..3 {
            o[c] = _mm256_blendv_ps(o[c], moved[c], kept);
            d[c] = _mm256_blendv_ps(d[c], dir[c], kept);
        }
        p.bounce = _mm256_sub_epi32(p.bounce, _mm256_castps_si256(kept));
        _mm256_movemask_ps(kept) as u32
    }

    /// The nearest hit of eight rays and its primitive (`NONE` for none), primitive `skip`
    /// left out (`hit_except`); the first in the scene's order at equal distances.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    fn closest(&self, o: V3, d: V3, skip: __m256i) -> (__m256, __m256i) {
        let mut best = _mm256_set1_ps(T_FAR);
        let mut index = _mm256_set1_epi32(NONE);
        for k in 0..self.kinds.len() {
            let t = self.hit(k, o, d);
            let kk = _mm256_set1_epi32(k as i32);
            let skipped = _mm256_castsi256_ps(_mm256_cmpeq_epi32(skip, kk));
            let nearer = _mm256_andnot_ps(skipped, between(t, best));
            best = _mm256_blendv_ps(best, t, nearer);
            index = _mm256_castps_si256(_mm256_blendv_ps(
                _mm256_castsi256_ps(index),
                _mm256_castsi256_ps(kk),
                nearer,
            ));
        }
        (best, index)
    }

    /// Whether each ray meets any primitive but `skip` and `from` before `t_max`.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    fn occluded(&self, o: V3, d: V3, t_max: __m256, skip: usize, from: __m256i) -> __m256 {
        let zero = _mm256_setzero_ps();
        let mut blocked = zero;
        for k in (0..self.kinds.len()).filter(|&k| k != skip) {
            let t = self.hit(k, o, d);
            let left = _mm256_castsi256_ps(_mm256_cmpeq_epi32(from, _mm256_set1_epi32(k as i32)));
            blocked = _mm256_or_ps(blocked, _mm256_andnot_ps(left, between(t, t_max)));
        }
        blocked
    }

    /// Primitive k's distance along eight rays (t_max `T_FAR`), or NO_HIT.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    fn hit(&self, k: usize, o: V3, d: V3) -> __m256 {
        match self.kinds[k] {
            Kind::Sphere => self.hit_sphere(k, o, d),
            Kind::Quad => self.hit_quad(k, o, d),
            Kind::Box => self.hit_box(k, o, d),
        }
    }

    /// `hit_sphere` of sphere `k` for the eight rays.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    fn hit_sphere(&self, k: usize, o: V3, d: V3) -> __m256 {
        let zero = _mm256_setzero_ps();
        let r = _mm256_set1_ps(self.r[k]);
        let g: V3 = std::array::from_fn(|c| _mm256_sub_ps(o[c], set(self.anchor[c][k])));
        let f: V3 = std::array::from_fn(|c| _mm256_add_ps(g[c], set(self.r_normal[c][k])));
        let b = dot(f, d);
        let l: V3 = std::array::from_fn(|c| _mm256_sub_ps(f[c], _mm256_mul_ps(b, d[c])));
        let ll = _mm256_sqrt_ps(dot(l, l));
        let disc = _mm256_mul_ps(_mm256_sub_ps(r, ll), _mm256_add_ps(r, ll));
        let an = [0, 1, 2].map(|c| set(self.normal[c][k]));
        let c = _mm256_add_ps(dot(g, g), _mm256_mul_ps(set(self.two_r[k]), dot(g, an)));
        let sq = _mm256_sqrt_ps(disc);
        let below = _mm256_cmp_ps::<_CMP_LT_OQ>(b, zero);
        let q = _mm256_sub_ps(neg(b), _mm256_blendv_ps(sq, neg(sq), below));
        let t0 = _mm256_div_ps(c, q);
        // f32::min and max: where t0 is NaN, q.
        let near = _mm256_min_ps(t0, q);
        let far = _mm256_max_ps(t0, q);
        let no_hit = set(NO_HIT);
        let t = _mm256_blendv_ps(
            _mm256_blendv_ps(no_hit, far, within(far)),
            near,
            within(near),
        );
        // Neither a ray that passes the sphere (disc < 0) nor one with q = 0 hits it.
        let fails = _mm256_or_ps(
            _mm256_cmp_ps::<_CMP_LT_OQ>(disc, zero),
            _mm256_cmp_ps::<_CMP_EQ_OQ>(q, zero),
        );
        _mm256_blendv_ps(t, no_hit, fails)
    }

    /// `hit_quad` of quad `k` for the eight rays.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    fn hit_quad(&self, k: usize, o: V3, d: V3) -> __m256 {
        let zero = _mm256_setzero_ps();
        let one = set(1.0);
        let [q, u, v, n, w] = self.quad.map(|t| [0, 1, 2].map(|c| set(t[c][k])));
        let denom = dot(n, d);
        let flat = _mm256_cmp_ps::<_CMP_LT_OQ>(abs(denom), set(1e-20));
        let qo: V3 = std::array::from_fn(|c| _mm256_sub_ps(q[c], o[c]));
        let t = _mm256_div_ps(dot(n, qo), denom);
        let p: V3 = std::array::from_fn(|c| {
            _mm256_sub_ps(_mm256_add_ps(o[c], _mm256_mul_ps(t, d[c])), q[c])
        });
        let alpha = dot(w, cross(p, v));
        let beta = dot(w, cross(u, p));
        let inside = |x: __m256| {
            _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GE_OQ>(x, zero),
                _mm256_cmp_ps::<_CMP_LE_OQ>(x, one),
            )
        };
        let hits = _mm256_andnot_ps(
            flat,
            _mm256_and_ps(within(t), _mm256_and_ps(inside(alpha), inside(beta))),
        );
        _mm256_blendv_ps(set(NO_HIT), t, hits)
    }

    /// `hit_box` of box `k` for the eight rays: the slab test in the box's frame.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    fn hit_box(&self, k: usize, o: V3, d: V3) -> __m256 {
        let axes = self.axes.map(|a| [0, 1, 2].map(|c| set(a[c][k])));
        let oc: V3 = std::array::from_fn(|c| _mm256_sub_ps(o[c], set(self.center[c][k])));
        let tiny = set(1e-30);
        // Per axis, the slab's two planes' distances t1 and t2, nearer and farther.
        let slabs: [(__m256, __m256); 3] = std::array::from_fn(|a| {
            let lo = dot(oc, axes[a]);
            let ld = dot(d, axes[a]);
            let safe = _mm256_blendv_ps(ld, tiny, _mm256_cmp_ps::<_CMP_LT_OQ>(abs(ld), tiny));
            let inv = _mm256_div_ps(set(1.0), safe);
            let h = set(self.half[a][k]);
            let t1 = _mm256_mul_ps(_mm256_sub_ps(neg(h), lo), inv);
            let t2 = _mm256_mul_ps(_mm256_sub_ps(h, lo), inv);
            (_mm256_min_ps(t1, t2), _mm256_max_ps(t1, t2))
        });
        let lo: V3 = slabs.map(|s| s.0);
        let hi: V3 = slabs.map(|s| s.1);
        // glam's max_element and min_element: max(max(x, z), y).
        let enter = _mm256_max_ps(_mm256_max_ps(lo[0], lo[2]), lo[1]);
        let exit = _mm256_min_ps(_mm256_min_ps(hi[0], hi[2]), hi[1]);
        let ahead = _mm256_cmp_ps::<_CMP_GT_OQ>(enter, _mm256_setzero_ps());
        let t = _mm256_blendv_ps(exit, enter, ahead);
        let hits = _mm256_andnot_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(enter, exit), within(t));
        _mm256_blendv_ps(set(NO_HIT), t, hits)
    }

    /// Where the rays hit their primitives `idx` at `t`: the point moved onto the surface,
    /// and the geometric normal (`sphere_surface`, `quad_surface`, `box_surface`).
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    fn surface(&self, o: V3, d: V3, t: __m256, idx: __m256i) -> (V3, V3) {
        let pick = |x: &Table| pick(x, idx);
        let pick3 = |x: &Tables3| pick3(x, idx);
        let zero = _mm256_setzero_ps();
        let kind_of = |kind: Kind| self.is_kind(kind, idx);
        let has = |kind: Kind| self.kinds.contains(&kind);
        let (mut position, mut normal) = ([zero; 3], [zero; 3]);
        let mut put = |mask: __m256, p: V3, n: V3| {
            for c in 0..3 {
                position[c] = _mm256_blendv_ps(position[c], p[c], mask);
                normal[c] = _mm256_blendv_ps(normal[c], n[c], mask);
            }
        };
        if has(Kind::Sphere) {
            let r = pick(&self.r);
            let (an, anc) = (pick3(&self.normal), pick3(&self.anchor));
            let q: V3 = std::array::from_fn(|c| {
                _mm256_add_ps(_mm256_sub_ps(o[c], anc[c]), _mm256_mul_ps(t, d[c]))
            });
            let m: V3 = std::array::from_fn(|c| _mm256_add_ps(_mm256_div_ps(q[c], r), an[c]));
            let len = _mm256_sqrt_ps(dot(m, m));
            let n = m.map(|x| _mm256_div_ps(x, len));
            let h = _mm256_div_ps(
                _mm256_add_ps(dot(q, q), _mm256_mul_ps(pick(&self.two_r), dot(q, an))),
                _mm256_add_ps(_mm256_mul_ps(r, len), r),
            );
            let p = std::array::from_fn(|c| {
                _mm256_add_ps(anc[c], _mm256_sub_ps(q[c], _mm256_mul_ps(h, n[c])))
            });
            let inward = flagged(&self.inward, idx);
            put(
                kind_of(Kind::Sphere),
                p,
                n.map(|x| _mm256_blendv_ps(x, neg(x), inward)),
            );
        }
        if has(Kind::Quad) {
            let (q, n) = (pick3(&self.quad[0]), pick3(&self.quad[3]));
            let p: V3 = std::array::from_fn(|c| _mm256_add_ps(o[c], _mm256_mul_ps(t, d[c])));
            let pq = std::array::from_fn(|c| _mm256_sub_ps(p[c], q[c]));
            let h = dot(n, pq);
            let at = std::array::from_fn(|c| _mm256_sub_ps(p[c], _mm256_mul_ps(n[c], h)));
            put(kind_of(Kind::Quad), at, n);
        }
        if has(Kind::Box) {
            let (center, half) = (pick3(&self.center), pick3(&self.half));
            let axes = self.axes.map(|a| pick3(&a));
            let oc: V3 = std::array::from_fn(|c| {
                _mm256_sub_ps(_mm256_add_ps(o[c], _mm256_mul_ps(t, d[c])), center[c])
            });
            let mut lp: V3 = std::array::from_fn(|a| dot(oc, axes[a]));
            let a: V3 = std::array::from_fn(|c| abs(_mm256_div_ps(lp[c], half[c])));
            let ge = |x: __m256, y: __m256| _mm256_cmp_ps::<_CMP_GE_OQ>(x, y);
            let on_x = _mm256_and_ps(ge(a[0], a[1]), ge(a[0], a[2]));
            let on_y = _mm256_andnot_ps(on_x, ge(a[1], a[2]));
            let on_z = _mm256_andnot_ps(
                _mm256_or_ps(on_x, on_y),
                _mm256_castsi256_ps(_mm256_set1_epi32(-1)),
            );
            let face = [on_x, on_y, on_z];
            let local: V3 = std::array::from_fn(|c| _mm256_and_ps(sign(lp[c]), face[c]));
            for c in 0..3 {
                lp[c] = _mm256_blendv_ps(lp[c], _mm256_mul_ps(local[c], half[c]), face[c]);
            }
            let p = std::array::from_fn(|c| {
                let mut w = _mm256_add_ps(center[c], _mm256_mul_ps(lp[0], axes[0][c]));
                w = _mm256_add_ps(w, _mm256_mul_ps(lp[1], axes[1][c]));
                _mm256_add_ps(w, _mm256_mul_ps(lp[2], axes[2][c]))
            });
            let m: V3 = std::array::from_fn(|c| {
                let s = _mm256_add_ps(
                    _mm256_mul_ps(local[0], axes[0][c]),
                    _mm256_mul_ps(local[1], axes[1][c]),
                );
                _mm256_add_ps(s, _mm256_mul_ps(local[2], axes[2][c]))
            });
            let len = _mm256_sqrt_ps(dot(m, m));
            put(kind_of(Kind::Box), p, m.map(|x| _mm256_div_ps(x, len)));
        }
        (position, normal)
    }

    /// The primitive a ray leaving `idx` on its outer side (`out`) or inner side cannot meet
    /// next (`Tracer::leaving`): a sphere where it leaves the side its normal points to, a
    /// quad always, a box where it leaves outward.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    fn leaving(&self, idx: __m256i, out: __m256) -> __m256i {
        // (`outward` is 0 but for the spheres.)
        let outward = flagged(&self.outward, idx);
        let same = _mm256_xor_ps(
            _mm256_xor_ps(out, outward),
            _mm256_castsi256_ps(_mm256_set1_epi32(-1)),
        );
        let keeps = _mm256_or_ps(
            self.is_kind(Kind::Quad, idx),
            _mm256_blendv_ps(out, same, self.is_kind(Kind::Sphere, idx)),
        );
        _mm256_castps_si256(_mm256_blendv_ps(
            _mm256_castsi256_ps(_mm256_set1_epi32(NONE)),
            _mm256_castsi256_ps(idx),
            keeps,
        ))
    }

    /// The density with which light sampling draws the point `at` of primitive `idx` from
    /// `origin`, where it is the light (`Tracer::light_pdf`, the one light chosen for
    /// certain): a sphere's cone, a quad's area; 0 for a box.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    fn light_pdf(&self, idx: __m256i, origin: V3, at: V3) -> __m256 {
        let pick = |x: &Table| pick(x, idx);
        let pick3 = |x: &Tables3| pick3(x, idx);
        let zero = _mm256_setzero_ps();
        let mut pdf = zero;
        let mask = |kind: Kind| self.is_kind(kind, idx);
        if self.kinds.contains(&Kind::Sphere) {
            // sphere_center: anchor − |r|·normal.
            let (anc, an, r) = (pick3(&self.anchor), pick3(&self.normal), pick(&self.r));
            let center: V3 =
                std::array::from_fn(|c| _mm256_sub_ps(anc[c], _mm256_mul_ps(r, an[c])));
            let dd: V3 = std::array::from_fn(|c| _mm256_sub_ps(center[c], origin[c]));
            let dist2 = dot(dd, dd);
            let r2 = _mm256_mul_ps(r, r);
            let cone = _mm256_div_ps(
                set(1.0),
                _mm256_mul_ps(set(2.0 * PI), cone_one_minus_cos(r2, dist2)),
            );
            let inside = _mm256_cmp_ps::<_CMP_LE_OQ>(dist2, r2);
            let p = _mm256_blendv_ps(cone, zero, inside);
            pdf = _mm256_blendv_ps(pdf, p, mask(Kind::Sphere));
        }
        if self.kinds.contains(&Kind::Quad) {
            let (u, v, n) = (
                pick3(&self.quad[1]),
                pick3(&self.quad[2]),
                pick3(&self.quad[3]),
            );
            let to: V3 = std::array::from_fn(|c| _mm256_sub_ps(at[c], origin[c]));
            let dist2 = dot(to, to);
            let cos_l = _mm256_div_ps(abs(dot(n, to)), _mm256_sqrt_ps(dist2));
            let uv = cross(u, v);
            let area = _mm256_sqrt_ps(dot(uv, uv));
            let p = _mm256_div_ps(dist2, _mm256_max_ps(_mm256_mul_ps(area, cos_l), set(1e-30)));
            pdf = _mm256_blendv_ps(pdf, p, mask(Kind::Quad));
        }
        pdf
    }

    /// `Tracer::sample_light` for the one light and the cosine lobe, at points `p` (facing
    /// normal n, leaving primitive `from`) in the lanes of `lanes`: the MIS-weighted light
    /// (its f·cos included, its tint not), and the primitive tests made.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    fn sample_light(
        &self,
        lamp: &Lamp,
        p: V3,
        n: V3,
        from: __m256i,
        lanes: __m256,
        rngs: &mut [Rng; LANES],
    ) -> (V3, u64) {
        let zero = _mm256_setzero_ps();
        let one = set(1.0);
        let active = _mm256_movemask_ps(lanes) as u32;
        let (u1, u2) = draw2(rngs, active);
        let (dir, pdf, ok) = match &lamp.shape {
            LampShape::Sphere { center, r2 } => {
                let to: V3 = std::array::from_fn(|c| _mm256_sub_ps(set(center[c]), p[c]));
                let dist2 = dot(to, to);
                let r2 = set(*r2);
                let one_minus = cone_one_minus_cos(r2, dist2);
                let cos_t = _mm256_sub_ps(one, _mm256_mul_ps(u1, one_minus));
                let sin_t = _mm256_sqrt_ps(_mm256_max_ps(
                    _mm256_sub_ps(one, _mm256_mul_ps(cos_t, cos_t)),
                    zero,
                ));
                let (sp, cp) = sin_cos_turns(u2);
                let root = _mm256_sqrt_ps(dist2);
                let b = basis(to.map(|x| _mm256_div_ps(x, root)));
                let (k0, k1) = (_mm256_mul_ps(sin_t, cp), _mm256_mul_ps(sin_t, sp));
                let v: V3 = std::array::from_fn(|c| {
                    _mm256_add_ps(
                        _mm256_add_ps(_mm256_mul_ps(b[0][c], k0), _mm256_mul_ps(b[1][c], k1)),
                        _mm256_mul_ps(b[2][c], cos_t),
                    )
                });
                let len = _mm256_sqrt_ps(dot(v, v));
                let dir = v.map(|x| _mm256_div_ps(x, len));
                let pdf = _mm256_div_ps(one, _mm256_mul_ps(set(2.0 * PI), one_minus));
                (dir, pdf, _mm256_cmp_ps::<_CMP_NLE_UQ>(dist2, r2))
            }
            LampShape::Quad { q, area } => {
                let [q, u, v, nl] = q.map(|x| x.map(|c| set(c)));
                let x: V3 = std::array::from_fn(|c| {
                    _mm256_add_ps(
                        _mm256_add_ps(q[c], _mm256_mul_ps(u1, u[c])),
                        _mm256_mul_ps(u2, v[c]),
                    )
                });
                let to: V3 = std::array::from_fn(|c| _mm256_sub_ps(x[c], p[c]));
                let dist2 = dot(to, to);
                let root = _mm256_sqrt_ps(dist2);
                let dir = to.map(|x| _mm256_div_ps(x, root));
                let cos_l = abs(dot(nl, dir));
                let pdf = _mm256_div_ps(dist2, _mm256_mul_ps(set(*area), cos_l));
                (dir, pdf, _mm256_cmp_ps::<_CMP_NLT_UQ>(cos_l, set(1e-6)))
            }
        };
        let cos_s = dot(n, dir);
        let mut ok = _mm256_and_ps(
            _mm256_and_ps(ok, lanes),
            _mm256_cmp_ps::<_CMP_GT_OQ>(cos_s, zero),
        );
        let mut tests = 0;
        if _mm256_movemask_ps(ok) != 0 {
            let origin = offset_ray(p, n);
            let t_light = self.hit(lamp.index, origin, dir);
            ok = _mm256_and_ps(ok, _mm256_cmp_ps::<_CMP_GT_OQ>(t_light, zero));
            let blocked = self.occluded(origin, dir, t_light, lamp.index, from);
            ok = _mm256_andnot_ps(blocked, ok);
            tests = (_mm256_movemask_ps(lanes).count_ones() as u64) * self.kinds.len() as u64;
        }
        // light_weighted's cosine lobe: radiance · (cos_s/π / pl · w(pl, cos_s/π)).
        let lobe = _mm256_div_ps(cos_s, set(PI));
        let f = _mm256_mul_ps(_mm256_div_ps(lobe, pdf), power_heuristic(pdf, lobe));
        let l = lamp
            .radiance
            .map(|r| _mm256_and_ps(_mm256_mul_ps(set(r), f), ok));
        (l, tests)
    }

    /// The lanes whose primitive `idx` is of `kind`.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    fn is_kind(&self, kind: Kind, idx: __m256i) -> __m256 {
        flagged(&self.of_kind[kind as usize], idx)
    }

    /// The sky in direction d (its y component): uniform, or the gradient (`Tracer::sky`).
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    fn sky(&self, dy: __m256) -> V3 {
        if self.sky_uniform {
            return self.sky_bottom.map(|c| set(c));
        }
        let one = set(1.0);
        let t = _mm256_mul_ps(set(0.5), _mm256_add_ps(dy, one));
        let s = _mm256_sub_ps(one, t);
        std::array::from_fn(|c| {
            _mm256_add_ps(
                _mm256_mul_ps(s, set(self.sky_bottom[c])),
                _mm256_mul_ps(t, set(self.sky_top[c])),
            )
        })
    }
}

/// Eight floats from an array of eight.
#[inline]
#[target_feature(enable = "avx")]
fn load(a: &Table) -> __m256 {
    // SAFETY: an unaligned load of eight floats from an array of eight.
    unsafe { _mm256_loadu_ps(a.as_ptr()) }
}

/// The lanes whose entry `idx` of a table of flags (1.0 or 0.0) is set.
#[inline]
#[target_feature(enable = "avx,avx2")]
fn flagged(t: &Table, idx: __m256i) -> __m256 {
    _mm256_cmp_ps::<_CMP_GT_OQ>(pick(t, idx), _mm256_setzero_ps())
}

/// Each lane's entry `idx` of a table of eight.
#[inline]
#[target_feature(enable = "avx,avx2")]
fn pick(t: &Table, idx: __m256i) -> __m256 {
    _mm256_permutevar8x32_ps(load(t), idx)
}

#[inline]
#[target_feature(enable = "avx,avx2")]
fn pick3(t: &Tables3, idx: __m256i) -> V3 {
    [pick(&t[0], idx), pick(&t[1], idx), pick(&t[2], idx)]
}

#[inline]
#[target_feature(enable = "avx")]
fn set(x: f32) -> __m256 {
    _mm256_set1_ps(x)
}

#[inline]
#[target_feature(enable = "avx")]
fn neg(x: __m256) -> __m256 {
    _mm256_xor_ps(x, _mm256_set1_ps(-0.0))
}

#[inline]
#[target_feature(enable = "avx")]
fn abs(x: __m256) -> __m256 {
    _mm256_andnot_ps(_mm256_set1_ps(-0.0), x)
}

/// WGSL's sign(): −1, 0 or 1 (`intersect::sign`).
#[inline]
#[target_feature(enable = "avx")]
fn sign(x: __m256) -> __m256 {
    let zero = _mm256_setzero_ps();
    let pos = _mm256_and_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(x, zero), set(1.0));
    let negative = _mm256_and_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(x, zero), set(-1.0));
    _mm256_or_ps(pos, negative)
}

/// t in (0, t_max): a hit the tests count (`hit_except`, `occluded`).
#[inline]
#[target_feature(enable = "avx")]
fn between(t: __m256, t_max: __m256) -> __m256 {
    _mm256_and_ps(
        _mm256_cmp_ps::<_CMP_GT_OQ>(t, _mm256_setzero_ps()),
        _mm256_cmp_ps::<_CMP_LT_OQ>(t, t_max),
    )
}

/// t in (0, T_FAR).
#[inline]
#[target_feature(enable = "avx")]
fn within(t: __m256) -> __m256 {
    between(t, set(T_FAR))
}

/// a² / (a² + b²).
#[inline]
#[target_feature(enable = "avx")]
fn power_heuristic(a: __m256, b: __m256) -> __m256 {
    let a2 = _mm256_mul_ps(a, a);
    _mm256_div_ps(a2, _mm256_add_ps(a2, _mm256_mul_ps(b, b)))
}

/// 1 − cos of the cone a sphere of radius² r2 fills seen from distance² dist2.
#[inline]
#[target_feature(enable = "avx")]
fn cone_one_minus_cos(r2: __m256, dist2: __m256) -> __m256 {
    let sin2 = _mm256_div_ps(r2, dist2);
    let root = _mm256_sqrt_ps(_mm256_max_ps(
        _mm256_sub_ps(set(1.0), sin2),
        _mm256_setzero_ps(),
    ));
    _mm256_div_ps(sin2, _mm256_add_ps(set(1.0), root))
}

/// `sampling::basis` (Duff et al. 2017) in lanes.
#[inline]
#[target_feature(enable = "avx")]
fn basis(n: V3) -> [V3; 3] {
    let one = set(1.0);
    let s = _mm256_blendv_ps(
        set(-1.0),
        one,
        _mm256_cmp_ps::<_CMP_GE_OQ>(n[2], _mm256_setzero_ps()),
    );
    let a = _mm256_div_ps(set(-1.0), _mm256_add_ps(s, n[2]));
    let b = _mm256_mul_ps(_mm256_mul_ps(n[0], n[1]), a);
    let mul = _mm256_mul_ps;
    [
        [
            _mm256_add_ps(one, mul(mul(mul(s, n[0]), n[0]), a)),
            mul(s, b),
            mul(neg(s), n[0]),
        ],
        [b, _mm256_add_ps(s, mul(mul(n[1], n[1]), a)), neg(n[1])],
        n,
    ]
}

/// All bits of lane k set where bit k of `mask` is.
#[inline]
#[target_feature(enable = "avx,avx2")]
fn lane_mask(mask: u32) -> __m256 {
    let bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    let m = _mm256_and_si256(_mm256_set1_epi32(mask as i32), bits);
    _mm256_castsi256_ps(_mm256_cmpeq_epi32(m, bits))
}

/// A draw of each lane in `active` from its sampler (0 elsewhere).
#[inline]
#[target_feature(enable = "avx")]
fn draw(rngs: &mut [Rng; LANES], active: u32) -> __m256 {
    let mut u = [0.0f32; 8];
    for (k, (u, rng)) in u.iter_mut().zip(rngs.iter_mut()).enumerate() {
        if active >> k & 1 != 0 {
            *u = rng.rand();
        }
    }
    load(&u)
}

/// A point of [0, 1)² for each lane in `active`, from its sampler.
#[inline]
#[target_feature(enable = "avx")]
fn draw2(rngs: &mut [Rng; LANES], active: u32) -> (__m256, __m256) {
    let (mut u, mut v) = ([0.0f32; 8], [0.0f32; 8]);
    for (k, rng) in rngs.iter_mut().enumerate() {
        if active >> k & 1 != 0 {
            (u[k], v[k]) = rng.rand2();
        }
    }
    (load(&u), load(&v))
}

/// glam's Vec3A dot: (x·x′ + y·y′) + z·z′.
#[inline]
#[target_feature(enable = "avx")]
fn dot(a: V3, b: V3) -> __m256 {
    _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(a[0], b[0]), _mm256_mul_ps(a[1], b[1])),
        _mm256_mul_ps(a[2], b[2]),
    )
}

/// The textbook cross product, as glam computes it.
#[inline]
#[target_feature(enable = "avx")]
fn cross(a: V3, c: V3) -> V3 {
    [
        _mm256_sub_ps(_mm256_mul_ps(a[1], c[2]), _mm256_mul_ps(a[2], c[1])),
        _mm256_sub_ps(_mm256_mul_ps(a[2], c[0]), _mm256_mul_ps(a[0], c[2])),
        _mm256_sub_ps(_mm256_mul_ps(a[0], c[1]), _mm256_mul_ps(a[1], c[0])),
    ]
}

/// `sampling::normalize_or`: v / |v|, or `fallback` where |v|² < 10⁻¹².
#[inline]
#[target_feature(enable = "avx")]
fn normalize_or(v: V3, fallback: V3) -> V3 {
    let l2 = dot(v, v);
    let short = _mm256_cmp_ps::<_CMP_LT_OQ>(l2, set(1e-12));
    let root = _mm256_sqrt_ps(l2);
    std::array::from_fn(|c| _mm256_blendv_ps(_mm256_div_ps(v[c], root), fallback[c], short))
}
/// `sampling::random_unit_vector` from its draws u and v.
#[inline]
#[target_feature(enable = "avx,avx2")]
fn random_unit_vector(u: __m256, v: __m256) -> [__m256; 3] {
    let one = _mm256_set1_ps(1.0);
    let z = _mm256_sub_ps(one, _mm256_mul_ps(_mm256_set1_ps(2.0), u));
    let r = _mm256_sqrt_ps(_mm256_max_ps(
        _mm256_sub_ps(one, _mm256_mul_ps(z, z)),
        _mm256_setzero_ps(),
    ));
    let (s, c) = sin_cos_turns(v);
    [_mm256_mul_ps(r, c), _mm256_mul_ps(r, s), z]
}

/// `sampling::sin_cos_turns` in lanes: the same polynomials, the same quadrant turns.
#[inline]
#[target_feature(enable = "avx,avx2")]
fn sin_cos_turns(t: __m256) -> (__m256, __m256) {
    use std::f32::consts::PI;
    let set = _mm256_set1_ps;
    let qi = _mm256_cvttps_epi32(_mm256_add_ps(_mm256_mul_ps(set(4.0), t), set(0.5)));
    let q = _mm256_cvtepi32_ps(qi);
    let x = _mm256_mul_ps(set(2.0 * PI), _mm256_sub_ps(t, _mm256_mul_ps(set(0.25), q)));
    let x2 = _mm256_mul_ps(x, x);
    let (add, mul, div) = (_mm256_add_ps, _mm256_mul_ps, _mm256_div_ps);
    // x * (1 + x2 * (-1/6 + x2 * (1/120 + x2 * (-1/5040 + x2 / 362880))))
    let s = mul(
        x,
        add(
            set(1.0),
            mul(
                x2,
                add(
                    set(-1.0 / 6.0),
                    mul(
                        x2,
                        add(
                            set(1.0 / 120.0),
                            mul(x2, add(set(-1.0 / 5040.0), div(x2, set(362880.0)))),
                        ),
                    ),
                ),
            ),
        ),
    );
    // 1 + x2 * (-1/2 + x2 * (1/24 + x2 * (-1/720 + x2 * (1/40320))))
    let c = add(
        set(1.0),
        mul(
            x2,
            add(
                set(-0.5),
                mul(
                    x2,
                    add(
                        set(1.0 / 24.0),
                        mul(x2, add(set(-1.0 / 720.0), mul(x2, set(1.0 / 40320.0)))),
                    ),
                ),
            ),
        ),
    );
    let one = _mm256_set1_epi32(1);
    let two = _mm256_set1_epi32(2);
    let odd = _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(qi, one), one));
    let a = _mm256_blendv_ps(s, c, odd);
    let b = _mm256_blendv_ps(c, s, odd);
    let flip_a = _mm256_slli_epi32::<30>(_mm256_and_si256(qi, two));
    let flip_b = _mm256_slli_epi32::<30>(_mm256_and_si256(_mm256_add_epi32(qi, one), two));
    (
        _mm256_xor_ps(a, _mm256_castsi256_ps(flip_a)),
        _mm256_xor_ps(b, _mm256_castsi256_ps(flip_b)),
    )
}

/// `intersect::offset_ray` in lanes (Wächter and Binder, Ray Tracing Gems ch. 6).
#[inline]
#[target_feature(enable = "avx,avx2")]
fn offset_ray(p: [__m256; 3], n: [__m256; 3]) -> [__m256; 3] {
    use super::intersect::{OFFSET_FLOAT_SCALE, OFFSET_INT_SCALE, OFFSET_ORIGIN};
    let abs = _mm256_castsi256_ps(_mm256_set1_epi32(i32::MAX));
    std::array::from_fn(|c| {
        let of_i = _mm256_cvttps_epi32(_mm256_mul_ps(_mm256_set1_ps(OFFSET_INT_SCALE), n[c]));
        let near = _mm256_add_ps(
            p[c],
            _mm256_mul_ps(_mm256_set1_ps(OFFSET_FLOAT_SCALE), n[c]),
        );
        let negative = _mm256_castps_si256(_mm256_cmp_ps::<_CMP_LT_OQ>(p[c], _mm256_setzero_ps()));
        let step = _mm256_sub_epi32(_mm256_xor_si256(of_i, negative), negative);
        let far = _mm256_castsi256_ps(_mm256_add_epi32(_mm256_castps_si256(p[c]), step));
        let small =
            _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_and_ps(p[c], abs), _mm256_set1_ps(OFFSET_ORIGIN));
        _mm256_blendv_ps(far, near, small)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::common::FrameSettings;
    use crate::cpu::rng::GROUP;
    use crate::cpu::trace::{ANY, Tracer};
    use crate::scene::Scene;

    /// Eight spheres: a hollow one (negative radius) behind the others, Lambertian and
    /// specular lobes at smoothness 0, 0.3 and 1 and a fuzzed one, a lens, a uniform sky, and few bounces, so
    /// that paths end at the bounce limit, by a miss and by absorption.
    const SHELL: &str = r##"
[camera]
look_from = [0, 0.4, 2.5]
look_at = [0, 0, -1]
vfov = 70
aperture = 0.1
focus_distance = 3.0
[render]
max_bounces = 3
[sky]
uniform = [0.6, 0.7, 0.9]
[[sphere]]
center = [0, 0, -12]
radius = -8
color = "#c0c0c0"
[[sphere]]
center = [0, -100.5, -1]
radius = 100
color = "#80a060"
[[sphere]]
center = [-1.1, 0, -1]
radius = 0.5
color = "#d04040"
[[sphere]]
center = [0, 0, -1]
radius = 0.5
color = "#e0e0e0"
specular = 1
smoothness = 1
[[sphere]]
center = [1.1, 0, -1]
radius = 0.5
color = "#4060d0"
specular = 1
smoothness = 0.3
[[sphere]]
center = [0.5, 0.8, -1.8]
radius = 0.3
color = "#a0a0a0"
specular = 1
smoothness = 0.7
absorption = 0.4
[[sphere]]
center = [-0.5, 0.9, -2.2]
radius = 0.35
color = "#f0d080"
[[sphere]]
center = [0, -0.3, 0.2]
radius = 0.2
color = "#606060"
"##;

    /// A shipped scene, or the test scene `SHELL`.
    fn scene(name: &str) -> Scene {
        match name {
            "shell" => Scene::from_toml(SHELL, "shell").unwrap(),
            _ => Scene::load(name).unwrap(),
        }
    }

    /// Every path the lanes trace (samples 5 to 40 of every pixel: three groups of
    /// samplers) against `Tracer::trace_path`'s, bit for bit: radiance, segments, and where
    /// its sampler's stream stands after it. Returns the paths compared and those that
    /// differ.
    fn compare(scene: &Scene, f: Features, w: u32, h: u32) -> (u64, u64) {
        let samples = 5..40;
        let settings = FrameSettings::new(w, h, scene.render.max_bounces.min(8), 5);
        let s = CpuScene::new(scene, &settings);
        let Some(lanes) = Lanes::of(&s, f) else {
            assert!(
                !std::arch::is_x86_feature_detected!("avx2"),
                "no lanes for the scene"
            );
            return (0, 0);
        };
        let mut t = Tracer::new(&s, f);
        let bits = |v: Vec3A| v.to_array().map(f32::to_bits);
        let (mut paths, mut differ) = (0, 0);
        for y in 0..h {
            for x0 in (0..w).step_by(LANES) {
                let n = (w - x0).min(LANES as u32) as usize;
                let mut got = std::collections::HashMap::new();
                let done = |x: usize, sample: u32, (radiance, segments): Traced, rng: &Rng| {
                    let mut rng = *rng;
                    let after = (rng.taken(), rng.rand().to_bits());
                    got.insert((x, sample), (bits(radiance), segments, after));
                };
                // SAFETY: `Lanes::of` made them only where the CPU has AVX2.
                unsafe { lanes.trace(&t, (x0, y, w), n, samples.clone(), (s.u.seed, 3), done) };
                assert_eq!(got.len(), n * samples.len());
                for sample in samples.clone() {
                    let pixels: [u32; GROUP] = std::array::from_fn(|x| y * w + x0 + x as u32);
                    let mut rngs = Rng::group(&pixels, sample, s.u.seed, 3);
                    for (x, rng) in rngs.iter_mut().enumerate().take(n) {
                        let px = (x0 + x as u32, y);
                        let ray = t.camera_ray(px.0, y, rng);
                        let (radiance, segments) = if f.nee {
                            t.trace_path::<ANY, true>(px, ray, None, rng)
                        } else {
                            t.trace_path::<ANY, false>(px, ray, None, rng)
                        };
                        let want = (
                            bits(radiance),
                            segments,
                            (rng.taken(), rng.rand().to_bits()),
                        );
                        let lanes = got[&(x, sample)];
                        if lanes != want && differ < 3 {
                            eprintln!("{px:?}, sample {sample}: {lanes:?} against {want:?}");
                        }
                        differ += (lanes != want) as u64;
                        paths += 1;
                    }
                }
            }
        }
        (paths, differ)
    }

    #[test]
    fn lanes_trace_the_scalar_paths_bit_for_bit() {
        let mut cases = vec![];
        for name in ["shell", "basic", "metal", "fuzz", "dof"] {
            let scene = scene(name);
            cases.push((name, Features::of(&scene), scene));
        }
        for name in ["lamp", "cornell"] {
            let scene = scene(name);
            let f = Features::of(&scene);
            cases.push((name, Features { nee: false, ..f }, scene.clone()));
            cases.push((name, f, scene));
        }
        for (name, f, scene) in &cases {
            let (paths, differ) = compare(scene, *f, 36, 20);
            eprintln!(
                "{name} (light sampling {}): {differ} of {paths} paths differ",
                f.nee
            );
            assert!(paths == 0 || paths == 36 * 20 * 35);
            assert_eq!(differ, 0);
        }
    }

    #[test]
    fn lanes_trace_what_they_can_and_leave_out_the_rest() {
        let settings = FrameSettings::new(16, 16, 8, 1);
        let has = std::arch::is_x86_feature_detected!("avx2");
        // Glass, several lights, a map, triangles, glTF's BRDF.
        for name in [
            "weekend",
            "dielectric",
            "emissive",
            "outdoor",
            "mesh",
            "pbr",
        ] {
            let scene = scene(name);
            let s = CpuScene::new(&scene, &settings);
            assert!(Lanes::of(&s, Features::of(&scene)).is_none(), "{name}");
        }
        for name in ["shell", "basic", "metal", "fuzz", "dof", "lamp", "cornell"] {
            let scene = scene(name);
            let s = CpuScene::new(&scene, &settings);
            assert_eq!(Lanes::of(&s, Features::of(&scene)).is_some(), has, "{name}");
        }
    }
}
