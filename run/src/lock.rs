//! One invocation per directory: a run directory (or an experiment directory) belongs
//! to the `fulcrum` process that locked it, and to the processes it started.
//!
//! The lock is an advisory `flock(2)` on `DIR/.lock`, a file that holds the locker's
//! pid (for the message a second invocation gets). Two invocations on one directory
//! would otherwise both append to `metrics.csv`, both write the checkpoint, or (an
//! experiment) delete a run another invocation is training.
//!
//! Why `flock` and this lifetime: the kernel releases the lock when the last file
//! descriptor of its open file description closes, so a killed process never blocks
//! the next start. The supervisor's descriptor is inherited by its children (no
//! close-on-exec: see [`DirLock::inherit`]), so the lock outlives a killed supervisor
//! exactly as long as its learner, actors and service still run (they die with it
//! within seconds, `PR_SET_PDEATHSIG`), and no new run can start under them.
//!
//! Who locks: `train` (a new run, `--out`, `--resume`) and `experiment` (its
//! directory; and it never clears a run directory someone else holds). `record` does
//! not: it only reads the checkpoint, which is always whole (replaced by rename), and
//! looking at a policy while it trains is a use, not a conflict.

use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, SeekFrom, Write};
use std::os::fd::AsRawFd;
use std::path::{Path, PathBuf};

/// The lock file's name inside a directory.
pub const LOCK_FILE: &str = ".lock";

/// Why a directory could not be locked.
#[derive(Debug, thiserror::Error)]
pub enum LockError {
    /// Another invocation holds it.
    #[error("{dir} is in use by another fulcrum invocation (pid {pid}, or the processes it started); wait for it to end or stop it")]
    Held {
        /// The directory.
        dir: PathBuf,
        /// The holder's pid as its lock file says ("unknown" while it is being written).
        pid: String,
    },
    /// The lock file could not be opened, locked or written.
    #[error("cannot lock {path}: {source}")]
    Io {
        /// The lock file.
        path: PathBuf,
        /// What failed.
        source: std::io::Error,
    },
}

impl From<LockError> for crate::error::Error {
    fn from(e: LockError) -> Self {
        crate::error::Error::Source(Box::new(e))
    }
}

/// A held lock on a directory; released when dropped (and by the kernel when this
/// process and every child that inherited it have exited).
#[derive(Debug)]
pub struct DirLock {
    file: File,
    dir: PathBuf,
}

impl DirLock {
    /// Lock `dir` (which must exist) for this process, or say who holds it. The lock
    /// file gets this process's pid.
    pub fn acquire(dir: &Path) -> Result<DirLock, LockError> {
        let path = dir.join(LOCK_FILE);
        let io = |source| LockError::Io {
            path: path.clone(),
            source,
        };
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(io)?;
        // SAFETY: flock on a descriptor this function owns.
        if unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } != 0 {
            let e = std::io::Error::last_os_error();
            if e.raw_os_error() != Some(libc::EWOULDBLOCK) {
                return Err(io(e));
            }
            let mut pid = String::new();
            let _ = file.read_to_string(&mut pid);
            let pid = pid.trim();
            return Err(LockError::Held {
                dir: dir.to_path_buf(),
                pid: if pid.is_empty() { "unknown" } else { pid }.to_string(),
            });
        }
        file.set_len(0)
            .and_then(|()| file.seek(SeekFrom::Start(0)))
            .and_then(|_| writeln!(file, "{}", std::process::id()))
            .map_err(io)?;
        Ok(DirLock {
            file,
            dir: dir.to_path_buf(),
        })
    }

    /// Whether another invocation holds `dir`'s lock (its pid if so); a directory
    /// without a lock file, or with a free one, is not held.
    pub fn holder(dir: &Path) -> Option<String> {
        if !dir.join(LOCK_FILE).exists() {
            return None;
        }
        match DirLock::acquire(dir) {
            Err(LockError::Held { pid, .. }) => Some(pid),
            _ => None,
        }
    }

    /// Let the child processes started from now on inherit the lock (clear
    /// close-on-exec), so that it is held until the last of them exits.
    pub fn inherit(self) -> Result<DirLock, LockError> {
        let fd = self.file.as_raw_fd();
        // SAFETY: fcntl on a descriptor this value owns.
        let ok = unsafe {
            let flags = libc::fcntl(fd, libc::F_GETFD);
            flags >= 0 && libc::fcntl(fd, libc::F_SETFD, flags & !libc::FD_CLOEXEC) == 0
        };
        if !ok {
            return Err(LockError::Io {
                path: self.dir.join(LOCK_FILE),
                source: std::io::Error::last_os_error(),
            });
        }
        Ok(self)
    }

    /// The locked directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

/// Lock `dir` for this invocation and its children: a directory held by another
/// invocation is a bad request (exit 2, one sentence naming the holder's pid).
pub fn lock_for_run(dir: &Path) -> crate::error::Result<DirLock> {
    match DirLock::acquire(dir).and_then(DirLock::inherit) {
        Ok(l) => Ok(l),
        Err(e @ LockError::Held { .. }) => Err(crate::error::BadRequest(e.to_string()).into()),
        Err(e) => Err(e.into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_lock_is_refused_with_the_holders_pid_and_free_after_drop() {
        let dir = std::env::temp_dir().join(format!("fulcrum-lock-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let first = DirLock::acquire(&dir).unwrap();
        // A second open file description of the same file conflicts even in this
        // process (flock locks belong to open file descriptions).
        match DirLock::acquire(&dir) {
            Err(LockError::Held { pid, .. }) => assert_eq!(pid, std::process::id().to_string()),
            other => panic!("expected Held, got {other:?}"),
        }
        assert_eq!(DirLock::holder(&dir), Some(std::process::id().to_string()));
        drop(first);
        assert_eq!(DirLock::holder(&dir), None);
        let again = DirLock::acquire(&dir).unwrap().inherit().unwrap();
        assert_eq!(again.dir(), dir.as_path());
        drop(again);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
