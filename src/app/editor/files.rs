//! The editor's level file on disk: opening another, saving (to its path or a new one),
//! reverting to what the file holds, and following changes made outside the editor to the
//! level and its assets (hot reload, with a prompt when both sides changed).

use super::*;

impl EditorApp {
    /// Edits the level in `path` instead of this one: a new world, history and camera,
    /// the same window. Nothing changes if it does not load.
    pub(super) fn open_level(&mut self, path: PathBuf) -> anyhow::Result<String> {
        let scene = Scene::load(&path)?;
        let disk = std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
        self.show_level(&scene, path, Editor::new(), disk);
        self.panels.autosave_offer = crate::edit::newer_autosave(&self.path);
        Ok(format!("opened {}", self.path.display()))
    }

    /// Makes `scene`, the level of the file `path` (whose bytes on disk are `disk`), the
    /// one edited, under `editor`: the camera starts from its view, and what belonged to
    /// the last level (its maps, its play-check, the panels' choices) goes.
    fn show_level(&mut self, scene: &Scene, path: PathBuf, editor: Editor, disk: Vec<u8>) {
        if assets_folder(&path) != assets_folder(&self.path) {
            self.thumbnails = super::palette_thumbnails(&path);
        }
        self.engine = editor_engine(scene, &self.options);
        self.camera = FlyCamera::from_view(&self.engine);
        self.camera.install(&mut self.engine.world);
        self.editor = editor;
        self.disk = disk;
        self.panels.opened(&path);
        self.forget_derived();
        self.autosaved = Instant::now();
        self.options.level = path.clone();
        self.path = path;
        self.watch_files();
    }

    /// Drops what was worked out from the last level: the exposure map and audibility on
    /// show or being computed, the play-check's answer, and the view's depth.
    fn forget_derived(&mut self) {
        self.view_depth = None;
        self.exposure = None;
        self.audibility = None;
        self.exposure_job = None;
        self.exposure_for = None;
        self.play_check = PlayCheck::default();
    }

    /// Edits the level the autosave holds instead of the file's (offered on opening when it
    /// is newer): unsaved until a save, the file on disk untouched, the camera kept.
    pub(super) fn take_autosave(&mut self) -> anyhow::Result<String> {
        let scene = crate::edit::load_autosave(&self.path)?;
        self.engine = editor_engine(&scene, &self.options);
        self.camera.install(&mut self.engine.world);
        self.editor = Editor::unsaved();
        // The autosave's entities are numbered as it lists them: the marks were the file's.
        self.panels.hidden.clear();
        self.panels.locked.clear();
        self.forget_derived();
        Ok(format!(
            "loaded {}: unsaved until Ctrl+S (File > Revert goes back to the file)",
            crate::edit::autosave_path(&self.path).display()
        ))
    }

    /// Starts a new level from the template, to be saved to `path` (which must not exist):
    /// unsaved until then. Nothing changes if it cannot be made.
    pub(super) fn new_level(&mut self, path: PathBuf) -> anyhow::Result<String> {
        let scene = crate::edit::template::new_scene(&path)?;
        self.show_level(&scene, path, Editor::unsaved(), Vec::new());
        Ok(format!(
            "a new level for {}: Ctrl+S writes it",
            self.path.display()
        ))
    }

    /// Saves the level to `path` (which becomes the file edited); says where.
    pub(super) fn save_to(&mut self, path: PathBuf) -> anyhow::Result<String> {
        self.editor.save(&mut self.engine, &path)?;
        self.disk = std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
        self.path = path;
        Ok(format!("saved {}", self.path.display()))
    }

    /// Reads the level file again, dropping unsaved edits, the editor's camera kept; on an
    /// error nothing changes.
    pub(super) fn force_reload(&mut self) -> anyhow::Result<&'static str> {
        let reloaded = match self.editor.reload(&mut self.engine, &self.path) {
            Ok(reloaded) => reloaded,
            Err(error) => {
                self.panels.file_error = Some(format!("{error:#}"));
                return Err(error);
            }
        };
        self.panels.file_error = None;
        self.disk = std::fs::read(&self.path)
            .with_context(|| format!("reading {}", self.path.display()))?;
        self.camera.install(&mut self.engine.world);
        Ok(match reloaded {
            Reloaded::Unchanged => "the file holds the level shown",
            Reloaded::Replaced => "reloaded",
        })
    }

    /// What changed on disk since the last frame, handled: the level (someone else's
    /// save), or assets it uses.
    pub(super) fn files_changed(&mut self) {
        let Some(watch) = &mut self.watch else { return };
        let changed = watch.poll();
        if changed.is_empty() {
            return;
        }
        self.view_depth = None;
        let level_changed = changed.iter().any(|file| *file == absolute(&self.path));
        let assets: Vec<PathBuf> = changed
            .into_iter()
            .filter(|file| *file != absolute(&self.path))
            .collect();
        if !assets.is_empty() {
            match self.editor.reload_assets(&mut self.engine, &assets) {
                Ok(count) => {
                    self.panels.file_error = None;
                    let names: Vec<String> =
                        assets.iter().map(|f| f.display().to_string()).collect();
                    self.notify(format!("reloaded {} ({count} entities)", names.join(", ")));
                }
                Err(error) => {
                    self.panels.file_error = Some(format!("{error:#}"));
                    self.notify(format!("{error:#}"));
                }
            }
        }
        if level_changed {
            let bytes = std::fs::read(&self.path).unwrap_or_default();
            if bytes == self.disk {
                // The editor's own save, or the file put back as the editor knows it.
                if self.panels.file_error.take().is_some() {
                    self.notify(format!(
                        "{}: the file holds the level shown",
                        self.path.display()
                    ));
                }
                return;
            }
            if self.editor.is_dirty() {
                self.panels.conflict = true;
                self.notify(format!(
                    "{} changed on disk while there are unsaved edits",
                    self.path.display()
                ));
                return;
            }
            match self.force_reload() {
                Ok(line) => {
                    self.notify(format!("{}: {line} (changed on disk)", self.path.display()))
                }
                Err(error) => self.notify(format!("{error:#}")),
            }
        }
    }

    /// Watches the level file and every asset the world has loaded.
    pub(super) fn watch_files(&mut self) {
        let Some(watch) = &mut self.watch else { return };
        let mut files = vec![self.path.clone()];
        if let Some(assets) = self.engine.world.get_resource::<crate::game::Assets>() {
            files.extend(assets.0.files().map(|f| f.to_path_buf()));
        }
        if files.iter().any(|file| !watch.watches(file))
            && let Err(error) = watch.set_files(files)
        {
            self.notify(format!("{error:#}"));
        }
    }
}
