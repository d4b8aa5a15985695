//! The preview through real OpenSSH: a throw-away sshd on a loopback port behind a throttling
//! proxy (`measure::ssh_link`), `ssh -tt` into it in a pseudo-terminal read by a terminal
//! emulator that answers status queries, as a user's terminal does. Checked for what the
//! far screen shows, not for how fast: each edit arrives with a restarted sample count, and
//! the status line shows the link as the preview measured it from the answers.

use std::time::Duration;
use termtrace::measure::preview::PreviewBench;
use termtrace::measure::ssh_link::{SSHD, SshLink};

#[test]
fn the_preview_works_through_openssh_and_measures_the_link() {
    assert!(
        std::path::Path::new(SSHD).exists(),
        "this test needs OpenSSH: apt-get install openssh-server openssh-client (.ci/run does)"
    );
    let link = SshLink::start(10e6, Duration::from_millis(20)).expect("sshd and the proxy start");
    let exe = env!("CARGO_BIN_EXE_termtrace");
    let remote: Vec<String> = [
        "env",
        "TERM=xterm-256color",
        "COLORTERM=truecolor",
        exe,
        "view",
        "basic",
        "--max-spp",
        "1000000",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    // Wide enough for the status line's last field, the link.
    let b = PreviewBench {
        presses: 2,
        settle: Duration::from_millis(300),
        // Generous: this checks what is shown, not how fast.
        timeout: Duration::from_secs(60),
        window: Duration::from_millis(1500),
        command: Some(link.command(&remote)),
        ..PreviewBench::new(exe, "basic", 140, 12)
    };
    let r = b.run().expect("the preview runs through ssh");
    assert_eq!(r.misses, 0, "{r:?}");
    assert_eq!(r.latencies.len(), 2, "{r:?}");
    for &(before, after) in &r.restarts {
        assert!(before >= 2 && after < before, "no restart seen: {r:?}");
    }
    let (first_before, first_after) = &r.edits[0];
    assert_ne!(first_before, first_after);
    assert_eq!(&r.edits[1].1, first_before, "{r:?}");
    // The emulator answered the status queries through ssh: the preview measured the link.
    let status = r.link_status.clone().unwrap_or_default();
    assert!(
        status.starts_with("link ") && status.ends_with(" ms"),
        "{r:?}"
    );
    assert!(r.fps > 0.0, "{r:?}");
}
