//! Choosing between a scene's specialized tracer and the generic one by measuring both.
//!
//! Leaving out what a scene does not need is meant to make it faster. On NVIDIA's driver the
//! specialized pipelines of scenes without lights were once measured about 30 % *slower* than
//! the generic one (BENCHMARKS.md, issue 12); the cause was the BVH walk's stacks, which WGSL
//! zeroes where they are declared and which were declared inside the walk, zeroed on every
//! ray, at a cost that depended on how the driver laid out each pipeline. With the stacks at
//! module scope every specialized pipeline measured is as fast as the generic one or faster
//! (H200 1.07–1.23×, lavapipe 1.0–2.9×). The tuner stays as the guard: both pipelines render
//! the same image bit for bit (tests/specialization.rs), so the choice can be measured rather
//! than assumed, as cuDNN's autotuner chooses among equivalent kernels: the first submissions
//! alternate between the two, and the generic one is kept only if it is clearly (3 %) faster
//! per path. A scene's default tracer is then never slower than the generic one by more than
//! the noise.

use crate::gpu::Features;

/// Timed submissions of each candidate before choosing.
const TRIALS: u32 = 5;
/// The generic pipeline must be this much faster per path to be chosen.
const MARGIN: f64 = 0.03;

#[derive(Clone, Debug)]
pub struct Tune {
    /// [specialized, generic].
    candidates: [Features; 2],
    /// The fastest seconds per path seen of each.
    best: [f64; 2],
    trials: [u32; 2],
}

impl Tune {
    pub fn new(specialized: Features, generic: Features) -> Tune {
        Tune {
            candidates: [specialized, generic],
            best: [f64::INFINITY; 2],
            trials: [0; 2],
        }
    }

    /// The pipeline chosen, once both have been timed enough.
    pub fn chosen(&self) -> Option<Features> {
        (self.trials.iter().all(|&t| t >= TRIALS)).then(|| {
            if self.best[1] < self.best[0] * (1.0 - MARGIN) {
                self.candidates[1]
            } else {
                self.candidates[0]
            }
        })
    }

    /// The pipeline for the next submission: the chosen one, or the one timed less so far.
    pub fn next(&self) -> Features {
        self.chosen().unwrap_or(if self.trials[1] < self.trials[0] {
            self.candidates[1]
        } else {
            self.candidates[0]
        })
    }

    /// A submission with `features` traced `paths` paths in `seconds` on the GPU.
    pub fn observe(&mut self, features: Features, paths: u64, seconds: f64) {
        if paths == 0 || self.chosen().is_some() {
            return;
        }
        if let Some(i) = self.candidates.iter().position(|&c| c == features) {
            self.best[i] = self.best[i].min(seconds / paths as f64);
            self.trials[i] += 1;
        }
    }

    /// Seconds per path of (specialized, generic), the fastest seen.
    pub fn measured(&self) -> (f64, f64) {
        (self.best[0], self.best[1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pair() -> (Features, Features) {
        let generic = Features::generic();
        let special = Features {
            dielectrics: false,
            ..generic
        };
        (special, generic)
    }

    #[test]
    fn both_are_timed_then_the_clearly_faster_one_is_kept() {
        let (s, g) = pair();
        let mut t = Tune::new(s, g);
        for _ in 0..TRIALS {
            let f = t.next();
            // The generic pipeline takes 20 % less time per path.
            t.observe(f, 1000, if f == g { 0.8e-3 } else { 1e-3 });
            let f = t.next();
            t.observe(f, 1000, if f == g { 0.8e-3 } else { 1e-3 });
        }
        assert_eq!(t.chosen(), Some(g));
        assert_eq!(t.next(), g);
    }

    #[test]
    fn within_the_margin_the_specialized_one_stays() {
        let (s, g) = pair();
        let mut t = Tune::new(s, g);
        for _ in 0..2 * TRIALS {
            let f = t.next();
            t.observe(f, 1000, if f == g { 0.99e-3 } else { 1e-3 });
        }
        assert_eq!(t.chosen(), Some(s));
    }
}
