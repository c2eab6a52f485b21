//! One error type for the library. [`Error::Input`] is the user's to fix (bad file, bad flag,
//! bad size) and maps to exit code 2; [`Error::Runtime`] is ours or the machine's (exit code 1).

/// An `ipfn` error, always a single line meant for a person.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Bad input: a missing or corrupt file, an impossible size, an unknown option.
    #[error("{}", one_line(.0))]
    Input(String),
    /// Something failed that the user's input does not explain.
    #[error("{}", one_line(.0))]
    Runtime(String),
    /// Stopped by a signal (Ctrl-C, SIGTERM: its number) after saving what there was to save.
    #[error("{}", one_line(.0))]
    Interrupted(String, i32),
}

impl Error {
    /// Process exit code for this error.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Input(_) => 2,
            Error::Runtime(_) => 1,
            Error::Interrupted(_, signal) => crate::stop::exit_code(*signal),
        }
    }
}

/// A message as one line: decoders' messages (a parser's caret diagram, a trailing newline)
/// are joined with "; ", so every error stays a single line for a person and a log.
pub fn one_line(message: &str) -> String {
    message
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join("; ")
}

pub type Result<T> = std::result::Result<T, Error>;

/// `Err(Error::Input(format!(...)))`.
#[macro_export]
macro_rules! input_error {
    ($($arg:tt)*) => { $crate::error::Error::Input(format!($($arg)*)) };
}
