//! One error type for the library. Its variants say what went wrong as data: a file and its
//! problem ([`Error::File`]), a setting and the value it refused ([`Error::Setting`]), other
//! input the user can fix ([`Error::Input`]); all three are the user's to fix and map to exit
//! code 2 ([`Error::is_input`]). [`Error::Runtime`] is ours or the machine's (exit code 1).
//! Each displays as one line meant for a person.

use std::path::{Path, PathBuf};

/// An `ipfn` error, always a single line meant for a person.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file that cannot be used as given: a missing, corrupt or unsuitable file (the
    /// exemplar, a model, a run folder's state). Displays as `PATH: PROBLEM`.
    #[error("{}: {}", .path.display(), one_line(.problem))]
    File { path: PathBuf, problem: String },
    /// A setting (a flag, `--bits`, or a config key, `lr_decay`) whose value is refused, with
    /// what it accepts. Displays as `--bits 12: ACCEPTS` for a flag, `lr_decay = 2: ACCEPTS`
    /// for a config key.
    #[error("{}", setting_line(.name, .value, .accepts))]
    Setting {
        name: String,
        value: String,
        accepts: String,
    },
    /// Other input the user can fix: settings that do not go together, a request the input
    /// cannot satisfy.
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
    /// `PATH: PROBLEM`, the user's to fix.
    pub fn file(path: impl AsRef<Path>, problem: impl Into<String>) -> Self {
        Error::File {
            path: path.as_ref().to_path_buf(),
            problem: problem.into(),
        }
    }

    /// A refused value of setting `name` (`--flag` or a config key) and what it accepts.
    pub fn setting(name: &str, value: impl ToString, accepts: impl Into<String>) -> Self {
        Error::Setting {
            name: name.to_string(),
            value: value.to_string(),
            accepts: accepts.into(),
        }
    }

    /// The user's to fix (exit code 2): a file, a setting or other input.
    pub fn is_input(&self) -> bool {
        matches!(
            self,
            Error::File { .. } | Error::Setting { .. } | Error::Input(_)
        )
    }

    /// The file this error is about, if it names one.
    pub fn path(&self) -> Option<&Path> {
        match self {
            Error::File { path, .. } => Some(path),
            _ => None,
        }
    }

    /// Input refused while reading `path` names it first: `PATH: the error`, an error about
    /// another file included (`run/latest.ipfn: photo.png: ...`, since the one file led to
    /// the other). An error already about `path` is not named twice; errors that are not the
    /// user's stay as they are.
    pub fn in_file(self, path: impl AsRef<Path>) -> Self {
        let path = path.as_ref();
        match self {
            Error::Input(problem) => Error::file(path, problem),
            Error::File { path: ref own, .. } if own == path => self,
            Error::File { .. } | Error::Setting { .. } => {
                let problem = self.to_string();
                Error::file(path, problem)
            }
            other => other,
        }
    }

    /// Process exit code for this error.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Runtime(_) => 1,
            Error::Interrupted(_, signal) => crate::stop::exit_code(*signal),
            _ => 2,
        }
    }
}

/// A setting's refusal as the user typed it: a flag as on the command line, a config key as in
/// `config.toml`.
fn setting_line(name: &str, value: &str, accepts: &str) -> String {
    let accepts = one_line(accepts);
    match name.starts_with("--") {
        true => format!("{name} {value}: {accepts}"),
        false => format!("{name} = {value}: {accepts}"),
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

/// `Error::Input(format!(...))`.
#[macro_export]
macro_rules! input_error {
    ($($arg:tt)*) => { $crate::error::Error::Input(format!($($arg)*)) };
}

/// `Error::File { path, problem: format!(...) }`: `file_error!(path, "problem {x}")`.
#[macro_export]
macro_rules! file_error {
    ($path:expr, $($arg:tt)*) => { $crate::error::Error::file($path, format!($($arg)*)) };
}

/// `Error::Setting { name, value, accepts: format!(...) }`:
/// `setting_error!("--bits", bits, "8 or 16")`.
#[macro_export]
macro_rules! setting_error {
    ($name:expr, $value:expr, $($arg:tt)*) => {
        $crate::error::Error::setting($name, $value, format!($($arg)*))
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variants_display_as_the_one_line_a_person_reads() {
        let e = file_error!("a/b.png", "unreadable ({})", "bad\nheader");
        assert_eq!(e.to_string(), "a/b.png: unreadable (bad; header)");
        assert_eq!(e.path(), Some(Path::new("a/b.png")));
        let flag = setting_error!("--bits", 12, "PNG output is 8 or 16 bits per channel");
        assert_eq!(
            flag.to_string(),
            "--bits 12: PNG output is 8 or 16 bits per channel"
        );
        let key = setting_error!("lr_decay", 2.5, "from 0 to 1");
        assert_eq!(key.to_string(), "lr_decay = 2.5: from 0 to 1");
        for e in [&e, &flag, &key, &input_error!("x")] {
            assert_eq!(e.exit_code(), 2);
            assert!(e.is_input());
        }
        assert_eq!(Error::Runtime("disk".into()).exit_code(), 1);
    }

    #[test]
    fn an_error_is_named_after_its_file_once() {
        let named = input_error!("no such tensor").in_file("m.ipfn");
        assert_eq!(named.to_string(), "m.ipfn: no such tensor");
        // Already this file's: named once.
        let once = file_error!("m.ipfn", "corrupt").in_file("m.ipfn");
        assert_eq!(once.to_string(), "m.ipfn: corrupt");
        // Another file's, reached through this one: this file first.
        let through = file_error!("x.png", "missing").in_file("run/latest.ipfn");
        assert_eq!(through.to_string(), "run/latest.ipfn: x.png: missing");
        assert_eq!(through.path(), Some(Path::new("run/latest.ipfn")));
        let flag = setting_error!("--crop", 7, "a multiple of 16").in_file("run/latest.ipfn");
        assert_eq!(
            flag.to_string(),
            "run/latest.ipfn: --crop 7: a multiple of 16"
        );
        assert!(matches!(
            Error::Runtime("r".into()).in_file("f"),
            Error::Runtime(_)
        ));
    }
}
