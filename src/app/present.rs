//! Frame step `present`, the window's own: the film's image tone mapped into pixels' frame
//! buffer at the configured resolution (the profiler overlay drawn into it), then the HUD
//! (`hud`) or the open menu (`menu`) over the scaled frame at the window's resolution
//! (`interface`); F12's screenshot of what was shown (`screenshot`).

use std::time::Instant;

use anyhow::{Context as _, anyhow};
use winit::event_loop::ActiveEventLoop;

use super::{
    App, CAUGHT_BANNER_SECONDS, NOTICE_SECONDS, hints, hud, interface, menu, screenshot, settings,
};
use crate::film::FilterMode;
use crate::game::Action;
use crate::profile::overlay;

impl App {
    /// Shows the frame: the film tone mapped into pixels' buffer (the profiler overlay
    /// drawn into it), then the HUD or the open menu over it at the window's resolution
    /// (`interface`), and a screenshot taken if F12 asked. False when there is no window to
    /// show it in, or presenting failed (the app is then closing).
    pub(super) fn present(&mut self, event_loop: &ActiveEventLoop) -> bool {
        profiling::scope!("present");
        let (width, height) = (self.options.width, self.options.height);
        let brightness = self.context.settings.brightness;
        let Some(pixels) = &mut self.pixels else {
            return false;
        };
        let frame = pixels.frame_mut();
        let engine = match &mut self.game {
            Some(game) => Some(&mut game.engine),
            None => self.backdrop.as_mut(),
        };
        match engine {
            Some(engine) => {
                // The buffer keeps the configured size: the filtered film is upscaled to
                // it already; still frames summed at a lowered resolution are resized.
                (engine.film.image()).tone_map_into(frame, width, height, brightness);
            }
            None => {
                for (index, rgba) in frame.chunks_exact_mut(4).enumerate() {
                    let shade = 10 + (index as u32 / width * 14 / height.max(1)) as u8;
                    rgba.copy_from_slice(&[shade, shade, shade + 4, 255]);
                }
            }
        }
        let menu_open = self.menu.is_some();
        let hud = self.game.as_mut().filter(|_| !menu_open).map(|game| {
            let settings = &self.context.settings;
            let controls = hints::Controls {
                keys: &settings.keys,
                pad: &settings.pad,
                device: self.device,
            };
            let caught = (self.caught.as_ref())
                .filter(|(at, _)| at.elapsed().as_secs_f32() < CAUGHT_BANNER_SECONDS)
                .map(|(_, by)| by.as_str());
            let watching = self.options.watch.is_some();
            let mut view = player_hud(
                &mut game.engine,
                (width, height),
                (caught, watching),
                &controls,
                &mut game.hints,
            );
            view.captions = self.captions.lines().map(str::to_string).collect();
            view
        });
        let status = self.status_line();
        if self.overlay {
            let frames = &self.log.profile.frames;
            let recent = &frames[frames.len().saturating_sub(overlay::HISTORY)..];
            let (refits, rebuilds) = self.game.as_ref().map_or((0, 0), |game| {
                let deform = game.engine.deform_stats();
                (deform.refits, deform.rebuilds)
            });
            let Some(pixels) = &mut self.pixels else {
                return false;
            };
            overlay::draw(pixels.frame_mut(), width, height, recent, refits, rebuilds);
        }
        let page = self.menu.as_ref().map(|menu| menu.view(&self.context));
        // The screenshot is what the player saw, without the notice that reports it.
        let screenshot = std::mem::take(&mut self.screenshot);
        let corner = hud::Corner {
            status,
            notice: (self.notice.as_ref())
                .filter(|(at, _)| !screenshot && at.elapsed().as_secs_f32() < NOTICE_SECONDS)
                .map(|(_, line)| line.clone()),
            file_error: self.file_error.clone(),
        };
        let (Some(screen), Some(interface)) = (self.screen(), &mut self.interface) else {
            return false;
        };
        interface.draw(&screen, |painter| {
            // A menu holds the level: the HUD waits under it.
            match (&page, &hud) {
                (Some(page), _) => menu::paint(painter, screen.rect, page),
                (None, Some(hud)) => hud::paint(painter, &screen, hud),
                (None, None) => {}
            }
            hud::paint_corner(painter, &screen, &corner);
        });
        let Some(pixels) = &self.pixels else {
            return false;
        };
        let presented = pixels.render_with(|encoder, target, context| {
            context.scaling_renderer.render(encoder, target);
            interface.paint(encoder, target, context);
            Ok(())
        });
        if let Err(error) = presented {
            self.fail(event_loop, anyhow!("presenting the frame: {error}"));
            return false;
        }
        if screenshot {
            self.save_screenshot();
        }
        true
    }

    /// Writes the frame just composed (and the film under it) to the screenshot folder, and
    /// says where, or why not.
    pub(super) fn save_screenshot(&mut self) {
        let (Some(pixels), Some(interface), Some(window)) =
            (&self.pixels, &mut self.interface, &self.window)
        else {
            return;
        };
        let size = window.inner_size();
        let size = (size.width, size.height);
        let shown = screenshot::capture(pixels, size, |encoder, target, context| {
            context.scaling_renderer.render(encoder, target);
            interface.paint(encoder, target, context);
        });
        let stem = match &self.game {
            Some(game) => game
                .level
                .file_stem()
                .map(|stem| stem.to_string_lossy().into_owned()),
            None => None,
        }
        .unwrap_or_else(|| "menu".to_owned());
        let film = self
            .game
            .as_ref()
            .map(|game| &game.engine)
            .or(self.backdrop.as_ref());
        let film = film.map(|engine| engine.film.image());
        let result = settings::screenshot_dir()
            .context("no pictures or data folder (is $HOME set?)")
            .and_then(|folder| screenshot::save(&folder, &stem, &shown?, size, film.as_deref()));
        match result {
            Ok(written) => {
                let exr = match &written.exr {
                    Some(exr) => format!(" and {}", exr.display()),
                    None => String::new(),
                };
                println!("screenshot: {}{exr}", written.png.display());
                self.notice = Some((
                    Instant::now(),
                    format!("screenshot: {}", written.png.display()),
                ));
            }
            Err(error) => self.notify(format!("screenshot not saved: {error:#}")),
        }
    }

    /// The window as the interface lays it out (None before it opens).
    pub(super) fn screen(&self) -> Option<interface::Screen> {
        let (window, pixels) = (self.window.as_ref()?, self.pixels.as_ref()?);
        let size = window.inner_size();
        Some(interface::Screen::new(
            (size.width, size.height),
            pixels.context().scaling_renderer.clip_rect(),
            (self.options.width, self.options.height),
            self.context.settings.ui_scale,
        ))
    }

    /// The corner's frame rate, internal resolution and film mode, while playing (and
    /// under a menu while the profiler overlay is up).
    pub(super) fn status_line(&mut self) -> Option<String> {
        if self.menu.is_some() && !self.overlay {
            return None;
        }
        let film = &self.engine_mut()?.film;
        let (internal_width, internal_height) = (film.settings.width, film.settings.height);
        let film = match film.filter.mode {
            FilterMode::Off => format!("{} spp", film.frames),
            mode => mode.name().to_string(),
        };
        let mean_ms = self.frame_ms.iter().sum::<f32>() / self.frame_ms.len().max(1) as f32;
        Some(format!(
            "{:.1} fps {:.1} ms {internal_width}x{internal_height}{} {film}{}",
            1000.0 / mean_ms.max(1e-3),
            mean_ms,
            match &self.resolution {
                Some(controller) => format!(" ({:.0}%)", controller.scale() * 100.0),
                None => String::new(),
            },
            if self.vsync { "" } else { " novsync" }
        ))
    }
}

/// The HUD over the player's view of `engine` at film size `film`: what it gathers, with
/// the banner of who caught the player and whether a recording is being watched
/// (`caught`, `watching`), and the campaign's first level's hint line.
fn player_hud(
    engine: &mut crate::frame::Engine,
    film: (u32, u32),
    (caught, watching): (Option<&str>, bool),
    controls: &hints::Controls,
    hints: &mut hints::Hints,
) -> hud::HudView {
    let interact = controls.label(Action::Interact);
    let mut view = hud::HudView::gather(engine, film, caught, watching, &interact);
    let first_level = engine
        .world
        .get_resource::<crate::game::LevelInfo>()
        .is_some_and(|info| info.campaign == Some(1));
    if first_level {
        view.hint = crate::game::status::moment(&mut engine.world)
            .and_then(|moment| hints.line(moment, controls));
    }
    view
}

/// The window's present without a window, for `gloam bench` (`headless::bench::frames`):
/// what `App::present` does on the CPU, with default settings and the player's HUD. The
/// film is tone mapped into a frame buffer of the size shown; the HUD is gathered, laid out
/// in an egui pass and tessellated, level 1's hint line included. The GPU's part (uploading
/// the buffer, scaling it to the window, drawing the shapes) needs a device and is not here.
pub struct HeadlessPresent {
    settings: settings::Settings,
    buffer: Vec<u8>,
    interface: egui::Context,
    hints: hints::Hints,
}

impl HeadlessPresent {
    pub fn new() -> HeadlessPresent {
        HeadlessPresent {
            settings: settings::Settings::default(),
            buffer: Vec::new(),
            interface: egui::Context::default(),
            hints: hints::Hints::default(),
        }
    }
}

impl Default for HeadlessPresent {
    fn default() -> Self {
        HeadlessPresent::new()
    }
}

impl crate::headless::bench::frames::Present for HeadlessPresent {
    fn present(&mut self, engine: &mut crate::frame::Engine, width: u32, height: u32) {
        let settings = &self.settings;
        self.buffer.resize(width as usize * height as usize * 4, 0);
        (engine.film.image()).tone_map_into(&mut self.buffer, width, height, settings.brightness);
        let controls = hints::Controls {
            keys: &settings.keys,
            pad: &settings.pad,
            device: hints::Device::Keyboard,
        };
        let view = player_hud(
            engine,
            (width, height),
            (None, false),
            &controls,
            &mut self.hints,
        );
        let screen = interface::Screen::new(
            (width, height),
            (0, 0, width, height),
            (width, height),
            settings.ui_scale,
        );
        let output = self.interface.run_ui(screen.input(), |ui| {
            hud::paint(ui.painter(), &screen, &view);
        });
        let shapes = self
            .interface
            .tessellate(output.shapes, screen.pixels_per_point);
        std::hint::black_box((&self.buffer, shapes));
    }
}
