//! The terminal while the preview owns it: raw mode and the alternate screen, stderr sent to
//! the log (native drivers print there), and a restore that runs on every exit path: normal
//! return, error, panic (hook), SIGTERM/SIGHUP (via the event loop).

use ratatui::crossterm::{cursor, execute, terminal};
use std::io::{self, Write};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicI32, AtomicU64, Ordering};

/// True while the terminal is in raw mode on the alternate screen.
static ACTIVE: AtomicBool = AtomicBool::new(false);
/// The original stderr, while fd 2 points elsewhere.
static SAVED_STDERR: AtomicI32 = AtomicI32::new(-1);

/// What removes the preview's pixel graphics on exit (set once the protocol is known).
static CLEAR: std::sync::OnceLock<String> = std::sync::OnceLock::new();

/// Sets what `restore` writes to remove the preview's pixel graphics.
pub fn set_clear(seq: String) {
    let _ = CLEAR.set(seq);
}

/// Owns the terminal; dropping it restores everything.
pub struct TerminalGuard;

impl TerminalGuard {
    /// Enters raw mode and the alternate screen; stderr goes to `log` (or nowhere).
    pub fn enter(log: Option<&Path>) -> io::Result<TerminalGuard> {
        redirect_stderr(log)?;
        install_panic_hook();
        terminal::enable_raw_mode()?;
        ACTIVE.store(true, Ordering::SeqCst);
        execute!(
            io::stdout(),
            terminal::EnterAlternateScreen,
            cursor::Hide,
            terminal::DisableLineWrap
        )?;
        Ok(TerminalGuard)
    }
}

impl Drop for TerminalGuard {
    fn drop(&mut self) {
        restore();
    }
}

/// Leaves the alternate screen and raw mode, shows the cursor, gives stderr back. Safe to call
/// more than once and from a panic hook.
pub fn restore() {
    if ACTIVE.swap(false, Ordering::SeqCst) {
        let mut out = io::stdout();
        // A kitty image would otherwise stay on screen in some terminals.
        if let Some(clear) = CLEAR.get() {
            let _ = out.write_all(clear.as_bytes());
        }
        let _ = execute!(
            out,
            terminal::EnableLineWrap,
            terminal::LeaveAlternateScreen,
            cursor::Show
        );
        let _ = terminal::disable_raw_mode();
    }
    restore_stderr();
}

fn install_panic_hook() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            // A device's failure on its own thread is caught and the preview goes on
            // (`render::failure`): the terminal stays as it is; stderr goes to the log.
            if !crate::render::failure::containing() {
                restore();
            }
            previous(info);
        }));
    });
}

#[cfg(unix)]
fn redirect_stderr(log: Option<&Path>) -> io::Result<()> {
    use std::os::fd::AsRawFd;
    let target = match log {
        Some(p) => std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(p)?,
        None => std::fs::OpenOptions::new().write(true).open("/dev/null")?,
    };
    // SAFETY: dup/dup2 on valid descriptors; the saved copy is closed in restore_stderr.
    unsafe {
        let saved = libc::dup(2);
        if saved < 0 {
            return Err(io::Error::last_os_error());
        }
        if libc::dup2(target.as_raw_fd(), 2) < 0 {
            libc::close(saved);
            return Err(io::Error::last_os_error());
        }
        SAVED_STDERR.store(saved, Ordering::SeqCst);
    }
    Ok(())
}

#[cfg(unix)]
fn restore_stderr() {
    let saved = SAVED_STDERR.swap(-1, Ordering::SeqCst);
    if saved >= 0 {
        // SAFETY: `saved` is the descriptor dup'ed in redirect_stderr.
        unsafe {
            libc::dup2(saved, 2);
            libc::close(saved);
        }
    }
}

#[cfg(not(unix))]
fn redirect_stderr(_log: Option<&Path>) -> io::Result<()> {
    Ok(())
}

#[cfg(not(unix))]
fn restore_stderr() {}

/// Stdout that counts the bytes written through it (for `--max-kbps` and the benchmark).
pub struct CountingWriter {
    /// A frame is hundreds of small writes (a cursor move, colours, a glyph per cell): they
    /// collect here and reach the terminal in a few large writes when the frame is flushed,
    /// not in 1 KiB pieces through stdout's line buffer.
    inner: io::BufWriter<io::Stdout>,
    count: Arc<AtomicU64>,
}

/// Bytes a frame may collect before they are written: a whole noisy 240×70 frame.
const FRAME_BUFFER: usize = 1 << 20;

impl CountingWriter {
    pub fn new(count: Arc<AtomicU64>) -> CountingWriter {
        CountingWriter {
            inner: io::BufWriter::with_capacity(FRAME_BUFFER, io::stdout()),
            count,
        }
    }
}

impl Write for CountingWriter {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.count.fetch_add(n as u64, Ordering::Relaxed);
        Ok(n)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}
