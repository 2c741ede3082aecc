//! The window's modes on one event loop: play, the editor, and the editor's play-tests.
//!
//! winit runs one loop per process, so each mode runs it in turn (`run_app_on_demand`) and
//! says, as it leaves, what comes next: F2 in play opens the editor on the level's file;
//! F5 in the editor plays the level as edited, from the editor's camera, and Esc (or
//! winning) comes back to the editor as it was left. Each mode closes its window before it
//! leaves the loop: winit carries no window from one run to the next.

use std::path::PathBuf;

use anyhow::Context as _;
use winit::event_loop::EventLoop;
use winit::platform::run_on_demand::EventLoopExtRunOnDemand as _;

use super::editor::{EditOptions, EditorApp};
use super::{App, PlayOptions};
use crate::film::FilterMode;
use crate::scene::Scene;

/// A play-test: the level as the editor holds it, with the player start at the editor's
/// camera.
pub struct PlayTest {
    pub scene: Scene,
    /// The level's file (where its assets are found; it is not read).
    pub level: PathBuf,
}

/// What a mode asks for as it leaves the loop.
pub enum Switch {
    /// Edit this level file.
    Edit(PathBuf),
    /// Play-test, then come back.
    PlayTest(Box<PlayTest>),
    /// The play-test ended: what happened, for the editor's status line.
    BackToEditor(String),
}

pub enum Mode {
    Play(Box<App>),
    Edit(Box<EditorApp>),
}

/// Runs the modes until one leaves with nothing next.
pub fn run(event_loop: &mut EventLoop<()>, first: Mode) -> anyhow::Result<()> {
    let mut mode = first;
    loop {
        mode = match mode {
            Mode::Play(mut app) => {
                event_loop
                    .run_app_on_demand(&mut *app)
                    .context("running the window's event loop")?;
                app.finish()?;
                match app.switch.take() {
                    Some(Switch::Edit(level)) => {
                        Mode::Edit(Box::new(EditorApp::open(EditOptions::for_level(level))?))
                    }
                    _ => return Ok(()),
                }
            }
            Mode::Edit(mut editor) => {
                event_loop
                    .run_app_on_demand(&mut *editor)
                    .context("running the editor's event loop")?;
                match editor.switch.take() {
                    Some(Switch::PlayTest(test)) => {
                        let ended = play_test(event_loop, *test)?;
                        editor.back_from_play_test(ended);
                        Mode::Edit(editor)
                    }
                    _ => return editor.finish(),
                }
            }
        };
    }
}

/// Plays `test` until it is left or won; says how it ended.
fn play_test(event_loop: &mut EventLoop<()>, test: PlayTest) -> anyhow::Result<String> {
    let options = PlayOptions {
        level: Some(test.level.clone()),
        width: super::DEFAULT_WIDTH,
        height: super::DEFAULT_HEIGHT,
        frames: None,
        linger: std::time::Duration::ZERO,
        headless: false,
        profiler: false,
        filter: FilterMode::Full,
        target_ms: None,
        record: None,
        watch: None,
    };
    let mut app = App::new(options);
    app.play_test = true;
    app.start(test.scene, test.level);
    event_loop
        .run_app_on_demand(&mut app)
        .context("running the play-test's event loop")?;
    app.finish()?;
    Ok(match app.switch.take() {
        Some(Switch::BackToEditor(line)) => line,
        _ => "play-test closed".to_owned(),
    })
}
