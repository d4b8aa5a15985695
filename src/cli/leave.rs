//! How the process ends: at once where a GPU driver is still compiling on another thread.

use std::process::ExitCode;

/// The code `main` returns for a command that ended with `code`, or, where a GPU pipeline is
/// still being compiled on another thread, the process ended at once with it (`exit`).
pub fn finish(code: ExitCode) -> ExitCode {
    if crate::gpu::trace::compiles_in_flight() == 0 {
        return code;
    }
    // (`ExitCode` does not give its number back.)
    let status = (0..=u8::MAX).find(|&k| ExitCode::from(k) == code);
    exit(status.unwrap_or(1))
}

/// Ends the process with `status`. Where a GPU pipeline is still being compiled on another
/// thread (`gpu::trace::compiles_in_flight`: the tuner's generic pipeline, which NVIDIA's
/// driver can take a minute over), it ends at once (`_exit`) after flushing stdout: a normal
/// exit runs the driver's library destructors under its compiler, and NVIDIA's (580) then
/// crashed with SIGSEGV after the render had been written. The outputs are in place by then
/// (written and renamed), and the operating system frees the rest.
pub fn exit(status: u8) -> ! {
    use std::io::Write;
    let _ = std::io::stdout().flush();
    let _ = std::io::stderr().flush();
    if crate::gpu::trace::compiles_in_flight() == 0 {
        std::process::exit(i32::from(status));
    }
    // SAFETY: `_exit` only ends the process; nothing runs after it.
    unsafe { libc::_exit(i32::from(status)) }
}
