//! The preview as a person uses it, in a real terminal: a tmux session 100×30 runs a shell,
//! the shell runs termtrace, keys change a material, write the scene, save a PNG, quit; the
//! screen is read with capture-pane at each step.

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

struct Session(String);

impl Drop for Session {
    fn drop(&mut self) {
        let _ = Command::new("tmux")
            .args(["kill-session", "-t", &self.0])
            .output();
    }
}

impl Session {
    /// A tmux session `name`, 120×30, running a clean shell in `dir`, at its prompt. Wide
    /// enough that the status line keeps the graphics mode: narrower, it drops it (after the
    /// adapter) when the samples, the rate and the noise take more room (at 100 columns a
    /// first frame of 274 spp at 14.98 Ms/s with a denoised estimate and the link's figure
    /// took 93 of them, and "cells" went).
    fn start(name: &str, dir: &Path) -> Session {
        let session = Session(name.to_string());
        let shell = "env -i PATH=/usr/bin:/bin HOME=/tmp TERM=xterm-256color COLORTERM=truecolor PS1='$ ' bash --norc --noprofile";
        let ok = Command::new("tmux")
            .args([
                "new-session",
                "-d",
                "-s",
                name,
                "-x",
                "120",
                "-y",
                "30",
                "-c",
            ])
            .arg(dir)
            .arg(shell)
            .status()
            .unwrap();
        assert!(ok.success(), "tmux new-session failed");
        session.wait_for("the shell prompt", 10, |s| {
            s.lines().any(|l| l.trim_end() == "$")
        });
        session
    }

    fn keys(&self, keys: &[&str]) {
        for k in keys {
            let ok = Command::new("tmux")
                .args(["send-keys", "-t", &self.0, k])
                .status()
                .unwrap();
            assert!(ok.success());
            std::thread::sleep(Duration::from_millis(150));
        }
    }

    fn screen(&self) -> String {
        let out = Command::new("tmux")
            .args(["capture-pane", "-p", "-t", &self.0])
            .output()
            .unwrap();
        String::from_utf8_lossy(&out.stdout).into_owned()
    }

    /// Waits until the screen satisfies `pred`; panics with the screen after `secs`.
    fn wait_for(&self, what: &str, secs: u64, pred: impl Fn(&str) -> bool) -> String {
        let deadline = Instant::now() + Duration::from_secs(secs);
        loop {
            let s = self.screen();
            if pred(&s) {
                return s;
            }
            if Instant::now() > deadline {
                panic!("timed out waiting for {what}; the screen:\n{s}");
            }
            std::thread::sleep(Duration::from_millis(200));
        }
    }
}

fn status_lines(screen: &str) -> String {
    screen
        .lines()
        .filter(|l| l.contains('│') || l.contains('▸'))
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn edit_a_material_write_save_and_quit_in_tmux() {
    assert!(
        Command::new("tmux")
            .arg("-V")
            .output()
            .is_ok_and(|o| o.status.success()),
        "this test needs tmux (apt-get install tmux; .ci/run installs it)"
    );
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("scene.toml"),
        "[render]\nwidth = 64\nheight = 36\nspp = 8\n\
         [[sphere]]\nname = \"ground\"\ncenter = [0, -100.5, -1]\nradius = 100\n\
         [[sphere]]\nname = \"red\"\ncenter = [0, 0, -1]\nradius = 0.5\ncolor = \"#ff0000\"\n",
    )
    .unwrap();
    let session = Session::start(
        &format!("termtrace-test-{}", std::process::id()),
        dir.path(),
    );
    let bin = env!("CARGO_BIN_EXE_termtrace");
    session.keys(&[&format!("{bin} scene.toml"), "Enter"]);
    let s = session.wait_for("the preview's status line", 60, |s| {
        s.contains(" spp ") && s.contains("▸ ground")
    });
    // Without tmux's passthrough the preview draws cells; the status line names them in one
    // word (why is the start-up message's and the log's), leaving room for the rest.
    assert!(status_lines(&s).contains("│ cells │"), "{s}");

    // Select the red sphere, raise its smoothness by two coarse steps.
    session.keys(&["Tab", "1", "]", "]"]);
    let s = session.wait_for("the change in the status line", 20, |s| {
        s.contains("▸ red") && s.contains("smooth 0.2")
    });
    assert!(status_lines(&s).contains("smooth 0.2"), "{s}");
    // The change restarted the accumulation: the frame shown is of the new scene.
    session.wait_for("a frame of the edited scene", 30, |s| s.contains(" spp "));

    session.keys(&["w"]);
    session.wait_for("the write message", 10, |s| {
        s.contains("wrote scene.edited.toml")
    });
    let written = std::fs::read_to_string(dir.path().join("scene.edited.toml")).unwrap();
    assert!(written.contains("smoothness = 0.2"), "{written}");
    let reloaded =
        termtrace::scene::Scene::load_file(&dir.path().join("scene.edited.toml")).unwrap();
    assert_eq!(reloaded.objects[1].material.smoothness, 0.2);

    session.keys(&["p"]);
    session.wait_for("the PNG to be saved", 120, |s| {
        s.contains("saved scene.png")
    });
    let png = image::open(dir.path().join("scene.png")).unwrap();
    assert_eq!((png.width(), png.height()), (64, 36));

    session.keys(&["q"]);
    let s = session.wait_for("the shell prompt after quitting", 20, |s| {
        let lines: Vec<&str> = s.lines().filter(|l| !l.trim().is_empty()).collect();
        lines.last().is_some_and(|l| l.trim_end() == "$")
    });
    // The alternate screen is gone: no image cells, no status line, just the shell.
    assert!(
        !s.contains('▀') && !s.contains(" spp "),
        "the preview left marks:\n{s}"
    );
    assert!(
        s.contains("scene.toml"),
        "the command line should still be there:\n{s}"
    );
    assert!(!Path::new(&dir.path().join("scene.edited.toml.bak")).exists());
}

/// Runs `termtrace view cornell --max-spp 64 ARGS` in a fresh 120×30 tmux session and returns
/// the screen with its colours (`capture-pane -e`) once the status line shows 64 spp, without
/// the status lines.
fn cornell_at_64_spp(args: &str, tag: &str) -> String {
    let name = format!("termtrace-test-{}-{tag}", std::process::id());
    let dir = tempfile::tempdir().unwrap();
    let session = Session::start(&name, dir.path());
    let bin = env!("CARGO_BIN_EXE_termtrace");
    session.keys(&[&format!("{bin} cornell --max-spp 64 {args}"), "Enter"]);
    session.wait_for("64 spp", 120, |s| s.contains(" 64 spp "));
    // The last frame is drawn with the status line that announces it.
    std::thread::sleep(Duration::from_millis(500));
    let out = Command::new("tmux")
        .args(["capture-pane", "-p", "-e", "-t", &name])
        .output()
        .unwrap();
    session.keys(&["q"]);
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter(|l| !l.contains('│') && !l.contains('▸'))
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn the_preview_on_two_devices_shows_one_devices_image_in_tmux() {
    // `--adapter cpu-native,cpu-native`: two CPU tracers share the preview's samples
    // (src/render/team/live.rs); they compute alike, so at 64 spp the cells' colours are those of
    // one CPU tracer's preview, escape for escape.
    let one = cornell_at_64_spp("--adapter cpu-native", "one");
    let two = cornell_at_64_spp("--adapter cpu-native,cpu-native", "two");
    assert!(one.contains("38;2;"), "truecolour cells expected:\n{one}");
    assert_eq!(one, two);
}
