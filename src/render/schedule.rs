//! How much work one submission carries. Long work is cut into submissions of about
//! `target` seconds each (far below the 2 s Windows TDR and the Linux watchdogs), sized from
//! a running estimate of the cost of one path.

use std::time::Duration;

/// Pixels in the first, probing submission of a fresh renderer.
const PROBE_PIXELS: u64 = 4096;
/// Fewest paths one submission traces once the cost is known: a submission has a fixed cost
/// (measured on lavapipe: about 5 ms however small), which a cost per path learned from tiny
/// submissions would count again and again, shrinking them to a row each.
const MIN_PATHS: u64 = 4096;
/// Most samples per pixel one round takes (keeps the preview's rounds short).
const MAX_SAMPLES_PER_ROUND: u32 = 256;
/// Most samples per pixel one round takes on a software adapter. llvmpipe (Mesa's gallivm)
/// ends every loop of a shader invocation once the invocation's loops together have turned
/// 65 535 times (`LP_MAX_TGSI_LOOP_ITERATIONS`, one counter per invocation, never reset
/// between loops). The tracer loops over all the samples of its round in one invocation, so
/// a long round was cut short silently: samples missing from some pixels, an intersection
/// missed in the sample it stopped in. Measured on Mesa 22.3.6: the worst pixel of a mirror
/// ball under a map (tests/envmap.rs's scene, 8 × 8) turned about 320 times per sample: it
/// kept every sample of rounds up to 206 and 203 to 239 of rounds of 217 to 281 (BENCHMARKS.md,
/// "The lost dispatch found"). The loss was intermittent in the tests because the rounds'
/// sizes follow the measured speed. Eight samples leave 8 000 turns per sample.
const MAX_SAMPLES_PER_ROUND_SOFTWARE: u32 = 8;

#[derive(Clone, Debug)]
pub struct Schedule {
    /// Wall time one submission should take.
    pub target: Duration,
    /// Seconds per pixel-sample, as an exponential moving average; `None` before any measure.
    cost: Option<f64>,
    /// Most samples per pixel one round takes.
    max_per_round: u32,
}

impl Schedule {
    pub fn new(target: Duration) -> Schedule {
        Schedule {
            target,
            cost: None,
            max_per_round: MAX_SAMPLES_PER_ROUND,
        }
    }

    /// A schedule for a software adapter: rounds of at most
    /// `MAX_SAMPLES_PER_ROUND_SOFTWARE` samples, which llvmpipe's loop limit does not cut.
    pub fn software(target: Duration) -> Schedule {
        Schedule {
            max_per_round: MAX_SAMPLES_PER_ROUND_SOFTWARE,
            ..Schedule::new(target)
        }
    }

    /// Records that `pixel_samples` paths took `elapsed`.
    pub fn observe(&mut self, pixel_samples: u64, elapsed: Duration) {
        if pixel_samples == 0 {
            return;
        }
        let c = elapsed.as_secs_f64() / pixel_samples as f64;
        self.cost = Some(match self.cost {
            None => c,
            Some(old) => 0.7 * old + 0.3 * c,
        });
    }

    /// Paths per second, once measured.
    pub fn rate(&self) -> Option<f64> {
        self.cost.filter(|c| *c > 0.0).map(|c| 1.0 / c)
    }

    /// Samples per pixel for the next round of a `width × height` image, at most `left`.
    pub fn samples_per_round(&self, width: u32, height: u32, left: u32) -> u32 {
        let Some(cost) = self.cost else {
            return 1;
        };
        let full = cost * width as f64 * height as f64;
        let k = whole(self.target.as_secs_f64() / full);
        (k as u32).clamp(1, self.max_per_round).min(left.max(1))
    }

    /// Rows of the next submission at `k` samples per pixel, at most `left`.
    pub fn rows(&self, width: u32, k: u32, left: u32) -> u32 {
        let rows = match self.cost {
            None => PROBE_PIXELS / width.max(1) as u64,
            Some(cost) => {
                let per_row = cost * width as f64 * k as f64;
                let fewest = MIN_PATHS.div_ceil(width.max(1) as u64 * k.max(1) as u64);
                (whole(self.target.as_secs_f64() / per_row) as u64).max(fewest)
            }
        };
        // Rows left over are spread evenly: a last sliver of a round would cost a whole
        // submission's overhead.
        let rows = (rows.max(1) as u32).min(left);
        let parts = left.div_ceil(rows);
        left.div_ceil(parts)
    }
}

/// `floor(x)`, forgiving the rounding of quotients that are whole numbers on paper.
fn whole(x: f64) -> f64 {
    (x + 1e-6).floor()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn probes_small_then_sizes_submissions_to_the_target() {
        let mut s = Schedule::new(Duration::from_millis(100));
        assert_eq!(s.samples_per_round(1000, 1000, 500), 1);
        assert_eq!(
            s.rows(1000, 1, 1000),
            4,
            "the probe covers about PROBE_PIXELS"
        );
        // 1 µs per path: a full 1000×1000 sample takes 1 s, ten times the target.
        s.observe(1_000_000, Duration::from_secs(1));
        assert_eq!(s.samples_per_round(1000, 1000, 500), 1);
        assert_eq!(s.rows(1000, 1, 1000), 100);
        assert_eq!(s.rows(1000, 1, 30), 30, "never past the rows left");
        // 1 ns per path: 1 ms per full sample, so up to 100 samples per round.
        let mut fast = Schedule::new(Duration::from_millis(100));
        fast.observe(1_000_000, Duration::from_millis(1));
        assert_eq!(fast.samples_per_round(1000, 1000, 500), 100);
        assert_eq!(
            fast.samples_per_round(1000, 1000, 7),
            7,
            "never past the samples left"
        );
        assert_eq!(fast.rows(1000, 100, 1000), 1000);
        // A software adapter's rounds stay below llvmpipe's loop limit however fast it is.
        let mut soft = Schedule::software(Duration::from_millis(100));
        soft.observe(1_000_000, Duration::from_millis(1));
        assert_eq!(soft.samples_per_round(1000, 1000, 500), 8);
        assert_eq!(soft.samples_per_round(1000, 1000, 3), 3);
    }
}
