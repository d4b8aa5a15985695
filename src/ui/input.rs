//! Terminal input read from stdin as bytes: keys, as crossterm `KeyEvent`s for `keys::action`,
//! and the terminal's answers to the status query that clocks frames (DSR `CSI 5 n` →
//! `CSI 0 n`, see `flow`).
//!
//! Written by hand because crossterm's reader parses the answer but keeps it to itself (its
//! `read` returns only public events, and holds the reader while it blocks, so no other
//! thread can ask for internal ones). The keys the preview uses are few: printable
//! characters, Tab and Shift-Tab, Enter, Backspace, Esc, Ctrl-letter, the arrows, Home/End,
//! Page Up/Down, Insert/Delete, F1–F4 (ECMA-48 CSI and SS3 forms, xterm's modifier
//! parameter). Sequences split across reads are kept until complete; a lone ESC at the end
//! of a read is the Esc key (terminals write a key's sequence in one piece).

use ratatui::crossterm::event::{KeyCode, KeyEvent, KeyModifiers};

/// What a terminal sent.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Input {
    Key(KeyEvent),
    /// `CSI 0 n`: the answer to a device status query, sent in order after everything
    /// written before the query.
    StatusReport,
}

/// Turns bytes into inputs; keeps an incomplete sequence for the next read.
#[derive(Default)]
pub struct Parser {
    pending: Vec<u8>,
}

const ESC: u8 = 0x1b;

fn key(code: KeyCode, modifiers: KeyModifiers) -> Input {
    Input::Key(KeyEvent::new(code, modifiers))
}

/// xterm's modifier parameter: 1 + (shift 1, alt 2, ctrl 4).
fn modifiers(param: Option<u32>) -> KeyModifiers {
    let m = param.unwrap_or(1).saturating_sub(1);
    let mut k = KeyModifiers::empty();
    if m & 1 != 0 {
        k |= KeyModifiers::SHIFT;
    }
    if m & 2 != 0 {
        k |= KeyModifiers::ALT;
    }
    if m & 4 != 0 {
        k |= KeyModifiers::CONTROL;
    }
    k
}

/// What `len` bytes at the start of `b` mean, or `None` when they are an incomplete sequence.
enum Step {
    Input(Option<Input>, usize),
    Incomplete,
}

fn csi(b: &[u8]) -> Step {
    // ESC [ params (0x30–0x3f) intermediates (0x20–0x2f) final (0x40–0x7e)
    let mut i = 2;
    while i < b.len() && (0x20..=0x3f).contains(&b[i]) {
        i += 1;
    }
    if i >= b.len() {
        return Step::Incomplete;
    }
    let fin = b[i];
    let params = std::str::from_utf8(&b[2..i]).unwrap_or("");
    let nums: Vec<Option<u32>> = params.split(';').map(|p| p.parse().ok()).collect();
    let first = nums.first().copied().flatten();
    let m = modifiers(nums.get(1).copied().flatten());
    let input = match fin {
        b'A' => Some(key(KeyCode::Up, m)),
        b'B' => Some(key(KeyCode::Down, m)),
        b'C' => Some(key(KeyCode::Right, m)),
        b'D' => Some(key(KeyCode::Left, m)),
        b'H' => Some(key(KeyCode::Home, m)),
        b'F' => Some(key(KeyCode::End, m)),
        b'Z' => Some(key(KeyCode::BackTab, KeyModifiers::SHIFT)),
        b'n' if params == "0" => Some(Input::StatusReport),
        b'~' => match first {
            Some(1 | 7) => Some(key(KeyCode::Home, m)),
            Some(2) => Some(key(KeyCode::Insert, m)),
            Some(3) => Some(key(KeyCode::Delete, m)),
            Some(4 | 8) => Some(key(KeyCode::End, m)),
            Some(5) => Some(key(KeyCode::PageUp, m)),
            Some(6) => Some(key(KeyCode::PageDown, m)),
            _ => None,
        },
        // Other replies (cursor position, device attributes) and unknown keys: ignored.
        _ => None,
    };
    Step::Input(input, i + 1)
}

fn escape(b: &[u8], end_of_read: bool) -> Step {
    match b.get(1) {
        None if end_of_read => Step::Input(Some(key(KeyCode::Esc, KeyModifiers::empty())), 1),
        None => Step::Incomplete,
        Some(b'[') => csi(b),
        Some(b'O') => match b.get(2) {
            None => Step::Incomplete,
            Some(&c) => {
                let code = match c {
                    b'A' => Some(KeyCode::Up),
                    b'B' => Some(KeyCode::Down),
                    b'C' => Some(KeyCode::Right),
                    b'D' => Some(KeyCode::Left),
                    b'H' => Some(KeyCode::Home),
                    b'F' => Some(KeyCode::End),
                    b'P'..=b'S' => Some(KeyCode::F(c - b'P' + 1)),
                    _ => None,
                };
                Step::Input(code.map(|k| key(k, KeyModifiers::empty())), 3)
            }
        },
        Some(&ESC) => Step::Input(Some(key(KeyCode::Esc, KeyModifiers::empty())), 1),
        // ESC then a key: that key with Alt.
        Some(_) => match plain(&b[1..]) {
            Step::Input(Some(Input::Key(mut k)), n) => {
                k.modifiers |= KeyModifiers::ALT;
                Step::Input(Some(Input::Key(k)), n + 1)
            }
            Step::Input(other, n) => Step::Input(other, n + 1),
            Step::Incomplete => Step::Incomplete,
        },
    }
}

/// A key that is not an escape sequence: a control byte or one UTF-8 character.
fn plain(b: &[u8]) -> Step {
    let none = KeyModifiers::empty();
    let c = b[0];
    let input = match c {
        b'\r' | b'\n' => key(KeyCode::Enter, none),
        b'\t' => key(KeyCode::Tab, none),
        0x7f | 0x08 => key(KeyCode::Backspace, none),
        0x01..=0x1a => key(KeyCode::Char((b'a' + c - 1) as char), KeyModifiers::CONTROL),
        0x00 | 0x1c..=0x1f => return Step::Input(None, 1),
        _ => {
            let len = match c {
                0x00..=0x7f => 1,
                0xc0..=0xdf => 2,
                0xe0..=0xef => 3,
                0xf0..=0xf7 => 4,
                _ => return Step::Input(None, 1),
            };
            if b.len() < len {
                return Step::Incomplete;
            }
            return match std::str::from_utf8(&b[..len])
                .ok()
                .and_then(|s| s.chars().next())
            {
                Some(ch) => {
                    let m = if ch.is_uppercase() {
                        KeyModifiers::SHIFT
                    } else {
                        none
                    };
                    Step::Input(Some(key(KeyCode::Char(ch), m)), len)
                }
                None => Step::Input(None, 1),
            };
        }
    };
    Step::Input(Some(input), 1)
}

impl Parser {
    /// The inputs in `bytes` (with what was left of the last read before them).
    pub fn feed(&mut self, bytes: &[u8]) -> Vec<Input> {
        self.pending.extend_from_slice(bytes);
        let mut out = Vec::new();
        let mut at = 0;
        while at < self.pending.len() {
            let b = &self.pending[at..];
            let step = if b[0] == ESC {
                escape(b, true)
            } else {
                plain(b)
            };
            match step {
                Step::Input(input, n) => {
                    out.extend(input);
                    at += n;
                }
                Step::Incomplete => break,
            }
        }
        self.pending.drain(..at);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn keys(bytes: &[u8]) -> Vec<Input> {
        Parser::default().feed(bytes)
    }

    fn k(code: KeyCode, m: KeyModifiers) -> Input {
        key(code, m)
    }

    #[test]
    fn printable_control_and_named_keys() {
        let none = KeyModifiers::empty();
        assert_eq!(
            keys(b"+a\tR\x03\r\x7f"),
            vec![
                k(KeyCode::Char('+'), none),
                k(KeyCode::Char('a'), none),
                k(KeyCode::Tab, none),
                k(KeyCode::Char('R'), KeyModifiers::SHIFT),
                k(KeyCode::Char('c'), KeyModifiers::CONTROL),
                k(KeyCode::Enter, none),
                k(KeyCode::Backspace, none),
            ]
        );
        assert_eq!(keys("é".as_bytes()), vec![k(KeyCode::Char('é'), none)]);
    }

    #[test]
    fn escape_sequences_and_the_status_report() {
        let none = KeyModifiers::empty();
        assert_eq!(
            keys(b"\x1b[A\x1bOB\x1b[1;5C\x1b[Z\x1b[0n\x1b[5~\x1b[12;40R\x1b"),
            vec![
                k(KeyCode::Up, none),
                k(KeyCode::Down, none),
                k(KeyCode::Right, KeyModifiers::CONTROL),
                k(KeyCode::BackTab, KeyModifiers::SHIFT),
                Input::StatusReport,
                k(KeyCode::PageUp, none),
                // The cursor position report is ignored; a lone ESC is the Esc key.
                k(KeyCode::Esc, none),
            ]
        );
        assert_eq!(
            keys(b"\x1bq"),
            vec![k(KeyCode::Char('q'), KeyModifiers::ALT)]
        );
    }

    #[test]
    fn a_sequence_split_across_reads_is_kept_until_complete() {
        let mut p = Parser::default();
        assert_eq!(
            p.feed(b"x\x1b[0"),
            vec![k(KeyCode::Char('x'), KeyModifiers::empty())]
        );
        assert_eq!(p.feed(b"n\x1b[1;"), vec![Input::StatusReport]);
        assert_eq!(p.feed(b"2A"), vec![k(KeyCode::Up, KeyModifiers::SHIFT)]);
        let euro = "€".as_bytes();
        assert_eq!(p.feed(&euro[..1]), vec![]);
        assert_eq!(
            p.feed(&euro[1..]),
            vec![k(KeyCode::Char('€'), KeyModifiers::empty())]
        );
    }
}
