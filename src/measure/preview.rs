//! `termtrace bench --preview`: the live preview measured as a user sees it. The real binary
//! runs in a pseudo-terminal (portable-pty) whose output a terminal emulator (vt100) reads;
//! an edit key is typed again and again, and each time the harness waits for the screen to
//! show the edited value with a restarted sample count. Reported: key → frame latency
//! (median, worst, misses), frames/s and output bytes/s while converging, and the samples/s
//! the status line shows.

use super::MeasureError;
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
    /// Put a model of a slow link between the program and the terminal.
    pub link: Option<Link>,
    /// Run this command line instead of `exe view scene args` (e.g. `ssh -tt … termtrace …`).
    pub command: Option<Vec<String>>,
    /// When set, the far terminal answers a status query only while this holds a positive
    /// count (taking one); later answers wait, in order, until it is raised (tests of the
    /// frame clock). `None`: every query is answered.
    pub answer_gate: Option<Arc<std::sync::atomic::AtomicI64>>,
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
    /// Most bytes written by the program and not yet on the far screen, at any moment.
    pub deepest_backlog: u64,
    /// Frames/s and bytes/s over the last quarter of the window (the noise has fallen).
    pub last_quarter: (f64, f64),
    /// Frames/s over the first second after a restart (0.1 s to 1.1 s), while the image
    /// changes most: what "frames/s while converging" means once a fast backend settles
    /// the image within the window and the preview slows to its idle rate.
    pub first_second_fps: f64,
    /// Pixel-graphics images/s and bytes/s over the first two seconds after a restart, and
    /// images/s over the last quarter of the window.
    pub images: (f64, f64, f64),
    /// The status line's link field at the end (`link 2.0 Mbit/s 80 ms`).
    pub link_status: Option<String>,
    /// Seconds from starting the program to its first frame on the far screen (the scene
    /// loaded, its BVH built, the pipeline made and a first sample traced and drawn).
    pub first_frame: f64,
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
    /// The status line's time since the accumulation started, in seconds.
    elapsed: Option<f64>,
    /// The status line's size and rate fields.
    size: String,
    rate: String,
    params: String,
    /// Output bytes and synchronized updates (frames) so far, and the time the emulator and
    /// this harness have spent parsing and reading them (not termtrace's share of a latency).
    bytes: u64,
    parse: Duration,
    frames: u64,
    /// Images sent by pixel graphics (kitty transmissions, sixel DCS, iTerm2 files).
    images: u64,
    /// Most bytes read from the program and not yet delivered, at any moment.
    deepest_backlog: u64,
    /// The status line's link field (`link 2.0 Mbit/s 80 ms`), when shown.
    link: Option<String>,
    /// Every change of what the screen shows of spp or parameters.
    history: Vec<Change>,
    exited: bool,
}

/// What the status lines showed at one moment, and the output by then.
#[derive(Clone, Debug)]
struct Change {
    at: Instant,
    spp: Option<u64>,
    params: String,
    elapsed: Option<f64>,
    bytes: u64,
    parse: Duration,
}

struct Shared {
    seen: Mutex<Seen>,
    /// The far terminal's screen.
    parser: Mutex<Option<vt100::Parser>>,
    cond: Condvar,
    /// When the program was started.
    started: Instant,
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
        seen.elapsed = fields
            .iter()
            .find_map(|f| f.strip_suffix(" s").and_then(|n| n.parse().ok()));
        if let Some(f) = fields.iter().find(|f| f.contains('×')) {
            seen.size = f.to_string();
        }
        if let Some(f) = fields.iter().find(|f| f.ends_with("s/s")) {
            seen.rate = f.to_string();
        }
        seen.link = fields
            .iter()
            .find(|f| f.starts_with("link ") || f.starts_with("no answer"))
            .map(|f| f.to_string());
    }
    if let Some(p) = params {
        seen.params = p.trim().to_string();
    }
}

const SYNC_BEGIN: &[u8] = b"\x1b[?2026h";

/// A model of the link between termtrace and the user's terminal (an SSH connection): the
/// program's output is read eagerly into a window of `window` bytes (OpenSSH's channel
/// window; past it the program blocks), leaves at the link's rate and reaches the terminal
/// half a round trip later; keys and the terminal's answers take half a round trip back.
#[derive(Clone, Copy, Debug)]
pub struct Link {
    pub bits_per_second: f64,
    pub rtt: Duration,
    pub window: usize,
}

/// OpenSSH's default channel window.
pub const SSH_WINDOW: usize = 2 << 20;

/// Bytes the link model moves at once.
const PIECE: usize = 4096;
/// The status query the terminal answers (see `ui::flow`), and its answer.
const QUERY: &[u8] = b"\x1b[5n";
const ANSWER: &[u8] = b"\x1b[0n";
/// Primary device attributes, which the preview asks once to learn the terminal's graphics,
/// and the emulator's answer as a VT220 without sixel would give it (vt100 draws text only).
const DA1: &[u8] = b"\x1b[c";
const DA1_ANSWER: &[u8] = b"\x1b[?62;22c";
/// How an image of each pixel-graphics protocol begins: kitty's transmission, sixel's DCS
/// (`ESC P 0;1;0 q`, and the like: any DCS, which the preview sends only for sixel), iTerm2's file.
const IMAGE_STARTS: [&[u8]; 3] = [b"\x1b_Ga=T", b"\x1bP", b"\x1b]1337;File"];

/// Output read from the program and not yet on the link.
struct Pipe {
    bytes: Mutex<(std::collections::VecDeque<u8>, bool)>,
    cond: Condvar,
}

/// Counts `pattern` in `data` preceded by `tail` (the end of the previous data); keeps the
/// new tail. The tail is shorter than the pattern, so nothing is counted twice.
fn count_split(tail: &mut Vec<u8>, data: &[u8], pattern: &[u8]) -> u64 {
    tail.extend_from_slice(data);
    let n = tail
        .windows(pattern.len())
        .filter(|w| *w == pattern)
        .count() as u64;
    tail.drain(..tail.len().saturating_sub(pattern.len() - 1));
    n
}

impl PreviewBench {
    /// `exe view scene` in a `cols × rows` terminal, nothing typed, no link between: the
    /// fields to set for a run start from here.
    pub fn new(exe: impl Into<PathBuf>, scene: &str, cols: u16, rows: u16) -> PreviewBench {
        PreviewBench {
            exe: exe.into(),
            scene: scene.to_string(),
            cols,
            rows,
            presses: 0,
            settle: Duration::ZERO,
            timeout: Duration::from_secs(60),
            window: Duration::ZERO,
            args: Vec::new(),
            link: None,
            command: None,
            answer_gate: None,
        }
    }

    /// The termtrace binary, as an absolute path (a relative one would be looked up in PATH).
    pub fn exe_path(&self) -> Result<std::path::PathBuf, MeasureError> {
        std::fs::canonicalize(&self.exe).map_err(MeasureError::io(format!(
            "no termtrace binary at {}",
            self.exe.display()
        )))
    }

    /// Runs the preview, types the edit keys and measures (see the module's doc).
    pub fn run(&self) -> Result<PreviewReport, MeasureError> {
        self.run_with(|probe| self.drive(probe))?
    }

    /// Runs the preview and hands `f` the screen and the keyboard; returns what `f` returns.
    pub fn run_with<R>(&self, f: impl FnOnce(&Probe<'_>) -> R) -> Result<R, MeasureError> {
        let pty = native_pty_system()
            .openpty(PtySize {
                rows: self.rows,
                cols: self.cols,
                pixel_width: self.cols * 10,
                pixel_height: self.rows * 20,
            })
            .map_err(MeasureError::pty("cannot open a pseudo-terminal"))?;
        let cmd = self.command()?;
        let what = format!(
            "cannot run {:?}",
            self.command
                .as_ref()
                .unwrap_or(&vec![self.exe.display().to_string()])
        );
        let mut child = pty
            .slave
            .spawn_command(cmd)
            .map_err(MeasureError::pty(&what))?;
        drop(pty.slave);
        let reader = pty
            .master
            .try_clone_reader()
            .map_err(MeasureError::pty("the pseudo-terminal's reader"))?;
        let writer = pty
            .master
            .take_writer()
            .map_err(MeasureError::pty("the pseudo-terminal's writer"))?;
        let shared = Arc::new(Shared {
            seen: Mutex::new(Seen::default()),
            parser: Mutex::new(None),
            cond: Condvar::new(),
            started: Instant::now(),
        });
        let link = self.link.unwrap_or(Link {
            bits_per_second: f64::INFINITY,
            rtt: Duration::ZERO,
            window: 1 << 20,
        });
        let half_rtt = link.rtt / 2;
        // To the program: keys and answers, each due half a round trip after it was sent.
        let (to_program, due) = std::sync::mpsc::channel::<(Instant, Vec<u8>)>();
        let writer_thread = std::thread::spawn(move || write_due(writer, due));
        // From the program: read eagerly into the window; past it the program blocks.
        let pipe = Arc::new(Pipe {
            bytes: Mutex::new((std::collections::VecDeque::new(), false)),
            cond: Condvar::new(),
        });
        let (p, window) = (pipe.clone(), link.window);
        let reader_thread = std::thread::spawn(move || read_into(reader, &p, window));
        // The link and the far terminal.
        let far = FarEnd {
            shared: shared.clone(),
            pipe: pipe.clone(),
            answers: to_program.clone(),
            gate: self.answer_gate.clone(),
            link,
            size: (self.rows, self.cols),
        };
        let far_thread = std::thread::spawn(move || far.run());

        let result = f(&Probe {
            shared: &shared,
            keys: &to_program,
            half_rtt,
        });
        let _ = to_program.send((Instant::now(), b"q".to_vec()));
        let deadline = Instant::now() + Duration::from_secs(20);
        while Instant::now() < deadline {
            if child.try_wait()?.is_some() {
                break;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        if child.try_wait()?.is_none() {
            let _ = child.kill();
        }
        drop(to_program);
        drop(pty.master);
        // The reader may wait for room in the window: there is room once the far end ends.
        pipe.bytes.lock().expect("pipe").0.clear();
        pipe.cond.notify_all();
        let _ = reader_thread.join();
        let _ = far_thread.join();
        let _ = writer_thread.join();
        Ok(result)
    }

    /// The program to run in the pseudo-terminal: the command given, else `termtrace view`
    /// of the scene, started in the current folder with a truecolor xterm's environment.
    fn command(&self) -> Result<CommandBuilder, MeasureError> {
        let mut cmd = match &self.command {
            Some(c) => {
                let mut cmd = CommandBuilder::new(&c[0]);
                cmd.args(&c[1..]);
                cmd
            }
            None => {
                let mut cmd = CommandBuilder::new(self.exe_path()?);
                cmd.arg("view");
                cmd.arg(&self.scene);
                cmd.args(&self.args);
                cmd
            }
        };
        // portable-pty starts the program in the home directory unless told: a scene named
        // relative to where the bench runs must be found.
        if let Ok(dir) = std::env::current_dir() {
            cmd.cwd(dir);
        }
        cmd.env("TERM", "xterm-256color");
        cmd.env("COLORTERM", "truecolor");
        Ok(cmd)
    }

    /// Types the keys (each reaching the program `half_rtt` after it is typed) and measures.
    fn drive(&self, probe: &Probe<'_>) -> Result<PreviewReport, MeasureError> {
        let shared = probe.shared;
        let type_key = |k: &[u8]| probe.type_key(k);
        let startup = Duration::from_secs(120);
        let Some((first, _)) = wait_for(shared, startup, |s| s.spp.is_some_and(|n| n >= 1)) else {
            let s = shared.seen.lock().expect("screen state").clone();
            return Err(MeasureError::Preview(format!(
                "the preview showed no frame within {} s (exited: {}, last status {:?})",
                startup.as_secs(),
                s.exited,
                s
            )));
        };
        let mut report = PreviewReport {
            first_frame: first
                .saturating_duration_since(shared.started)
                .as_secs_f64(),
            ..Default::default()
        };
        for i in 0..self.presses {
            std::thread::sleep(self.settle);
            // A restart must be visible: at least 2 spp before the key.
            let Some((_, before)) = wait_for(shared, startup, |s| s.spp.is_some_and(|n| n >= 2))
            else {
                return Err(MeasureError::Preview(
                    "the preview stopped accumulating".into(),
                ));
            };
            let key: &[u8] = if i % 2 == 0 { b"+" } else { b"-" };
            let spp_before = before.spp.unwrap_or(0);
            let t0 = Instant::now();
            type_key(key);
            // The edit is shown when the status line has the new value and its accumulation
            // restarted after the key: fewer spp than before, or (on a fast GPU behind a slow
            // link, whose count may pass the old one before the first frame arrives) a time
            // since the start shorter than the time since the key.
            let restarted = |spp: Option<u64>, elapsed: Option<f64>, at: Instant| {
                spp.is_some_and(|n| n < spp_before)
                    || elapsed.is_some_and(|e| e <= at.duration_since(t0).as_secs_f64() + 0.05)
            };
            let shown = wait_for(shared, self.timeout, |s| {
                s.params != before.params && restarted(s.spp, s.elapsed, Instant::now())
            });
            match shown {
                Some((now, after)) => {
                    // The first screen after the key that showed the edit.
                    let at = after
                        .history
                        .iter()
                        .find(|c| {
                            c.at >= t0
                                && c.params != before.params
                                && restarted(c.spp, c.elapsed, c.at)
                        })
                        .map_or((now, after.bytes, after.parse), |c| {
                            (c.at, c.bytes, c.parse)
                        });
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
                    // Let it show before the next press, so presses stay independent; a press
                    // that changes nothing (a parameter at its bound) never shows.
                    wait_for(shared, self.timeout, |s| s.params != before.params);
                }
            }
        }
        // Converging: frames and bytes over the window, after a restart.
        type_key(b"r");
        std::thread::sleep(Duration::from_millis(100));
        let (f0, b0, i0, t0) = {
            let s = shared.seen.lock().expect("screen state");
            (s.frames, s.bytes, s.images, Instant::now())
        };
        let first = Duration::from_secs(1).min(self.window.mul_f64(0.75));
        std::thread::sleep(first);
        let f_first = shared.seen.lock().expect("screen state").frames;
        report.first_second_fps = (f_first - f0) as f64 / t0.elapsed().as_secs_f64();
        let two = Duration::from_secs(2).min(self.window.mul_f64(0.75));
        std::thread::sleep(two.saturating_sub(first));
        {
            let s = shared.seen.lock().expect("screen state");
            let secs = t0.elapsed().as_secs_f64();
            report.images.0 = (s.images - i0) as f64 / secs;
            report.images.1 = (s.bytes - b0) as f64 / secs;
        }
        std::thread::sleep(self.window.mul_f64(0.75).saturating_sub(two));
        let (f1, b1, i1, t1) = {
            let s = shared.seen.lock().expect("screen state");
            (s.frames, s.bytes, s.images, Instant::now())
        };
        std::thread::sleep(self.window.mul_f64(0.25));
        let s = shared.seen.lock().expect("screen state").clone();
        let secs = t0.elapsed().as_secs_f64();
        report.fps = (s.frames - f0) as f64 / secs;
        report.bytes_per_second = (s.bytes - b0) as f64 / secs;
        let last = t1.elapsed().as_secs_f64();
        report.last_quarter = ((s.frames - f1) as f64 / last, (s.bytes - b1) as f64 / last);
        report.images.2 = (s.images - i1) as f64 / last;
        report.samples_per_second = s.rate.clone();
        report.link_status = s.link.clone();
        report.deepest_backlog = s.deepest_backlog;
        report.size = s.size.clone();
        Ok(report)
    }
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

/// What a run hands its driver: the far screen as read so far, and the keyboard.
pub struct Probe<'a> {
    shared: &'a Shared,
    keys: &'a std::sync::mpsc::Sender<(Instant, Vec<u8>)>,
    half_rtt: Duration,
}

/// One cell of the far screen.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FarCell {
    pub glyph: String,
    pub fg: Option<[u8; 3]>,
    pub bg: Option<[u8; 3]>,
}

/// The far screen's status, as `Probe::screen` reads it.
#[derive(Clone, Debug, Default)]
pub struct Screen {
    pub spp: Option<u64>,
    /// The parameter line.
    pub params: String,
    /// The status line's link field.
    pub link: Option<String>,
    /// Synchronized updates (frames) and bytes received so far.
    pub frames: u64,
    pub bytes: u64,
}

impl Probe<'_> {
    /// Types `keys`; they reach the program half a round trip later.
    pub fn type_key(&self, keys: &[u8]) {
        let _ = self
            .keys
            .send((Instant::now() + self.half_rtt, keys.to_vec()));
    }

    fn view(s: &Seen) -> Screen {
        Screen {
            spp: s.spp,
            params: s.params.clone(),
            link: s.link.clone(),
            frames: s.frames,
            bytes: s.bytes,
        }
    }

    pub fn screen(&self) -> Screen {
        Self::view(&self.shared.seen.lock().expect("screen state"))
    }

    /// The far screen's cells in `rows` (top first): glyph and 24-bit colours (`None` for a
    /// default or indexed colour).
    pub fn cells(&self, rows: std::ops::Range<u16>) -> Vec<Vec<FarCell>> {
        let guard = self.shared.parser.lock().expect("screen");
        let Some(parser) = guard.as_ref() else {
            return Vec::new();
        };
        let screen = parser.screen();
        let (_, cols) = screen.size();
        let rgb = |c: vt100::Color| match c {
            vt100::Color::Rgb(r, g, b) => Some([r, g, b]),
            _ => None,
        };
        rows.map(|r| {
            (0..cols.get())
                .map(|c| {
                    screen
                        .cell(r, c)
                        .map_or(FarCell::default(), |cell| FarCell {
                            glyph: cell.contents().to_string(),
                            fg: rgb(cell.fgcolor()),
                            bg: rgb(cell.bgcolor()),
                        })
                })
                .collect()
        })
        .collect()
    }

    /// Waits until `pred` holds of the screen, or `timeout`.
    pub fn wait_for(&self, timeout: Duration, pred: impl Fn(&Screen) -> bool) -> Option<Screen> {
        wait_for(self.shared, timeout, |s| pred(&Self::view(s))).map(|(_, s)| Self::view(&s))
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
    println!(
        "first frame  {:.0} ms from start (scene loaded, BVH built, pipeline made, first sample drawn)",
        r.first_frame * 1e3
    );
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
    if let Some(l) = &r.link_status {
        println!("status line  {l}");
    }
    if let Some(l) = b.link {
        println!(
            "link model   {:.1} Mbit/s, round trip {:.0} ms, window {} KiB: deepest backlog {:.0} kB ({:.2} s of link)",
            l.bits_per_second / 1e6,
            l.rtt.as_secs_f64() * 1e3,
            l.window >> 10,
            r.deepest_backlog as f64 / 1e3,
            r.deepest_backlog as f64 * 8.0 / l.bits_per_second
        );
    }
    println!(
        "converging   {:.1} frames/s ({:.1} in the first second), {:.1} kB/s of output, status line {}; last quarter {:.1} frames/s, {:.2} kB/s",
        r.fps,
        r.first_second_fps,
        r.bytes_per_second / 1e3,
        r.samples_per_second,
        r.last_quarter.0,
        r.last_quarter.1 / 1e3
    );
    if r.images.0 > 0.0 || r.images.2 > 0.0 {
        println!(
            "images       {:.1} images/s and {:.1} kB/s in the first 2 s; {:.2} images/s in the last quarter",
            r.images.0,
            r.images.1 / 1e3,
            r.images.2
        );
    }
}

/// The writer's thread: each key or answer written when it is due.
fn write_due(
    mut writer: Box<dyn Write + Send>,
    due: std::sync::mpsc::Receiver<(Instant, Vec<u8>)>,
) {
    for (at, bytes) in due {
        std::thread::sleep(at.saturating_duration_since(Instant::now()));
        if writer
            .write_all(&bytes)
            .and_then(|()| writer.flush())
            .is_err()
        {
            break;
        }
    }
}

/// The reader's thread: the program's output read into `pipe` while it holds less than
/// `window` bytes (past it the program blocks, as over SSH); marks the end.
fn read_into(mut reader: Box<dyn Read + Send>, p: &Pipe, window: usize) {
    let mut buf = vec![0u8; 1 << 16];
    loop {
        {
            let mut q = p.bytes.lock().expect("pipe");
            while q.0.len() >= window {
                q = p.cond.wait(q).expect("pipe");
            }
        }
        let n = match reader.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => n,
        };
        let mut q = p.bytes.lock().expect("pipe");
        q.0.extend(&buf[..n]);
        p.cond.notify_all();
    }
    p.bytes.lock().expect("pipe").1 = true;
    p.cond.notify_all();
}

/// The link and the far terminal: the program's output crosses the link at its rate and
/// delay into a terminal emulator, which answers the program's queries over it.
struct FarEnd {
    shared: Arc<Shared>,
    pipe: Arc<Pipe>,
    answers: std::sync::mpsc::Sender<(Instant, Vec<u8>)>,
    /// Holds the answers to frame queries back (see `answer_gate`).
    gate: Option<Arc<std::sync::atomic::AtomicI64>>,
    link: Link,
    size: (u16, u16),
}

/// The far terminal's count of what crossed the link, across pieces.
#[derive(Default)]
struct Tails {
    frame: Vec<u8>,
    query: Vec<u8>,
    da1: Vec<u8>,
    images: [Vec<u8>; 3],
    /// Queries read and not yet answered.
    held: u64,
}

impl FarEnd {
    fn run(self) {
        let (sh, p, answers, gate, link) = (
            &self.shared,
            &self.pipe,
            &self.answers,
            &self.gate,
            self.link,
        );
        let (rows, cols) = self.size;
        let half_rtt = link.rtt / 2;
        let nz = |n: u16| std::num::NonZeroU16::new(n.max(1)).expect("at least 1");
        *sh.parser.lock().expect("screen") = Some(vt100::Parser::new(nz(rows), nz(cols), 0));
        let mut tails = Tails::default();
        let mut on_wire: std::collections::VecDeque<(Instant, Vec<u8>)> = Default::default();
        let mut link_free = Instant::now();
        loop {
            // Take one from the gate, if it holds any.
            let take = |g: &std::sync::atomic::AtomicI64| {
                use std::sync::atomic::Ordering::SeqCst;
                g.fetch_update(SeqCst, SeqCst, |v| (v > 0).then(|| v - 1))
                    .is_ok()
            };
            while tails.held > 0 && gate.as_deref().is_none_or(take) {
                tails.held -= 1;
                let _ = answers.send((Instant::now() + half_rtt, ANSWER.to_vec()));
            }
            // Put what the link can take now on the wire.
            let mut ended = false;
            {
                let mut q = p.bytes.lock().expect("pipe");
                let now = Instant::now();
                while link_free <= now && !q.0.is_empty() {
                    let n = q.0.len().min(PIECE);
                    let piece: Vec<u8> = q.0.drain(..n).collect();
                    let depart = link_free.max(now);
                    link_free =
                        depart + Duration::from_secs_f64(n as f64 * 8.0 / link.bits_per_second);
                    on_wire.push_back((link_free + half_rtt, piece));
                }
                p.cond.notify_all();
                let backlog = q.0.len() + on_wire.iter().map(|w| w.1.len()).sum::<usize>();
                let mut s = sh.seen.lock().expect("screen state");
                s.deepest_backlog = s.deepest_backlog.max(backlog as u64);
                if q.0.is_empty() && on_wire.is_empty() {
                    if q.1 {
                        ended = true;
                    } else {
                        drop(s);
                        let _ = p.cond.wait_timeout(q, Duration::from_millis(50));
                        continue;
                    }
                }
            }
            if ended {
                break;
            }
            // Deliver what has arrived.
            let now = Instant::now();
            while on_wire.front().is_some_and(|w| w.0 <= now) {
                let (_, piece) = on_wire.pop_front().expect("a piece");
                self.deliver(&piece, &mut tails);
            }
            // Sleep until the next arrival or until the link is free again.
            let next = on_wire.front().map(|w| w.0).into_iter().chain([link_free]);
            let until = next.min().unwrap_or(now + Duration::from_millis(1));
            let nap = until
                .saturating_duration_since(Instant::now())
                .min(Duration::from_millis(1));
            std::thread::sleep(nap.max(Duration::from_micros(100)));
        }
        let mut s = sh.seen.lock().expect("screen state");
        s.exited = true;
        sh.cond.notify_all();
    }

    /// A piece of output arrives: the screen, the frames and images in it, the queries to
    /// answer, and the status line's change, noted with when it was seen.
    fn deliver(&self, piece: &[u8], t: &mut Tails) {
        let (sh, answers) = (&self.shared, &self.answers);
        let half_rtt = self.link.rtt / 2;
        let parse_start = Instant::now();
        let mut guard = sh.parser.lock().expect("screen");
        let parser = guard.as_mut().expect("a parser");
        parser.process(piece);
        let frames = count_split(&mut t.frame, piece, SYNC_BEGIN);
        let queries = count_split(&mut t.query, piece, QUERY);
        for _ in 0..count_split(&mut t.da1, piece, DA1) {
            let _ = answers.send((Instant::now() + half_rtt, DA1_ANSWER.to_vec()));
        }
        let mut s = sh.seen.lock().expect("screen state");
        let before = (s.spp, s.params.clone());
        read_status(parser.screen(), &mut s);
        drop(guard);
        s.parse += parse_start.elapsed();
        s.bytes += piece.len() as u64;
        s.frames += frames;
        for (tail, start) in t.images.iter_mut().zip(IMAGE_STARTS) {
            s.images += count_split(tail, piece, start);
        }
        t.held += queries;
        if (s.spp, s.params.clone()) != before {
            let change = Change {
                at: Instant::now(),
                spp: s.spp,
                params: s.params.clone(),
                elapsed: s.elapsed,
                bytes: s.bytes,
                parse: s.parse,
            };
            s.history.push(change);
        }
        sh.cond.notify_all();
    }
}
