//! Frame step `present`: the heads-up display over the level being played, drawn by the
//! `interface` layer at the window's resolution: the light gem, each warden's state mark
//! over its head, noise rings, the lamp prompt, the first level's hints, the captions, the
//! caught banner, the shards, and in the corner the frame rate and notices.
//!
//! Two halves: `HudView::gather` asks the game what the HUD shows (`game::status`) and
//! places what sits in the scene at film pixels, and `paint` lays it out in points, so
//! the layout is tested without a window.

use egui::{Align2, Color32, FontId, Painter, Pos2, Rect, Stroke, pos2, vec2};

use super::interface::Screen;
use crate::frame::Engine;
use crate::game::exposure::curve::{GEM_STEPS, gem_cells};
use crate::game::status::{self, LampInReach};
use crate::game::{self, WardenState};

/// Text sizes, points (`interface::REFERENCE_WINDOW` has 540 of them top to bottom).
pub const BODY_TEXT: f32 = 17.0;
pub const CORNER_TEXT: f32 = 13.0;
const MARK_TEXT: f32 = 22.0;
/// Space kept between the HUD and the window's edges, points.
pub const MARGIN: f32 = 12.0;
/// How far apart lines of body text are, points.
pub const LINE: f32 = 22.0;

/// The HUD's colours: warm white text on a dark shadow, readable over a lamp's pool and
/// over the dark.
pub const TEXT: Color32 = Color32::from_rgb(236, 230, 214);
const SHADOW: Color32 = Color32::from_rgba_premultiplied(0, 0, 0, 210);
const ALERT: Color32 = Color32::from_rgb(230, 50, 40);
const SUSPICION: Color32 = Color32::from_rgb(235, 200, 60);

/// How far above a warden's feet its state mark floats (metres), and the farthest a
/// mark is drawn from.
pub const MARK_HEIGHT: f32 = 2.15;
pub const MARK_RANGE: f32 = 30.0;
/// How many points a noise ring is drawn with.
pub const RING_POINTS: usize = 96;

/// A warden's state mark: where its head is on the film, what it knows.
#[derive(Clone, Debug, PartialEq)]
pub struct Mark {
    pub at: (f32, f32),
    pub state: WardenState,
    pub suspicion: f32,
}

/// A noise the player made: its ring of reach on the floor, as film points (None behind
/// the camera), and how much of it is left (1 new, fading to 0).
#[derive(Clone, Debug, PartialEq)]
pub struct Ring {
    pub points: Vec<Option<(f32, f32)>>,
    pub strength: f32,
}

/// What the HUD shows this frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HudView {
    /// The light gem's value, 0..1 (None: no player).
    pub gem: Option<f32>,
    pub marks: Vec<Mark>,
    pub rings: Vec<Ring>,
    /// What the interact control would do to the lamp aimed at: "E  douse the lamp".
    pub prompt: Option<String>,
    /// The first level's hint of the moment, a quarter down the screen.
    pub hint: Option<String>,
    /// "Caught by ...", a third down the screen.
    pub banner: Option<String>,
    /// Lines at the bottom left, the lowest first: the shards, a free walk's notice.
    pub progress: Vec<String>,
    /// Sounds heard lately, the oldest first.
    pub captions: Vec<String>,
}

/// The corner's lines, top left: the frame rate, a notice, a level file's problems.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Corner {
    pub status: Option<String>,
    pub notice: Option<String>,
    pub file_error: Option<String>,
}

impl HudView {
    /// Reads the HUD of the level in `engine` (`game::status`), seen through a `film`
    /// (width, height) camera. `caught`: the warden that caught the player, while the
    /// banner shows; `watching`: a recording is being watched (its caught attempt stays on
    /// screen); `interact`: the label of the control that douses a lamp.
    pub fn gather(
        engine: &mut Engine,
        film: (u32, u32),
        caught: Option<&str>,
        watching: bool,
        interact: &str,
    ) -> HudView {
        let projection = engine.view_camera(film.0, film.1).projection();
        let world = &mut engine.world;
        let mut view = HudView {
            gem: status::gem(world),
            ..HudView::default()
        };
        // Each warden's state above its head: what it knows, the player knows.
        for warden in status::warden_heads(world, MARK_HEIGHT) {
            let seen = projection.project_lanes(warden.head.into());
            if seen.in_front && seen.distance < MARK_RANGE {
                view.marks.push(Mark {
                    at: (seen.x, seen.y),
                    state: warden.state,
                    suspicion: warden.suspicion,
                });
            }
        }
        if let Some(noises) = world.get_resource::<game::Noises>() {
            for noise in &noises.0 {
                let points = (0..RING_POINTS)
                    .map(|i| {
                        let angle = i as f32 / RING_POINTS as f32 * std::f32::consts::TAU;
                        let at = noise.at
                            + glam::Vec3::new(
                                angle.cos() * noise.radius,
                                0.05,
                                angle.sin() * noise.radius,
                            );
                        let seen = projection.project_lanes(at.into());
                        seen.in_front.then_some((seen.x, seen.y))
                    })
                    .collect();
                let strength = 1.0 - noise.age / game::noise::tuning::RING_SECONDS;
                view.rings.push(Ring { points, strength });
            }
        }
        view.prompt = status::lamp_in_reach(world).map(|lamp| {
            let verb = match lamp {
                LampInReach::Lit => "douse the lamp",
                LampInReach::Doused => "light the lamp",
            };
            format!("{interact}  {verb}")
        });
        view.banner = caught.map(|by| format!("Caught by {by}. The level starts again."));
        if let Some(shards) = status::shards(world)
            && shards.total > 0
        {
            view.progress
                .push(format!("shards {}/{}", shards.taken, shards.total));
        }
        if status::outcome(world).is_some() && status::is_free_walk(world) {
            view.progress
                .push("free walk: this level has no way out".to_string());
        }
        if status::outcome(world) == Some(game::Outcome::Caught) && watching {
            // Only a watched recording shows this: in play the level has restarted.
            let by = status::caught_by(world);
            view.banner = Some(format!("Caught by {by}.  Esc: menu"));
        }
        view
    }
}

/// Draws `line` with its `anchor` at `at` over a soft shadow; returns the rectangle it
/// covers.
pub fn text(
    painter: &Painter,
    at: Pos2,
    anchor: Align2,
    line: &str,
    font: FontId,
    colour: Color32,
) -> Rect {
    let galley = painter.layout_no_wrap(line.to_string(), font, colour);
    let rect = anchor.anchor_size(at, galley.size());
    // A one-point shadow down and right: enough to read white text over a lit wall.
    let shadow = (rect.min + vec2(1.0, 1.0)).round();
    painter.galley_with_override_text_color(shadow, galley.clone(), SHADOW);
    painter.galley(rect.min.round(), galley, colour);
    rect
}

fn body(size: f32) -> FontId {
    FontId::proportional(size)
}

/// The light gem, bottom centre: `GEM_STEPS` cells lit up to `value` (0..1), dim grey to
/// warm white as they fill, in a dark frame. Returns the frame's rectangle.
pub fn paint_gem(painter: &Painter, screen: &Screen, value: f32) -> Rect {
    const CELL: f32 = 18.0;
    const GAP: f32 = 4.0;
    let total = GEM_STEPS as f32 * (CELL + GAP) + GAP;
    let frame = Rect::from_min_size(
        pos2(
            screen.rect.center().x - total / 2.0,
            screen.rect.bottom() - MARGIN - CELL - 2.0 * GAP,
        ),
        vec2(total, CELL + 2.0 * GAP),
    );
    painter.rect_filled(frame, 3.0, Color32::from_rgba_unmultiplied(12, 12, 16, 220));
    let lit = gem_cells(value);
    for step in 0..GEM_STEPS {
        let cell = Rect::from_min_size(
            frame.min + vec2(GAP + step as f32 * (CELL + GAP), GAP),
            vec2(CELL, CELL),
        );
        let colour = if step < lit {
            let warmth = (step + 1) as f32 / GEM_STEPS as f32;
            Color32::from_rgb(
                (120.0 + 135.0 * warmth) as u8,
                (110.0 + 120.0 * warmth) as u8,
                (90.0 + 80.0 * warmth) as u8,
            )
        } else {
            Color32::from_rgb(40, 40, 46)
        };
        painter.rect_filled(cell, 2.0, colour);
    }
    frame
}

/// A warden's state mark at `at`: `?` while suspicious or searching, `!` when alert, `X`
/// when it caught the player, over a bar filled to its suspicion (yellow, red when alert).
/// A patrolling warden with no suspicion shows nothing.
pub fn paint_mark(painter: &Painter, at: Pos2, state: WardenState, suspicion: f32) {
    let glyph = match state {
        WardenState::Patrol if suspicion <= 0.0 => return,
        WardenState::Patrol => "",
        WardenState::Suspicious | WardenState::Searching => "?",
        WardenState::Alert => "!",
        WardenState::Caught => "X",
    };
    let colour = if matches!(state, WardenState::Alert | WardenState::Caught) {
        ALERT
    } else {
        SUSPICION
    };
    let bar = Rect::from_center_size(at, vec2(30.0, 6.0));
    painter.rect_filled(bar.expand(1.0), 1.0, Color32::from_rgb(20, 20, 24));
    let filled = bar.width() * suspicion.clamp(0.0, 1.0);
    painter.rect_filled(
        Rect::from_min_size(bar.min, vec2(filled, bar.height())),
        0.0,
        colour,
    );
    if !glyph.is_empty() {
        let font = FontId::proportional(MARK_TEXT);
        text(
            painter,
            bar.center_top(),
            Align2::CENTER_BOTTOM,
            glyph,
            font,
            colour,
        );
    }
}

/// A noise ring: its points joined where they are in front of the camera, white fading
/// with `strength`.
fn paint_ring(painter: &Painter, points: impl Iterator<Item = Option<Pos2>>, strength: f32) {
    let alpha = (strength.clamp(0.0, 1.0) * 230.0) as u8;
    let stroke = Stroke::new(2.0_f32, Color32::from_white_alpha(alpha));
    let mut run: Vec<Pos2> = Vec::new();
    for point in points.chain(std::iter::once(None)) {
        match point {
            Some(point) => run.push(point),
            None if run.len() > 1 => {
                painter.add(egui::Shape::line(std::mem::take(&mut run), stroke));
            }
            None => run.clear(),
        }
    }
}

/// Paints `view` over `screen`.
pub fn paint(painter: &Painter, screen: &Screen, view: &HudView) {
    let film = |at: (f32, f32)| screen.film_point(at);
    for ring in &view.rings {
        let points = ring.points.iter().map(|point| point.map(film));
        // Closed: the last point joins the first.
        let closed = points
            .clone()
            .chain(ring.points.first().map(|p| p.map(film)));
        paint_ring(painter, closed, ring.strength);
    }
    for mark in &view.marks {
        paint_mark(painter, film(mark.at), mark.state, mark.suspicion);
    }
    let centre = screen.rect.center();
    let bottom = match view.gem {
        Some(gem) => paint_gem(painter, screen, gem).top(),
        None => screen.rect.bottom() - MARGIN,
    };
    // Under the aim point, clear of the captions along the bottom.
    if let Some(prompt) = &view.prompt {
        let at = centre + vec2(0.0, 2.0 * LINE);
        text(
            painter,
            at,
            Align2::CENTER_TOP,
            prompt,
            body(BODY_TEXT),
            TEXT,
        );
    }
    if let Some(hint) = &view.hint {
        let at = pos2(centre.x, screen.rect.height() / 4.0);
        text(painter, at, Align2::CENTER_TOP, hint, body(BODY_TEXT), TEXT);
    }
    if let Some(banner) = &view.banner {
        let at = pos2(centre.x, screen.rect.height() / 3.0);
        text(
            painter,
            at,
            Align2::CENTER_TOP,
            banner,
            body(BODY_TEXT + 3.0),
            TEXT,
        );
    }
    // Captions centred above the gem, the newest lowest.
    for (row, line) in view.captions.iter().rev().enumerate() {
        let at = pos2(centre.x, bottom - 8.0 - row as f32 * LINE);
        text(
            painter,
            at,
            Align2::CENTER_BOTTOM,
            line,
            body(BODY_TEXT),
            TEXT,
        );
    }
    for (row, line) in view.progress.iter().enumerate() {
        let at = pos2(MARGIN, screen.rect.bottom() - MARGIN - row as f32 * LINE);
        text(
            painter,
            at,
            Align2::LEFT_BOTTOM,
            line,
            body(BODY_TEXT),
            TEXT,
        );
    }
}

/// The most lines of a level file's problems shown.
const ERROR_LINES: usize = 6;

/// Paints the corner's lines, top left: the status in a fixed-width face (its numbers
/// change every frame and must not dance), then the notice, then a file's problems wrapped
/// to the window.
pub fn paint_corner(painter: &Painter, screen: &Screen, corner: &Corner) {
    let mut at = pos2(MARGIN, MARGIN);
    if let Some(status) = &corner.status {
        let font = FontId::monospace(CORNER_TEXT);
        at.y = text(painter, at, Align2::LEFT_TOP, status, font, TEXT).bottom() + 4.0;
    }
    if let Some(notice) = &corner.notice {
        at.y = text(painter, at, Align2::LEFT_TOP, notice, body(BODY_TEXT), TEXT).bottom() + 4.0;
    }
    if let Some(error) = &corner.file_error {
        let shown: Vec<&str> = error.lines().take(ERROR_LINES).collect();
        let wrap = (screen.rect.width() - 2.0 * MARGIN).max(40.0);
        let font = FontId::monospace(CORNER_TEXT);
        let galley = painter.layout(shown.join("\n"), font, TEXT, wrap);
        let back = Rect::from_min_size(at, galley.size()).expand(4.0);
        painter.rect_filled(back, 2.0, Color32::from_black_alpha(190));
        painter.galley(at, galley, TEXT);
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::app::interface::pixels_per_point;

    /// Runs one egui pass of `draw` over a `window` (physical pixels) and returns each
    /// text it drew with its line box in physical pixels.
    pub(crate) fn texts_drawn(
        window: (u32, u32),
        draw: impl FnOnce(&Painter, &Screen),
    ) -> Vec<(String, Rect)> {
        let buffer = (480, 270);
        let screen = Screen::new(window, (0, 0, window.0, window.1), buffer, 1.0);
        let context = egui::Context::default();
        let mut draw = Some(draw);
        let output = context.run_ui(screen.input(), |ui| {
            if let Some(draw) = draw.take() {
                draw(ui.painter(), &screen);
            }
        });
        let scale = pixels_per_point(window, 1.0);
        output
            .shapes
            .iter()
            .filter_map(|clipped| match &clipped.shape {
                egui::Shape::Text(shape)
                    if shape.override_text_color.is_none() && !shape.galley.is_empty() =>
                {
                    // The line's box (its font's height), not the glyphs' ink.
                    let rect = Rect::from_min_size(shape.pos, shape.galley.size());
                    let physical = Rect::from_min_max(rect.min * scale, rect.max * scale);
                    Some((shape.galley.text().to_string(), physical))
                }
                _ => None,
            })
            .collect()
    }

    fn busy_view() -> HudView {
        HudView {
            gem: Some(0.6),
            marks: vec![Mark {
                at: (240.0, 100.0),
                state: WardenState::Alert,
                suspicion: 0.8,
            }],
            rings: Vec::new(),
            prompt: Some("E  douse the lamp".to_string()),
            hint: Some("Take the three shards, then find the way out.".to_string()),
            banner: Some("Caught by Aldous. The level starts again.".to_string()),
            progress: vec!["shards 1/3".to_string()],
            captions: vec![
                "a warden's footsteps, behind you".to_string(),
                "a lamp goes out, close by".to_string(),
                "a door creaks, left".to_string(),
            ],
        }
    }

    #[test]
    fn the_hud_reads_at_960x540_and_is_sharper_not_smaller_at_1920x1080() {
        for (window, least_height) in [((960, 540), 14.0), ((1920, 1080), 28.0)] {
            let drawn = texts_drawn(window, |painter, screen| {
                paint(painter, screen, &busy_view())
            });
            let lines = [
                "E  douse the lamp",
                "shards 1/3",
                "a door creaks, left",
                "!",
            ];
            for line in lines {
                let (_, rect) = drawn
                    .iter()
                    .find(|(text, _)| text == line)
                    .unwrap_or_else(|| panic!("{line:?} was not drawn at {window:?}"));
                assert!(
                    rect.height() >= least_height,
                    "{line:?} is {} px tall at {window:?}",
                    rect.height()
                );
                let inside =
                    Rect::from_min_size(Pos2::ZERO, vec2(window.0 as f32, window.1 as f32));
                assert!(
                    inside.contains_rect(*rect),
                    "{line:?} at {rect:?} leaves {window:?}"
                );
            }
        }
    }

    #[test]
    fn no_two_lines_of_the_hud_overlap() {
        for window in [(960, 540), (1920, 1080), (640, 360)] {
            let drawn = texts_drawn(window, |painter, screen| {
                paint(painter, screen, &busy_view());
                let corner = Corner {
                    status: Some("60.0 fps 16.6 ms 480x270 (100%) temporal".to_string()),
                    notice: Some("screenshot saved".to_string()),
                    file_error: None,
                };
                paint_corner(painter, screen, &corner);
            });
            // The warden's mark floats over the scene, where it may meet anything.
            let lines: Vec<_> = drawn.iter().filter(|(text, _)| text != "!").collect();
            for (i, (a, first)) in lines.iter().enumerate() {
                for (b, second) in &lines[i + 1..] {
                    assert!(
                        !first.intersects(*second),
                        "{a:?} {first:?} overlaps {b:?} {second:?} at {window:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_gem_lights_as_many_cells_as_its_value_asks() {
        let context = egui::Context::default();
        let lit = |value: f32| {
            let output = context.run_ui(egui::RawInput::default(), |ui| {
                let screen = Screen::new((960, 540), (0, 0, 960, 540), (480, 270), 1.0);
                paint_gem(ui.painter(), &screen, value);
            });
            // Dark frame, unlit cells (40, 40, 46), lit cells warmer and brighter.
            (output.shapes.iter())
                .filter(|clipped| match &clipped.shape {
                    egui::Shape::Rect(rect) => rect.fill.r() > 100,
                    _ => false,
                })
                .count()
        };
        assert_eq!(lit(0.0), 0);
        assert_eq!(lit(0.4), 2);
        assert_eq!(lit(1.0), GEM_STEPS);
    }
}
