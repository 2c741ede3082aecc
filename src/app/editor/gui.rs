//! egui on pixels' own wgpu device: the editor's interface and, inside it, the path-traced
//! view. pixels uploads the frame buffer to its texture; that texture is registered with
//! egui's renderer and drawn as an image in the central panel, so the view keeps its aspect
//! beside the side panels and a pointer position maps straight to a film pixel.

use egui::{Context, TextureId, ViewportId};
use pixels::{Pixels, PixelsContext, wgpu};
use winit::event::WindowEvent;
use winit::event_loop::ActiveEventLoop;
use winit::window::Window;

use crate::app::interface::EguiPaint;

pub struct Gui {
    pub context: Context,
    state: egui_winit::State,
    paint: EguiPaint,
    /// pixels' frame texture, as egui knows it.
    pub view: TextureId,
    /// egui asked for the next frame at once (an animation, a tooltip on its way).
    pub wants_repaint: bool,
}

impl Gui {
    pub fn new(event_loop: &ActiveEventLoop, window: &Window, pixels: &Pixels<'_>) -> Gui {
        let size = window.inner_size();
        let scale = window.scale_factor() as f32;
        let context = Context::default();
        let max_texture = pixels.device().limits().max_texture_dimension_2d as usize;
        let state = egui_winit::State::new(
            context.clone(),
            ViewportId::ROOT,
            event_loop,
            Some(scale),
            None,
            Some(max_texture),
        );
        let mut paint = EguiPaint::new(pixels, (size.width, size.height), scale);
        let texture = &pixels.context().texture;
        let view = paint.renderer_mut().register_native_texture(
            pixels.device(),
            &texture.create_view(&wgpu::TextureViewDescriptor::default()),
            // The film's pixels stay sharp when the view is drawn larger than it.
            wgpu::FilterMode::Nearest,
        );
        Gui {
            context,
            state,
            paint,
            view,
            wants_repaint: true,
        }
    }

    /// Passes a window event to egui; true when egui used it (a click on a panel, a key
    /// typed into a text field).
    pub fn on_event(&mut self, window: &Window, event: &WindowEvent) -> bool {
        match event {
            WindowEvent::Resized(size) if size.width > 0 && size.height > 0 => {
                let scale = window.scale_factor() as f32;
                self.paint.set_screen((size.width, size.height), scale);
            }
            WindowEvent::ScaleFactorChanged { scale_factor, .. } => {
                let [width, height] = self.paint.size_in_pixels();
                self.paint.set_screen((width, height), *scale_factor as f32);
            }
            _ => {}
        }
        self.state.on_window_event(window, event).consumed
    }

    /// Runs one egui frame of `ui` and keeps what it drew for `paint`.
    pub fn run(&mut self, window: &Window, ui: impl FnMut(&mut egui::Ui)) {
        let input = self.state.take_egui_input(window);
        let output = self.context.run_ui(input, ui);
        self.wants_repaint = output
            .viewport_output
            .get(&ViewportId::ROOT)
            .is_none_or(|viewport| viewport.repaint_delay.is_zero());
        self.state
            .handle_platform_output(window, output.platform_output);
        self.paint
            .take(&self.context, output.shapes, output.textures_delta);
    }

    /// Draws the last frame's interface into `target` (the view is part of it).
    pub fn paint(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        context: &PixelsContext,
    ) {
        self.paint
            .paint(encoder, target, context, Some(wgpu::Color::BLACK));
    }
}
