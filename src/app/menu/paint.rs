//! Frame step `present`, when a menu is open: the page (`PageView`) laid out in egui points
//! and painted over the darkened game by the `interface` layer at the window's resolution.
//! `layout` is the one placement both the painting and the pointer's hits (`row_at`) read.

use egui::{Align2, Color32, FontId, Painter, Rect, pos2, vec2};

use super::{GAME_NAME, PageView};
use crate::app::hud::{self, TEXT, text};

/// A menu row's height, points (the row text's 18 and a gap).
const ROW_HEIGHT: u32 = 28;
/// Kept free below the rows for the hint line, points.
const HINT_SPACE: u32 = 30;
/// A title line's text size and height, points; the main page's first line, the game's
/// name, is larger.
const TITLE_TEXT: f32 = 22.0;
const TITLE_LINE: u32 = 30;
const NAME_TEXT: f32 = 34.0;
const NAME_LINE: u32 = 46;
const ROW_TEXT: f32 = 18.0;
const HINT_TEXT: f32 = 14.0;

/// The size and height of each of `view`'s title lines.
fn title_lines(view: &PageView) -> impl Iterator<Item = (f32, u32)> + '_ {
    let main = view.title.first().is_some_and(|line| line == GAME_NAME);
    (0..view.title.len()).map(move |line| match main && line == 0 {
        true => (NAME_TEXT, NAME_LINE),
        false => (TITLE_TEXT, TITLE_LINE),
    })
}

/// The height of `view`'s title lines and the gap under them.
fn title_height(view: &PageView) -> u32 {
    title_lines(view).map(|(_, height)| height).sum::<u32>() + 18
}

/// Where each row of a page is drawn: (x, y, width, height) in points, centred; None for a
/// row scrolled out of view. A page taller than the window (the keys page in a small
/// window, or at a large `ui_scale`) shows the rows that fit under its title, with the
/// selected one among them, and leaves the title out when not even one row would fit
/// beside it.
pub fn layout(view: &PageView, width: u32, height: u32) -> Vec<Option<(u32, u32, u32, u32)>> {
    let rows = view.rows.len() as u32;
    let row_width = (width * 3 / 5).clamp(200, 640).min(width);
    let left = (width - row_width) / 2;
    let title = title_height(view);
    let total = title + rows * ROW_HEIGHT;
    let place = |top: u32, first: u32, shown: u32| {
        (0..rows)
            .map(|row| {
                (row >= first && row < first + shown).then(|| {
                    (
                        left,
                        top + (row - first) * ROW_HEIGHT,
                        row_width,
                        ROW_HEIGHT - 2,
                    )
                })
            })
            .collect()
    };
    if total + HINT_SPACE <= height {
        return place((height - total - HINT_SPACE) / 2 + title, 0, rows);
    }
    let (top, room) = if height >= title + ROW_HEIGHT + HINT_SPACE {
        (title, height - title - HINT_SPACE)
    } else {
        (0, height.saturating_sub(HINT_SPACE).max(ROW_HEIGHT))
    };
    let shown = (room / ROW_HEIGHT).clamp(1, rows.max(1));
    let selected = (view.selected as u32).min(rows.saturating_sub(1));
    let first = selected
        .saturating_sub(shown / 2)
        .min(rows.saturating_sub(shown));
    place(top, first, shown)
}

/// The window in whole points, as `layout` and `row_at` take it.
fn whole_points(screen: &Rect) -> (u32, u32) {
    (screen.width() as u32, screen.height() as u32)
}

/// Paints `view` over `screen` (points): darkens what is behind, then the title, the rows
/// (the selected one highlighted) and the hint line.
pub fn paint(painter: &Painter, screen: Rect, view: &PageView) {
    // The interface blends in linear light: 88% black leaves the scene at about a third
    // of its displayed brightness, dim enough to read over and still there.
    painter.rect_filled(screen, 0.0, Color32::from_black_alpha(224));
    let (width, height) = whole_points(&screen);
    let boxes = layout(view, width, height);
    let first_top = boxes.iter().flatten().next().map(|&(_, y, _, _)| y);
    // The title above the rows, where `layout` left room for it.
    if let Some(title_top) =
        first_top.map_or(Some(height / 3), |y| y.checked_sub(title_height(view)))
    {
        let mut top = title_top;
        for (words, (size, height)) in view.title.iter().zip(title_lines(view)) {
            let at = pos2(screen.center().x, top as f32);
            text(
                painter,
                at,
                Align2::CENTER_TOP,
                words,
                FontId::proportional(size),
                TEXT,
            );
            top += height;
        }
    }
    let font = FontId::proportional(ROW_TEXT);
    for (index, (row, &(x, y, w, h))) in view
        .rows
        .iter()
        .zip(&boxes)
        .enumerate()
        .filter_map(|(index, (row, placed))| Some((index, (row, placed.as_ref()?))))
    {
        let rect = Rect::from_min_size(pos2(x as f32, y as f32), vec2(w as f32, h as f32));
        if index == view.selected {
            painter.rect_filled(rect, 3.0, Color32::from_rgb(74, 64, 44));
        }
        let left = rect.left_center() + vec2(12.0, 0.0);
        text(
            painter,
            left,
            Align2::LEFT_CENTER,
            &row.label,
            font.clone(),
            TEXT,
        );
        if let Some(value) = &row.value {
            let value = if index == view.selected && row.adjustable {
                format!("<  {value}  >")
            } else {
                value.clone()
            };
            let right = rect.right_center() - vec2(12.0, 0.0);
            text(
                painter,
                right,
                Align2::RIGHT_CENTER,
                &value,
                font.clone(),
                TEXT,
            );
        }
    }
    if !view.hint.is_empty() {
        // Under the rows, inside the `HINT_SPACE` `layout` keeps free.
        let below = (boxes.iter().flatten().last()).map_or(height / 2, |&(_, y, _, h)| y + h + 10);
        let y = below.min(height.saturating_sub(HINT_SPACE - 6)) as f32;
        let font = FontId::proportional(HINT_TEXT);
        let colour = hud::TEXT.gamma_multiply(0.75);
        text(
            painter,
            pos2(screen.center().x, y),
            Align2::CENTER_TOP,
            view.hint,
            font,
            colour,
        );
    }
}

/// The row under window point `at` (points), on a page laid out over `screen`.
pub fn row_at(view: &PageView, screen: Rect, at: egui::Pos2) -> Option<usize> {
    let (width, height) = whole_points(&screen);
    let (x, y) = (at.x.max(0.0) as u32, at.y.max(0.0) as u32);
    layout(view, width, height).iter().position(|placed| {
        placed.is_some_and(|(bx, by, bw, bh)| x >= bx && x < bx + bw && y >= by && y < by + bh)
    })
}

#[cfg(test)]
mod tests {
    use super::super::tests::context;
    use super::super::{Menu, Page};
    use super::*;

    #[test]
    fn rows_are_hit_where_they_are_drawn() {
        let context = context();
        let menu = Menu::new(Page::Main);
        let view = menu.view(&context);
        let screen = Rect::from_min_size(egui::Pos2::ZERO, vec2(960.0, 540.0));
        for (row, placed) in layout(&view, 960, 540).iter().enumerate() {
            let (x, y, w, h) = placed.expect("the main menu fits at 960 x 540");
            let middle = pos2((x + w / 2) as f32, (y + h / 2) as f32);
            assert_eq!(row_at(&view, screen, middle), Some(row));
        }
        assert_eq!(row_at(&view, screen, egui::Pos2::ZERO), None);
    }

    #[test]
    fn every_page_reads_whole_inside_the_window_at_960x540_and_1920x1080() {
        let context = context();
        let mut menu = Menu::new(Page::Main);
        for page in [
            Page::Main,
            Page::Settings,
            Page::Keys,
            Page::Pad,
            Page::Paused,
        ] {
            menu.stack.push((page, 0));
            let view = menu.view(&context);
            for window in [(960, 540), (1920, 1080)] {
                let drawn = crate::app::hud::tests::texts_drawn(window, |painter, screen| {
                    paint(painter, screen.rect, &view)
                });
                let inside =
                    Rect::from_min_size(egui::Pos2::ZERO, vec2(window.0 as f32, window.1 as f32));
                for row in &view.rows {
                    let (_, rect) = (drawn.iter().find(|(text, _)| *text == row.label))
                        .unwrap_or_else(|| panic!("{:?} not drawn at {window:?}", row.label));
                    // 18-point rows: at least 16 pixels tall at the smaller window.
                    assert!(rect.height() >= 16.0 * window.1 as f32 / 540.0);
                    assert!(inside.contains_rect(*rect), "{:?} at {rect:?}", row.label);
                }
                for (i, (a, first)) in drawn.iter().enumerate() {
                    for (b, second) in &drawn[i + 1..] {
                        assert!(!first.intersects(*second), "{a:?} overlaps {b:?}");
                    }
                }
            }
            menu.stack.pop();
        }
    }

    #[test]
    fn a_page_taller_than_the_frame_scrolls_to_the_selected_row() {
        let context = context();
        let mut menu = Menu::new(Page::Main);
        menu.stack.push((Page::Keys, 0));
        let rows = menu.view(&context).rows.len();
        for (width, height) in [(320, 180), (160, 90)] {
            for selected in [0, rows / 2, rows - 1] {
                menu.select(selected);
                let view = menu.view(&context);
                let boxes = layout(&view, width, height);
                let shown: Vec<_> = boxes.iter().flatten().collect();
                assert!(shown.len() < rows, "the keys page is taller than {height}");
                let (x, y, w, h) = boxes[selected].expect("the selected row is shown");
                // Inside the frame, above the hint line, and hit where drawn.
                assert!(x + w <= width && y + h + HINT_SPACE <= height);
                for &&(_, y, _, h) in &shown {
                    assert!(y + h + HINT_SPACE <= height, "{width} x {height}");
                }
                let screen =
                    Rect::from_min_size(egui::Pos2::ZERO, vec2(width as f32, height as f32));
                let middle = pos2((x + w / 2) as f32, (y + h / 2) as f32);
                assert_eq!(row_at(&view, screen, middle), Some(selected));
            }
        }
    }
}
