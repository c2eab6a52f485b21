//! Stopping on Ctrl-C (SIGINT) or SIGTERM (what schedulers, `timeout` and `kill` send).
//!
//! A job that can stop cleanly (training) installs [`OnSignal::FinishStep`] and reads
//! [`flag`] between steps: the first signal lets the current step end and a checkpoint be
//! saved, and the job then exits with `128 + signal` (130 for Ctrl-C, 143 for SIGTERM). A
//! second signal exits at once. Every other command installs [`OnSignal::ExitNow`]. Either way,
//! the temporary files of writes still in progress ([`crate::io::AtomicFile`] registers them)
//! are removed before the process exits, so a stop never leaves a half-written file behind.

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicI32, AtomicU8, Ordering};

use signal_hook::consts::{SIGINT, SIGTERM};
use signal_hook::iterator::Signals;

/// What the first signal does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OnSignal {
    /// Raise [`flag`]; the job stops at its next safe point. A second signal exits at once.
    FinishStep,
    /// Remove temporary files and exit at once.
    ExitNow,
}

static MODE: AtomicU8 = AtomicU8::new(0);
static STOP: AtomicBool = AtomicBool::new(false);
static SIGNAL: AtomicI32 = AtomicI32::new(0);
static TEMPORARIES: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
static INSTALLED: std::sync::Once = std::sync::Once::new();

/// Handles SIGINT and SIGTERM from now on, as `mode` says (a later call changes the mode).
pub fn install(mode: OnSignal) {
    MODE.store(mode as u8, Ordering::SeqCst);
    INSTALLED.call_once(|| {
        // Registration fails only where signals cannot be handled; the defaults then apply.
        let Ok(mut signals) = Signals::new([SIGINT, SIGTERM]) else {
            return;
        };
        std::thread::spawn(move || {
            for signal in signals.forever() {
                let first = !STOP.swap(true, Ordering::SeqCst);
                if first {
                    SIGNAL.store(signal, Ordering::SeqCst);
                }
                if first && MODE.load(Ordering::SeqCst) == OnSignal::FinishStep as u8 {
                    eprintln!(
                        "\n{}: finishing this iteration and saving a checkpoint ({} again to quit at once)",
                        name(signal),
                        name(signal)
                    );
                    continue;
                }
                remove_temporaries();
                // `_exit`: no atexit handlers (a GPU driver's teardown) racing the main thread.
                signal_hook::low_level::exit(128 + signal);
            }
        });
    });
}

/// Raised by the first signal under [`OnSignal::FinishStep`].
pub fn flag() -> &'static AtomicBool {
    &STOP
}

/// The signal that asked to stop, if one did.
pub fn signal() -> Option<i32> {
    match SIGNAL.load(Ordering::SeqCst) {
        0 => None,
        s => Some(s),
    }
}

/// The exit code after a stop by `signal`: 128 + its number (130 for SIGINT, 143 for SIGTERM).
pub fn exit_code(signal: i32) -> i32 {
    128 + signal
}

/// How a signal is called in messages.
pub fn name(signal: i32) -> &'static str {
    match signal {
        SIGINT => "interrupted (Ctrl-C)",
        SIGTERM => "terminated (SIGTERM)",
        _ => "stopped",
    }
}

/// Remembers a temporary file being written, to be removed if a signal ends the process.
pub(crate) fn register_temporary(path: &Path) {
    if let Ok(mut list) = TEMPORARIES.lock() {
        list.push(path.to_path_buf());
    }
}

/// Forgets a temporary file that was renamed into place or removed.
pub(crate) fn forget_temporary(path: &Path) {
    if let Ok(mut list) = TEMPORARIES.lock()
        && let Some(i) = list.iter().position(|p| p == path)
    {
        list.swap_remove(i);
    }
}

fn remove_temporaries() {
    if let Ok(list) = TEMPORARIES.lock() {
        for path in list.iter() {
            let _ = std::fs::remove_file(path);
        }
    }
}
