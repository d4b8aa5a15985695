//! The team live: the preview's other devices, each tracing, on its own thread, the samples
//! it claims of the preview's accumulation (`render::claims`, shared with the render
//! thread's device), and publishing its exact sums about every frame interval and when its
//! claims run out; the render thread adds them to its own device's for the frames
//! (`ui::worker`). Every sample
//! index is traced once, so the preview shows what one device would have traced. A helper
//! whose device fails (a panic on its thread: `render::failure`) gives back every sample it
//! claimed, publishes why, and ends; the render thread takes it out and the others trace
//! those samples.

use crate::common::FrameSettings;
use crate::common::accum::Sums;
use crate::render::claims::Claims;
use crate::render::failure::{DeviceFailure, contained};
use crate::render::{Backend, RenderOptions, Renderer};
use crate::scene::Scene;
use std::sync::mpsc::{Receiver, Sender, TryRecvError};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// What the render thread asks of a helper.
enum Order {
    /// Trace `scene` from now on, taking samples from `claims` as device `device`; what it
    /// publishes carries `epoch`.
    Trace {
        scene: Arc<Scene>,
        settings: FrameSettings,
        claims: Arc<Claims>,
        device: usize,
        epoch: u64,
    },
    /// Go on tracing `epoch` if its claims have samples again (a device failed and gave
    /// its back).
    Resume {
        epoch: u64,
    },
    Quit,
}

/// A helper's sums of one epoch (the render thread's count of restarts).
#[derive(Default)]
struct Published {
    epoch: u64,
    samples: u32,
    paths: u64,
    sums: Option<Arc<Sums>>,
    /// The claims it takes from, and as which device (given back if it fails).
    claims: Option<(Arc<Claims>, usize)>,
    /// Why its device failed: it traces no more.
    failed: Option<DeviceFailure>,
}

struct Helper {
    name: String,
    orders: Sender<Order>,
    published: Arc<Mutex<Published>>,
    thread: Option<JoinHandle<()>>,
}

impl Helper {
    /// What it has published (a helper that failed while holding it left it whole: every
    /// write is one assignment).
    fn published(&self) -> MutexGuard<'_, Published> {
        self.published.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// The preview's devices after the first, one thread each.
pub struct Helpers {
    helpers: Vec<Helper>,
}

impl Helpers {
    /// A helper on each of `backends`; each renders with `options`, a submission at a time,
    /// and publishes about every `every` (the render thread's frame interval).
    pub fn spawn(backends: Vec<Backend>, options: RenderOptions, every: Duration) -> Helpers {
        let helpers = backends
            .into_iter()
            .enumerate()
            .map(|(i, backend)| {
                let (orders, rx) = std::sync::mpsc::channel();
                let published = Arc::new(Mutex::new(Published::default()));
                let shared = published.clone();
                // The CPU tracer helping traces on all cores but two, so that the render
                // thread feeding the first device and the terminal's thread are not held back
                // (its own pool: rayon's work in `install` stays there).
                let pool = matches!(backend, Backend::Cpu)
                    .then(|| {
                        rayon::ThreadPoolBuilder::new()
                            .num_threads(rayon::current_num_threads().saturating_sub(2).max(1))
                            .thread_name(|i| format!("helper cpu {i}"))
                            .build()
                            .ok()
                    })
                    .flatten();
                let name = backend.describe();
                let name_of_thread = name.clone();
                let thread = std::thread::Builder::new()
                    .name(format!("render helper {}", i + 1))
                    .spawn(move || {
                        let to_run = shared.clone();
                        let ran = contained(|| match pool {
                            Some(pool) => pool.install(|| run(backend, options, every, rx, to_run)),
                            None => run(backend, options, every, rx, to_run),
                        });
                        if let Err(why) = ran {
                            fail(&shared, &name_of_thread, why);
                        }
                    })
                    .expect("spawn a helper thread");
                Helper {
                    name,
                    orders,
                    published,
                    thread: Some(thread),
                }
            })
            .collect();
        Helpers { helpers }
    }

    pub fn len(&self) -> usize {
        self.helpers.len()
    }

    pub fn is_empty(&self) -> bool {
        self.helpers.is_empty()
    }

    /// The helpers whose device failed, taken out (their threads have ended): each one's
    /// device and why. The samples each had claimed are back in its claims.
    pub fn take_failed(&mut self) -> Vec<(String, DeviceFailure)> {
        let mut failed = Vec::new();
        let mut i = 0;
        while i < self.helpers.len() {
            let why = self.helpers[i].published().failed.clone();
            match why {
                Some(why) => {
                    let mut h = self.helpers.remove(i);
                    if let Some(t) = h.thread.take() {
                        let _ = t.join();
                    }
                    failed.push((h.name.clone(), why));
                }
                None => i += 1,
            }
        }
        failed
    }

    /// Every helper goes on tracing `epoch` where it stopped, if its claims have samples
    /// again.
    pub fn resume(&self, epoch: u64) {
        for h in &self.helpers {
            let _ = h.orders.send(Order::Resume { epoch });
        }
    }

    /// Every helper traces `scene` from now on, helper `i` as device `i + 1` of `claims`
    /// (the render thread's device is 0); what each had is dropped.
    pub fn trace(
        &self,
        scene: &Arc<Scene>,
        settings: FrameSettings,
        claims: &Arc<Claims>,
        epoch: u64,
    ) {
        for (i, h) in self.helpers.iter().enumerate() {
            let _ = h.orders.send(Order::Trace {
                scene: scene.clone(),
                settings,
                claims: claims.clone(),
                device: i + 1,
                epoch,
            });
        }
    }

    /// Samples and paths the helpers have published of `epoch` (without their sums).
    pub fn progress(&self, epoch: u64) -> (u32, u64) {
        self.helpers
            .iter()
            .map(|h| {
                let p = h.published();
                if p.epoch == epoch {
                    (p.samples, p.paths)
                } else {
                    (0, 0)
                }
            })
            .fold((0, 0), |(s, n), (a, b)| (s + a, n + b))
    }

    /// The sums each helper has published of `epoch` (shared, not copied: the render thread
    /// adds them to its own device's).
    pub fn contributions(&self, epoch: u64) -> Vec<Arc<Sums>> {
        self.helpers
            .iter()
            .filter_map(|h| {
                let p = h.published();
                p.sums.clone().filter(|_| p.epoch == epoch)
            })
            .collect()
    }
}

impl Drop for Helpers {
    /// Each helper finishes its step and ends.
    fn drop(&mut self) {
        for h in &self.helpers {
            let _ = h.orders.send(Order::Quit);
        }
        for h in &mut self.helpers {
            if let Some(t) = h.thread.take() {
                let _ = t.join();
            }
        }
    }
}

/// A helper's device, `name`, failed with `why`: it gives back the samples it claimed and
/// publishes nothing more but why.
fn fail(published: &Mutex<Published>, name: &str, why: DeviceFailure) {
    let mut p = published.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((claims, device)) = p.claims.take() {
        super::give_back(&claims, device, name, &why);
    }
    *p = Published {
        epoch: p.epoch,
        failed: Some(why),
        ..Published::default()
    };
}

/// A helper's thread: idle until told to trace; then steps of one submission (so that an
/// edit is taken within a few milliseconds), publishing its sums about every `every` and
/// when its claims run out, until they do or another order comes.
fn run(
    backend: Backend,
    options: RenderOptions,
    every: Duration,
    orders: Receiver<Order>,
    published: Arc<Mutex<Published>>,
) {
    let mut renderer: Option<Renderer> = None;
    let mut epoch = 0;
    let mut tracing = false;
    let mut paths = 0u64;
    // Samples traced since the last publication, and when that was.
    let mut unpublished = false;
    let mut last_published = Instant::now();
    loop {
        // Of several orders only the last matters (a quit among them ends the thread).
        let mut last = if tracing {
            match orders.try_recv() {
                Ok(o) => Some(o),
                Err(TryRecvError::Empty) => None,
                Err(TryRecvError::Disconnected) => return,
            }
        } else {
            match orders.recv() {
                Ok(o) => Some(o),
                Err(_) => return,
            }
        };
        while let Ok(o) = orders.try_recv() {
            if matches!(last, Some(Order::Quit)) {
                break;
            }
            last = Some(o);
        }
        match last {
            Some(Order::Quit) => return,
            Some(Order::Resume { epoch: e }) => tracing |= renderer.is_some() && e == epoch,
            Some(Order::Trace {
                scene,
                settings,
                claims,
                device,
                epoch: e,
            }) => {
                let r = match renderer.as_mut() {
                    Some(r) => {
                        r.set_scene(&scene, settings);
                        r
                    }
                    None => {
                        renderer.insert(Renderer::new(backend.clone(), &scene, settings, options))
                    }
                };
                r.share(claims.clone(), device);
                epoch = e;
                paths = 0;
                tracing = true;
                unpublished = false;
                *published.lock().expect("helper poisoned") = Published {
                    epoch,
                    claims: Some((claims, device)),
                    ..Published::default()
                };
            }
            None => {}
        }
        let Some(r) = renderer.as_mut().filter(|_| tracing) else {
            continue;
        };
        let step = r.step(options.submission, u32::MAX);
        paths += step.paths;
        unpublished |= step.paths > 0;
        // No paths: its claims have run out (or the others would finish before its next
        // sample).
        let done = step.paths == 0;
        if unpublished && (done || last_published.elapsed() >= every) {
            let sums = r.exact_sums();
            let mut p = published.lock().expect("helper poisoned");
            p.samples = r.samples();
            p.paths = paths;
            p.sums = Some(Arc::new(sums));
            #[cfg(test)]
            let held = p.claims.clone().filter(|_| !done);
            drop(p);
            unpublished = false;
            last_published = Instant::now();
            // A test's failure after the render thread uploaded these sums: the next claim
            // waits for that upload.
            #[cfg(test)]
            if let Some((claims, device)) = held {
                claims.await_upload(device);
            }
        }
        tracing = !done;
    }
}
