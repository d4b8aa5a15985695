//! The native CPU tracer: the GPU tracer's model (shaders/trace.wgsl) in Rust on every core
//! (rayon), for machines without a GPU, where it replaces Mesa's software adapters.
//!
//! It reads the scene the GPU reads (`common::arrays`: the same primitives, lights and
//! BVH, the latter collapsed to four-wide nodes in `cpu::bvh`, and to eight-wide ones in
//! `cpu::bvh8` for single rays on a CPU with AVX, their leaves' triangles tested eight at a
//! time in `cpu::tri8`, and where that is one node of a few quads and boxes, tested all at
//! once in `cpu::few`), traces the same random streams (a group
//! of eight pixels' samplers made at once: `rng::Rng::group`; where the scene is at most
//! eight spheres, quads and boxes of the lecture's certain lobes, lit by the sky and at most
//! one light, their paths side by side in vector lanes, sixteen on AVX-512, eight on AVX2,
//! `cpu::lanes` over `cpu::simd`), and keeps the same exact fixed-point sums of even and
//! odd samples in the GPU's word layout (`cpu::fixed`), so that the renderer's rounds, the
//! snapshot, the noise estimate, `converge`, `--target-error` and the preview work
//! unchanged on it. A submission's rows are its tasks, or, where they are
//! too few to keep every thread busy (the preview's small images on a many-core machine),
//! ranges of each row's samples (`parts_per_row`). Its modules mirror the WGSL files: `rng`,
//! `fixed`, `sampling`, `intersect`, `material`, `trace`.

pub mod bvh;
#[cfg(target_arch = "x86_64")]
pub mod bvh8;
#[cfg(target_arch = "x86_64")]
mod draws;
#[cfg(target_arch = "x86_64")]
pub mod few;
pub mod fixed;
pub mod intersect;
#[cfg(target_arch = "x86_64")]
pub mod lanes;
#[cfg(test)]
mod lcg;
pub mod lens;
pub mod material;
pub mod mirror;
#[cfg(target_arch = "x86_64")]
mod packet;
pub mod pbr;
pub mod rng;
pub mod sampling;
pub mod scene;
#[cfg(target_arch = "x86_64")]
mod simd;
pub mod texture;
pub mod trace;
#[cfg(target_arch = "x86_64")]
pub mod tri8;

use crate::common::Resolved;
use crate::common::accum::{ACCUM_WORDS, AccumData, Sums, decode};
use crate::common::engine::Engine;
use crate::common::guides::{GUIDE_SEED, GUIDE_WORDS, Guides};
use crate::common::layout::DispatchUniforms;
use crate::common::{Features, FrameSettings};
use crate::scene::Scene;
use fixed::Fixed;
use intersect::{LANES, Ray};
use rayon::prelude::*;
use rng::Rng;
use scene::CpuScene;
use trace::{ANY, SPHERES, Tracer};

// A pixel group's samplers are made together.
const _: () = assert!(LANES == rng::GROUP);

/// The name `--adapter` and `termtrace adapters` know the CPU tracer by.
pub const ADAPTER_NAME: &str = "cpu-native";

/// One line naming the CPU tracer and the threads it runs on.
pub fn describe() -> String {
    format!(
        "termtrace native CPU tracer ({}, {})",
        threads(),
        std::env::consts::ARCH
    )
}

/// "1 thread", "16 threads": what the CPU tracer runs on (`--threads`).
pub fn threads() -> String {
    match rayon::current_num_threads() {
        1 => "1 thread".into(),
        n => format!("{n} threads"),
    }
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

/// A range of one row's samples traced apart: the row, its pixels' (even, odd) sums, and
/// what was counted.
type Part = (u32, Vec<(Fixed, Fixed)>, Counters);

/// Into how many sample ranges each of `rows` rows is split, so that every one of `threads`
/// threads has several tasks (load balance: rows differ in cost) when a submission has few
/// rows, as the preview's small images on a many-core machine do.
fn parts_per_row(rows: usize, samples: u32, threads: usize) -> u32 {
    const TASKS_PER_THREAD: usize = 4;
    let want = (threads * TASKS_PER_THREAD).div_ceil(rows.max(1));
    want.clamp(1, samples.max(1) as usize) as u32
}

/// Traces samples `samples` of every pixel of row `y`, adding them to `sums` (a pixel's even
/// and odd halves).
fn trace_row<const P: u32, const NEE: bool>(
    scene: &CpuScene,
    f: Features,
    ahead: usize,
    y: u32,
    samples: std::ops::Range<u32>,
    sums: &mut [(Fixed, Fixed)],
) -> Counters {
    let width = sums.len() as u32;
    let mut c = Counters::default();
    // Where the scene allows (`lanes::Lanes::of`), eight or sixteen pixels' paths side by
    // side in lanes.
    #[cfg(target_arch = "x86_64")]
    if let Some(l) = lanes::Lanes::of(scene, f).filter(|_| !trace::recording()) {
        let lanes = l.width() as u32;
        for x0 in (0..width).step_by(lanes as usize) {
            let n = (width - x0).min(lanes) as usize;
            let sums = &mut sums[x0 as usize..x0 as usize + n];
            let done = |x: usize, sample: u32, path: lanes::Traced| {
                c.record_words(&mut sums[x], sample, path.words, path.segments, path.taken);
            };
            let (visits, tests) = l.trace((x0, y, width), n, samples.clone(), scene.u.seed, done);
            c.visits += visits;
            c.tests += tests;
        }
        return c;
    }
    let mut t = Tracer::new(scene, f);
    // Eight neighbouring pixels at a time: their camera rays are walked together where the
    // scene allows (`Tracer::camera_hits`), each path then alone.
    for x0 in (0..width).step_by(LANES) {
        let n = (width - x0).min(LANES as u32) as usize;
        let sums = &mut sums[x0 as usize..x0 as usize + n];
        for sample in samples.clone() {
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
                    t.trace_path::<P, NEE>((x0 + x as u32, y), ray, known, &mut rngs[x]);
                c.record(&mut sums[x], sample, radiance, segments, &rngs[x]);
            }
        }
    }
    c.visits = t.tally.visits;
    c.tests = t.tally.tests;
    c
}

impl Counters {
    /// A path of sample `sample` traced: its radiance added to its pixel's half of the sums
    /// (even or odd samples), or counted invalid; its segments and draws counted.
    #[inline(always)]
    fn record(
        &mut self,
        sums: &mut (Fixed, Fixed),
        sample: u32,
        radiance: glam::Vec3A,
        segments: u32,
        rng: &Rng,
    ) {
        let words = radiance
            .is_finite()
            .then(|| fixed::words(radiance.to_array()));
        self.record_words(sums, sample, words, segments, rng.taken());
    }

    /// `record` of a path whose radiance is given as its `fixed::words` (`None` where it is
    /// not finite), and its sampler's Sobol draws taken (`Rng::taken`).
    #[inline(always)]
    fn record_words(
        &mut self,
        sums: &mut (Fixed, Fixed),
        sample: u32,
        words: Option<[u64; 3]>,
        segments: u32,
        taken: u32,
    ) {
        self.segments += segments as u64;
        self.drawn[taken as usize] += 1;
        let Some(words) = words else {
            self.invalid += 1;
            return;
        };
        let half = if sample & 1 == 0 {
            &mut sums.0
        } else {
            &mut sums.1
        };
        half.add_words(words);
    }
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
        // The rows of this submission: every `stride`-th from `row_offset`, `row_count` of
        // them at most.
        let stride = d.row_stride.max(1) as usize;
        let ys: Vec<u32> = (d.row_offset..self.height)
            .step_by(stride)
            .take(d.row_count as usize)
            .collect();
        let parts = parts_per_row(ys.len(), d.sample_count, rayon::current_num_threads());
        let scene = &self.scene;
        let ahead = self.ahead;
        let trace = |y: u32, samples: std::ops::Range<u32>, sums: &mut [(Fixed, Fixed)]| {
            trace_row::<P, NEE>(scene, f, ahead, y, samples, sums)
        };
        // Those rows with their words in each half, in the order of `ys`.
        let rows_words = self
            .even
            .par_chunks_mut(row_words)
            .zip(self.odd.par_chunks_mut(row_words))
            .skip(d.row_offset as usize)
            .step_by(stride)
            .take(ys.len())
            .zip(ys.par_iter().copied())
            .map(|(halves, y)| (y, halves));
        let load = |words: (&[u32], &[u32])| -> Vec<(Fixed, Fixed)> {
            (0..width as usize)
                .map(|x| {
                    let at = x * ACCUM_WORDS..(x + 1) * ACCUM_WORDS;
                    if d.accumulate != 0 {
                        (Fixed::load(&words.0[at.clone()]), Fixed::load(&words.1[at]))
                    } else {
                        Default::default()
                    }
                })
                .collect()
        };
        let store = |sums: &[(Fixed, Fixed)], words: (&mut [u32], &mut [u32])| {
            for (x, (e, o)) in sums.iter().enumerate() {
                let at = x * ACCUM_WORDS..(x + 1) * ACCUM_WORDS;
                e.store(&mut words.0[at.clone()]);
                o.store(&mut words.1[at]);
            }
        };
        if parts == 1 {
            // A task per row, its sums added to in place.
            return rows_words
                .map(|(y, (e, o))| {
                    let mut sums = load((e, o));
                    let c = trace(y, d.sample_base..d.sample_base + d.sample_count, &mut sums);
                    store(&sums, (e, o));
                    c
                })
                .reduce(Counters::default, |a, b| a + b);
        }
        // Fewer rows than the threads need: each row's samples split into `parts` ranges,
        // traced into sums of their own, then added to the row's. The sums are exact integers,
        // so the image is the same bit for bit however the samples are split.
        let traced: Vec<Part> = (0..ys.len() * parts as usize)
            .into_par_iter()
            .map(|i| {
                let (y, k) = (ys[i / parts as usize], (i % parts as usize) as u32);
                let range = |k: u32| d.sample_base + d.sample_count * k / parts;
                let mut sums = vec![(Fixed::default(), Fixed::default()); width as usize];
                let c = trace(y, range(k)..range(k + 1), &mut sums);
                (y, sums, c)
            })
            .collect();
        let counters = traced.iter().fold(Counters::default(), |a, t| a + t.2);
        rows_words
            .zip(traced.par_chunks(parts as usize))
            .for_each(|((y, (e, o)), part)| {
                debug_assert!(part.iter().all(|t| t.0 == y));
                let mut sums = load((e, o));
                for (_, p, _) in part {
                    for (s, q) in sums.iter_mut().zip(p) {
                        s.0.merge(&q.0);
                        s.1.merge(&q.1);
                    }
                }
                store(&sums, (e, o));
            });
        counters
    }

    /// The denoiser's guide sums (`GUIDE_WORDS` words per pixel) of guide samples
    /// `samples` of every pixel, as `fn guides` in trace.wgsl makes them, rows in parallel.
    pub fn guides(&self, f: Features, samples: std::ops::Range<u32>) -> Vec<u32> {
        let spheres_only = !(f.quads || f.boxes || f.triangles);
        let width = self.width as usize;
        let mut words = vec![0u32; width * self.height as usize * GUIDE_WORDS];
        let scene = &self.scene;
        words
            .par_chunks_mut(width * GUIDE_WORDS)
            .enumerate()
            .for_each(|(y, row)| {
                let mut t = Tracer::new(scene, f);
                for (x, w) in row.chunks_exact_mut(GUIDE_WORDS).enumerate() {
                    let pixel = (y * width + x) as u32;
                    for sample in samples.clone() {
                        let mut rng = Rng::new(pixel, sample, scene.u.seed ^ GUIDE_SEED);
                        let ray = t.camera_ray(x as u32, y as u32, &mut rng);
                        let (albedo, normal) = if spheres_only {
                            t.guide::<SPHERES>(ray)
                        } else {
                            t.guide::<ANY>(ray)
                        };
                        Guides::add(w, albedo, normal);
                    }
                }
            });
        words
    }
}

/// The CPU tracer's side of the renderer's seam.
impl Engine for CpuEngine {
    /// Replaces the scene and settings (the BVH kept where the geometry is unchanged).
    fn set_scene(&mut self, scene: &Scene, s: &FrameSettings, _: Features) {
        self.scene.update(scene, s);
        if (s.width, s.height) != (self.width, self.height) {
            let words = s.width as usize * s.height as usize * ACCUM_WORDS;
            self.even = vec![0; words];
            self.odd = vec![0; words];
            (self.width, self.height) = (s.width, s.height);
        }
    }

    /// Nodes of the (four-wide) BVH and the seconds its build and collapse took.
    fn bvh_stats(&self) -> (usize, f64) {
        (self.scene.node_count, self.scene.build_seconds)
    }

    /// Bytes the accumulation holds.
    fn bytes(&self) -> u64 {
        4 * (self.even.len() + self.odd.len()) as u64
    }

    /// Paths side by side in lanes (`lanes::Lanes::try_of`), or one at a time and why.
    fn path_loop(&self, f: Features) -> Option<String> {
        #[cfg(target_arch = "x86_64")]
        let how = match lanes::Lanes::try_of(&self.scene, f) {
            Ok(l) => {
                let isa = if l.width() == 16 { "AVX-512" } else { "AVX2" };
                format!("paths side by side in {} lanes ({isa})", l.width())
            }
            Err(why) => format!("one path at a time (not in lanes: {why})"),
        };
        #[cfg(not(target_arch = "x86_64"))]
        let how = {
            let _ = f;
            "one path at a time (the lanes are x86-64's)".to_string()
        };
        Some(how)
    }

    fn reset_counters(&mut self) {
        self.counters = Counters::default();
    }

    /// The exact sums (even, odd) and the invalid samples.
    fn exact_sums(&self) -> Sums {
        Sums {
            even: self.even.clone(),
            odd: self.odd.clone(),
            invalid: self.counters.invalid,
        }
    }

    /// The sums on the host, as the GPU's readback gives them.
    fn read(&self) -> AccumData {
        AccumData {
            invalid: self.counters.invalid,
            segments: self.counters.segments,
            node_visits: self.counters.visits,
            primitive_tests: self.counters.tests,
            ..AccumData::from_halves(decode(&self.even), decode(&self.odd))
        }
    }

    /// The preview's frame: resolve.wgsl's terms computed on the host (`Resolved::from_sums`).
    fn resolve_on_host(&self, factor: u32) -> Option<Resolved> {
        Some(Resolved::from_sums(
            &self.even,
            &self.odd,
            (self.width, self.height),
            factor,
            self.counters.invalid,
        ))
    }

    /// No pipelines: the tracer is compiled into the binary.
    fn ready(&self, _: Features) -> bool {
        true
    }

    fn prepare(&mut self, _: Features, _: bool) {}

    fn scratch_slots(&self) -> u64 {
        0
    }

    /// Traces on every core before it returns.
    fn dispatch(
        &mut self,
        features: Features,
        d: DispatchUniforms,
        _: u32,
    ) -> Option<std::time::Duration> {
        let start = std::time::Instant::now();
        self.run(&d, features);
        Some(start.elapsed())
    }

    fn finish_oldest(&mut self) {}

    fn timed_seconds(&self) -> Option<f64> {
        None
    }

    fn make_guides(
        &mut self,
        features: Features,
        _: (u32, u32),
        samples: std::ops::Range<u32>,
    ) -> Option<Vec<u32>> {
        Some(self.guides(features, samples))
    }

    fn read_guides(&self) -> Vec<u32> {
        Vec::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_split_strided_or_whole_sum_to_the_same_words() {
        let scene = Scene::load("showcase").unwrap();
        let settings = FrameSettings::new(20, 6, scene.render.max_bounces, 1);
        let f = Features::of(&scene);
        let dispatch = |(sample_base, sample_count, accumulate),
                        (row_offset, row_count, row_stride)| {
            DispatchUniforms {
                sample_base,
                sample_count,
                row_offset,
                row_count,
                accumulate,
                lanes: 1,
                row_stride,
                _pad: 0,
            }
        };
        let run = |threads, submissions: &[DispatchUniforms]| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut e = CpuEngine::new(&scene, &settings);
            pool.install(|| submissions.iter().for_each(|d| e.run(d, f)));
            (e.even, e.odd, e.counters.segments, e.counters.drawn)
        };
        let (first, rest) = ((0, 3, 0), (3, 9, 1));
        // Three samples, then nine more added to them, each a submission of the six rows.
        let whole = [dispatch(first, (0, 6, 1)), dispatch(rest, (0, 6, 1))];
        // The same, the three taken by every other row (the preview's first look: rows 0, 2,
        // 4, then 1, 3, 5), the nine by rows 0-3 and then by a submission asking for rows 4-8
        // of the six.
        let parted = [
            dispatch(first, (0, 3, 2)),
            dispatch(first, (1, 3, 2)),
            dispatch(rest, (0, 4, 1)),
            dispatch(rest, (4, 5, 1)),
        ];
        // One thread: a task per row; sixteen: each row's samples in three and in nine parts.
        assert_eq!(parts_per_row(6, 9, 1), 1);
        assert_eq!(parts_per_row(6, 3, 16), 3);
        assert_eq!(parts_per_row(6, 9, 16), 9);
        let one = run(1, &whole);
        assert!(one.2 > 0);
        assert!(one == run(16, &whole), "the split rows' sums differ");
        assert!(one == run(1, &parted), "the strided rows' sums differ");
        assert!(
            one == run(16, &parted),
            "the split strided rows' sums differ"
        );
    }

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
