//! What the terminal can draw, asked of the terminal itself (so it works over SSH, where the
//! questions reach the user's terminal): the kitty graphics query, XTSMGRAPHICS for the
//! number of sixel colour registers, `CSI 16 t` for the cell size in pixels, and DA1, whose
//! reply lists sixel (attribute 4) and, since terminals answer in order and every one answers
//! DA1, ends the wait. Inside tmux the questions would reach tmux, not the terminal: there
//! tmux's `allow-passthrough` and its client's terminal name decide instead.

use super::graphics::Protocol;
use std::time::{Duration, Instant};

/// The questions, in the order they are answered.
pub const QUERIES: &str = concat!(
    "\x1b_Gi=31,s=1,v=1,a=q,t=d,f=24;AAAA\x1b\\", // kitty graphics: answers `OK`
    "\x1b[?1;1;0S",                               // XTSMGRAPHICS: colour registers
    "\x1b[16t",                                   // cell size in pixels
    "\x1b[c",                                     // DA1, answered last
);

/// What the answers said.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Answers {
    pub kitty: bool,
    pub sixel: bool,
    /// Sixel colour registers.
    pub colors: Option<u16>,
    /// A cell's width and height in pixels.
    pub cell: Option<(u16, u16)>,
    /// DA1 answered: every answer before it is in.
    pub complete: bool,
}

/// Parses the terminal's answers (any other bytes, such as keys typed meanwhile, are skipped).
pub fn parse(bytes: &[u8]) -> Answers {
    let mut a = Answers::default();
    let s = String::from_utf8_lossy(bytes);
    let mut rest: &str = &s;
    while let Some(i) = rest.find('\x1b') {
        rest = &rest[i..];
        if let Some(body) = rest.strip_prefix("\x1b_G") {
            // Kitty: `ESC _ G i=31;OK ESC \`.
            let end = body.find("\x1b\\").unwrap_or(body.len());
            if body[..end].contains("i=31") && body[..end].contains(";OK") {
                a.kitty = true;
            }
            rest = &body[end..];
        } else if let Some(body) = rest.strip_prefix("\x1b[") {
            let end = body
                .find(|c: char| c.is_ascii_alphabetic())
                .unwrap_or(body.len());
            let (params, fin) = (&body[..end], body[end..].chars().next());
            let nums = |p: &str| -> Vec<u32> {
                p.trim_start_matches('?')
                    .split(';')
                    .filter_map(|x| x.parse().ok())
                    .collect()
            };
            match fin {
                Some('c') if params.starts_with('?') => {
                    a.complete = true;
                    a.sixel = nums(params).iter().skip(1).any(|&n| n == 4);
                }
                Some('S') if params.starts_with('?') => {
                    // `CSI ? 1 ; 0 ; N S`: item 1 (colours), status 0 (success), value N.
                    if let [1, 0, n, ..] = nums(params)[..] {
                        a.colors = Some(n.min(u16::MAX as u32) as u16);
                    }
                }
                Some('t') => {
                    // `CSI 6 ; height ; width t`.
                    if let [6, h, w] = nums(params)[..]
                        && h > 0
                        && w > 0
                    {
                        a.cell =
                            Some((w.min(u16::MAX as u32) as u16, h.min(u16::MAX as u32) as u16));
                    }
                }
                _ => {}
            }
            rest = &body[end.min(body.len())..];
        } else {
            rest = &rest[1..];
        }
    }
    a
}

/// Writes the questions to the terminal (in raw mode, before the input thread starts) and
/// reads the answers until DA1's or `timeout`.
#[cfg(unix)]
pub fn ask(timeout: Duration) -> Answers {
    use std::io::Write;
    let mut out = std::io::stdout();
    if out
        .write_all(QUERIES.as_bytes())
        .and_then(|_| out.flush())
        .is_err()
    {
        return Answers::default();
    }
    let deadline = Instant::now() + timeout;
    let mut got = Vec::new();
    let mut buf = [0u8; 1024];
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            break;
        }
        let mut pfd = libc::pollfd {
            fd: 0,
            events: libc::POLLIN,
            revents: 0,
        };
        // SAFETY: one valid pollfd for the duration of the call.
        let ready = unsafe { libc::poll(&mut pfd, 1, left.as_millis().max(1) as i32) };
        if ready <= 0 {
            break;
        }
        // SAFETY: reads into a buffer we own, of its length.
        let n = unsafe { libc::read(0, buf.as_mut_ptr().cast(), buf.len()) };
        if n <= 0 {
            break;
        }
        got.extend_from_slice(&buf[..n as usize]);
        if parse(&got).complete {
            break;
        }
    }
    parse(&got)
}

#[cfg(not(unix))]
pub fn ask(_timeout: Duration) -> Answers {
    Answers::default()
}

/// Why the preview draws cells instead of an image.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum NoGraphics {
    #[error("the terminal did not answer")]
    Unanswered,
    #[error("no graphics in the terminal's answers")]
    NoneOffered,
    #[error("tmux: set allow-passthrough on for graphics")]
    TmuxPassthrough,
    /// Inside tmux, whose outer terminal cannot be asked (its name, when tmux knows it).
    #[error(
        "tmux in {}: cannot ask it for graphics (--graphics sixel|kitty|iterm)",
        .0.as_deref().unwrap_or("an unknown terminal")
    )]
    TmuxOuter(Option<String>),
}

/// The protocol `auto` picks from the answers and the environment, or why none.
pub fn choose(a: &Answers, term_program: Option<&str>) -> Result<Protocol, NoGraphics> {
    if a.kitty {
        return Ok(Protocol::Kitty);
    }
    if a.sixel {
        return Ok(Protocol::Sixel);
    }
    if matches!(term_program, Some("iTerm.app" | "WezTerm")) {
        return Ok(Protocol::Iterm);
    }
    Err(if a.complete {
        NoGraphics::NoneOffered
    } else {
        NoGraphics::Unanswered
    })
}

/// Inside tmux: whether its passthrough is allowed (`allow-passthrough on|all`), and the
/// outer terminal's name (`client_termname`), from tmux itself.
pub fn tmux_outer() -> (bool, Option<String>) {
    let run = |args: &[&str]| {
        std::process::Command::new("tmux")
            .args(args)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    let allowed = run(&["show-options", "-gqv", "allow-passthrough"])
        .is_some_and(|v| v == "on" || v == "all");
    (
        allowed,
        run(&["display-message", "-p", "#{client_termname}"]),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_answers_of_kitty_xterm_and_a_plain_terminal() {
        // kitty: graphics OK, cell size, DA1 without sixel.
        let k = parse(b"\x1b_Gi=31;OK\x1b\\\x1b[6;20;10t\x1b[?62;c");
        assert_eq!(
            k,
            Answers {
                kitty: true,
                sixel: false,
                colors: None,
                cell: Some((10, 20)),
                complete: true
            }
        );
        // xterm -ti vt340: no kitty answer, registers, sixel in DA1.
        let x = parse(b"\x1b[?1;0;256S\x1b[6;17;9t\x1b[?63;1;2;4;6;9;15;16;22;28;29c");
        assert!(x.sixel && !x.kitty && x.complete);
        assert_eq!((x.colors, x.cell), (Some(256), Some((9, 17))));
        assert_eq!(choose(&x, None), Ok(Protocol::Sixel));
        // A plain terminal: DA1 only (the 4 of `?64` is not an attribute).
        let p = parse(b"\x1b[?64;1;2c");
        assert!(p.complete && !p.sixel);
        assert!(choose(&p, None).is_err());
        assert_eq!(choose(&p, Some("iTerm.app")), Ok(Protocol::Iterm));
        // Keys typed meanwhile and a failed XTSMGRAPHICS do no harm; no DA1: incomplete.
        let q = parse(b"abc\x1b[?1;3;0S\x1b[A");
        assert_eq!(q, Answers::default());
        assert_eq!(choose(&q, None), Err(NoGraphics::Unanswered));
    }
}
