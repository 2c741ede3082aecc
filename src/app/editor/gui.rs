//! egui on pixels' own wgpu device: the editor's interface and, inside it, the path-traced
//! view. pixels uploads the frame buffer to its texture; that texture is registered with
//! egui's renderer and drawn as an image in the central panel, so the view keeps its aspect
//! beside the side panels and a pointer position maps straight to a film pixel.

use egui::{ClippedPrimitive, Context, TextureId, TexturesDelta, ViewportId};
use egui_wgpu::{Renderer, RendererOptions, ScreenDescriptor};
use pixels::{Pixels, PixelsContext, wgpu};
use winit::event::WindowEvent;
use winit::event_loop::ActiveEventLoop;
use winit::window::Window;

pub struct Gui {
    pub context: Context,
    state: egui_winit::State,
    screen: ScreenDescriptor,
    renderer: Renderer,
    paint_jobs: Vec<ClippedPrimitive>,
    textures: TexturesDelta,
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
        let mut renderer = Renderer::new(
            pixels.device(),
            pixels.render_texture_format(),
            RendererOptions::default(),
        );
        let texture = &pixels.context().texture;
        let view = renderer.register_native_texture(
            pixels.device(),
            &texture.create_view(&wgpu::TextureViewDescriptor::default()),
            // The film's pixels stay sharp when the view is drawn larger than it.
            wgpu::FilterMode::Nearest,
        );
        Gui {
            context,
            state,
            screen: ScreenDescriptor {
                size_in_pixels: [size.width.max(1), size.height.max(1)],
                pixels_per_point: scale,
            },
            renderer,
            paint_jobs: Vec::new(),
            textures: TexturesDelta::default(),
            view,
            wants_repaint: true,
        }
    }

    /// Passes a window event to egui; true when egui used it (a click on a panel, a key
    /// typed into a text field).
    pub fn on_event(&mut self, window: &Window, event: &WindowEvent) -> bool {
        match event {
            WindowEvent::Resized(size) if size.width > 0 && size.height > 0 => {
                self.screen.size_in_pixels = [size.width, size.height];
            }
            WindowEvent::ScaleFactorChanged { scale_factor, .. } => {
                self.screen.pixels_per_point = *scale_factor as f32;
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
        self.textures.append(output.textures_delta);
        self.state
            .handle_platform_output(window, output.platform_output);
        self.paint_jobs = self
            .context
            .tessellate(output.shapes, self.screen.pixels_per_point);
    }

    /// Draws the last frame's interface into `target` (the view is part of it).
    pub fn paint(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        context: &PixelsContext,
    ) {
        for (id, delta) in &self.textures.set {
            self.renderer
                .update_texture(&context.device, &context.queue, *id, delta);
        }
        self.renderer.update_buffers(
            &context.device,
            &context.queue,
            encoder,
            &self.paint_jobs,
            &self.screen,
        );
        {
            let mut pass = encoder
                .begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("editor interface"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: target,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                            store: wgpu::StoreOp::Store,
                        },
                        depth_slice: None,
                    })],
                    depth_stencil_attachment: None,
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                })
                .forget_lifetime();
            self.renderer
                .render(&mut pass, &self.paint_jobs, &self.screen);
        }
        for id in &std::mem::take(&mut self.textures).free {
            self.renderer.free_texture(id);
        }
    }
}
