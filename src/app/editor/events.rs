//! The level editor's window, its events (winit's `ApplicationHandler`): egui sees every
//! window event first; the window's own (close, resize, focus, redraw) are answered here;
//! mouse motion turns the flying camera; and between events the editor decides whether
//! to draw again at once or wait (`about_to_wait`).

use std::time::Instant;

use glam::Vec2;
use winit::application::ApplicationHandler;
use winit::dpi::LogicalSize;
use winit::event::{DeviceEvent, DeviceId, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow};
use winit::window::WindowId;

use super::{AUTOSAVE_EVERY, EditorApp, IDLE_FRAME, Leave, NOTICE_SECONDS, gui};
use crate::scene::watch::FileWatch;

impl ApplicationHandler for EditorApp {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.window.is_some() {
            return;
        }
        let buffer = (self.options.width, self.options.height);
        let size = LogicalSize::new(1280, 760);
        let (window, pixels) =
            match crate::app::open_window(event_loop, self.title(), size, buffer, true) {
                Ok(opened) => opened,
                Err(error) => return self.fail(event_loop, error),
            };
        self.gui = Some(gui::Gui::new(event_loop, &window, &pixels));
        self.pixels = Some(pixels);
        self.window = Some(window);
        self.last_frame = Instant::now();
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        if let (Some(window), Some(gui)) = (&self.window, &mut self.gui) {
            gui.on_event(window, &event);
            // Any input may change what is shown: answer it with a frame.
            if !matches!(event, WindowEvent::RedrawRequested) {
                window.request_redraw();
            }
        }
        match event {
            WindowEvent::CloseRequested => {
                if self.editor.is_dirty() {
                    self.panels.leaving = Some(Leave::Quit);
                } else {
                    event_loop.exit();
                }
            }
            WindowEvent::Resized(size) => {
                if let Err(error) = crate::app::resize_surface(&mut self.pixels, size) {
                    self.fail(event_loop, error);
                }
            }
            WindowEvent::Focused(false) => {
                self.panels.flying = false;
                self.set_grab(false);
            }
            WindowEvent::RedrawRequested => self.redraw(event_loop),
            _ => {}
        }
    }

    fn device_event(&mut self, _: &ActiveEventLoop, _: DeviceId, event: DeviceEvent) {
        if let DeviceEvent::MouseMotion { delta } = event
            && self.panels.flying
        {
            self.look += Vec2::new(delta.0 as f32, -delta.1 as f32);
        }
    }

    /// Frames are drawn back to back while anything moves (the view converging, the
    /// camera flying, a drag, an exposure map on its way, egui animating). Once all is
    /// still the editor waits for input, waking `IDLE_FRAME` apart only to look for work
    /// that needs a frame (a file changed on disk, a notice to take down, an autosave due,
    /// a file dialog open), so a converged view leaves the cores alone. A measured run
    /// (`--frames`) draws its idle frames on every wake-up instead, to time them and end.
    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        let Some(window) = self.window.clone() else {
            return;
        };
        let busy = !self.converged()
            || self.panels.flying
            || self.panels.primary_down
            || self.exposure_job.is_some()
            || self.gui.as_ref().is_some_and(|gui| gui.wants_repaint);
        if busy {
            event_loop.set_control_flow(ControlFlow::Poll);
            window.request_redraw();
            return;
        }
        let next = self.last_frame.max(self.last_check) + IDLE_FRAME;
        if Instant::now() < next {
            event_loop.set_control_flow(ControlFlow::WaitUntil(next));
            return;
        }
        self.last_check = Instant::now();
        if self.options.frames.is_some() || self.idle_work() {
            window.request_redraw();
        } else {
            event_loop.set_control_flow(ControlFlow::WaitUntil(self.last_check + IDLE_FRAME));
        }
    }
}

impl EditorApp {
    /// Whether an idle editor has something to do that needs a frame.
    fn idle_work(&mut self) -> bool {
        let notice_over = self
            .panels
            .notice
            .as_ref()
            .is_some_and(|(at, _)| at.elapsed().as_secs_f32() >= NOTICE_SECONDS);
        if notice_over {
            self.panels.notice = None;
        }
        let autosave_due = self.editor.is_dirty() && self.autosaved.elapsed() >= AUTOSAVE_EVERY;
        let files = self.watch.as_mut().is_some_and(FileWatch::has_changes);
        let checking = self.play_check.running_for().is_some();
        let arrived = self.thumbnails.poll();
        let thumbnails = !arrived.is_empty();
        self.panels.thumbnails_arrived(arrived);
        notice_over
            || thumbnails
            || autosave_due
            || files
            || checking
            || self.dialog.is_some()
            || !self.shows_converged
    }
}
