//! Why the preview could not open, or ended on an error.

/// Why the preview could not open, or ended on an error.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    #[error(transparent)]
    Scene(#[from] crate::scene::SceneError),
    #[error(transparent)]
    Device(#[from] crate::render::OpenError),
    #[error(transparent)]
    TooLarge(#[from] crate::render::TooLarge),
    #[error(
        "the live preview needs a terminal on stdin and stdout; for files use `termtrace \
         render {scene} -o out.png`"
    )]
    NoTerminal { scene: String },
    #[error("the terminal: {0}")]
    Terminal(#[from] std::io::Error),
    #[error("an escape sequence could not be formatted")]
    Format(#[from] std::fmt::Error),
}
