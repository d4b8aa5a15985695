//! Samples claimed in stages aimed at a target error: `render --target-error` and the
//! preview's `--target-error` stop where the estimate reaches the target, not where a clock
//! happened to look at it.
//!
//! The estimate falls as 1/√n (the halves' relMSE, `common::estimate`), so a stage that ends
//! at `n` samples with estimate `e` is followed by one ending at `n·(e/E)²`, at most twice the
//! samples (an estimate early on is rough, and a stage too long goes far past the target).
//! A check by the clock alone stopped far past the target on a small image: 500 ms of samples
//! at 96×54 took `basic` to 0.04 of a 5 % target (BENCHMARKS.md, "An honest error estimate").

/// Samples per pixel of the first stage: two in each half, the fewest that give an estimate.
pub const FIRST_STAGE_SPP: u32 = 4;

/// Where the first stage ends, of `max` samples in all: with a target error FIRST_STAGE_SPP,
/// without one all `max` at once.
pub fn first_end(target: Option<f64>, max: u32) -> u32 {
    match target {
        Some(_) => max.min(FIRST_STAGE_SPP),
        None => max,
    }
}

/// What follows a stage whose samples are all traced.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Next {
    /// The estimate is at or below the target: stop.
    Reached,
    /// Every sample allowed is traced, short of the target.
    Exhausted,
    /// Trace on to this many samples per pixel.
    To(u32),
}

/// The stage after one that ended at `end` samples per pixel with error estimate `noise`
/// (`None`: no estimate, as for a black image), aiming at `target`, `max` samples at most.
pub fn next(end: u32, noise: Option<f64>, target: f64, max: u32) -> Next {
    match noise {
        Some(n) if n <= target => Next::Reached,
        _ if end >= max => Next::Exhausted,
        Some(n) => {
            let want = (end as f64 * (n / target).powi(2)).ceil();
            Next::To((want.min(2.0 * end as f64) as u32).max(end + 1).min(max))
        }
        None => Next::To(end.saturating_mul(2).min(max)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stage_aims_at_the_target_falling_as_one_over_root_n() {
        // 1.2 × the target at 100 samples: 144 more would reach it.
        assert_eq!(next(100, Some(0.06), 0.05, 10_000), Next::To(144));
        // Far from it: at most twice the samples.
        assert_eq!(next(4, Some(0.9), 0.05, 10_000), Next::To(8));
        // Just above it: at least one sample more.
        assert_eq!(next(100, Some(0.050_001), 0.05, 10_000), Next::To(101));
    }

    #[test]
    fn a_stage_stops_at_the_target_or_the_limit() {
        assert_eq!(next(64, Some(0.05), 0.05, 100), Next::Reached);
        assert_eq!(next(100, Some(0.07), 0.05, 100), Next::Exhausted);
        assert_eq!(next(80, Some(0.07), 0.05, 100), Next::To(100));
        assert_eq!(next(4, None, 0.05, 100), Next::To(8));
        assert_eq!(first_end(Some(0.05), 16_384), FIRST_STAGE_SPP);
        assert_eq!(first_end(Some(0.05), 2), 2);
        assert_eq!(first_end(None, 16_384), 16_384);
    }
}
