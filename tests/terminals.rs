//! Pixel graphics in real terminals, as a person sees them: xterm as a VT340 (sixel) and
//! kitty (kitty graphics), each on a virtual X display (Xvfb), run the preview of a small
//! scene; a screenshot of the display (ImageMagick's `import`) must show, where the image
//! cells are, the image a direct `render` of the same view makes, within a stated tolerance.
//! `.ci/run` installs xvfb, xterm, kitty and imagemagick.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const SPP: u32 = 32;

/// A virtual X display, killed on drop.
struct Display {
    server: Child,
    name: String,
    log: PathBuf,
}

impl Drop for Display {
    fn drop(&mut self) {
        let _ = self.server.kill();
        let _ = self.server.wait();
        let _ = std::fs::remove_file(&self.log);
    }
}

fn display() -> Display {
    // A display number no other test (of this run or another) holds. An Xvfb that exits
    // instead of opening its socket (a number taken meanwhile, a stale lock) is retried on
    // the next number; the last one's own words are in the failure.
    static NEXT: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let base = 100 + std::process::id() % 300;
    let mut failures = Vec::new();
    for _attempt in 0..5 {
        let n = (0..300)
            .map(|_| base + NEXT.fetch_add(1, std::sync::atomic::Ordering::SeqCst))
            .find(|n| {
                !Path::new(&format!("/tmp/.X11-unix/X{n}")).exists()
                    && !Path::new(&format!("/tmp/.X{n}-lock")).exists()
            })
            .expect("a free display number");
        let name = format!(":{n}");
        // Its messages go to a file (a pipe nobody reads could fill and stall it).
        let log = std::env::temp_dir().join(format!("termtrace-xvfb-{n}.log"));
        let server = Command::new("Xvfb")
            .args([&name, "-screen", "0", "1024x768x24", "-nolisten", "tcp"])
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log).expect("Xvfb's log file"))
            .spawn()
            .expect("Xvfb (apt-get install xvfb)");
        // Dropped on failure: the server killed and its log removed.
        let mut d = Display { server, name, log };
        let deadline = Instant::now() + Duration::from_secs(60);
        loop {
            if Path::new(&format!("/tmp/.X11-unix/X{n}")).exists() {
                return d;
            }
            if let Ok(Some(status)) = d.server.try_wait() {
                let words = std::fs::read_to_string(&d.log).unwrap_or_default();
                failures.push(format!(
                    "{}: Xvfb exited ({status}): {}",
                    d.name,
                    words.trim()
                ));
                break;
            }
            if Instant::now() >= deadline {
                failures.push(format!("{}: no socket after 60 s", d.name));
                break;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }
    panic!("Xvfb did not start:\n{}", failures.join("\n"));
}

struct Killed(Child);
impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Waits until the log has a line containing `what`; returns the log.
fn wait_log(log: &Path, what: &str, secs: u64) -> String {
    let deadline = Instant::now() + Duration::from_secs(secs);
    loop {
        let text = std::fs::read_to_string(log).unwrap_or_default();
        if text.contains(what) {
            return text;
        }
        assert!(
            Instant::now() < deadline,
            "no `{what}` in the preview's log within {secs} s:\n{text}"
        );
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// The value after `prefix` up to the next space in the log's last line that has it.
fn field<'a>(log: &'a str, prefix: &str) -> &'a str {
    let line = log.lines().rev().find(|l| l.contains(prefix)).unwrap();
    let rest = &line[line.find(prefix).unwrap() + prefix.len()..];
    rest.split([' ', ')']).next().unwrap()
}

/// Mean over 4×4 blocks of the absolute difference of their mean sRGB values (0–255),
/// between the screenshot at offset (dx, dy) and the reference: averaging a block takes out
/// most of a dithered palette's error and of the preview's noise, not a wrong picture.
fn block_error(shot: &image::RgbImage, reference: &image::RgbImage, dx: u32, dy: u32) -> f64 {
    let (w, h) = reference.dimensions();
    let (mut sum, mut n) = (0.0, 0usize);
    for by in 0..h / 4 {
        for bx in 0..w / 4 {
            for c in 0..3 {
                let mean = |img: &image::RgbImage, ox: u32, oy: u32| {
                    let mut s = 0.0;
                    for y in 0..4 {
                        for x in 0..4 {
                            s += img.get_pixel(ox + bx * 4 + x, oy + by * 4 + y)[c] as f64;
                        }
                    }
                    s / 16.0
                };
                sum += (mean(shot, dx, dy) - mean(reference, 0, 0)).abs();
                n += 1;
            }
        }
    }
    sum / n as f64
}

/// Runs the preview in `terminal` (a command line taking the program after it), waits for
/// its last frame, and compares a screenshot with a direct render; returns the protocol the
/// preview chose and the error.
fn check(terminal: &[&str], expect: &str) {
    let exe = env!("CARGO_BIN_EXE_termtrace");
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("preview.log");
    let d = display();
    let mut cmd = Command::new(terminal[0]);
    cmd.args(&terminal[1..])
        .args([
            exe,
            "view",
            "basic",
            "--max-spp",
            &SPP.to_string(),
            "--exit-after",
            "120",
        ])
        // Every pixel of the terminal traced (not fewer, fitted to the backend's speed), so
        // that the screen and the direct render have the same pixels.
        .args(["--scale", "1"])
        .arg("--log")
        .arg(&log)
        .arg("-vv")
        .env("DISPLAY", &d.name)
        .env_remove("TMUX")
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    let _term = Killed(
        cmd.spawn()
            .unwrap_or_else(|e| panic!("{}: {e}", terminal[0])),
    );
    let text = wait_log(&log, &format!("frame at {SPP} spp delivered"), 120);
    assert!(
        text.contains(&format!("graphics: {expect}")),
        "the preview chose other graphics than {expect}:\n{text}"
    );
    let size = field(&text, "preview image ");
    let (w, h) = size.split_once('x').unwrap();
    let (w, h): (u32, u32) = (w.parse().unwrap(), h.parse().unwrap());
    // Let the terminal draw the last frame.
    std::thread::sleep(Duration::from_secs(2));
    let shot_path = dir.path().join("shot.png");
    let ok = Command::new("import")
        .args(["-display", &d.name, "-window", "root"])
        .arg(&shot_path)
        .status()
        .expect("import (apt-get install imagemagick)");
    assert!(ok.success());
    let reference_path = dir.path().join("reference.png");
    let ok = Command::new(exe)
        .args([
            "render",
            "basic",
            "--width",
            &w.to_string(),
            "--height",
            &h.to_string(),
        ])
        .args(["--spp", "256", "-o"])
        .arg(&reference_path)
        .stderr(Stdio::null())
        .status()
        .unwrap();
    assert!(ok.success());
    let shot = image::open(&shot_path).unwrap().to_rgb8();
    let reference = image::open(&reference_path).unwrap().to_rgb8();
    // The image starts at the window's top-left cell; the terminal's border is a few pixels.
    let (best, at) = (0..=8)
        .flat_map(|dy| (0..=8).map(move |dx| (dx, dy)))
        .map(|(dx, dy)| (block_error(&shot, &reference, dx, dy), (dx, dy)))
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .unwrap();
    // The same comparison against the picture upside down: what a wrong image scores.
    let flipped = image::imageops::flip_vertical(&reference);
    let wrong = block_error(&shot, &flipped, at.0, at.1);
    let keep = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("terminal-{expect}.png"));
    let _ = std::fs::copy(&shot_path, &keep);
    eprintln!(
        "{expect}: {w}x{h} image at {at:?}, block error {best:.2} levels (upside down {wrong:.1}); screenshot {}",
        keep.display()
    );
    assert!(
        best < 4.0,
        "{expect}: the screen differs from a direct render by {best:.2} levels per 4×4 block (screenshot {})",
        keep.display()
    );
    assert!(
        wrong > 4.0 * best,
        "the comparison cannot tell pictures apart"
    );
}

#[test]
fn xterm_as_a_vt340_shows_the_image_by_sixel() {
    check(
        &[
            "xterm",
            "-ti",
            "vt340",
            "-xrm",
            "XTerm*numColorRegisters: 256",
            "-geometry",
            "100x30+0+0",
            "-e",
        ],
        "sixel",
    );
}

#[test]
fn kitty_shows_the_image_by_kitty_graphics() {
    check(
        &[
            "kitty",
            "--config",
            "NONE",
            "-o",
            "initial_window_width=640",
            "-o",
            "initial_window_height=400",
            "-o",
            "remember_window_size=no",
        ],
        "kitty",
    );
}
