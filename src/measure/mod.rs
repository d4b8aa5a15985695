//! The measuring tools behind `termtrace bench --preview`: the live preview run in a
//! pseudo-terminal and timed as a user sees it (`preview`), and a real OpenSSH connection
//! through a throttled loopback link to run it over (`ssh_link`). The tests use them too.

pub mod preview;
pub mod ssh_link;

/// Why a measurement could not be made: a program that would not run, a link that would not
/// open, a preview that showed nothing.
#[derive(Debug, thiserror::Error)]
pub enum MeasureError {
    #[error("{what}: {source}")]
    Io {
        what: String,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Os(#[from] std::io::Error),
    /// The pseudo-terminal (portable-pty reports its own errors as text).
    #[error("{what}: {message}")]
    Pty { what: String, message: String },
    #[error("{command} failed: {stderr}")]
    Failed { command: String, stderr: String },
    #[error("{0}")]
    Preview(String),
    #[error("{0}")]
    Link(String),
}

impl MeasureError {
    /// An I/O error with what was being done.
    pub(crate) fn io(what: impl Into<String>) -> impl FnOnce(std::io::Error) -> MeasureError {
        let what = what.into();
        move |source| MeasureError::Io { what, source }
    }

    /// A pseudo-terminal error with what was being done (`{:#}`: its whole chain).
    pub(crate) fn pty<E: std::fmt::Display>(what: &str) -> impl FnOnce(E) -> MeasureError + '_ {
        move |e| MeasureError::Pty {
            what: what.to_string(),
            message: format!("{e:#}"),
        }
    }
}
