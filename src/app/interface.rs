//! Frame step `present`, its last layer: the interface (the HUD, the captions, the menus and
//! the end pages) drawn with egui's painter at the window's own resolution, over the frame
//! buffer pixels has already scaled up. The path-traced view is rendered small and shown
//! large; text drawn into it would grow blocky with it, so none is.
//!
//! Per presented frame:
//! 1. `Screen::new` places the window in egui points: `pixels_per_point` grows with the
//!    window (a 960 x 540 window is 960 x 540 points) times the player's `ui_scale`, and
//!    the frame buffer's rectangle is where pixels' scaling renderer shows it, so a film
//!    pixel (a warden's head, a noise ring) maps to the point over it;
//! 2. `Interface::draw` runs one egui pass whose only widget is a painter (`hud`, `menu`);
//! 3. `Interface::paint` draws the tessellated shapes over the target after pixels' own
//!    scaling pass, in the same command encoder.
//!
//! `EguiPaint` is the wgpu half of 2 and 3, shared with the editor, whose interface is a
//! whole egui application around the view.

use egui::{ClippedPrimitive, Context, Pos2, Rect, TexturesDelta, ViewportId, epaint};
use egui_wgpu::{Renderer, RendererOptions, ScreenDescriptor};
use pixels::{Pixels, PixelsContext, wgpu};

/// The window size at which one egui point is one pixel at `ui_scale` 1: the interface is
/// laid out for this many points and scales with the window from there.
pub const REFERENCE_WINDOW: (f32, f32) = (960.0, 540.0);

/// The least a window's size scales the interface, so a small window still has text a
/// person can read (at 480 x 270 the points are 0.75 pixels each, not 0.5).
const SMALLEST_FIT: f32 = 0.75;

/// Physical pixels per egui point for a `window` (physical pixels) and the player's
/// `ui_scale`: the window's fit inside `REFERENCE_WINDOW`, times the scale.
pub fn pixels_per_point((width, height): (u32, u32), ui_scale: f32) -> f32 {
    let fit = (width as f32 / REFERENCE_WINDOW.0).min(height as f32 / REFERENCE_WINDOW.1);
    fit.max(SMALLEST_FIT) * ui_scale
}

/// The window as the interface sees it: its size in points, and where the frame buffer is
/// shown in it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Screen {
    /// The whole window, points.
    pub rect: Rect,
    /// The frame buffer's rectangle on the window, points (pixels' scaling renderer keeps
    /// the buffer's aspect and may leave a border).
    pub film: Rect,
    /// The frame buffer's size, pixels.
    buffer: (u32, u32),
    /// The window's physical size, pixels (what egui's output is drawn into).
    window: (u32, u32),
    /// Physical pixels per point.
    pub pixels_per_point: f32,
}

impl Screen {
    /// `window`: the surface's physical size; `shown`: pixels' clip rectangle (x, y,
    /// width, height, physical); `buffer`: the frame buffer's size.
    pub fn new(
        window: (u32, u32),
        shown: (u32, u32, u32, u32),
        buffer: (u32, u32),
        ui_scale: f32,
    ) -> Screen {
        let pixels_per_point = pixels_per_point(window, ui_scale);
        let points = |x: u32, y: u32| Pos2::new(x as f32, y as f32) / pixels_per_point;
        let (x, y, width, height) = shown;
        Screen {
            rect: Rect::from_min_max(Pos2::ZERO, points(window.0, window.1)),
            film: Rect::from_min_max(points(x, y), points(x + width, y + height)),
            buffer,
            window,
            pixels_per_point,
        }
    }

    /// The point over frame-buffer point `(x, y)` (pixels, as a camera projects).
    pub fn film_point(&self, (x, y): (f32, f32)) -> Pos2 {
        let scale = self.film.size() / egui::vec2(self.buffer.0 as f32, self.buffer.1 as f32);
        self.film.min + egui::vec2(x, y) * scale
    }

    /// egui's input for a pass that only paints over this screen.
    pub fn input(&self) -> egui::RawInput {
        let mut input = egui::RawInput {
            screen_rect: Some(self.rect),
            ..Default::default()
        };
        input
            .viewports
            .entry(ViewportId::ROOT)
            .or_default()
            .native_pixels_per_point = Some(self.pixels_per_point);
        input
    }

    /// The point under a window position (physical pixels, as winit reports the cursor).
    pub fn window_point(&self, (x, y): (f64, f64)) -> Pos2 {
        Pos2::new(x as f32, y as f32) / self.pixels_per_point
    }
}

/// egui's output on pixels' wgpu device: the renderer, the shapes of the last pass
/// tessellated for it, and the textures egui asked for.
pub struct EguiPaint {
    renderer: Renderer,
    screen: ScreenDescriptor,
    paint_jobs: Vec<ClippedPrimitive>,
    textures: TexturesDelta,
}

impl EguiPaint {
    pub fn new(pixels: &Pixels<'_>, size: (u32, u32), pixels_per_point: f32) -> EguiPaint {
        let renderer = Renderer::new(
            pixels.device(),
            pixels.render_texture_format(),
            RendererOptions::default(),
        );
        EguiPaint {
            renderer,
            screen: ScreenDescriptor {
                size_in_pixels: [size.0.max(1), size.1.max(1)],
                pixels_per_point,
            },
            paint_jobs: Vec::new(),
            textures: TexturesDelta::default(),
        }
    }

    pub fn renderer_mut(&mut self) -> &mut Renderer {
        &mut self.renderer
    }

    /// The surface's physical size and points' scale for the next `take`.
    pub fn set_screen(&mut self, size: (u32, u32), pixels_per_point: f32) {
        self.screen = ScreenDescriptor {
            size_in_pixels: [size.0.max(1), size.1.max(1)],
            pixels_per_point,
        };
    }

    pub fn size_in_pixels(&self) -> [u32; 2] {
        self.screen.size_in_pixels
    }

    /// Keeps a pass's shapes, tessellated, and its texture changes for `paint`.
    pub fn take(
        &mut self,
        context: &Context,
        shapes: Vec<epaint::ClippedShape>,
        textures: TexturesDelta,
    ) {
        self.textures.append(textures);
        self.paint_jobs = context.tessellate(shapes, self.screen.pixels_per_point);
    }

    /// Draws what `take` kept into `target`: over what is there (`clear` None) or over
    /// a cleared target.
    pub fn paint(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        context: &PixelsContext,
        clear: Option<wgpu::Color>,
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
                    label: Some("interface"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: target,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: clear.map_or(wgpu::LoadOp::Load, wgpu::LoadOp::Clear),
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

/// The game's interface: an egui context that only paints (the menus read the keys, the
/// pad and the pointer themselves) and its output on the device.
pub struct Interface {
    context: Context,
    paint: EguiPaint,
}

impl Interface {
    pub fn new(pixels: &Pixels<'_>) -> Interface {
        Interface {
            context: Context::default(),
            paint: EguiPaint::new(pixels, (1, 1), 1.0),
        }
    }

    /// One egui pass over `screen`: `draw` paints with a painter that covers the window.
    pub fn draw(&mut self, screen: &Screen, draw: impl FnOnce(&egui::Painter)) {
        self.paint
            .set_screen(screen.window, screen.pixels_per_point);
        let mut draw = Some(draw);
        let output = self.context.run_ui(screen.input(), |ui| {
            if let Some(draw) = draw.take() {
                draw(ui.painter());
            }
        });
        self.paint
            .take(&self.context, output.shapes, output.textures_delta);
    }

    /// Draws the last pass over `target`, which holds the scaled frame.
    pub fn paint(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        context: &PixelsContext,
    ) {
        self.paint.paint(encoder, target, context, None);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_interface_grows_with_the_window_and_the_players_scale() {
        assert_eq!(pixels_per_point((960, 540), 1.0), 1.0);
        assert_eq!(pixels_per_point((1920, 1080), 1.0), 2.0);
        assert_eq!(pixels_per_point((1920, 1080), 1.5), 3.0);
        // A wide window scales by its height, a tall one by its width.
        assert_eq!(pixels_per_point((2560, 1080), 1.0), 2.0);
        assert_eq!(pixels_per_point((960, 1080), 1.0), 1.0);
        // A tiny window keeps text of a readable size.
        assert_eq!(pixels_per_point((320, 180), 1.0), SMALLEST_FIT);
    }

    #[test]
    fn a_film_pixel_maps_to_the_point_over_it() {
        // A 480 x 270 buffer shown 3x at 1440 x 810, in a 1500 x 850 window (bordered).
        let screen = Screen::new((1500, 850), (30, 20, 1440, 810), (480, 270), 1.0);
        let scale = pixels_per_point((1500, 850), 1.0);
        let corner = screen.film_point((0.0, 0.0));
        assert!((corner.x - 30.0 / scale).abs() < 1e-4);
        assert!((corner.y - 20.0 / scale).abs() < 1e-4);
        let middle = screen.film_point((240.0, 135.0));
        let window_middle = screen.window_point((30.0 + 720.0, 20.0 + 405.0));
        assert!(
            (middle - window_middle).length() < 1e-3,
            "{middle:?} {window_middle:?}"
        );
    }
}
