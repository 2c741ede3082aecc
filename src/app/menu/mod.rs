//! Frame step `present`, when a menu is open: the front end, drawn by the `interface` layer
//! at the window's resolution over the darkened game (or a plain backdrop before a level is
//! chosen): this module is its pages as a model, `paint` lays them out in egui points and
//! paints them.
//!
//! The menus are a small state machine with no window in it, so tests drive it: the shell
//! turns keys, the mouse and gamepad buttons into [`MenuInput`]s, and [`Menu::input`]
//! answers with a [`MenuCommand`] for the shell to carry out (play a level, resume,
//! quit...). Pages: main -> level select, settings -> keys, gamepad buttons; Esc (or Start)
//! in play opens the pause page. No single key quits: Quit is a row to choose and confirm
//! with Enter, A or a click.

use std::path::{Path, PathBuf};

use winit::keyboard::KeyCode;

use super::settings::{
    ACTION_NAMES, Best, BestTimes, Key, KeyBindings, PadBindings, PadButton, Settings, ranges,
};
use crate::game::Action;

mod paint;
pub use paint::{layout, paint, row_at};

/// The main page's first title line.
const GAME_NAME: &str = "G L O A M";

/// A playable level the level select lists.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelEntry {
    pub path: PathBuf,
    pub name: String,
}

/// The playable levels in `folder` (`*.ron` whose level is playable), in campaign order
/// (the level's `campaign` number, then the file name); a file that does not load is left
/// out and named in the returned warnings.
pub fn find_levels(folder: &Path) -> (Vec<LevelEntry>, Vec<String>) {
    let mut found: Vec<(u32, LevelEntry)> = Vec::new();
    let mut warnings = Vec::new();
    let Ok(entries) = std::fs::read_dir(folder) else {
        warnings.push(format!("{}: cannot list the levels", folder.display()));
        return (Vec::new(), warnings);
    };
    let mut paths: Vec<PathBuf> = entries
        .filter_map(|entry| entry.ok().map(|entry| entry.path()))
        .filter(|path| path.extension().is_some_and(|ext| ext == "ron"))
        .collect();
    paths.sort();
    for path in paths {
        match crate::scene::level::load_level(&path) {
            Ok(level) if level.playable => {
                let name = if level.name.is_empty() {
                    BestTimes::key(&path)
                } else {
                    level.name.clone()
                };
                found.push((
                    level.campaign.unwrap_or(u32::MAX),
                    LevelEntry { path, name },
                ));
            }
            Ok(_) => {}
            Err(error) => warnings.push(error.to_string().lines().next().unwrap_or("").into()),
        }
    }
    found.sort_by(|a, b| a.0.cmp(&b.0).then_with(|| a.1.path.cmp(&b.1.path)));
    (
        found.into_iter().map(|(_, entry)| entry).collect(),
        warnings,
    )
}

/// A won attempt, for the end page.
#[derive(Clone, Debug, PartialEq)]
pub struct Finish {
    pub level: PathBuf,
    pub best: Best,
    /// This finish is now the level's best.
    pub new_best: bool,
    /// The time to beat before this attempt.
    pub previous: Option<Best>,
    /// Noclip was used: the run does not count for best times.
    pub noclip: bool,
}

/// What the menus read and change.
pub struct MenuContext {
    pub levels: Vec<LevelEntry>,
    pub best: BestTimes,
    pub settings: Settings,
    /// The level being played (pause and end pages).
    pub playing: Option<PathBuf>,
    pub finish: Option<Finish>,
}

impl MenuContext {
    /// The level after `level` in campaign order.
    pub fn next_level(&self, level: &Path) -> Option<&LevelEntry> {
        let at = self.levels.iter().position(|entry| entry.path == level)?;
        self.levels.get(at + 1)
    }

    /// Where "Play" starts: the first level not yet won, else the first.
    fn first_unbeaten(&self) -> Option<&LevelEntry> {
        self.levels
            .iter()
            .find(|entry| self.best.get(&entry.path).is_none())
            .or(self.levels.first())
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Page {
    Main,
    Levels,
    Settings,
    Keys,
    /// The gamepad's buttons for each action.
    Pad,
    Paused,
    Won,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MenuInput {
    Up,
    Down,
    Left,
    Right,
    /// Enter, or a click on the selected row.
    Activate,
    /// Esc: back a page (or resume from the pause page).
    Back,
    /// The pointer is over row `n`.
    Point(usize),
    /// A key press, while the keys page waits for one to bind.
    Key(KeyCode),
    /// A gamepad button press, while the gamepad page waits for one to bind.
    Pad(PadButton),
}

#[derive(Clone, Debug, PartialEq)]
pub enum MenuCommand {
    Play(PathBuf),
    Resume,
    Restart,
    /// Leave the level for the main page.
    MainMenu,
    Quit,
    /// A setting changed: apply it and save the file.
    SettingsChanged,
}

/// One of the settings' volumes (`audio::Volumes`).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Channel {
    Master,
    Effects,
    Voices,
    Ambience,
}

impl Channel {
    fn name(self) -> &'static str {
        match self {
            Channel::Master => "Master",
            Channel::Effects => "Effects",
            Channel::Voices => "Voices",
            Channel::Ambience => "Ambience",
        }
    }

    fn of(self, volumes: &mut crate::audio::Volumes) -> &mut f32 {
        match self {
            Channel::Master => &mut volumes.master,
            Channel::Effects => &mut volumes.effects,
            Channel::Voices => &mut volumes.voices,
            Channel::Ambience => &mut volumes.ambience,
        }
    }
}

/// What a row does.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Row {
    Play,
    ChooseLevel,
    Settings,
    Quit,
    Level(usize),
    Back,
    MouseSensitivity,
    InvertY,
    FieldOfView,
    Brightness,
    FrameTimeTarget,
    InterfaceSize,
    Captions,
    /// One of the settings' volumes.
    Volume(Channel),
    Keys,
    Bind(Action),
    ResetKeys,
    Pad,
    BindPad(Action),
    ResetPad,
    Resume,
    Restart,
    MainMenu,
    NextLevel,
    PlayAgain,
}

impl Row {
    /// A setting's row: Left and Right step its value (`adjust`).
    fn is_setting(self) -> bool {
        matches!(
            self,
            Row::MouseSensitivity
                | Row::InvertY
                | Row::FieldOfView
                | Row::Brightness
                | Row::FrameTimeTarget
                | Row::InterfaceSize
                | Row::Captions
                | Row::Volume(_)
        )
    }
}

/// A row as drawn: its label and, for a setting, its value.
#[derive(Clone, Debug, PartialEq)]
pub struct RowView {
    pub label: String,
    pub value: Option<String>,
    /// Left and Right change the value.
    pub adjustable: bool,
}

/// A page as drawn.
#[derive(Clone, Debug, PartialEq)]
pub struct PageView {
    pub title: Vec<String>,
    pub rows: Vec<RowView>,
    pub selected: usize,
    pub hint: &'static str,
}

pub struct Menu {
    /// Pages open, the last shown; each with its selected row.
    stack: Vec<(Page, usize)>,
    /// The keys page is waiting for the key to bind to this action.
    binding: Option<Action>,
    /// The gamepad page is waiting for the button to bind to this action.
    pad_binding: Option<Action>,
}

impl Menu {
    pub fn new(page: Page) -> Menu {
        Menu {
            stack: vec![(page, 0)],
            binding: None,
            pad_binding: None,
        }
    }

    /// The keys page waits for the key to bind (or the gamepad page for a button, which a
    /// key cancels): every key goes to it.
    pub fn waiting_for_key(&self) -> bool {
        self.binding.is_some() || self.pad_binding.is_some()
    }

    pub fn page(&self) -> Page {
        self.stack.last().map_or(Page::Main, |&(page, _)| page)
    }

    fn rows(&self, context: &MenuContext) -> Vec<Row> {
        match self.page() {
            Page::Main => vec![Row::Play, Row::ChooseLevel, Row::Settings, Row::Quit],
            Page::Levels => (0..context.levels.len())
                .map(Row::Level)
                .chain([Row::Back])
                .collect(),
            Page::Settings => vec![
                Row::MouseSensitivity,
                Row::InvertY,
                Row::FieldOfView,
                Row::Brightness,
                Row::FrameTimeTarget,
                Row::InterfaceSize,
                Row::Captions,
                Row::Volume(Channel::Master),
                Row::Volume(Channel::Effects),
                Row::Volume(Channel::Voices),
                Row::Volume(Channel::Ambience),
                Row::Keys,
                Row::Pad,
                Row::Back,
            ],
            Page::Keys => ACTION_NAMES
                .iter()
                .map(|&(action, _)| Row::Bind(action))
                .chain([Row::ResetKeys, Row::Back])
                .collect(),
            Page::Pad => ACTION_NAMES
                .iter()
                .map(|&(action, _)| Row::BindPad(action))
                .chain([Row::ResetPad, Row::Back])
                .collect(),
            Page::Paused => vec![
                Row::Resume,
                Row::Restart,
                Row::Settings,
                Row::MainMenu,
                Row::Quit,
            ],
            Page::Won => {
                let next = context
                    .playing
                    .as_deref()
                    .and_then(|level| context.next_level(level));
                next.map(|_| Row::NextLevel)
                    .into_iter()
                    .chain([Row::PlayAgain, Row::ChooseLevel, Row::MainMenu])
                    .collect()
            }
        }
    }

    fn selected(&self) -> usize {
        self.stack.last().map_or(0, |&(_, selected)| selected)
    }

    fn select(&mut self, row: usize) {
        if let Some((_, selected)) = self.stack.last_mut() {
            *selected = row;
        }
    }

    fn open(&mut self, page: Page) {
        self.stack.push((page, 0));
    }

    /// One input; returns what the shell must do, if anything.
    pub fn input(&mut self, input: MenuInput, context: &mut MenuContext) -> Option<MenuCommand> {
        if let Some(action) = self.pad_binding {
            match input {
                // Start keeps the binding, as Esc does on the keys page.
                MenuInput::Pad(button) => {
                    self.pad_binding = None;
                    if context.settings.pad.bind(action, button) {
                        return Some(MenuCommand::SettingsChanged);
                    }
                }
                MenuInput::Key(_) | MenuInput::Back => self.pad_binding = None,
                _ => {}
            }
            return None;
        }
        if let Some(action) = self.binding {
            if let MenuInput::Key(code) = input {
                self.binding = None;
                if code != KeyCode::Escape && Key::bindable(code) {
                    context.settings.keys.bind(action, code);
                    return Some(MenuCommand::SettingsChanged);
                }
            }
            return None;
        }
        let rows = self.rows(context);
        let count = rows.len().max(1);
        let selected = self.selected().min(count - 1);
        match input {
            MenuInput::Up => self.select((selected + count - 1) % count),
            MenuInput::Down => self.select((selected + 1) % count),
            MenuInput::Point(row) if row < rows.len() => self.select(row),
            MenuInput::Left | MenuInput::Right => {
                let step = if input == MenuInput::Left { -1 } else { 1 };
                return rows
                    .get(selected)
                    .and_then(|&row| adjust(row, step, &mut context.settings));
            }
            MenuInput::Activate => {
                let row = *rows.get(selected)?;
                return self.activate(row, context);
            }
            MenuInput::Back => return self.back(),
            _ => {}
        }
        None
    }

    fn back(&mut self) -> Option<MenuCommand> {
        match self.page() {
            Page::Paused => Some(MenuCommand::Resume),
            Page::Main | Page::Won => None,
            _ => {
                self.stack.pop();
                None
            }
        }
    }

    fn activate(&mut self, row: Row, context: &mut MenuContext) -> Option<MenuCommand> {
        match row {
            Row::Play => context
                .first_unbeaten()
                .map(|entry| MenuCommand::Play(entry.path.clone())),
            Row::ChooseLevel => {
                self.open(Page::Levels);
                None
            }
            Row::Settings => {
                self.open(Page::Settings);
                None
            }
            Row::Keys => {
                self.open(Page::Keys);
                None
            }
            Row::Quit => Some(MenuCommand::Quit),
            Row::Level(index) => context
                .levels
                .get(index)
                .map(|entry| MenuCommand::Play(entry.path.clone())),
            Row::Back => self.back(),
            Row::Bind(action) => {
                self.binding = Some(action);
                None
            }
            Row::ResetKeys => {
                context.settings.keys = KeyBindings::default();
                Some(MenuCommand::SettingsChanged)
            }
            Row::Pad => {
                self.open(Page::Pad);
                None
            }
            Row::BindPad(action) => {
                self.pad_binding = Some(action);
                None
            }
            Row::ResetPad => {
                context.settings.pad = PadBindings::default();
                Some(MenuCommand::SettingsChanged)
            }
            Row::Resume => Some(MenuCommand::Resume),
            Row::Restart | Row::PlayAgain => Some(MenuCommand::Restart),
            Row::MainMenu => Some(MenuCommand::MainMenu),
            Row::NextLevel => context
                .playing
                .as_deref()
                .and_then(|level| context.next_level(level))
                .map(|entry| MenuCommand::Play(entry.path.clone())),
            // A setting's row steps its value forward when chosen.
            setting => adjust(setting, 1, &mut context.settings),
        }
    }

    /// The current page as drawn.
    pub fn view(&self, context: &MenuContext) -> PageView {
        let rows = self.rows(context);
        let settings = &context.settings;
        let title = match self.page() {
            Page::Main => vec![
                GAME_NAME.to_string(),
                "a thief's night in path-traced light".to_string(),
            ],
            Page::Levels => vec!["Choose a level".to_string()],
            Page::Settings => vec!["Settings".to_string()],
            Page::Keys => vec![match self.binding {
                Some(action) => format!("Press a key for {}  (Esc: keep it)", action_name(action)),
                None => "Keys".to_string(),
            }],
            Page::Pad => vec![match self.pad_binding {
                Some(action) => format!(
                    "Press a button for {}  (Start or Esc: keep it)",
                    action_name(action)
                ),
                None => "Gamepad buttons".to_string(),
            }],
            Page::Paused => vec![
                "Paused".to_string(),
                context
                    .playing
                    .as_deref()
                    .and_then(|level| context.levels.iter().find(|entry| entry.path == level))
                    .map_or_else(String::new, |entry| entry.name.clone()),
            ],
            Page::Won => won_title(context),
        };
        let rows = rows
            .iter()
            .map(|&row| {
                let (label, value) = match row {
                    Row::Play => ("Play".to_string(), None),
                    Row::ChooseLevel => ("Choose a level".to_string(), None),
                    Row::Settings => ("Settings".to_string(), None),
                    Row::Quit => ("Quit Gloam".to_string(), None),
                    Row::Level(index) => {
                        let entry = &context.levels[index];
                        let best = context.best.get(&entry.path).map_or_else(
                            || "not yet won".to_string(),
                            |best| format!("best {}", crate::game::play_time(best.seconds)),
                        );
                        (format!("{}  {}", index + 1, entry.name), Some(best))
                    }
                    Row::Back => ("Back".to_string(), None),
                    Row::MouseSensitivity => (
                        "Mouse sensitivity".to_string(),
                        Some(format!("{:.1}", settings.mouse_sensitivity)),
                    ),
                    Row::InvertY => (
                        "Invert mouse Y".to_string(),
                        Some(if settings.invert_y { "on" } else { "off" }.to_string()),
                    ),
                    Row::Captions => (
                        "Captions".to_string(),
                        Some(if settings.captions { "on" } else { "off" }.to_string()),
                    ),
                    Row::Volume(channel) => (
                        format!("{} volume", channel.name()),
                        Some(format!(
                            "{:.0}%",
                            *channel.of(&mut { settings.volume }) * 100.0
                        )),
                    ),
                    Row::FieldOfView => (
                        "Field of view".to_string(),
                        Some(format!("{:.0} deg", settings.field_of_view)),
                    ),
                    Row::Brightness => (
                        "Brightness".to_string(),
                        Some(format!("{:.2}", settings.brightness)),
                    ),
                    Row::FrameTimeTarget => (
                        "Frame-time target".to_string(),
                        Some(match settings.frame_time_target_ms {
                            Some(ms) => format!("{ms:.1} ms"),
                            None => "off (fixed)".to_string(),
                        }),
                    ),
                    Row::InterfaceSize => (
                        "Interface size".to_string(),
                        Some(format!("{:.0}%", settings.ui_scale * 100.0)),
                    ),
                    Row::Keys => ("Keys".to_string(), None),
                    Row::Bind(action) => {
                        let labels = settings.keys.of(action).iter().map(|key| key.label());
                        let value = bound_value(labels, self.binding == Some(action));
                        (action_name(action).to_string(), Some(value))
                    }
                    Row::ResetKeys => ("Reset keys to defaults".to_string(), None),
                    Row::Pad => ("Gamepad buttons".to_string(), None),
                    Row::BindPad(action) => {
                        let labels = (settings.pad.of(action).iter())
                            .map(|button| button.label().to_string());
                        let value = bound_value(labels, self.pad_binding == Some(action));
                        (action_name(action).to_string(), Some(value))
                    }
                    Row::ResetPad => ("Reset buttons to defaults".to_string(), None),
                    Row::Resume => ("Resume".to_string(), None),
                    Row::Restart => ("Restart the level".to_string(), None),
                    Row::MainMenu => ("Main menu".to_string(), None),
                    Row::NextLevel => ("Next level".to_string(), None),
                    Row::PlayAgain => ("Play again".to_string(), None),
                };
                RowView {
                    label,
                    value,
                    adjustable: row.is_setting(),
                }
            })
            .collect();
        let hint = match self.page() {
            Page::Settings => "Up/Down choose  Left/Right change  Esc back",
            Page::Keys if self.binding.is_some() => "",
            Page::Pad if self.pad_binding.is_some() => "",
            Page::Main | Page::Won => "Up/Down choose  Enter select",
            Page::Paused => "Up/Down choose  Enter select  Esc resume",
            _ => "Up/Down choose  Enter select  Esc back",
        };
        PageView {
            title,
            rows,
            selected: self.selected(),
            hint,
        }
    }
}

/// A binding row's value: what is bound, "(none)", or "..." while the page waits for
/// the input to bind.
fn bound_value(labels: impl Iterator<Item = String>, waiting: bool) -> String {
    if waiting {
        return "...".to_string();
    }
    let labels: Vec<String> = labels.collect();
    if labels.is_empty() {
        "(none)".to_string()
    } else {
        labels.join(" ")
    }
}

fn action_name(action: Action) -> &'static str {
    ACTION_NAMES
        .iter()
        .find(|(named, _)| *named == action)
        .map_or("?", |(_, name)| name)
}

fn won_title(context: &MenuContext) -> Vec<String> {
    let Some(finish) = &context.finish else {
        return vec!["You got out.".to_string()];
    };
    let best = finish.best;
    let mut lines = vec![
        "You got out.".to_string(),
        format!(
            "time {}  shards {}  seen {} times",
            crate::game::play_time(best.seconds),
            best.shards,
            best.times_seen
        ),
    ];
    if finish.noclip {
        lines.push("Noclip was used: this run does not count for best times.".to_string());
        return lines;
    }
    lines.push(match (finish.new_best, finish.previous) {
        (true, Some(previous)) => format!(
            "A new best: {} faster than {}",
            crate::game::play_time(previous.seconds - best.seconds),
            crate::game::play_time(previous.seconds)
        ),
        (true, None) => "Your first escape: the time to beat.".to_string(),
        (false, Some(previous)) => format!("Best {}", crate::game::play_time(previous.seconds)),
        (false, None) => String::new(),
    });
    lines
}

/// Steps a setting's row by `step` (wrapping through choices, clamping numbers).
fn adjust(row: Row, step: i32, settings: &mut Settings) -> Option<MenuCommand> {
    let stepped = |value: f32, (low, high, by): (f32, f32, f32)| {
        let steps = ((value - low) / by).round() as i32 + step;
        (low + steps as f32 * by).clamp(low, high)
    };
    match row {
        Row::MouseSensitivity => {
            settings.mouse_sensitivity =
                stepped(settings.mouse_sensitivity, ranges::MOUSE_SENSITIVITY)
        }
        Row::InvertY => settings.invert_y = !settings.invert_y,
        Row::Captions => settings.captions = !settings.captions,
        Row::FieldOfView => {
            settings.field_of_view = stepped(settings.field_of_view, ranges::FIELD_OF_VIEW)
        }
        Row::Brightness => settings.brightness = stepped(settings.brightness, ranges::BRIGHTNESS),
        Row::InterfaceSize => settings.ui_scale = stepped(settings.ui_scale, ranges::UI_SCALE),
        Row::Volume(channel) => {
            let volume = channel.of(&mut settings.volume);
            *volume = stepped(*volume, ranges::VOLUME);
        }
        Row::FrameTimeTarget => {
            let choices = ranges::FRAME_TIME_TARGETS;
            let at = choices
                .iter()
                .position(|&choice| choice == settings.frame_time_target_ms)
                .unwrap_or(0) as i32;
            let next = (at + step).rem_euclid(choices.len() as i32) as usize;
            settings.frame_time_target_ms = choices[next];
        }
        _ => return None,
    }
    Some(MenuCommand::SettingsChanged)
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(super) fn context() -> MenuContext {
        MenuContext {
            levels: vec![
                LevelEntry {
                    path: "levels/a.ron".into(),
                    name: "A".into(),
                },
                LevelEntry {
                    path: "levels/b.ron".into(),
                    name: "B".into(),
                },
            ],
            best: BestTimes::default(),
            settings: Settings::default(),
            playing: None,
            finish: None,
        }
    }

    #[test]
    fn play_starts_the_first_level_not_yet_won() {
        let mut context = context();
        let mut menu = Menu::new(Page::Main);
        assert_eq!(
            menu.input(MenuInput::Activate, &mut context),
            Some(MenuCommand::Play("levels/a.ron".into()))
        );
        context.best.offer(
            Path::new("levels/a.ron"),
            Best {
                seconds: 50.0,
                shards: 3,
                times_seen: 0,
            },
        );
        assert_eq!(
            menu.input(MenuInput::Activate, &mut context),
            Some(MenuCommand::Play("levels/b.ron".into()))
        );
    }

    #[test]
    fn the_level_select_shows_best_times_and_plays_the_chosen_level() {
        let mut context = context();
        context.best.offer(
            Path::new("levels/b.ron"),
            Best {
                seconds: 62.25,
                shards: 2,
                times_seen: 1,
            },
        );
        let mut menu = Menu::new(Page::Main);
        menu.input(MenuInput::Down, &mut context);
        menu.input(MenuInput::Activate, &mut context);
        assert_eq!(menu.page(), Page::Levels);
        let view = menu.view(&context);
        assert_eq!(view.rows[0].value.as_deref(), Some("not yet won"));
        assert_eq!(view.rows[1].value.as_deref(), Some("best 1:02.3"));
        menu.input(MenuInput::Point(1), &mut context);
        assert_eq!(
            menu.input(MenuInput::Activate, &mut context),
            Some(MenuCommand::Play("levels/b.ron".into()))
        );
        assert_eq!(menu.input(MenuInput::Back, &mut context), None);
        assert_eq!(menu.page(), Page::Main);
    }

    #[test]
    fn no_single_key_quits_and_esc_on_the_pause_page_resumes() {
        let mut context = context();
        let mut main = Menu::new(Page::Main);
        assert_eq!(main.input(MenuInput::Back, &mut context), None);
        assert_eq!(main.page(), Page::Main);
        let mut paused = Menu::new(Page::Paused);
        assert_eq!(
            paused.input(MenuInput::Back, &mut context),
            Some(MenuCommand::Resume)
        );
        // Quit is the last row: reached by moving there, then chosen.
        paused.input(MenuInput::Up, &mut context);
        assert_eq!(paused.view(&context).rows[4].label, "Quit Gloam");
        assert_eq!(
            paused.input(MenuInput::Activate, &mut context),
            Some(MenuCommand::Quit)
        );
    }

    #[test]
    fn settings_step_within_their_ranges() {
        let mut context = context();
        let mut menu = Menu::new(Page::Settings);
        menu.input(MenuInput::Point(2), &mut context); // field of view
        for _ in 0..20 {
            assert_eq!(
                menu.input(MenuInput::Right, &mut context),
                Some(MenuCommand::SettingsChanged)
            );
        }
        assert_eq!(context.settings.field_of_view, ranges::FIELD_OF_VIEW.1);
        menu.input(MenuInput::Point(4), &mut context); // frame-time target
        menu.input(MenuInput::Right, &mut context);
        assert_eq!(context.settings.frame_time_target_ms, Some(50.0));
        menu.input(MenuInput::Right, &mut context);
        assert_eq!(context.settings.frame_time_target_ms, None);
        menu.input(MenuInput::Point(1), &mut context); // invert Y
        menu.input(MenuInput::Activate, &mut context);
        assert!(context.settings.invert_y);
    }

    #[test]
    fn a_key_is_rebound_on_the_keys_page_and_esc_keeps_the_old_one() {
        let mut context = context();
        let mut menu = Menu::new(Page::Keys);
        menu.input(MenuInput::Activate, &mut context); // forward
        assert!(menu.view(&context).title[0].starts_with("Press a key for forward"));
        assert_eq!(
            menu.input(MenuInput::Key(KeyCode::ArrowUp), &mut context),
            Some(MenuCommand::SettingsChanged)
        );
        assert_eq!(
            context.settings.keys.action(Key(KeyCode::ArrowUp)),
            Some(Action::MoveForward)
        );
        menu.input(MenuInput::Activate, &mut context);
        assert_eq!(
            menu.input(MenuInput::Key(KeyCode::Escape), &mut context),
            None
        );
        assert_eq!(
            context.settings.keys.action(Key(KeyCode::ArrowUp)),
            Some(Action::MoveForward)
        );
    }

    #[test]
    fn a_pad_button_is_rebound_from_the_settings_and_start_keeps_the_old_one() {
        let mut context = context();
        let mut menu = Menu::new(Page::Settings);
        let rows = menu.rows(&context);
        let pad = rows.iter().position(|&row| row == Row::Pad).unwrap();
        menu.input(MenuInput::Point(pad), &mut context);
        menu.input(MenuInput::Activate, &mut context);
        assert_eq!(menu.page(), Page::Pad);
        let view = menu.view(&context);
        assert_eq!(view.rows[4].label, "jump");
        assert_eq!(view.rows[4].value.as_deref(), Some("A"));
        menu.input(MenuInput::Point(4), &mut context);
        menu.input(MenuInput::Activate, &mut context);
        assert!(menu.waiting_for_key());
        assert!(menu.view(&context).title[0].starts_with("Press a button for jump"));
        assert_eq!(
            menu.input(MenuInput::Pad(PadButton::North), &mut context),
            Some(MenuCommand::SettingsChanged)
        );
        assert_eq!(context.settings.pad.jump, [PadButton::North]);
        // Start (and a key) keeps the binding as it was.
        menu.input(MenuInput::Activate, &mut context);
        assert_eq!(
            menu.input(MenuInput::Pad(PadButton::Start), &mut context),
            None
        );
        assert!(!menu.waiting_for_key());
        assert_eq!(context.settings.pad.jump, [PadButton::North]);
        menu.input(MenuInput::Activate, &mut context);
        menu.input(MenuInput::Key(KeyCode::Escape), &mut context);
        assert_eq!(context.settings.pad.jump, [PadButton::North]);
        assert_eq!(
            menu.page(),
            Page::Pad,
            "Esc cancelled the binding, not the page"
        );
    }

    #[test]
    fn the_end_page_offers_the_next_level_and_says_how_the_best_moved() {
        let mut context = context();
        context.playing = Some("levels/a.ron".into());
        context.finish = Some(Finish {
            noclip: false,
            level: "levels/a.ron".into(),
            best: Best {
                seconds: 55.0,
                shards: 3,
                times_seen: 0,
            },
            new_best: true,
            previous: Some(Best {
                seconds: 60.0,
                shards: 3,
                times_seen: 2,
            }),
        });
        let mut menu = Menu::new(Page::Won);
        let view = menu.view(&context);
        assert_eq!(view.title[2], "A new best: 0:05.0 faster than 1:00.0");
        assert_eq!(
            menu.input(MenuInput::Activate, &mut context),
            Some(MenuCommand::Play("levels/b.ron".into()))
        );
    }
}
