//! The native CPU tracer: the GPU tracer's model (shaders/trace.wgsl) in Rust on every core
//! (rayon), for machines without a GPU, where it replaces Mesa's software adapters.
//!
//! It reads the scene the GPU reads (`gpu::scene_buffers`: the same primitives, lights and
//! BVH, the latter collapsed to four-wide nodes in `cpu::bvh`, and to eight-wide ones in
//! `cpu::bvh8` for single rays on a CPU with AVX), traces the same random streams (a group
//! of eight pixels' samplers made at once: `rng::Rng::group`), and keeps the same exact
//! fixed-point sums of even and odd samples in the GPU's word layout (`cpu::fixed`), so that
//! the renderer's rounds, the snapshot, the noise estimate, `converge`, `--target-error` and
//! the preview work unchanged on it. Its modules
//! mirror the WGSL files: `rng`, `fixed`, `sampling`, `intersect`, `material`, `trace`.

pub mod bvh;
#[cfg(target_arch = "x86_64")]
pub mod bvh8;
pub mod fixed;
pub mod intersect;
pub mod material;
#[cfg(target_arch = "x86_64")]
mod packet;
pub mod rng;
pub mod sampling;
pub mod scene;
pub mod trace;

use crate::gpu::accum::{ACCUM_WORDS, AccumData, decode, decode_pixel};
use crate::gpu::layout::DispatchUniforms;
use crate::gpu::resolve::Resolved;
use crate::gpu::{Features, FrameSettings};
use crate::scene::Scene;
use fixed::Fixed;
use intersect::Ray;
use rayon::prelude::*;
use rng::Rng;
use scene::CpuScene;
use trace::{ANY, LANES, SPHERES, Tracer};

// A pixel group's samplers are made together.
const _: () = assert!(LANES == rng::GROUP);

/// The name `--adapter` and `termtrace adapters` know the CPU tracer by.
pub const ADAPTER_NAME: &str = "cpu-native";

/// One line naming the CPU tracer and the threads it runs on.
pub fn describe() -> String {
    format!(
        "termtrace native CPU tracer ({} threads, {})",
        rayon::current_num_threads(),
        std::env::consts::ARCH
    )
}

/// Counters of one submission or since a reset (as the GPU's counters buffer holds them).
#[derive(Clone, Copy, Default, Debug)]
struct Counters {
    invalid: u64,
    segments: u64,
    visits: u64,
    tests: u64,
    /// Paths by the number of Sobol draws they took (`Rng::taken`).
    drawn: [u64; rng::QMC_SLOTS as usize + 1],
}

impl std::ops::Add for Counters {
    type Output = Counters;
    fn add(self, o: Counters) -> Counters {
        Counters {
            invalid: self.invalid + o.invalid,
            segments: self.segments + o.segments,
            visits: self.visits + o.visits,
            tests: self.tests + o.tests,
            drawn: std::array::from_fn(|k| self.drawn[k] + o.drawn[k]),
        }
    }
}

/// The scene and the accumulation on the host.
pub struct CpuEngine {
    scene: CpuScene,
    /// The sums of the even and odd samples, `ACCUM_WORDS` words per pixel.
    even: Vec<u32>,
    odd: Vec<u32>,
    counters: Counters,
    /// Sobol points made ahead for the next submission's samplers (`ahead_for`).
    ahead: usize,
    width: u32,
    height: u32,
}

/// The Sobol points worth making ahead (`Rng::group`): those that at least this share of
/// the paths draw. A point made ahead costs every path a share of eight lanes' work, one
/// made when drawn costs the paths that draw it a chain of hashes; with 0.25 `weekend`
/// (4 ahead), `lamp` (3), `cornell` (10) and `showcase` (4) each run at their fastest of the
/// counts tried (BENCHMARKS.md).
const AHEAD_SHARE: f64 = 0.25;

/// The number of leading Sobol draws that at least `AHEAD_SHARE` of the paths counted in
/// `drawn` took (all of them before anything is counted).
fn ahead_for(drawn: &[u64]) -> usize {
    let total: u64 = drawn.iter().sum();
    if total == 0 {
        return drawn.len() - 1;
    }
    // Paths that took more than k draws, for k = 0, 1, ...
    let mut beyond = total;
    for (k, &n) in drawn.iter().enumerate() {
        beyond -= n;
        if (beyond as f64) < AHEAD_SHARE * total as f64 {
            return k;
        }
    }
    drawn.len() - 1
}

impl CpuEngine {
    pub fn new(scene: &Scene, s: &FrameSettings) -> CpuEngine {
        let pixels = s.width as usize * s.height as usize;
        CpuEngine {
            scene: CpuScene::new(scene, s),
            even: vec![0; pixels * ACCUM_WORDS],
            odd: vec![0; pixels * ACCUM_WORDS],
            counters: Counters::default(),
            ahead: rng::QMC_SLOTS as usize,
            width: s.width,
            height: s.height,
        }
    }

    /// Replaces the scene and settings (the BVH kept where the geometry is unchanged).
    pub fn set_scene(&mut self, scene: &Scene, s: &FrameSettings) {
        self.scene.update(scene, s);
        if (s.width, s.height) != (self.width, self.height) {
            let words = s.width as usize * s.height as usize * ACCUM_WORDS;
            self.even = vec![0; words];
            self.odd = vec![0; words];
            (self.width, self.height) = (s.width, s.height);
        }
    }

    /// Nodes of the (four-wide) BVH and the seconds its build and collapse took.
    pub fn bvh_stats(&self) -> (usize, f64) {
        (self.scene.node_count, self.scene.build_seconds)
    }

    /// Bytes the accumulation holds.
    pub fn bytes(&self) -> u64 {
        4 * (self.even.len() + self.odd.len()) as u64
    }

    pub fn reset_counters(&mut self) {
        self.counters = Counters::default();
    }

    /// Traces one submission (as `fn trace` in trace.wgsl with one lane) on every core, and
    /// returns when it is done.
    pub fn run(&mut self, d: &DispatchUniforms, f: Features) {
        let spheres_only = !(f.quads || f.boxes || f.triangles);
        let c = match (spheres_only, f.nee) {
            (true, true) => self.run_with::<SPHERES, true>(d, f),
            (true, false) => self.run_with::<SPHERES, false>(d, f),
            (false, true) => self.run_with::<ANY, true>(d, f),
            (false, false) => self.run_with::<ANY, false>(d, f),
        };
        self.counters = self.counters + c;
        // Scenes differ in how many draws a path takes (lights, lobes, bounces); the draws
        // are the same however many are made ahead, only the speed is not.
        self.ahead = ahead_for(&c.drawn);
    }

    fn run_with<const P: u32, const NEE: bool>(
        &mut self,
        d: &DispatchUniforms,
        f: Features,
    ) -> Counters {
        let width = self.width;
        let row_words = width as usize * ACCUM_WORDS;
        let stride = d.row_stride.max(1);
        let rows = d.row_offset..(d.row_offset + d.row_count * stride).min(self.height);
        let scene = &self.scene;
        let ahead = self.ahead;
        self.even
            .par_chunks_mut(row_words)
            .zip(self.odd.par_chunks_mut(row_words))
            .enumerate()
            .filter(|(y, _)| {
                let y = *y as u32;
                rows.contains(&y) && (y - d.row_offset).is_multiple_of(stride)
            })
            .map(|(y, (even, odd))| {
                let mut t = Tracer::new(scene, f);
                let mut c = Counters::default();
                let y = y as u32;
                // Eight neighbouring pixels at a time: their camera rays are walked together
                // where the scene allows (`Tracer::camera_hits`), each path then alone.
                for x0 in (0..width).step_by(LANES) {
                    let n = (width - x0).min(LANES as u32) as usize;
                    let words = |x: usize| {
                        let p = x0 as usize + x;
                        p * ACCUM_WORDS..(p + 1) * ACCUM_WORDS
                    };
                    let mut sums: [(Fixed, Fixed); LANES] = Default::default();
                    if d.accumulate != 0 {
                        for (x, s) in sums.iter_mut().enumerate().take(n) {
                            *s = (Fixed::load(&even[words(x)]), Fixed::load(&odd[words(x)]));
                        }
                    }
                    for i in 0..d.sample_count {
                        let sample = d.sample_base + i;
                        let pixel = |x: usize| y * width + x0 + x as u32;
                        let mut rngs: [Rng; LANES] =
                            Rng::group(&std::array::from_fn(pixel), sample, scene.u.seed, ahead);
                        let rays: [Option<Ray>; LANES] = std::array::from_fn(|x| {
                            (x < n).then(|| t.camera_ray(x0 + x as u32, y, &mut rngs[x]))
                        });
                        let first = t.camera_hits::<P>(&rays);
                        for x in 0..n {
                            let ray = rays[x].expect("a ray for every pixel of the group");
                            let known = first.map(|h| h[x]);
                            let (radiance, segments) =
                                t.trace_path::<P, NEE>(ray, known, &mut rngs[x]);
                            c.segments += segments as u64;
                            c.drawn[rngs[x].taken() as usize] += 1;
                            if !radiance.is_finite() {
                                c.invalid += 1;
                                continue;
                            }
                            let half = if sample & 1 == 0 {
                                &mut sums[x].0
                            } else {
                                &mut sums[x].1
                            };
                            half.add(radiance.to_array());
                        }
                    }
                    for (x, (e, o)) in sums.iter().enumerate().take(n) {
                        e.store(&mut even[words(x)]);
                        o.store(&mut odd[words(x)]);
                    }
                }
                c.visits = t.tally.visits;
                c.tests = t.tally.tests;
                c
            })
            .reduce(Counters::default, |a, b| a + b)
    }

    /// The sums on the host, as the GPU's readback gives them.
    pub fn read(&self) -> AccumData {
        AccumData {
            invalid: self.counters.invalid,
            segments: self.counters.segments,
            node_visits: self.counters.visits,
            primitive_tests: self.counters.tests,
            ..AccumData::from_halves(decode(&self.even), decode(&self.odd))
        }
    }

    /// The preview's frame: resolve.wgsl's terms computed on the host (every output pixel
    /// the mean of a `factor × factor` block, and the two-halves noise terms), in parallel.
    pub fn resolve(&self, factor: u32) -> Resolved {
        let f = factor.max(1);
        let out = ((self.width / f).max(1), (self.height / f).max(1));
        let (w, h) = (self.width as usize, self.height as usize);
        let value = |words: &[u32], p: usize| -> ([f32; 3], f32) {
            let [r, g, b, n] = decode_pixel(&words[p * ACCUM_WORDS..(p + 1) * ACCUM_WORDS]);
            ([r, g, b], n)
        };
        let blocks: Vec<[f32; 8]> = (0..out.0 as usize * out.1 as usize)
            .into_par_iter()
            .map(|i| {
                let (bx, by) = (i % out.0 as usize, i / out.0 as usize);
                let mut b = [0.0f32; 8];
                b[3] = f32::INFINITY;
                for dy in 0..f as usize {
                    for dx in 0..f as usize {
                        let (x, y) = (bx * f as usize + dx, by * f as usize + dy);
                        if x >= w || y >= h {
                            continue;
                        }
                        let p = y * w + x;
                        let ((se, ne), (so, no)) = (value(&self.even, p), value(&self.odd, p));
                        if ne + no > 0.0 {
                            for c in 0..3 {
                                b[c] += (se[c] + so[c]) / (ne + no);
                            }
                        } else {
                            // A row the first look has not reached: show its neighbour.
                            let near = if y == 0 { p + w } else { p - w };
                            if near < w * h {
                                let ((s2, n2), (t2, m2)) =
                                    (value(&self.even, near), value(&self.odd, near));
                                if n2 + m2 > 0.0 {
                                    for c in 0..3 {
                                        b[c] += (s2[c] + t2[c]) / (n2 + m2);
                                    }
                                }
                            }
                        }
                        b[3] = b[3].min(ne.min(no));
                        if ne >= 1.0 && no >= 1.0 {
                            let k = ne * no / ((ne + no) * (ne + no));
                            for c in 0..3 {
                                let d = se[c] / ne - so[c] / no;
                                let v = d * d * k;
                                b[4] += v;
                                b[5] += v
                                    / ((se[c] / ne * (so[c] / no)).max(0.0)
                                        + crate::render::REL_MSE_EPSILON as f32);
                            }
                        }
                    }
                }
                let n = (f * f) as f32;
                for c in b.iter_mut().take(3) {
                    *c /= n;
                }
                b
            })
            .collect();
        Resolved::from_blocks(&blocks, out, f, self.counters.invalid)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_are_made_ahead_for_the_draws_a_quarter_of_the_paths_take() {
        // Nothing counted yet: all of them.
        assert_eq!(ahead_for(&[0; 11]), 10);
        // weekend's counts: 2 draws 17 %, 3 46 %, 4 18 %, 5 10 %, ...: draws 0-3 are taken by
        // at least 37 % of the paths, draw 4 by 19 %.
        let weekend = [
            0, 0, 90054, 245244, 94021, 52226, 22105, 13223, 7342, 4743, 11042,
        ];
        assert_eq!(ahead_for(&weekend), 4);
        // Every path takes all ten.
        let mut all = [0; 11];
        all[10] = 5;
        assert_eq!(ahead_for(&all), 10);
        // Every path takes exactly one.
        let mut one = [0; 11];
        one[1] = 5;
        assert_eq!(ahead_for(&one), 1);
    }
}
