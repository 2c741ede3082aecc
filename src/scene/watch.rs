//! Load time, again: notices when a level file or an asset it uses changes on disk, for
//! hot reload in the editor and in play (`notify`: inotify on Linux).
//!
//! Each watched file's folder is watched, not the file: editors (and Gloam's own
//! `write_atomically`) replace a file by renaming a new one over it, which a watch on the
//! old file would not see. A burst of events (write, rename, metadata) is reported once,
//! when the files have been quiet for `QUIET`.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, channel};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use notify::{RecursiveMode, Watcher as _};

use super::files::absolute;

/// How long changes must stop before they are reported (one save is several events).
pub const QUIET: Duration = Duration::from_millis(150);

pub struct FileWatch {
    watcher: notify::RecommendedWatcher,
    events: Receiver<notify::Result<notify::Event>>,
    /// The files whose changes are reported (absolute, `.` and `..` worked out).
    files: BTreeSet<PathBuf>,
    folders: BTreeSet<PathBuf>,
    /// Watched files changed since the last report, and when the last change came.
    changed: BTreeSet<PathBuf>,
    last_change: Option<Instant>,
}

impl FileWatch {
    /// Starts watching `files` (a level and the assets it uses).
    pub fn new(files: impl IntoIterator<Item = PathBuf>) -> anyhow::Result<FileWatch> {
        let (sender, events) = channel();
        let watcher = notify::recommended_watcher(move |event| {
            let _ = sender.send(event);
        })
        .context("starting to watch files for changes")?;
        let mut watch = FileWatch {
            watcher,
            events,
            files: BTreeSet::new(),
            folders: BTreeSet::new(),
            changed: BTreeSet::new(),
            last_change: None,
        };
        watch.set_files(files)?;
        Ok(watch)
    }

    /// Watches `files` from now on (the level placed a new asset, say).
    pub fn set_files(&mut self, files: impl IntoIterator<Item = PathBuf>) -> anyhow::Result<()> {
        self.files = files.into_iter().map(|file| absolute(&file)).collect();
        for folder in self.files.iter().filter_map(|file| file.parent()) {
            if self.folders.insert(folder.to_owned()) {
                self.watcher
                    .watch(folder, RecursiveMode::NonRecursive)
                    .with_context(|| format!("watching {} for changes", folder.display()))?;
            }
        }
        Ok(())
    }

    /// Whether `file` is watched.
    pub fn watches(&self, file: &Path) -> bool {
        self.files.contains(&absolute(file))
    }

    /// Whether watched files have changed since the last `poll` reported (settled or
    /// not): a cheap check for a loop that only polls when there is news. Never blocks.
    pub fn has_changes(&mut self) -> bool {
        self.receive();
        !self.changed.is_empty()
    }

    /// The watched files that changed, once changes have stopped for `QUIET`; empty
    /// otherwise. Never blocks.
    pub fn poll(&mut self) -> Vec<PathBuf> {
        self.receive();
        match self.last_change {
            Some(at) if at.elapsed() >= QUIET => {
                self.last_change = None;
                std::mem::take(&mut self.changed).into_iter().collect()
            }
            _ => Vec::new(),
        }
    }

    /// Takes in the watcher's events so far.
    fn receive(&mut self) {
        while let Ok(event) = self.events.try_recv() {
            let Ok(event) = event else { continue };
            if event.kind.is_access() {
                continue;
            }
            for path in event.paths {
                let path = absolute(&path);
                if self.files.contains(&path) {
                    self.changed.insert(path);
                    self.last_change = Some(Instant::now());
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_replaced_by_rename_is_reported_once_after_it_settles() {
        let dir = std::env::temp_dir().join(format!("gloam-watch-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let level = dir.join("x.ron");
        let other = dir.join("unwatched.ron");
        std::fs::write(&level, "one").unwrap();
        let mut watch = FileWatch::new([dir.join(".").join("x.ron")]).unwrap();
        assert!(watch.watches(&level));
        crate::scene::files::write_atomically(&level, b"two").unwrap();
        std::fs::write(&other, "not watched").unwrap();
        let mut noticed = false;
        let mut reported = Vec::new();
        for _ in 0..100 {
            noticed |= watch.has_changes();
            reported.extend(watch.poll());
            if !reported.is_empty() {
                break;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        assert_eq!(reported, [absolute(&level)]);
        assert!(noticed, "has_changes saw it first");
        std::thread::sleep(QUIET * 2);
        assert!(!watch.has_changes());
        assert!(watch.poll().is_empty(), "reported once");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
