//! The desktop's own file dialogs for the editor's Open and Save as (rfd), where the
//! desktop has them. On Linux rfd asks the XDG desktop portal over the session bus, else
//! runs zenity; a desktop with neither shows no Browse button, and the File menu's path
//! field, which is always there, does the same work.
//!
//! A dialog runs on a thread of its own, so the view keeps drawing behind it; the window
//! polls for the answer once a frame.

use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, TryRecvError, channel};

use winit::window::Window;

/// Which file the designer is choosing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DialogKind {
    /// A level to edit instead of this one.
    Open,
    /// The file to save this level to, which becomes the one edited.
    SaveAs,
}

/// A dialog on screen.
pub struct PendingDialog {
    pub kind: DialogKind,
    answer: Receiver<Option<PathBuf>>,
}

impl PendingDialog {
    /// Shows the dialog for `kind`, starting in the folder of `level` (the file edited).
    pub fn show(kind: DialogKind, window: &Window, level: &Path) -> PendingDialog {
        let folder = level
            .parent()
            .filter(|folder| !folder.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let dialog = rfd::FileDialog::new()
            .set_parent(window)
            .set_directory(folder)
            .add_filter("Gloam level", &["ron"]);
        let name = level.file_name().map_or_else(
            || "level.ron".to_owned(),
            |n| n.to_string_lossy().into_owned(),
        );
        let (send, answer) = channel();
        std::thread::spawn(move || {
            let chosen = match kind {
                DialogKind::Open => dialog.set_title("Open a level").pick_file(),
                DialogKind::SaveAs => dialog
                    .set_title("Save the level as")
                    .set_file_name(name)
                    .save_file(),
            };
            // The editor may have closed meanwhile; then nobody is waiting.
            let _ = send.send(chosen);
        });
        PendingDialog { kind, answer }
    }

    /// The answer, once the dialog has closed: the file chosen, or None if it was
    /// cancelled (or could not be shown).
    pub fn poll(&self) -> Option<Option<PathBuf>> {
        match self.answer.try_recv() {
            Ok(chosen) => Some(chosen),
            Err(TryRecvError::Empty) => None,
            Err(TryRecvError::Disconnected) => Some(None),
        }
    }
}

/// Whether this desktop can show a file dialog: on Linux and the BSDs, a session bus with
/// the desktop portal's service installed, or zenity on the PATH (rfd's two ways);
/// elsewhere the system's own dialogs are always there.
pub fn available() -> bool {
    if !cfg!(any(
        target_os = "linux",
        target_os = "freebsd",
        target_os = "dragonfly",
        target_os = "netbsd",
        target_os = "openbsd"
    )) {
        return true;
    }
    portal_installed() || on_path("zenity")
}

fn portal_installed() -> bool {
    let env = |name| std::env::var_os(name).filter(|value| !value.is_empty());
    let session_bus = env("DBUS_SESSION_BUS_ADDRESS").is_some()
        || env("XDG_RUNTIME_DIR").is_some_and(|dir| Path::new(&dir).join("bus").exists());
    // The D-Bus service files of the session bus live under the XDG data folders.
    let mut data = vec![
        env("XDG_DATA_HOME")
            .map(PathBuf::from)
            .or_else(|| env("HOME").map(|home| Path::new(&home).join(".local/share"))),
    ];
    let system = env("XDG_DATA_DIRS").unwrap_or_else(|| "/usr/local/share:/usr/share".into());
    data.extend(std::env::split_paths(&system).map(Some));
    session_bus
        && data.into_iter().flatten().any(|folder| {
            folder
                .join("dbus-1/services/org.freedesktop.portal.Desktop.service")
                .is_file()
        })
}

fn on_path(program: &str) -> bool {
    std::env::var_os("PATH").is_some_and(|path| {
        std::env::split_paths(&path).any(|folder| folder.join(program).is_file())
    })
}
