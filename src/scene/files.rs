//! Writing files safely: every file Gloam writes (levels, generated assets, reports) goes
//! through `write_atomically`, so a crash or a full disk never leaves a half-written file.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use anyhow::Context as _;

/// Writes `bytes` to a temporary file beside `path`, flushes it to the disk, renames it over
/// `path` and flushes the folder, so a reader never sees a half-written file and a power
/// cut after this returns cannot lose the new one. Creates missing parent folders.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let folder = match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent.to_owned(),
        _ => PathBuf::from("."),
    };
    std::fs::create_dir_all(&folder)
        .with_context(|| format!("cannot create folder '{}'", folder.display()))?;
    let file_name = path
        .file_name()
        .with_context(|| format!("'{}' has no file name", path.display()))?;
    let temporary = folder.join(format!(
        ".{}.{}-{}.tmp",
        file_name.to_string_lossy(),
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let result = (|| -> std::io::Result<()> {
        let mut file = std::fs::File::create(&temporary)?;
        file.write_all(bytes)?;
        file.sync_all()?;
        std::fs::rename(&temporary, path)?;
        // The rename lives in the folder's entries: without this a crash can bring back
        // the old file (POSIX leaves it to the folder's own fsync).
        #[cfg(unix)]
        std::fs::File::open(&folder)?.sync_all()?;
        Ok(())
    })();
    if let Err(error) = result {
        let _ = std::fs::remove_file(&temporary);
        return Err(error).with_context(|| format!("cannot write '{}'", path.display()));
    }
    Ok(())
}

/// The level played and measured when none is named: levels/first-light.ron under the
/// working folder, else in the source tree Gloam was built from.
pub fn default_level() -> PathBuf {
    let relative = PathBuf::from("levels/first-light.ron");
    if relative.exists() {
        relative
    } else {
        Path::new(env!("CARGO_MANIFEST_DIR")).join(relative)
    }
}

/// `path` made absolute (from the working folder) with `.` and `..` worked out, without
/// asking the file system: the same file named two ways compares equal.
pub fn absolute(path: &Path) -> PathBuf {
    let whole = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut out = PathBuf::new();
    for part in whole.components() {
        match part {
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}

/// The project's assets folder for the level file `level`: `assets/` beside the level's
/// folder (levels/ and assets/ are siblings), else the one Gloam was built from.
pub fn assets_folder(level: &Path) -> PathBuf {
    let beside = level
        .parent()
        .and_then(Path::parent)
        .map(|root| root.join("assets"));
    match beside {
        Some(folder) if folder.is_dir() => folder,
        _ => Path::new(env!("CARGO_MANIFEST_DIR")).join("assets"),
    }
}
