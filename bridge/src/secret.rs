//! The run's secret: what a host must prove it knows before its zenoh session is
//! accepted.
//!
//! Why zenoh's user/password authentication (cargo feature `auth_usrpwd`): it needs no
//! new dependency (the HMAC is zenoh's own), builds in seconds, and the password never
//! crosses the wire: the accepting side sends a random nonce, the joining side answers
//! HMAC(nonce, password), and a session whose answer is wrong (or absent) is closed
//! before any message is routed. Public-key auth pulls in RSA, TLS pulls in rustls and
//! a certificate authority to manage; both are heavier than a shared secret per run
//! warrants. What it does not give: the link is not encrypted (the run's data can be
//! read on the wire) and a joining host does not authenticate the learner's host. Use a
//! private network or a VPN between hosts that must not be overheard.
//!
//! The secret is 32 random bytes, hex, generated into the run directory as `secret`
//! (owner-only, mode 600, written atomically) the first time the run's bridge listens,
//! and kept across `--resume`. The file is also zenoh's user dictionary
//! (`fulcrum:<hex>`, one line). An actor host reads it from the environment
//! ([`SECRET_ENV`]) or from a copy of the file (`--secret-file`), never from its
//! command line, which every user of the machine can read in `ps`.

use std::io::Read;
use std::os::unix::fs::{OpenOptionsExt, PermissionsExt};
use std::path::{Path, PathBuf};

use crate::error::refuse;
use crate::error::{Context, Result};

/// The name of the secret's file in the run directory.
pub const SECRET_FILE: &str = "secret";
/// The environment variable an actor host may take the secret from.
pub const SECRET_ENV: &str = "FULCRUM_SECRET";
/// The user name every host presents (the password is what matters).
pub const USER: &str = "fulcrum";

/// A run's secret (64 hex digits).
#[derive(Clone, PartialEq, Eq)]
pub struct Secret(String);

impl std::fmt::Debug for Secret {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Secret(***)")
    }
}

impl Secret {
    /// The secret as text (for the line that tells users how to join).
    pub fn expose(&self) -> &str {
        &self.0
    }

    /// Parse a secret from text: `<hex>` or the file's `fulcrum:<hex>`; `what` names
    /// where it came from.
    pub fn parse(text: &str, what: &str) -> Result<Secret> {
        let t = text.trim();
        let hex = t.strip_prefix(&format!("{USER}:")).unwrap_or(t);
        if hex.len() < 32 || !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
            return refuse(format!(
                "{what} does not hold a run secret (at least 32 hex digits, as in the run directory's '{SECRET_FILE}' file)"
            ));
        }
        Ok(Secret(hex.to_ascii_lowercase()))
    }

    /// Read a secret from a file.
    pub fn from_file(path: &Path) -> Result<Secret> {
        let text = match std::fs::read_to_string(path) {
            Ok(t) => t,
            Err(e) => {
                return refuse(format!(
                    "cannot read the secret file {}: {e}",
                    path.display()
                ))
            }
        };
        Secret::parse(&text, &path.display().to_string())
    }

    /// The secret from `file` if given, else from [`SECRET_ENV`]; `None` when neither.
    pub fn from_file_or_env(file: Option<&Path>) -> Result<Option<Secret>> {
        if let Some(p) = file {
            return Secret::from_file(p).map(Some);
        }
        match std::env::var(SECRET_ENV) {
            Ok(v) if !v.trim().is_empty() => Secret::parse(&v, SECRET_ENV).map(Some),
            _ => Ok(None),
        }
    }

    /// The run's secret in `dir`, generated (owner-only, atomically) when there is none.
    pub fn for_run(dir: &Path) -> Result<(Secret, PathBuf)> {
        let path = dir.join(SECRET_FILE);
        if path.exists() {
            let s = Secret::from_file(&path)?;
            let mode = std::fs::metadata(&path)?.permissions().mode() & 0o777;
            if mode & 0o077 != 0 {
                std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600))
                    .with_context(|| format!("cannot make {} owner-only", path.display()))?;
            }
            return Ok((s, path));
        }
        let mut bytes = [0u8; 32];
        std::fs::File::open("/dev/urandom")
            .and_then(|mut f| f.read_exact(&mut bytes))
            .context("cannot read /dev/urandom for the run's secret")?;
        let s = Secret(bytes.iter().map(|b| format!("{b:02x}")).collect());
        let path = s.write_dictionary(dir)?;
        Ok((s, path))
    }

    /// Write the secret into `dir` as [`SECRET_FILE`], zenoh's user dictionary
    /// (`fulcrum:<hex>`): owner-only, atomically; returns its path.
    pub fn write_dictionary(&self, dir: &Path) -> Result<PathBuf> {
        let path = dir.join(SECRET_FILE);
        // The temporary file is created owner-only before anything is written to it,
        // so the secret is never readable by others, not even for a moment.
        let tmp = dir.join(format!(".{SECRET_FILE}.tmp-{}", std::process::id()));
        let _ = std::fs::remove_file(&tmp);
        std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .mode(0o600)
            .open(&tmp)
            .with_context(|| format!("cannot create {}", tmp.display()))?;
        let line = format!("{USER}:{}\n", self.0);
        fulcrum_contracts::fsio::replace_via(&path, &tmp, line.as_bytes(), false).map_err(
            |(what, e)| crate::error::Contextual {
                what: what.to_string(),
                source: Some(Box::new(e)),
            },
        )?;
        Ok(path)
    }

    /// Set zenoh's user/password authentication: every session presents the secret;
    /// `dictionary` (the listening side's secret file) makes the session demand it of
    /// every peer that connects.
    pub(crate) fn configure(
        &self,
        c: &mut zenoh::Config,
        dictionary: Option<&Path>,
    ) -> Result<(), zenoh::Error> {
        let q = |s: &str| serde_json::to_string(s).expect("a string serialises");
        c.insert_json5("transport/auth/usrpwd/user", &q(USER))?;
        c.insert_json5("transport/auth/usrpwd/password", &q(&self.0))?;
        if let Some(d) = dictionary {
            c.insert_json5(
                "transport/auth/usrpwd/dictionary_file",
                &q(&d.display().to_string()),
            )?;
        }
        Ok(())
    }
}
