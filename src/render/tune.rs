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
//! than assumed, as cuDNN's autotuner chooses among equivalent kernels: the first rounds
//! alternate between the two, and the generic one is kept only if it is clearly (3 %) faster
//! per path. A scene's default tracer is then never slower than the generic one by more than
//! the noise.
//!
//! The unit of a trial is a round (a number of samples of every pixel), not a submission: a
//! large image on a slow adapter takes a round in several submissions of a few rows each, and
//! rows differ in cost (sky against ground: weekend's differ by 2×), so submissions of
//! different rows compared the rows as much as the pipelines. A round traces every row.

use crate::common::Features;

/// Timed rounds of each candidate before choosing.
const TRIALS: u32 = 5;
/// The generic pipeline must be this much faster per path to be chosen.
const MARGIN: f64 = 0.03;
/// After one round of each, a pipeline this much faster per path is chosen at once: a
/// difference no round's noise makes, and the rounds of a large image on a slow adapter are
/// seconds long (weekend 1280×720 on lavapipe: 1.1 s, the generic pipeline half as fast).
const DECISIVE: f64 = 0.3;

#[derive(Clone, Debug)]
pub struct Tune {
    /// [specialized, generic].
    candidates: [Features; 2],
    /// The fastest seconds per path seen of each, over whole rounds.
    best: [f64; 2],
    trials: [u32; 2],
    /// Rounds given to each and not refunded (`start_round`, `refund`).
    assigned: [u32; 2],
    /// Rounds timed or refunded.
    seen: u32,
}

impl Tune {
    pub fn new(specialized: Features, generic: Features) -> Tune {
        Tune {
            candidates: [specialized, generic],
            best: [f64::INFINITY; 2],
            trials: [0; 2],
            assigned: [0; 2],
            seen: 0,
        }
    }

    /// The pipeline chosen, once both have been timed enough.
    pub fn chosen(&self) -> Option<Features> {
        let [special, generic] = self.best;
        if self.trials.iter().all(|&t| t >= 1) {
            if generic < special * (1.0 - DECISIVE) {
                return Some(self.candidates[1]);
            }
            if special < generic * (1.0 - DECISIVE) {
                return Some(self.candidates[0]);
            }
        }
        (self.trials.iter().all(|&t| t >= TRIALS)).then(|| {
            if generic < special * (1.0 - MARGIN) {
                self.candidates[1]
            } else {
                self.candidates[0]
            }
        })
    }

    /// A round is about to start: the candidate to time on it (given fewer rounds so far),
    /// or None once the choice is made. Every submission of the round should use it.
    pub fn start_round(&mut self) -> Option<usize> {
        if self.chosen().is_some() {
            return None;
        }
        let i = usize::from(self.assigned[1] < self.assigned[0]);
        self.assigned[i] += 1;
        Some(i)
    }

    /// Candidate `i`'s pipeline.
    pub fn candidate(&self, i: usize) -> Features {
        self.candidates[i]
    }

    /// A round of candidate `i` traced `paths` paths in `seconds` on the GPU, all of them
    /// with its pipeline.
    pub fn record(&mut self, i: usize, paths: u64, seconds: f64) {
        if self.chosen().is_some() || paths == 0 {
            return;
        }
        self.seen += 1;
        self.best[i] = self.best[i].min(seconds / paths as f64);
        self.trials[i] += 1;
    }

    /// A round of candidate `i` that does not count (cut short by a reset, too short to
    /// time, or partly traced by the other pipeline while this one compiled): `i` is owed it.
    pub fn refund(&mut self, i: usize) {
        self.assigned[i] = self.assigned[i].saturating_sub(1);
        self.seen += 1;
    }

    /// Whether the choice is still to come: no round has finished yet, or rounds are being
    /// timed (where every round is too short to time, none ever is, and the scene's own
    /// pipeline is used).
    pub fn pending(&self) -> bool {
        self.chosen().is_none() && (self.seen == 0 || self.trials.iter().any(|&t| t > 0))
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

    /// A new tuner after `rounds` rounds, each of `parts` submissions whose costs per path
    /// are `row_cost(part)` times the candidate's: 1 µs for the specialized pipeline,
    /// `generic` seconds for the generic one.
    fn timed(rounds: u32, parts: u32, generic: f64) -> Tune {
        let (s, g) = pair();
        let mut t = Tune::new(s, g);
        let per_path = |f: Features| if f == g { generic } else { 1e-6 };
        let row_cost = |part: u32| if part.is_multiple_of(2) { 1.0 } else { 3.0 };
        for _ in 0..rounds {
            let Some(i) = t.start_round() else { break };
            let seconds: f64 = (0..parts)
                .map(|p| 1000.0 * per_path(t.candidate(i)) * row_cost(p))
                .sum();
            t.record(i, 1000 * parts as u64, seconds);
        }
        t
    }

    #[test]
    fn both_are_timed_then_the_clearly_faster_one_is_kept() {
        let (_, g) = pair();
        // The generic pipeline takes 20 % less time per path.
        let mut t = timed(2 * TRIALS, 1, 0.8e-6);
        assert_eq!(t.chosen(), Some(g));
        assert_eq!(t.start_round(), None);
    }

    #[test]
    fn within_the_margin_the_specialized_one_stays() {
        let (s, _) = pair();
        assert_eq!(timed(2 * TRIALS, 1, 0.99e-6).chosen(), Some(s));
    }

    #[test]
    fn rounds_of_cheap_and_dear_rows_compare_the_pipelines_not_the_rows() {
        // Four submissions a round, rows alternately 1× and 3× as costly; the generic
        // pipeline 5 % faster. Had the candidates alternated by submission, the specialized
        // one would have had the cheap rows and looked 2.9× faster.
        let (_, g) = pair();
        let t = timed(2 * TRIALS, 4, 0.95e-6);
        assert_eq!(t.chosen(), Some(g));
        let (special, generic) = t.measured();
        assert!((generic / special - 0.95).abs() < 1e-9);
    }

    #[test]
    fn a_decisive_difference_is_chosen_after_one_round_of_each() {
        let (s, g) = pair();
        for (generic, kept) in [(2e-6, s), (0.6e-6, g)] {
            assert_eq!(timed(2, 4, generic).chosen(), Some(kept));
        }
        // 20 % is not decisive: five rounds of each.
        assert_eq!(timed(2, 4, 0.8e-6).chosen(), None);
    }

    #[test]
    fn a_refunded_round_is_given_again() {
        let (s, g) = pair();
        let mut t = Tune::new(s, g);
        assert!(t.pending());
        assert_eq!(t.start_round(), Some(0));
        t.refund(0);
        // Refunded rounds only: too short to time, nothing pending.
        assert!(!t.pending());
        assert_eq!(t.start_round(), Some(0));
        assert_eq!(t.start_round(), Some(1));
        t.record(1, 1000, 1e-3);
        assert!(t.pending());
        assert_eq!(t.start_round(), Some(0));
    }
}
