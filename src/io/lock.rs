//! One writer per run folder: `run.lock`, held with an advisory file lock (`flock`) for as long
//! as a run trains. The kernel releases the lock when its process ends, however it ends, so a
//! lock left by a killed process never blocks a resume; the file itself only records who held
//! it last, for the message.

use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, Write};
use std::path::Path;

use crate::error::{Error, Result};

/// The lock of a run folder, released when dropped (or when the process ends).
#[derive(Debug)]
pub struct RunLock {
    _file: File,
}

impl RunLock {
    /// Takes the lock of `run_dir` (which must exist), or says which process holds it.
    pub fn acquire(run_dir: &Path) -> Result<Self> {
        let path = run_dir.join("run.lock");
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(|e| crate::file_error!(&path, "cannot open: {e}"))?;
        // `ipfn view` probes the lock for a moment with a shared lock: retry briefly.
        let mut attempt = file.try_lock();
        for _ in 0..20 {
            if !matches!(attempt, Err(TryLockError::WouldBlock)) {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(25));
            attempt = file.try_lock();
        }
        match attempt {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => {
                let mut holder = String::new();
                let _ = file.read_to_string(&mut holder);
                let holder = holder.trim();
                let who = if holder.is_empty() {
                    "another process".to_string()
                } else {
                    format!("another process ({holder})")
                };
                return Err(crate::file_error!(
                    &run_dir,
                    "this run is in use by {who}; wait for it to end, or stop it (SIGTERM or Ctrl-C saves a checkpoint), then resume",
                ));
            }
            // A file system without locks (some network mounts): train unguarded.
            // ENOLCK (37): NFS without a lock daemon, some FUSE and CIFS mounts.
            Err(TryLockError::Error(e))
                if e.kind() == std::io::ErrorKind::Unsupported || e.raw_os_error() == Some(37) => {}
            Err(TryLockError::Error(e)) => {
                return Err(Error::Runtime(format!(
                    "{}: cannot lock: {e}",
                    path.display()
                )));
            }
        }
        let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap_or_default();
        let record = format!(
            "ipfn train, pid {}, host {}",
            std::process::id(),
            host.trim()
        );
        let _ = file
            .set_len(0)
            .and_then(|_| file.rewind())
            .and_then(|_| file.write_all(record.as_bytes()));
        Ok(Self { _file: file })
    }
}
