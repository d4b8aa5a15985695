//! The multi-device team: one render on several devices (every GPU of a host, or a list of
//! adapters). Each device claims the next samples of every pixel when it is ready, sized by
//! its own measured rate, and their exact fixed-point sums are added. Every sample index is
//! traced once, by whichever device claimed it, with its own random stream, so on devices
//! that compute alike the image is the one a single device makes, bit for bit (the sums do
//! not depend on the order).
//!
//! Two ways to run one: [`Team`] renders to a sample count or a time (`render`, `bench`,
//! `converge`); [`live::Helpers`] keeps the preview's other devices tracing while its first
//! device makes the frames and restarts on every edit. How much each device claims:
//! `claims`. A device that fails (its driver lost, a panic on its thread) gives back every
//! sample it claimed and its sums are left out ([`give_back`]); the others trace those
//! samples again (`failure`), so the image is still every sample's, once.

pub mod live;

use crate::common::FrameSettings;
use crate::common::accum::Sums;
use crate::common::accum::{AccumData, decode};
use crate::render::claims::Claims;
use crate::render::failure::{DeviceFailure, contained};
use crate::render::{Backend, RenderOptions, Renderer, Snapshot};
use crate::scene::Scene;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// Device `device` of `claims`, named `name`, failed with `why`: every sample it claimed goes
/// back to the others (how many per pixel is returned, and logged).
pub fn give_back(claims: &Claims, device: usize, name: &str, why: &DeviceFailure) -> u32 {
    let given = claims.release(device);
    tracing::warn!("{name} failed ({why}); its {given} samples per pixel go to the other devices");
    given
}

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
    /// Why it failed, once it has: it traces no more and its sums are left out.
    failed: Mutex<Option<DeviceFailure>>,
}

impl Member {
    fn failure(&self) -> Option<DeviceFailure> {
        self.failed.lock().expect("failure poisoned").clone()
    }

    /// Its renderer, or `None` once it has failed (a renderer that panicked while held is
    /// poisoned until its failure is recorded).
    fn renderer(&self) -> Option<MutexGuard<'_, Renderer>> {
        if self.failure().is_some() {
            return None;
        }
        self.renderer.lock().ok()
    }
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
    /// Why it failed, if it did (its samples were traced again by the others).
    pub failed: Option<String>,
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
                failed: Mutex::new(None),
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

    /// Starts afresh: every accumulation empty, samples `range` to share (a device that
    /// failed takes no part).
    pub fn restart(&mut self, range: Range<u32>) {
        self.claims = Arc::new(Claims::new(range, self.members.len()));
        for (i, m) in self.members.iter_mut().enumerate() {
            if m.failure().is_some() {
                self.claims.release(i);
                continue;
            }
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

    /// The devices that have not failed.
    fn live(&self) -> impl Iterator<Item = &Member> {
        self.members.iter().filter(|m| m.failure().is_none())
    }

    /// The first working device's renderer (its features, guides, BVH statistics).
    pub fn first(&self) -> MutexGuard<'_, Renderer> {
        self.members
            .iter()
            .find_map(Member::renderer)
            .expect("every device of the team failed")
    }

    /// Samples per pixel of the completed rounds of every working device.
    pub fn samples(&self) -> u64 {
        self.live().map(|m| m.samples.load(Ordering::Relaxed)).sum()
    }

    /// Paths the working devices traced since the last restart.
    pub fn paths(&self) -> u64 {
        self.live().map(|m| m.paths.load(Ordering::Relaxed)).sum()
    }

    /// Seconds the passes of every working device took on the GPU, where timed.
    pub fn gpu_seconds(&self) -> f64 {
        self.live()
            .map(|m| m.gpu_nanos.load(Ordering::Relaxed) as f64 * 1e-9)
            .sum()
    }

    /// Whether any device's tuner is still measuring (`Renderer::tuning`).
    pub fn tuning(&self) -> bool {
        self.members
            .iter()
            .filter_map(Member::renderer)
            .any(|r| r.tuning())
    }

    /// Makes device `device` fail at its claim after `after` claims (a test's device loss).
    #[cfg(test)]
    pub(crate) fn fail_after(&self, device: usize, after: u32) {
        self.claims.fail_after(device, after);
    }

    /// Goes on to samples up to `end` of every pixel (the accumulation kept).
    pub fn extend(&self, end: u32) {
        self.claims.extend(end);
    }

    /// Traces until every sample is claimed and traced, `deadline` passes, or `watch`
    /// (called about every `every` from this thread, with the team to read) returns false;
    /// then every device finishes its submissions in flight and stops. One device traces on
    /// this thread, several on one thread each. A device that fails on its thread gives its
    /// samples back and the others trace them; only when every device has failed does the
    /// run panic, with every device's reason (one device alone traces on this thread, and
    /// its failure is the panic it was).
    pub fn run(
        &self,
        every: Duration,
        deadline: Option<Instant>,
        mut watch: impl FnMut(&Team) -> bool,
    ) {
        let stop = AtomicBool::new(false);
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
        // Again while a failed device's samples are left and another device works (the
        // others may have stopped before it failed).
        while !stop.load(Ordering::Relaxed) && !past() && self.live().next().is_some() {
            let done = AtomicU64::new(0);
            let live: Vec<(usize, &Member)> = self
                .members
                .iter()
                .enumerate()
                .filter(|(_, m)| m.failure().is_none())
                .collect();
            std::thread::scope(|s| {
                for &(i, m) in &live {
                    let (stop, done) = (&stop, &done);
                    s.spawn(move || {
                        let traced = contained(|| {
                            while !stop.load(Ordering::Relaxed) && !past() && trace(m) {}
                        });
                        if let Err(why) = traced {
                            // Left out first, then its samples given back.
                            *m.failed.lock().expect("failure poisoned") = Some(why.clone());
                            m.samples.store(0, Ordering::Relaxed);
                            m.paths.store(0, Ordering::Relaxed);
                            give_back(&self.claims, i, &m.name, &why);
                        }
                        done.fetch_add(1, Ordering::Relaxed);
                    });
                }
                let mut next = Instant::now() + every;
                while done.load(Ordering::Relaxed) < live.len() as u64 {
                    std::thread::sleep(Duration::from_millis(5));
                    if Instant::now() >= next && !stop.load(Ordering::Relaxed) {
                        next = Instant::now() + every;
                        if !watch(self) {
                            stop.store(true, Ordering::Relaxed);
                        }
                    }
                }
            });
            if self.claims.left() == 0 || live.iter().all(|(_, m)| m.failure().is_none()) {
                break;
            }
        }
        if self.live().next().is_none() {
            let why: Vec<String> = self
                .members
                .iter()
                .filter_map(|m| Some(m.failure()?.0))
                .collect();
            panic!("every device failed: {}", why.join("; "));
        }
    }

    /// The exact sums of every device added (`ACCUM_WORDS` words per pixel, even then odd
    /// half) and the samples discarded as invalid.
    pub fn exact_sums(&self) -> Sums {
        let mut total: Option<Sums> = None;
        for r in self.members.iter().filter_map(Member::renderer) {
            let sums = r.exact_sums();
            match &mut total {
                None => total = Some(sums),
                Some(t) => t.add(&sums),
            }
        }
        total.expect("a team has a working device")
    }

    /// The accumulation of every device added, read back; with one device, its own (with
    /// the counters of a benchmark: segments, BVH nodes).
    pub fn snapshot(&self) -> Snapshot {
        if let [one] = self.members.as_slice() {
            return one.renderer.lock().expect("renderer poisoned").snapshot();
        }
        let Sums { even, odd, invalid } = self.exact_sums();
        let mut data = AccumData {
            invalid,
            ..AccumData::from_halves(decode(&even), decode(&odd))
        };
        // A second readback of every device, for a benchmark's counters alone.
        if self.counted {
            for r in self.members.iter().filter_map(Member::renderer) {
                let d = r.snapshot().data;
                data.segments += d.segments;
                data.node_visits += d.node_visits;
                data.primitive_tests += d.primitive_tests;
            }
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
                failed: m.failure().map(|f| f.0),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings() -> FrameSettings {
        FrameSettings::new(24, 16, 6, 1)
    }

    #[test]
    fn a_failed_device_s_samples_are_traced_by_the_others() {
        // Two CPU tracers, the second lost at its third claim (its renderer panics, as one
        // waiting on a lost GPU does): the first traces every sample the second had, and the
        // image is one device's bit for bit.
        let scene = Scene::load("showcase").unwrap();
        let spp = 24;
        let one = Team::new(
            &[Backend::Cpu],
            &scene,
            settings(),
            RenderOptions::default(),
            0..spp,
        );
        one.run(Duration::from_millis(20), None, |_| true);
        let team = Team::new(
            &[Backend::Cpu, Backend::Cpu],
            &scene,
            settings(),
            RenderOptions::default(),
            0..spp,
        );
        team.fail_after(1, 2);
        team.run(Duration::from_millis(20), None, |_| true);
        let shares = team.shares();
        assert!(shares[0].failed.is_none(), "{shares:?}");
        let why = shares[1]
            .failed
            .as_deref()
            .expect("the second device failed");
        assert!(why.contains("injected"), "{why}");
        assert!(shares[1].ranges.is_empty(), "its claims given back");
        assert_eq!(team.samples(), spp as u64);
        let mut ranges = shares[0].ranges.clone();
        ranges.sort_by_key(|r| r.start);
        let covered: u32 = ranges.iter().map(|r| r.len() as u32).sum();
        assert_eq!(covered, spp, "{ranges:?}");
        assert!(ranges.windows(2).all(|w| w[0].end == w[1].start));
        assert_eq!(team.exact_sums(), one.exact_sums());
    }
}
