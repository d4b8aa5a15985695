//! What reaches the UI thread, on one channel: terminal input (read on its own thread,
//! `spawn_input`), frames from the render thread, save progress and signals.

use super::app::Stats;
use super::input;
use crate::output::LinearImage;
use ratatui::crossterm::event::Event as TermEvent;
use ratatui::crossterm::terminal;
use std::sync::mpsc::Sender;
use std::time::Instant;

/// One preview frame.
pub struct Frame {
    /// The traced image averaged down by the request's `factor`.
    pub image: LinearImage,
    /// Per image pixel, the standard error of its value (see `Resolved::sigma`).
    pub sigma: Vec<f32>,
    /// The accumulation has stopped: the image is final.
    pub last: bool,
    pub stats: Stats,
    /// The `Request::Scene` this frame renders.
    pub generation: u64,
}

/// Everything that reaches the UI thread.
pub enum Event {
    Input(TermEvent),
    Frame(Box<Frame>),
    SaveProgress {
        done: u32,
        total: u32,
    },
    Saved(Result<String, super::save::SaveError>),
    /// Another device of the preview failed (what to tell the user); the others go on.
    DeviceLost(String),
    /// SIGTERM, SIGHUP or SIGINT from outside.
    Signal,
    /// The terminal answered a status query (`flow`): everything written before it has
    /// reached the terminal.
    StatusReport(Instant),
}

/// Reads the terminal's input on its own thread, so that input never waits on drawing:
/// keys, and the answers to the status queries that clock frames (`input`). Window size
/// changes come from SIGWINCH.
pub(super) fn spawn_input(tx: Sender<Event>) -> std::io::Result<()> {
    use std::io::Read;
    let keys = tx.clone();
    std::thread::Builder::new()
        .name("input".into())
        .spawn(move || {
            let mut parser = input::Parser::default();
            let mut buf = [0u8; 4096];
            let stdin = std::io::stdin();
            loop {
                let n = match stdin.lock().read(&mut buf) {
                    Ok(0) | Err(_) => break,
                    Ok(n) => n,
                };
                let now = Instant::now();
                for i in parser.feed(&buf[..n]) {
                    let ev = match i {
                        input::Input::Key(k) => Event::Input(TermEvent::Key(k)),
                        input::Input::StatusReport => Event::StatusReport(now),
                    };
                    if keys.send(ev).is_err() {
                        return;
                    }
                }
            }
        })?;
    #[cfg(unix)]
    {
        let mut signals = signal_hook::iterator::Signals::new([signal_hook::consts::SIGWINCH])?;
        std::thread::Builder::new()
            .name("resize".into())
            .spawn(move || {
                for _ in signals.forever() {
                    let Ok((w, h)) = terminal::size() else {
                        continue;
                    };
                    if tx.send(Event::Input(TermEvent::Resize(w, h))).is_err() {
                        break;
                    }
                }
            })?;
    }
    Ok(())
}
