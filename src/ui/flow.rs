//! Frames clocked by the terminal's acknowledgements. After each frame the preview writes a
//! device status query (DSR, `CSI 5 n`); every terminal answers `CSI 0 n` in order, once it
//! has read everything before it, so an answer means the frame has crossed the link (an SSH
//! connection, say) and been parsed. At most [`MAX_UNACKED`] frames are unanswered at once:
//! while the UI waits, newer images replace older ones and only the latest is drawn, as a
//! diff against what the far screen will hold. Nothing queues up in the link's buffers, so a
//! key's frame waits behind at most one frame in flight, whatever the link.
//!
//! The answers also measure the link: its round trip (the quickest answer to a small frame)
//! and its rate (a large frame's bytes over the time its answer took beyond the later of two
//! bounds: a round trip after it was written, and the previous answer), shown in the status
//! line; a frame may take [`FRAME_TIME`] of the link at that rate. A terminal that never
//! answers gets a byte budget instead, and the status line says so. Inside tmux the answers
//! come from tmux itself, so they measure the link to tmux.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// Frames written and not yet answered, at most.
pub const MAX_UNACKED: usize = 2;
/// With no answer to the first query by then, the terminal does not answer: use a budget.
pub const ANSWER_TIMEOUT: Duration = Duration::from_secs(3);
/// The budget of a terminal that does not answer, in kilobits per second (a link that a
/// remote shell commonly has; `--max-kbps` sets another).
pub const FALLBACK_KBPS: f64 = 4000.0;
/// The status query.
pub const QUERY: &[u8] = b"\x1b[5n";
/// Frames smaller than this measure the round trip, larger ones the rate.
const SMALL_FRAME: u64 = 2048;
/// Link time one frame may take: a key's frame waits behind at most one frame in flight,
/// and at most two are in the link's buffers (a backlog of at most twice this).
pub const FRAME_TIME: Duration = Duration::from_millis(60);
/// The budget of the first frames, before an answer to a large frame has measured the
/// link's rate: small, so that a slow link is not flooded at the start (0.26 s of a
/// 0.5 Mbit/s link), and large enough to measure the rate.
pub const INITIAL_BUDGET: u64 = 16 << 10;

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Mode {
    /// Waiting for the first answer.
    Probing,
    /// The terminal answers: frames are clocked by the answers.
    Acked,
    /// No answer came: frames are paced by a byte budget.
    Budget,
}

#[derive(Clone, Debug)]
struct Sent {
    at: Instant,
    bytes: u64,
}

#[derive(Clone, Debug)]
pub struct Flow {
    unacked: VecDeque<Sent>,
    mode: Mode,
    last_answer: Option<Instant>,
    /// Round trip: the quickest answer to a small frame seen lately.
    rtt: Option<Duration>,
    /// Bytes per second, smoothed.
    rate: Option<f64>,
}

impl Default for Flow {
    fn default() -> Self {
        Flow {
            unacked: VecDeque::new(),
            mode: Mode::Probing,
            last_answer: None,
            rtt: None,
            rate: None,
        }
    }
}

impl Flow {
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// Frames written and not yet answered.
    pub fn unanswered(&self) -> usize {
        self.unacked.len()
    }

    /// Whether a frame may be written now (a budget, when there is one, is the caller's).
    pub fn can_send(&self) -> bool {
        self.mode == Mode::Budget || self.unacked.len() < MAX_UNACKED
    }

    /// A frame of `bytes` (its query included) was written at `at`.
    pub fn sent(&mut self, at: Instant, bytes: u64) {
        if self.mode != Mode::Budget {
            self.unacked.push_back(Sent { at, bytes });
        }
    }

    /// The terminal answered at `at`: the oldest unanswered frame has arrived.
    pub fn answered(&mut self, at: Instant) {
        let Some(f) = self.unacked.pop_front() else {
            return;
        };
        self.mode = Mode::Acked;
        // The answer cannot come before a round trip plus the transfer after the frame was
        // written, nor before the transfer after the previous answer (the link carries one
        // frame at a time): the later of the two bounds leaves the transfer.
        let quick = at.saturating_duration_since(f.at);
        if f.bytes <= SMALL_FRAME {
            // The quickest lately: a slowly rising floor, so that a changed route shows.
            self.rtt = Some(match self.rtt {
                Some(r) if r < quick => r + (quick - r) / 8,
                _ => quick,
            });
        } else if let Some(rtt) = self.rtt {
            let after_trip = f.at + rtt;
            let start = match self.last_answer {
                Some(prev) if prev > after_trip => prev,
                _ => after_trip,
            };
            let transfer = at.saturating_duration_since(start);
            if transfer > Duration::from_micros(500) {
                let r = f.bytes as f64 / transfer.as_secs_f64();
                self.rate = Some(self.rate.map_or(r, |old| 0.7 * old + 0.3 * r));
            }
        }
        self.last_answer = Some(at);
    }

    /// Bytes a frame may take on this link: [`FRAME_TIME`] at the measured rate, and
    /// [`INITIAL_BUDGET`] before the rate is known; `None` (no limit) for a terminal that
    /// does not answer, which gets a byte budget instead.
    pub fn frame_budget(&self) -> Option<u64> {
        match (self.mode, self.rate) {
            (Mode::Budget, _) => None,
            (_, Some(r)) => Some(((r * FRAME_TIME.as_secs_f64()) as u64).max(SMALL_FRAME)),
            (_, None) => Some(INITIAL_BUDGET),
        }
    }

    /// Called now and then: with no answer ever and a query older than [`ANSWER_TIMEOUT`],
    /// the terminal does not answer, and frames go by budget from now on.
    pub fn tick(&mut self, now: Instant) {
        if self.mode == Mode::Probing
            && self
                .unacked
                .front()
                .is_some_and(|f| now.saturating_duration_since(f.at) >= ANSWER_TIMEOUT)
        {
            self.mode = Mode::Budget;
            self.unacked.clear();
        }
    }

    /// The link as measured, for the status line: `link 2.0 Mbit/s 80 ms`.
    pub fn status(&self, budget_kbps: f64) -> Option<String> {
        match self.mode {
            Mode::Probing => None,
            Mode::Budget => Some(format!(
                "no answer to status queries: {:.0} kbit/s budget",
                budget_kbps
            )),
            Mode::Acked => {
                let rate = self.rate.map_or("–".to_string(), |r| {
                    let bits = r * 8.0;
                    if bits >= 1e6 {
                        format!("{:.1} Mbit/s", bits / 1e6)
                    } else {
                        format!("{:.0} kbit/s", bits / 1e3)
                    }
                });
                let rtt = self.rtt.map_or("–".to_string(), |d| {
                    format!("{:.0} ms", d.as_secs_f64() * 1e3)
                });
                Some(format!("link {rate} {rtt}"))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    #[test]
    fn frames_beyond_the_limit_wait_for_an_answer() {
        let t = Instant::now();
        let mut f = Flow::default();
        for i in 0..MAX_UNACKED {
            assert!(f.can_send(), "frame {i}");
            f.sent(t, 1000);
        }
        assert!(!f.can_send());
        f.answered(t + ms(80));
        assert!(f.can_send());
        assert_eq!(f.mode(), Mode::Acked);
        assert_eq!(f.unanswered(), MAX_UNACKED - 1);
    }

    #[test]
    fn a_silent_terminal_gets_a_budget() {
        let t = Instant::now();
        let mut f = Flow::default();
        f.sent(t, 1000);
        f.sent(t, 1000);
        f.tick(t + ANSWER_TIMEOUT - ms(1));
        assert_eq!(f.mode(), Mode::Probing);
        assert!(!f.can_send());
        f.tick(t + ANSWER_TIMEOUT);
        assert_eq!(f.mode(), Mode::Budget);
        assert!(f.can_send());
        assert!(f.status(4000.0).unwrap().contains("budget"));
    }

    #[test]
    fn the_answers_measure_round_trip_and_rate() {
        // A 2 Mbit/s link (250 kB/s) with an 80 ms round trip.
        let t = Instant::now();
        let mut f = Flow::default();
        // A small frame on an idle link: the round trip.
        f.sent(t, 500);
        f.answered(t + ms(82));
        // Two large frames back to back: 50 kB each takes 200 ms on the link.
        let t1 = t + ms(100);
        f.sent(t1, 50_000);
        f.sent(t1, 50_000);
        f.answered(t1 + ms(80 + 200));
        f.answered(t1 + ms(80 + 400));
        let s = f.status(0.0).unwrap();
        assert_eq!(s, "link 2.0 Mbit/s 82 ms");
    }
}
