//! One render on several devices (`--adapter all`, `--adapter 0,1`): each device claims the
//! next samples of every pixel when it is ready, sized by its own measured rate, and their
//! exact fixed-point sums are added. Every sample index is traced once, by whichever device
//! claimed it, with its own random stream, so on devices that compute alike the image is
//! the one a single device makes, bit for bit (the sums do not depend on the order).
//!
//! How much each device claims: `claims`.

use super::claims::Claims;
use super::shard::{Sums, add_sums};
use super::{Backend, RenderOptions, Renderer, Snapshot};
use crate::common::FrameSettings;
use crate::common::accum::{AccumData, decode};
use crate::scene::Scene;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// One device of a team: its renderer and what it has done.
struct Member {
    renderer: Mutex<Renderer>,
    name: String,
    /// Paths traced, and seconds spent tracing them, since the last restart.
    paths: AtomicU64,
    micros: AtomicU64,
    /// Nanoseconds its passes took on the GPU, where timed.
    gpu_nanos: AtomicU64,
    /// Samples per pixel of its completed rounds.
    samples: AtomicU64,
}

/// What one device of a team did.
#[derive(Clone, Debug)]
pub struct Share {
    pub device: String,
    pub paths: u64,
    pub seconds: f64,
    /// Samples per pixel it traced, and the ranges they were (`Claims::claimed`).
    pub samples: u64,
    pub ranges: Vec<Range<u32>>,
}

/// Several renderers of one scene sharing the samples of one render.
pub struct Team {
    members: Vec<Member>,
    claims: Arc<Claims>,
    settings: FrameSettings,
    /// The renderers count segments (`RenderOptions::count_segments`, a benchmark): only
    /// then does a snapshot read each device's counters of segments and BVH work, which
    /// only a benchmark reports.
    counted: bool,
}

impl Team {
    /// A renderer of `scene` on each of `backends`, sharing samples `range` of every pixel.
    /// The renderers are made in parallel (each compiles its pipelines and builds its BVH).
    pub fn new(
        backends: &[Backend],
        scene: &Scene,
        settings: FrameSettings,
        options: RenderOptions,
        range: Range<u32>,
    ) -> Team {
        assert!(!backends.is_empty(), "a team of no devices");
        let renderers: Vec<Renderer> = std::thread::scope(|s| {
            let made: Vec<_> = backends
                .iter()
                .map(|b| s.spawn(move || Renderer::new(b.clone(), scene, settings, options)))
                .collect();
            made.into_iter()
                .map(|h| h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)))
                .collect()
        });
        let members = renderers
            .into_iter()
            .map(|r| Member {
                name: r.backend().describe(),
                renderer: Mutex::new(r),
                paths: AtomicU64::new(0),
                micros: AtomicU64::new(0),
                gpu_nanos: AtomicU64::new(0),
                samples: AtomicU64::new(0),
            })
            .collect();
        let mut team = Team {
            members,
            claims: Arc::new(Claims::new(0..0, backends.len())),
            settings,
            counted: options.count_segments,
        };
        team.restart(range);
        team
    }

    /// Starts afresh: every accumulation empty, samples `range` to share.
    pub fn restart(&mut self, range: Range<u32>) {
        self.claims = Arc::new(Claims::new(range, self.members.len()));
        for (i, m) in self.members.iter_mut().enumerate() {
            let r = m.renderer.get_mut().expect("renderer poisoned");
            r.share(self.claims.clone(), i);
            m.paths.store(0, Ordering::Relaxed);
            m.micros.store(0, Ordering::Relaxed);
            m.gpu_nanos.store(0, Ordering::Relaxed);
            m.samples.store(0, Ordering::Relaxed);
        }
    }

    pub fn len(&self) -> usize {
        self.members.len()
    }
    pub fn is_empty(&self) -> bool {
        self.members.is_empty()
    }

    /// The devices, one line: `A + B`.
    pub fn describe(&self) -> String {
        let names: Vec<&str> = self.members.iter().map(|m| m.name.as_str()).collect();
        names.join(" + ")
    }

    /// The first device's renderer (its features, guides, BVH statistics).
    pub fn first(&self) -> MutexGuard<'_, Renderer> {
        self.members[0].renderer.lock().expect("renderer poisoned")
    }

    /// Samples per pixel of the completed rounds of every device.
    pub fn samples(&self) -> u64 {
        self.members
            .iter()
            .map(|m| m.samples.load(Ordering::Relaxed))
            .sum()
    }

    /// Paths traced since the last restart.
    pub fn paths(&self) -> u64 {
        self.members
            .iter()
            .map(|m| m.paths.load(Ordering::Relaxed))
            .sum()
    }

    /// Seconds the passes of every device took on the GPU, where timed.
    pub fn gpu_seconds(&self) -> f64 {
        self.members
            .iter()
            .map(|m| m.gpu_nanos.load(Ordering::Relaxed) as f64 * 1e-9)
            .sum()
    }

    /// Whether any device's tuner is still measuring (`Renderer::tuning`).
    pub fn tuning(&self) -> bool {
        self.members
            .iter()
            .any(|m| m.renderer.lock().expect("renderer poisoned").tuning())
    }

    /// Goes on to samples up to `end` of every pixel (the accumulation kept).
    pub fn extend(&self, end: u32) {
        self.claims.extend(end);
    }

    /// Traces until every sample is claimed and traced, `deadline` passes, or `watch`
    /// (called about every `every` from this thread, with the team to read) returns false;
    /// then every device finishes its submissions in flight and stops. One device traces on
    /// this thread, several on one thread each.
    pub fn run(
        &self,
        every: Duration,
        deadline: Option<Instant>,
        mut watch: impl FnMut(&Team) -> bool,
    ) {
        let stop = AtomicBool::new(false);
        let done = AtomicU64::new(0);
        let past = || deadline.is_some_and(|d| Instant::now() >= d);
        let trace = |m: &Member| {
            let budget = match deadline {
                Some(d) => d.saturating_duration_since(Instant::now()).min(every),
                None => every,
            };
            let mut r = m.renderer.lock().expect("renderer poisoned");
            let s = r.step(budget, u32::MAX);
            m.paths.fetch_add(s.paths, Ordering::Relaxed);
            m.micros
                .fetch_add(s.elapsed.as_micros() as u64, Ordering::Relaxed);
            m.gpu_nanos
                .fetch_add((s.gpu_seconds * 1e9) as u64, Ordering::Relaxed);
            m.samples.store(r.samples() as u64, Ordering::Relaxed);
            s.paths > 0
        };
        if let [one] = self.members.as_slice() {
            while trace(one) && watch(self) && !past() {}
            return;
        }
        std::thread::scope(|s| {
            for m in &self.members {
                let (stop, done) = (&stop, &done);
                s.spawn(move || {
                    while !stop.load(Ordering::Relaxed) && !past() && trace(m) {}
                    done.fetch_add(1, Ordering::Relaxed);
                });
            }
            let mut next = Instant::now() + every;
            while done.load(Ordering::Relaxed) < self.members.len() as u64 {
                std::thread::sleep(Duration::from_millis(5));
                if Instant::now() >= next && !stop.load(Ordering::Relaxed) {
                    next = Instant::now() + every;
                    if !watch(self) {
                        stop.store(true, Ordering::Relaxed);
                    }
                }
            }
        });
    }

    /// The exact sums of every device added (`ACCUM_WORDS` words per pixel, even then odd
    /// half) and the samples discarded as invalid.
    pub fn exact_sums(&self) -> Sums {
        let mut total: Option<Sums> = None;
        for m in &self.members {
            let sums = m.renderer.lock().expect("renderer poisoned").exact_sums();
            match &mut total {
                None => total = Some(sums),
                Some(t) => add_sums(t, &sums),
            }
        }
        total.expect("a team has a device")
    }

    /// The accumulation of every device added, read back; with one device, its own (with
    /// the counters of a benchmark: segments, BVH nodes).
    pub fn snapshot(&self) -> Snapshot {
        if let [one] = self.members.as_slice() {
            return one.renderer.lock().expect("renderer poisoned").snapshot();
        }
        let (even, odd, invalid) = self.exact_sums();
        let mut data = AccumData {
            invalid,
            ..AccumData::from_halves(decode(&even), decode(&odd))
        };
        // A second readback of every device, for a benchmark's counters alone.
        for m in self.members.iter().filter(|_| self.counted) {
            let d = m
                .renderer
                .lock()
                .expect("renderer poisoned")
                .snapshot()
                .data;
            data.segments += d.segments;
            data.node_visits += d.node_visits;
            data.primitive_tests += d.primitive_tests;
        }
        Snapshot {
            width: self.settings.width,
            height: self.settings.height,
            data,
            samples: self.samples().min(u32::MAX as u64) as u32,
        }
    }

    /// What each device did since the last restart.
    pub fn shares(&self) -> Vec<Share> {
        let claimed = self.claims.claimed();
        self.members
            .iter()
            .zip(claimed)
            .map(|(m, ranges)| Share {
                device: m.name.clone(),
                paths: m.paths.load(Ordering::Relaxed),
                seconds: m.micros.load(Ordering::Relaxed) as f64 * 1e-6,
                samples: m.samples.load(Ordering::Relaxed),
                ranges,
            })
            .collect()
    }
}
