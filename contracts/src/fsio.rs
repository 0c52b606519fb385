//! Writing files so that nothing is lost: a reader sees the old file or the new one,
//! never half of either.
//!
//! [`write_atomic`] writes a temporary file beside the target, fsyncs it and renames it
//! over the target. A target that exists and is not a regular file (`/dev/null`,
//! `/dev/stdout`, a FIFO) is written in place instead: renaming over it would replace a
//! device node with a regular file, which on a shared machine breaks every later
//! process that reads `/dev/null` (cargo's own `rustc -` probe among them).
//!
//! Every temporary file is named `.<name>.tmp-<pid>-<n>` ([`temp_path`]): two writers
//! never share one (a shared name let two invocations truncate each other's checkpoint
//! into a mixed file), and one left by a writer that died is recognised by its dead pid
//! and removed ([`remove_stale_temps`], called when a run directory is locked).
//!
//! [`write_atomic`]: crate::fsio::write_atomic
//! [`temp_path`]: crate::fsio::temp_path
//! [`remove_stale_temps`]: crate::fsio::remove_stale_temps

use std::ffi::OsString;
use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Write `bytes` to `path` atomically: a temp file in the same directory, fsync, then
/// rename over `path`. On any error the temp file is removed and `path` is left as it
/// was. A `path` that exists and is not a regular file (a device, a FIFO, a socket, or
/// a link to one) is opened and written in place; a directory is an error.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    if let Ok(meta) = fs::metadata(path) {
        if meta.is_dir() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("{} is a directory", path.display()),
            ));
        }
        if !meta.is_file() {
            return OpenOptions::new().write(true).open(path)?.write_all(bytes);
        }
    }
    let tmp = temp_path(path)?;
    replace_via(path, &tmp, bytes, true).map_err(|(_, e)| e)
}

/// A temporary path beside `path` that no other writer uses:
/// `.<name>.tmp-<pid>-<n>`, `n` counting this process's temporary files.
pub fn temp_path(path: &Path) -> io::Result<PathBuf> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let name = path.file_name().ok_or_else(|| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{} does not name a file", path.display()),
        )
    })?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let mut tmp_name = OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(
        ".tmp-{}-{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    Ok(dir.join(tmp_name))
}

/// The writer's pid of a name made by [`temp_path`]; None for other names.
fn temp_writer(name: &str) -> Option<u32> {
    let rest = name.strip_prefix('.')?;
    let (_, tail) = rest.rsplit_once(".tmp-")?;
    let (pid, n) = tail.split_once('-')?;
    n.parse::<u64>().ok()?;
    pid.parse().ok()
}

/// Remove the temporary files in `dir` (not below it) whose writer has exited: what a
/// writer killed between creating and renaming its temporary file left. Returns how
/// many went. Files of live writers, and every other file, stay.
pub fn remove_stale_temps(dir: &Path) -> io::Result<usize> {
    let mut removed = 0;
    for e in fs::read_dir(dir)? {
        let e = e?;
        let name = e.file_name();
        let Some(pid) = name.to_str().and_then(temp_writer) else {
            continue;
        };
        // SAFETY: kill with signal 0 only checks whether the process exists.
        let alive = pid == std::process::id()
            || unsafe { libc::kill(pid as libc::pid_t, 0) } == 0
            || io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH);
        if !alive && e.file_type()?.is_file() {
            fs::remove_file(e.path())?;
            removed += 1;
        }
    }
    Ok(removed)
}

/// The one way fulcrum replaces a file: write `bytes` to `tmp` (a path in the same
/// directory as `path`; `create_new` refuses one that exists, otherwise it is
/// truncated), fsync it, rename it over `path`, fsync the directory. On an error the
/// temporary file is removed (when it was ours) and the error says which step failed.
pub fn replace_via(
    path: &Path,
    tmp: &Path,
    bytes: &[u8],
    create_new: bool,
) -> Result<(), (String, io::Error)> {
    let mut file = OpenOptions::new()
        .write(true)
        .create(true)
        .create_new(create_new)
        .truncate(!create_new)
        .open(tmp)
        .map_err(|e| {
            (
                format!("cannot create the temporary file {}", tmp.display()),
                e,
            )
        })?;
    let written = file
        .write_all(bytes)
        .map_err(|e| (format!("cannot write {}", tmp.display()), e))
        .and_then(|()| {
            file.sync_all()
                .map_err(|e| (format!("cannot fsync {}", tmp.display()), e))
        })
        .and_then(|()| {
            drop(file);
            fs::rename(tmp, path)
                .map_err(|e| (format!("cannot rename {} over it", tmp.display()), e))
        });
    if let Err(e) = written {
        let _ = fs::remove_file(tmp);
        return Err(e);
    }
    // Make the rename itself durable; not every platform can open a directory.
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if let Ok(d) = File::open(dir) {
        d.sync_all()
            .map_err(|e| (format!("cannot fsync the directory {}", dir.display()), e))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;
    use std::os::unix::fs::FileTypeExt;
    use std::path::PathBuf;

    struct TempDir(PathBuf);
    impl TempDir {
        fn new(tag: &str) -> TempDir {
            let p = std::env::temp_dir().join(format!(
                "fulcrum-fsio-{tag}-{}-{:?}",
                std::process::id(),
                std::thread::current().id()
            ));
            let _ = fs::remove_dir_all(&p);
            fs::create_dir_all(&p).expect("temp dir");
            TempDir(p)
        }
    }
    impl Drop for TempDir {
        fn drop(&mut self) {
            let _ = fs::remove_dir_all(&self.0);
        }
    }

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(dir)
            .expect("read dir")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn replaces_a_regular_file_and_leaves_no_temp_file() {
        let dir = TempDir::new("regular");
        let path = dir.0.join("f.json");
        write_atomic(&path, b"one").expect("write");
        write_atomic(&path, b"two").expect("overwrite");
        assert_eq!(fs::read(&path).expect("read"), b"two");
        assert_eq!(entries(&dir.0), ["f.json"]);
        // A directory is refused by name and nothing is left beside it.
        let sub = dir.0.join("sub");
        fs::create_dir(&sub).expect("mkdir");
        let e = write_atomic(&sub, b"x").expect_err("a directory");
        assert!(e.to_string().contains("is a directory"), "{e}");
        assert_eq!(entries(&dir.0), ["f.json", "sub"]);
        assert!(write_atomic(&dir.0.join("missing").join("f"), b"x").is_err());
        assert!(write_atomic(Path::new("/"), b"x").is_err());
    }

    /// The failure this guards against: `--json /dev/null` renamed a regular file over
    /// the device node. A FIFO stands in for the device so that a wrong implementation
    /// cannot break this machine's `/dev/null`.
    #[test]
    fn writes_into_a_fifo_and_keeps_it_a_fifo() {
        let dir = TempDir::new("fifo");
        let fifo = dir.0.join("pipe");
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .expect("mkfifo runs");
        assert!(made.success(), "mkfifo {}", fifo.display());
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || {
                let mut got = Vec::new();
                File::open(&fifo)
                    .expect("open the fifo for reading")
                    .read_to_end(&mut got)
                    .expect("read the fifo");
                got
            })
        };
        write_atomic(&fifo, b"{\"steps\": 3}\n").expect("write into the fifo");
        // Checked before joining: a FIFO replaced by a file would leave the reader
        // waiting for a writer forever.
        let kind = fs::symlink_metadata(&fifo).expect("stat").file_type();
        assert!(kind.is_fifo(), "the fifo was replaced by {kind:?}");
        assert_eq!(reader.join().expect("reader"), b"{\"steps\": 3}\n");
        assert_eq!(entries(&dir.0), ["pipe"]);
    }

    /// Temporary names are unique per write, and a stale one (its writer gone) is
    /// cleaned while a live writer's and every other file stay.
    #[test]
    fn temp_names_are_unique_and_only_dead_writers_temps_are_cleaned() {
        let dir = TempDir::new("stale");
        let path = dir.0.join("latest.safetensors");
        let (a, b) = (temp_path(&path).unwrap(), temp_path(&path).unwrap());
        assert_ne!(a, b);
        let me = std::process::id();
        assert!(a
            .file_name()
            .unwrap()
            .to_str()
            .unwrap()
            .starts_with(&format!(".latest.safetensors.tmp-{me}-")));
        // A writer that has exited (reaped: its pid names no process now).
        let mut child = std::process::Command::new("true").spawn().expect("true");
        let dead = child.id();
        child.wait().expect("wait");
        let stale = dir.0.join(format!(".latest.safetensors.tmp-{dead}-3"));
        let live = dir.0.join(format!(".latest.safetensors.tmp-{me}-9"));
        for p in [&stale, &live, &path, &dir.0.join(".notes.tmp-x-1")] {
            fs::write(p, b"x").unwrap();
        }
        assert_eq!(remove_stale_temps(&dir.0).unwrap(), 1);
        assert_eq!(
            entries(&dir.0),
            [
                format!(".latest.safetensors.tmp-{me}-9"),
                ".notes.tmp-x-1".to_string(),
                "latest.safetensors".to_string()
            ]
        );
    }
}
