//! The samples of a render shared by several devices (`multi`): each claims the next ones
//! when it is ready, by guided self-scheduling weighted by rate (Polychronopoulos and Kuck
//! 1987): at most half of its rate's share of what is left, so that the claims shrink
//! towards the end and the devices finish together; a device that could not finish one
//! sample before the others still claiming finish the rest stops claiming. A device that
//! fails (`release`) gives back every sample it claimed, for the others to claim again.

use std::ops::Range;
use std::sync::Mutex;

/// The samples of a render not yet claimed, and the devices' measured rates.
#[derive(Debug)]
pub struct Claims {
    state: Mutex<ClaimState>,
}

#[derive(Debug)]
struct ClaimState {
    next: u32,
    end: u32,
    /// Paths per second of each device, once measured.
    rates: Vec<Option<f64>>,
    /// The ranges each device claimed, in order.
    claimed: Vec<Vec<Range<u32>>>,
    /// Devices refused as too slow: they claim no more, and the others no longer wait on
    /// them (so the last device still claiming takes the rest, whatever the rates).
    stopped: Vec<bool>,
    /// Devices that failed: they claim no more, ever.
    failed: Vec<bool>,
    /// Samples a failed device had claimed, claimed again first, in order.
    returned: Vec<Range<u32>>,
    /// A test's device failure: device, and when it fails.
    #[cfg(test)]
    fail: Option<(usize, Fail)>,
    /// Whether a GPU's resolve pass has been given the other devices' sums (`note_upload`).
    #[cfg(test)]
    uploaded: bool,
}

/// When a test's device fails (`Claims::fail_when`; the preview's worker passes one along
/// in its tests).
#[cfg_attr(not(test), allow(dead_code))]
#[derive(Clone, Copy, Debug)]
pub(crate) enum Fail {
    /// When it asks for its claim after so many claims.
    After(u32),
    /// At its first claim after the preview's render thread has uploaded the other devices'
    /// sums to its GPU's resolve pass (`note_upload`): those sums are then stale on the GPU.
    AfterUpload,
}

impl ClaimState {
    /// Samples of every pixel not claimed (or given back).
    fn left(&self) -> u32 {
        self.end - self.next + self.returned.iter().map(|r| r.len() as u32).sum::<u32>()
    }
}

impl Claims {
    /// The samples `range` of every pixel, shared by `devices` devices.
    pub fn new(range: Range<u32>, devices: usize) -> Claims {
        Claims {
            state: Mutex::new(ClaimState {
                next: range.start,
                end: range.end.max(range.start),
                rates: vec![None; devices],
                claimed: vec![Vec::new(); devices],
                stopped: vec![false; devices],
                failed: vec![false; devices],
                returned: Vec::new(),
                #[cfg(test)]
                fail: None,
                #[cfg(test)]
                uploaded: false,
            }),
        }
    }

    /// Claims up to `want` samples of every pixel for `device`, whose measured rate is
    /// `rate` (paths per second): `(first sample, count)`, or `None` when none are left or
    /// the others still claiming would finish what is left before this device finished one
    /// sample (it is then stopped until `extend`).
    pub fn claim(&self, device: usize, want: u32, rate: Option<f64>) -> Option<(u32, u32)> {
        let mut s = self.state.lock().expect("claims poisoned");
        if let Some(r) = rate.filter(|r| r.is_finite() && *r > 0.0) {
            s.rates[device] = Some(r);
        }
        let left = s.left();
        if left == 0 || s.stopped[device] || s.failed[device] {
            return None;
        }
        let mut take = want.clamp(1, left);
        // The devices still claiming: the rates that share what is left.
        let active: Vec<Option<f64>> = (0..s.rates.len())
            .filter(|&d| !s.stopped[d] && !s.failed[d])
            .map(|d| s.rates[d])
            .collect();
        if active.len() > 1 {
            let known: Vec<f64> = active.iter().flatten().copied().collect();
            if let (Some(mine), true) = (s.rates[device], known.len() == active.len()) {
                let total: f64 = known.iter().sum();
                let share = left as f64 * mine / total;
                let fastest = known.iter().all(|&r| r <= mine);
                if share < 1.0 && !fastest {
                    s.stopped[device] = true;
                    return None;
                }
                take = take.min(((share / 2.0).floor() as u32).max(1));
            } else {
                // Until every rate is known, one sample at a time: a device not yet measured
                // may be far slower than this one.
                take = 1;
            }
        }
        // Samples given back by a failed device first, one contiguous run at a time.
        let first = match s.returned.first_mut() {
            Some(r) => {
                let first = r.start;
                take = take.min(r.len() as u32);
                r.start += take;
                if r.start == r.end {
                    s.returned.remove(0);
                }
                first
            }
            None => {
                let first = s.next;
                s.next += take;
                first
            }
        };
        s.claimed[device].push(first..first + take);
        Some((first, take))
    }

    /// `device` failed: it claims no more, and every sample it claimed (traced or not: its
    /// sums are lost with it) is given back to be claimed again, so the others still trace
    /// every sample once. The devices stopped as too slow may claim again. Returns the
    /// samples per pixel given back.
    pub fn release(&self, device: usize) -> u32 {
        let mut s = self.state.lock().expect("claims poisoned");
        s.failed[device] = true;
        let given: Vec<Range<u32>> = std::mem::take(&mut s.claimed[device]);
        let n = given.iter().map(|r| r.len() as u32).sum();
        s.returned.extend(given);
        s.stopped.iter_mut().for_each(|d| *d = false);
        n
    }

    /// Samples of every pixel not yet claimed (including those given back).
    pub fn left(&self) -> u32 {
        self.state.lock().expect("claims poisoned").left()
    }

    /// A test's device failure: `device` fails (its renderer panics, `Renderer::start_round`)
    /// when it asks for its claim after `after` claims.
    #[cfg(test)]
    pub(crate) fn fail_after(&self, device: usize, after: u32) {
        self.fail_when(device, Fail::After(after));
    }

    /// A test's device failure: `device` fails at `when`.
    #[cfg(test)]
    pub(crate) fn fail_when(&self, device: usize, when: Fail) {
        self.state.lock().expect("claims poisoned").fail = Some((device, when));
    }

    /// The preview's render thread has uploaded the other devices' sums to its GPU
    /// (`Fail::AfterUpload`).
    #[cfg(test)]
    pub(crate) fn note_upload(&self) {
        self.state.lock().expect("claims poisoned").uploaded = true;
    }

    /// Holds a helper that is to fail after the upload (`Fail::AfterUpload`) until the render
    /// thread has uploaded its published sums, so that it is still claiming then (up to a
    /// minute, then it goes on and the test sees no failure).
    #[cfg(test)]
    pub(crate) fn await_upload(&self, device: usize) {
        let until = std::time::Instant::now() + std::time::Duration::from_secs(60);
        while std::time::Instant::now() < until {
            let s = self.state.lock().expect("claims poisoned");
            if s.uploaded || !matches!(s.fail, Some((d, Fail::AfterUpload)) if d == device) {
                return;
            }
            drop(s);
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
    }

    /// Whether `device` is to fail now (`fail_when`).
    #[cfg(test)]
    pub(crate) fn failing(&self, device: usize) -> bool {
        let s = self.state.lock().expect("claims poisoned");
        s.fail.is_some_and(|(d, when)| {
            d == device
                && match when {
                    Fail::After(after) => s.claimed[d].len() as u32 >= after,
                    Fail::AfterUpload => s.uploaded,
                }
        })
    }

    /// Makes the samples up to `end` claimable too (a render continued to more samples).
    /// Devices stopped as too slow for the old end may claim again.
    pub fn extend(&self, end: u32) {
        let mut s = self.state.lock().expect("claims poisoned");
        s.end = s.end.max(end);
        s.stopped.iter_mut().for_each(|d| *d = false);
    }

    /// The samples each device claimed, as ranges in the order claimed.
    pub fn claimed(&self) -> Vec<Vec<Range<u32>>> {
        self.state.lock().expect("claims poisoned").claimed.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_device_claims_what_it_asks_for() {
        let c = Claims::new(3..10, 1);
        assert_eq!(c.claim(0, 1, None), Some((3, 1)));
        assert_eq!(c.claim(0, 4, Some(1.0)), Some((4, 4)));
        assert_eq!(c.claim(0, 4, Some(1.0)), Some((8, 2)), "never past the end");
        assert_eq!(c.claim(0, 4, Some(1.0)), None);
        assert_eq!(c.claimed(), vec![vec![3..4, 4..8, 8..10]]);
    }

    #[test]
    fn the_last_device_claiming_takes_the_rest() {
        // Two devices of about one rate, measured again between claims: the first is refused
        // as the slower (a share of 0.95 samples), then the other, now measured slower than
        // the first's last rate, must still take the rest: a refused device no longer counts.
        let c = Claims::new(0..4, 2);
        assert_eq!(c.claim(0, 1, Some(1.0)), Some((0, 1)));
        assert_eq!(c.claim(1, 1, Some(1.1)), Some((1, 1)));
        assert_eq!(c.claim(0, 4, Some(1.0)), None, "0.95 of a sample: too slow");
        assert_eq!(c.claim(1, 4, Some(0.9)), Some((2, 2)), "the only one left");
        assert_eq!(c.claim(1, 4, Some(0.9)), None);
        assert_eq!(c.claimed(), vec![vec![0..1], vec![1..2, 2..4]]);
        let c = Claims::new(0..4, 2);
        assert_eq!(c.claim(1, 1, Some(1.0)), Some((0, 1)));
        assert_eq!(c.claim(0, 1, Some(9.0)), Some((1, 1)));
        assert_eq!(c.claim(1, 1, Some(1.0)), None, "0.3 of a sample: too slow");
        assert_eq!(
            c.claim(1, 1, Some(100.0)),
            None,
            "stopped until the end moves"
        );
        c.extend(40);
        assert_eq!(
            c.claim(1, 1, Some(1.0)),
            Some((2, 1)),
            "38 more: its share is 3.8"
        );
    }

    #[test]
    fn claims_follow_the_rates_and_cover_the_range_once() {
        // A device 9× as fast as the other: until both rates are known one sample each, then
        // at most half of each one's share of what is left; the slow one stops once its
        // share is under a sample, and the fast one takes the rest.
        let c = Claims::new(0..100, 2);
        assert_eq!(c.claim(0, 50, None), Some((0, 1)));
        assert_eq!(c.claim(1, 50, Some(1.0)), Some((1, 1)));
        let (_, fast) = c.claim(0, 50, Some(9.0)).unwrap();
        assert_eq!(fast, 44, "half of 9/10 of the 98 left");
        let (_, slow) = c.claim(1, 50, Some(1.0)).unwrap();
        assert_eq!(slow, 2, "half of 1/10 of the 54 left");
        let mut taken = 2 + fast + slow;
        let mut slow_stopped = false;
        while let Some((_, n)) = c.claim(0, 50, Some(9.0)) {
            taken += n;
            if !slow_stopped {
                match c.claim(1, 50, Some(1.0)) {
                    Some((_, n)) => taken += n,
                    None => slow_stopped = true,
                }
            }
        }
        assert!(slow_stopped);
        assert_eq!(taken, 100);
        // Every sample once: the ranges tile 0..100.
        let mut all: Vec<Range<u32>> = c.claimed().concat();
        all.sort_by_key(|r| r.start);
        let mut at = 0;
        for r in all {
            assert_eq!(r.start, at);
            at = r.end;
        }
        assert_eq!(at, 100);
    }

    #[test]
    fn a_failed_device_gives_its_samples_back() {
        let c = Claims::new(0..20, 2);
        assert_eq!(c.claim(0, 3, None), Some((0, 1)));
        assert_eq!(c.claim(1, 3, None), Some((1, 1)));
        assert_eq!(
            c.claim(1, 8, Some(1.0)),
            Some((2, 1)),
            "one at a time: a rate unknown"
        );
        assert_eq!(c.claim(0, 3, Some(1.0)), Some((3, 3)));
        assert_eq!(c.left(), 14);
        assert_eq!(c.release(1), 2, "samples 1 and 2");
        assert_eq!(c.left(), 16);
        assert_eq!(
            c.claim(1, 3, Some(100.0)),
            None,
            "a failed device claims no more"
        );
        // The one device left takes the given-back samples first, a run at a time, then the
        // rest, whatever it asks for.
        assert_eq!(c.claim(0, 10, Some(1.0)), Some((1, 1)));
        assert_eq!(c.claim(0, 10, Some(1.0)), Some((2, 1)));
        assert_eq!(c.claim(0, 100, Some(1.0)), Some((6, 14)));
        assert_eq!(c.claim(0, 100, Some(1.0)), None);
        assert_eq!(c.left(), 0);
        assert!(c.claimed()[1].is_empty());
        let mut all = c.claimed()[0].clone();
        all.sort_by_key(|r| r.start);
        assert_eq!(all, vec![0..1, 1..2, 2..3, 3..6, 6..20]);
    }
}
