//! `termtrace bench --preview`: the live preview measured as a user sees it. The real binary
//! runs in a pseudo-terminal (portable-pty) whose output a terminal emulator (vt100) reads;
//! an edit key is typed again and again, and each time the harness waits for the screen to
//! show the edited value with a restarted sample count. Reported: key → frame latency
//! (median, worst, misses), frames/s and output bytes/s while converging, and the samples/s
//! the status line shows.

use anyhow::{Context, bail};
use portable_pty::{CommandBuilder, PtySize, native_pty_system};
use std::io::{Read, Write};
use std::path::PathBuf;
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// What to measure.
#[derive(Clone, Debug)]
pub struct PreviewBench {
    /// The termtrace binary to run (another build, to compare before and after).
    pub exe: PathBuf,
    pub scene: String,
    pub cols: u16,
    pub rows: u16,
    /// Key presses to time; they alternate between `+` and `-` (the selected object's first
    /// parameter, a fine step up and down).
    pub presses: usize,
    /// Time the accumulation runs before each press.
    pub settle: Duration,
    /// A press whose frame has not shown by then is a miss.
    pub timeout: Duration,
    /// Seconds of converging over which frames/s and bytes/s are measured.
    pub window: Duration,
    /// Extra arguments for the preview (`--adapter …`, `--fps …`).
    pub args: Vec<String>,
}

/// What was measured.
#[derive(Clone, Debug, Default)]
pub struct PreviewReport {
    /// The status line's traced size, e.g. `120×76`.
    pub size: String,
    /// Key → frame, one per press that showed (seconds).
    pub latencies: Vec<f64>,
    pub misses: usize,
    pub fps: f64,
    pub bytes_per_second: f64,
    /// The status line's samples/s at the end of the window, as it reads.
    pub samples_per_second: String,
    /// Samples per pixel seen before each press and right after it (the restarted count).
    pub restarts: Vec<(u64, u64)>,
    /// The parameter line before and after each press.
    pub edits: Vec<(String, String)>,
    /// Output bytes from each press until its frame had been read.
    pub edit_bytes: Vec<u64>,
    /// Of each latency, the seconds the emulator and harness spent parsing that output.
    pub edit_parse: Vec<f64>,
}

impl PreviewReport {
    pub fn median(&self) -> Option<f64> {
        let mut v = self.latencies.clone();
        v.sort_by(f64::total_cmp);
        (!v.is_empty()).then(|| v[v.len() / 2])
    }
    pub fn worst(&self) -> Option<f64> {
        self.latencies.iter().copied().reduce(f64::max)
    }
}

/// The screen as the harness reads it.
#[derive(Clone, Debug, Default)]
struct Seen {
    spp: Option<u64>,
    /// The status line's size and rate fields.
    size: String,
    rate: String,
    params: String,
    /// Output bytes and synchronized updates (frames) so far, and the time the emulator and
    /// this harness have spent parsing and reading them (not termtrace's share of a latency).
    bytes: u64,
    parse: Duration,
    frames: u64,
    /// Every change of what the screen shows of spp or parameters: when it was read, and
    /// the output bytes by then.
    history: Vec<(Instant, Option<u64>, String, u64, Duration)>,
    exited: bool,
}

struct Shared {
    seen: Mutex<Seen>,
    cond: Condvar,
}

/// Reads the status lines off the emulated screen: its last two rows (the whole screen would
/// cost the harness more than the terminal's parsing, on every read of a large frame).
fn read_status(screen: &vt100::Screen, seen: &mut Seen) {
    let (rows, cols) = screen.size();
    let (rows, cols) = (rows.get(), cols.get());
    let text = screen.contents_between(rows.saturating_sub(2), 0, rows - 1, cols);
    let stats = text.lines().find(|l| l.contains(" spp"));
    let params = text.lines().find(|l| l.trim_start().starts_with('▸'));
    if let Some(line) = stats {
        let fields: Vec<&str> = line.split('│').map(str::trim).collect();
        seen.spp = fields
            .iter()
            .find_map(|f| f.strip_suffix(" spp").and_then(|n| n.trim().parse().ok()));
        if let Some(f) = fields.iter().find(|f| f.contains('×')) {
            seen.size = f.to_string();
        }
        if let Some(f) = fields.iter().find(|f| f.ends_with("s/s")) {
            seen.rate = f.to_string();
        }
    }
    if let Some(p) = params {
        seen.params = p.trim().to_string();
    }
}

const SYNC_BEGIN: &[u8] = b"\x1b[?2026h";

impl PreviewBench {
    pub fn run(&self) -> anyhow::Result<PreviewReport> {
        let pty = native_pty_system()
            .openpty(PtySize {
                rows: self.rows,
                cols: self.cols,
                pixel_width: self.cols * 10,
                pixel_height: self.rows * 20,
            })
            .context("cannot open a pseudo-terminal")?;
        // A relative path would be looked up in PATH.
        let exe = std::fs::canonicalize(&self.exe)
            .with_context(|| format!("no termtrace binary at {}", self.exe.display()))?;
        let mut cmd = CommandBuilder::new(&exe);
        cmd.arg("view");
        cmd.arg(&self.scene);
        cmd.args(&self.args);
        cmd.env("TERM", "xterm-256color");
        cmd.env("COLORTERM", "truecolor");
        let mut child = pty
            .slave
            .spawn_command(cmd)
            .with_context(|| format!("cannot run {}", self.exe.display()))?;
        drop(pty.slave);
        let mut reader = pty.master.try_clone_reader()?;
        let mut writer = pty.master.take_writer()?;
        let shared = Arc::new(Shared {
            seen: Mutex::new(Seen::default()),
            cond: Condvar::new(),
        });
        let (rows, cols) = (self.rows, self.cols);
        let sh = shared.clone();
        let reader_thread = std::thread::spawn(move || {
            let nz = |n: u16| std::num::NonZeroU16::new(n.max(1)).expect("at least 1");
            let mut parser = vt100::Parser::new(nz(rows), nz(cols), 0);
            let mut buf = vec![0u8; 1 << 16];
            // The last bytes of the previous chunk: a marker split across reads still
            // counts, and none is counted twice (the tail is shorter than a marker).
            let mut tail: Vec<u8> = Vec::new();
            loop {
                let n = match reader.read(&mut buf) {
                    Ok(0) | Err(_) => break,
                    Ok(n) => n,
                };
                let parse_start = Instant::now();
                parser.process(&buf[..n]);
                tail.extend_from_slice(&buf[..n]);
                let frames = tail
                    .windows(SYNC_BEGIN.len())
                    .filter(|w| *w == SYNC_BEGIN)
                    .count() as u64;
                tail.drain(..tail.len().saturating_sub(SYNC_BEGIN.len() - 1));
                let mut s = sh.seen.lock().expect("screen state");
                let before = (s.spp, s.params.clone());
                read_status(parser.screen(), &mut s);
                let parsed = parse_start.elapsed();
                s.bytes += n as u64;
                s.parse += parsed;
                s.frames += frames;
                if (s.spp, s.params.clone()) != before {
                    let change = (Instant::now(), s.spp, s.params.clone(), s.bytes, s.parse);
                    s.history.push(change);
                }
                sh.cond.notify_all();
            }
            let mut s = sh.seen.lock().expect("screen state");
            s.exited = true;
            sh.cond.notify_all();
        });

        let result = self.drive(&shared, &mut *writer);
        let _ = writer.write_all(b"q");
        let _ = writer.flush();
        let deadline = Instant::now() + Duration::from_secs(10);
        while Instant::now() < deadline {
            if child.try_wait()?.is_some() {
                break;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        if child.try_wait()?.is_none() {
            let _ = child.kill();
        }
        drop(writer);
        drop(pty.master);
        let _ = reader_thread.join();
        result
    }

    /// Waits until `pred` holds of the screen, or `timeout`; returns the screen then.
    fn wait_for(
        shared: &Shared,
        timeout: Duration,
        pred: impl Fn(&Seen) -> bool,
    ) -> Option<(Instant, Seen)> {
        let deadline = Instant::now() + timeout;
        let mut s = shared.seen.lock().expect("screen state");
        loop {
            if pred(&s) {
                return Some((Instant::now(), s.clone()));
            }
            let now = Instant::now();
            if now >= deadline || s.exited {
                return None;
            }
            s = shared
                .cond
                .wait_timeout(s, deadline - now)
                .expect("screen state")
                .0;
        }
    }

    fn drive(&self, shared: &Shared, keys: &mut dyn Write) -> anyhow::Result<PreviewReport> {
        let startup = Duration::from_secs(120);
        if Self::wait_for(shared, startup, |s| s.spp.is_some_and(|n| n >= 1)).is_none() {
            let s = shared.seen.lock().expect("screen state").clone();
            bail!(
                "the preview showed no frame within {} s (exited: {}, last status {:?})",
                startup.as_secs(),
                s.exited,
                s
            );
        }
        let mut report = PreviewReport::default();
        for i in 0..self.presses {
            std::thread::sleep(self.settle);
            // A restart must be visible: at least 2 spp before the key.
            let Some((_, before)) =
                Self::wait_for(shared, startup, |s| s.spp.is_some_and(|n| n >= 2))
            else {
                bail!("the preview stopped accumulating");
            };
            let key: &[u8] = if i % 2 == 0 { b"+" } else { b"-" };
            let spp_before = before.spp.unwrap_or(0);
            let t0 = Instant::now();
            keys.write_all(key)?;
            keys.flush()?;
            let shown = Self::wait_for(shared, self.timeout, |s| {
                s.params != before.params && s.spp.is_some_and(|n| n < spp_before)
            });
            match shown {
                Some((now, after)) => {
                    // The first screen after the key that showed the edit.
                    let at = after
                        .history
                        .iter()
                        .find(|(t, spp, params, _, _)| {
                            *t >= t0
                                && *params != before.params
                                && spp.is_some_and(|n| n < spp_before)
                        })
                        .map_or((now, after.bytes, after.parse), |h| (h.0, h.3, h.4));
                    report
                        .latencies
                        .push(at.0.saturating_duration_since(t0).as_secs_f64());
                    report.edit_bytes.push(at.1 - before.bytes);
                    report.edit_parse.push((at.2 - before.parse).as_secs_f64());
                    report.restarts.push((spp_before, after.spp.unwrap_or(0)));
                    report.edits.push((before.params.clone(), after.params));
                }
                None => {
                    report.misses += 1;
                    // Let it show before the next press, so presses stay independent.
                    Self::wait_for(shared, startup, |s| s.params != before.params);
                }
            }
        }
        // Converging: frames and bytes over the window, after a restart.
        keys.write_all(b"r")?;
        keys.flush()?;
        std::thread::sleep(Duration::from_millis(100));
        let (f0, b0, t0) = {
            let s = shared.seen.lock().expect("screen state");
            (s.frames, s.bytes, Instant::now())
        };
        std::thread::sleep(self.window);
        let s = shared.seen.lock().expect("screen state").clone();
        let secs = t0.elapsed().as_secs_f64();
        report.fps = (s.frames - f0) as f64 / secs;
        report.bytes_per_second = (s.bytes - b0) as f64 / secs;
        report.samples_per_second = s.rate.clone();
        report.size = s.size.clone();
        Ok(report)
    }
}

/// Prints a report as `bench` does.
pub fn print(b: &PreviewBench, r: &PreviewReport) {
    let ms = |x: Option<f64>| x.map_or("–".to_string(), |v| format!("{:.0} ms", v * 1e3));
    println!(
        "preview      {} in a {}x{} terminal, traced at {}, {}",
        b.scene,
        b.cols,
        b.rows,
        r.size,
        b.exe.display()
    );
    println!(
        "key → frame  median {}, worst {}, {} of {} presses missed (not shown within {:.1} s)",
        ms(r.median()),
        ms(r.worst()),
        r.misses,
        b.presses,
        b.timeout.as_secs_f64()
    );
    let all: Vec<String> = r
        .latencies
        .iter()
        .map(|v| format!("{:.0}", v * 1e3))
        .collect();
    println!("latencies    {} ms", all.join(" "));
    let mut bytes = r.edit_bytes.clone();
    bytes.sort_unstable();
    let mut parse = r.edit_parse.clone();
    parse.sort_by(f64::total_cmp);
    if let (Some(b), Some(p)) = (bytes.get(bytes.len() / 2), parse.get(parse.len() / 2)) {
        println!(
            "edit frames  {:.0} kB of output from a key to its frame, {:.0} ms of it parsing in the emulator and harness (medians)",
            *b as f64 / 1e3,
            p * 1e3
        );
    }
    println!(
        "converging   {:.1} frames/s, {:.1} kB/s of output, status line {}",
        r.fps,
        r.bytes_per_second / 1e3,
        r.samples_per_second
    );
}
