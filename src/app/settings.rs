//! The player's own files, read when the window opens and written when they change: the
//! settings (mouse sensitivity and invert Y, field of view, brightness, frame-time target,
//! interface size, keys, gamepad buttons, captions, volumes: [`SETTINGS_FILE`]) and the
//! best time of each level ([`BEST_TIMES_FILE`]), both RON in the user's config folder
//! (`$GLOAM_CONFIG_DIR`, else `$XDG_CONFIG_HOME/gloam`, `~/.config/gloam`, `%APPDATA%\gloam`
//! or `~/Library/Application Support/gloam`). F12's screenshots go to the pictures folder
//! (`screenshot_dir`).
//!
//! A file that cannot be read as what it should be (bad syntax, an unknown field, a value
//! out of range, an unknown key, or one of the window's own keys, Esc, F2, F3, F4, F11, F12
//! and V, or the pad's Start, which cannot be rebound) is named in one line with the place
//! (`settings.ron:3:5: unknown field ...`), renamed aside to `<name>.broken` so nothing is
//! lost, and the defaults are used. Writes are atomic (a temporary file, then a rename).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use winit::keyboard::KeyCode;

use crate::game::Action;
use crate::scene::files::write_atomically;
use crate::scene::{Diagnostic, Pointer};

/// The frame time the adaptive resolution holds unless the settings or `--target-ms` say
/// otherwise (30 fps).
pub const DEFAULT_TARGET_MS: f64 = 33.3;

/// Everything the settings screen changes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Settings {
    /// Times the base mouse look (0.0025 radians per pixel of motion).
    pub mouse_sensitivity: f32,
    /// Moving the mouse forward looks down.
    pub invert_y: bool,
    /// Vertical field of view of the player's eye, degrees.
    pub field_of_view: f32,
    /// Multiplies the image's radiance before tone mapping.
    pub brightness: f32,
    /// The frame time the internal resolution adapts to hold, milliseconds; None keeps the
    /// resolution fixed. A first run chooses it from its first frames
    /// (`resolution::first_run_target`).
    pub frame_time_target_ms: Option<f64>,
    pub keys: KeyBindings,
    /// Captions for the sounds that matter to play, with where they come from.
    pub captions: bool,
    /// The sound's volumes, 0 to 1 each: `(master: 1.0, effects: 1.0, voices: 1.0,
    /// ambience: 1.0)`.
    pub volume: crate::audio::Volumes,
    /// The window fills the screen (F11 toggles it, and it is remembered).
    pub fullscreen: bool,
    /// Frames wait for the display's refresh (V toggles it, and it is remembered).
    pub vsync: bool,
    /// The gamepad's buttons bound to each game action (the left stick always moves, the
    /// right stick always looks, Start always pauses).
    pub pad: PadBindings,
    /// The size of the HUD's and the menus' text and marks, times their size for the
    /// window (1.0: 17-point text in a 960 x 540 window, twice that at 1920 x 1080).
    pub ui_scale: f32,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            mouse_sensitivity: 1.0,
            invert_y: false,
            field_of_view: 70.0,
            brightness: 1.0,
            frame_time_target_ms: Some(DEFAULT_TARGET_MS),
            keys: KeyBindings::default(),
            captions: true,
            volume: crate::audio::Volumes::default(),
            fullscreen: false,
            vsync: true,
            pad: PadBindings::default(),
            ui_scale: 1.0,
        }
    }
}

/// The ranges the settings screen steps through, and the file is held to.
pub mod ranges {
    pub const MOUSE_SENSITIVITY: (f32, f32, f32) = (0.1, 5.0, 0.1);
    pub const FIELD_OF_VIEW: (f32, f32, f32) = (50.0, 110.0, 5.0);
    pub const BRIGHTNESS: (f32, f32, f32) = (0.25, 4.0, 0.25);
    pub const UI_SCALE: (f32, f32, f32) = (0.5, 2.0, 0.1);
    /// Each volume, as a share of full.
    pub const VOLUME: (f32, f32, f32) = (0.0, 1.0, 0.1);
    /// The frame-time targets offered, milliseconds (None: fixed resolution).
    pub const FRAME_TIME_TARGETS: [Option<f64>; 5] = [
        None,
        Some(16.7),
        Some(25.0),
        Some(super::DEFAULT_TARGET_MS),
        Some(50.0),
    ];
}

impl Settings {
    /// Values out of range, each with the field it is in.
    fn problems(&self) -> Vec<(Pointer, String)> {
        let mut problems = Vec::new();
        let mut within = |field: &str, value: f32, (low, high, _): (f32, f32, f32)| {
            if !(low..=high).contains(&value) {
                // A nested field (`volume.master`) points into its struct.
                let at = field
                    .split('.')
                    .fold(Pointer::root(), |at, key| at.key(key));
                problems.push((at, format!("{field} {value} is outside {low}..={high}")));
            }
        };
        within(
            "mouse_sensitivity",
            self.mouse_sensitivity,
            ranges::MOUSE_SENSITIVITY,
        );
        within("field_of_view", self.field_of_view, ranges::FIELD_OF_VIEW);
        within("brightness", self.brightness, ranges::BRIGHTNESS);
        within("ui_scale", self.ui_scale, ranges::UI_SCALE);
        let volume = &self.volume;
        for (field, value) in [
            ("volume.master", volume.master),
            ("volume.effects", volume.effects),
            ("volume.voices", volume.voices),
            ("volume.ambience", volume.ambience),
        ] {
            within(field, value, ranges::VOLUME);
        }
        if let Some(target) = self.frame_time_target_ms
            && !(target.is_finite() && (1.0..=1000.0).contains(&target))
        {
            problems.push((
                Pointer::root().key("frame_time_target_ms"),
                format!("frame_time_target_ms {target} is outside 1..=1000"),
            ));
        }
        problems
    }
}

/// The inputs bound to each game action: `KeyBindings` (keyboard keys, by winit key code
/// name: `"KeyW"`, `"ShiftLeft"`, `"Space"`, `"ArrowUp"`...) and `PadBindings` (gamepad
/// buttons). The window's own keys (`RESERVED_KEYS`: Esc, F2, F3, F4, F11, F12 and V) and
/// button (Start) are fixed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(
    deny_unknown_fields,
    default,
    bound(deserialize = "T: Deserialize<'de>, Bindings<T>: Default")
)]
pub struct Bindings<T> {
    pub forward: Vec<T>,
    pub back: Vec<T>,
    pub left: Vec<T>,
    pub right: Vec<T>,
    pub jump: Vec<T>,
    pub crouch: Vec<T>,
    pub sprint: Vec<T>,
    pub interact: Vec<T>,
    pub noclip: Vec<T>,
}

pub type KeyBindings = Bindings<Key>;
pub type PadBindings = Bindings<PadButton>;

impl<T: Copy + PartialEq> Bindings<T> {
    /// What is bound to `action`, the first one shown in prompts.
    pub fn of(&self, action: Action) -> &Vec<T> {
        match action {
            Action::MoveForward => &self.forward,
            Action::MoveBack => &self.back,
            Action::MoveLeft => &self.left,
            Action::MoveRight => &self.right,
            Action::MoveUp => &self.jump,
            Action::MoveDown => &self.crouch,
            Action::Sprint => &self.sprint,
            Action::Interact => &self.interact,
            Action::Noclip => &self.noclip,
        }
    }

    fn of_mut(&mut self, action: Action) -> &mut Vec<T> {
        match action {
            Action::MoveForward => &mut self.forward,
            Action::MoveBack => &mut self.back,
            Action::MoveLeft => &mut self.left,
            Action::MoveRight => &mut self.right,
            Action::MoveUp => &mut self.jump,
            Action::MoveDown => &mut self.crouch,
            Action::Sprint => &mut self.sprint,
            Action::Interact => &mut self.interact,
            Action::Noclip => &mut self.noclip,
        }
    }

    /// The game action `input` is bound to.
    pub fn action(&self, input: T) -> Option<Action> {
        Action::ALL
            .into_iter()
            .find(|&action| self.of(action).contains(&input))
    }

    /// Binds `input` to `action` alone: it leaves any other action it was bound to, and
    /// the action's other inputs go.
    fn bind_alone(&mut self, action: Action, input: T) {
        for other in Action::ALL {
            self.of_mut(other).retain(|&bound| bound != input);
        }
        *self.of_mut(action) = vec![input];
    }

    /// Each action that holds one of `reserved`, as a problem of the file's `field`.
    fn reserved_problems(
        &self,
        field: &str,
        reserved: &[T],
        name: impl Fn(T) -> String,
        whose: &str,
    ) -> Vec<(Pointer, String)> {
        let mut problems = Vec::new();
        for (action, action_name) in ACTION_NAMES {
            for &input in self.of(action) {
                if reserved.contains(&input) {
                    problems.push((
                        Pointer::root().key(field),
                        format!(
                            "{} is the window's own {whose}; {action_name} cannot take it",
                            name(input)
                        ),
                    ));
                }
            }
        }
        problems
    }
}

impl Default for KeyBindings {
    fn default() -> Self {
        let keys = |codes: &[KeyCode]| codes.iter().copied().map(Key).collect();
        KeyBindings {
            forward: keys(&[KeyCode::KeyW]),
            back: keys(&[KeyCode::KeyS]),
            left: keys(&[KeyCode::KeyA]),
            right: keys(&[KeyCode::KeyD]),
            jump: keys(&[KeyCode::Space]),
            crouch: keys(&[KeyCode::KeyC, KeyCode::ControlLeft]),
            sprint: keys(&[KeyCode::ShiftLeft]),
            interact: keys(&[KeyCode::KeyE]),
            noclip: keys(&[KeyCode::KeyN]),
        }
    }
}

/// Each game action with the name the settings screen shows.
pub const ACTION_NAMES: [(Action, &str); 9] = [
    (Action::MoveForward, "forward"),
    (Action::MoveBack, "back"),
    (Action::MoveLeft, "left"),
    (Action::MoveRight, "right"),
    (Action::MoveUp, "jump"),
    (Action::MoveDown, "crouch"),
    (Action::Sprint, "sprint"),
    (Action::Interact, "douse / light"),
    (Action::Noclip, "noclip"),
];

/// Keys no game action may take: the window's own (pause and menus, fullscreen, profiler,
/// filters, vsync).
pub const RESERVED_KEYS: [KeyCode; super::controls::WINDOW_KEYS.len()] = {
    let mut keys = [KeyCode::Escape; super::controls::WINDOW_KEYS.len()];
    let mut i = 0;
    while i < keys.len() {
        keys[i] = super::controls::WINDOW_KEYS[i].0;
        i += 1;
    }
    keys
};

impl KeyBindings {
    /// Binds `code` to `action` alone (`Bindings::bind_alone`); a reserved key is refused.
    pub fn bind(&mut self, action: Action, code: KeyCode) -> bool {
        if RESERVED_KEYS.contains(&code) {
            return false;
        }
        self.bind_alone(action, Key(code));
        true
    }

    fn problems(&self) -> Vec<(Pointer, String)> {
        let reserved: Vec<Key> = RESERVED_KEYS.iter().copied().map(Key).collect();
        self.reserved_problems("keys", &reserved, Key::name, "key")
    }
}

/// A gamepad button, by where it sits on a standard pad (the names gilrs' mapping gives
/// every pad it knows); written by these names in the settings file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum PadButton {
    /// The bottom face button (A on an Xbox pad, Cross on a PlayStation one).
    South,
    East,
    West,
    North,
    LeftBumper,
    RightBumper,
    LeftTrigger,
    RightTrigger,
    /// Pressing the left stick in.
    LeftStick,
    RightStick,
    DPadUp,
    DPadDown,
    DPadLeft,
    DPadRight,
    Select,
    /// The window's own: pause, and back in the menus.
    Start,
}

impl PadButton {
    /// What the settings screen shows, in Xbox terms, the commonest labels.
    pub fn label(self) -> &'static str {
        match self {
            PadButton::South => "A",
            PadButton::East => "B",
            PadButton::West => "X",
            PadButton::North => "Y",
            PadButton::LeftBumper => "LB",
            PadButton::RightBumper => "RB",
            PadButton::LeftTrigger => "LT",
            PadButton::RightTrigger => "RT",
            PadButton::LeftStick => "L3",
            PadButton::RightStick => "R3",
            PadButton::DPadUp => "D-pad up",
            PadButton::DPadDown => "D-pad down",
            PadButton::DPadLeft => "D-pad left",
            PadButton::DPadRight => "D-pad right",
            PadButton::Select => "Select",
            PadButton::Start => "Start",
        }
    }
}

impl Default for PadBindings {
    /// The layout most first-person games share: A jumps, B (or the right stick pressed)
    /// crouches, the left stick pressed (or the left trigger) runs, X uses, and the d-pad
    /// walks as the left stick does.
    fn default() -> Self {
        use PadButton::*;
        PadBindings {
            forward: vec![DPadUp],
            back: vec![DPadDown],
            left: vec![DPadLeft],
            right: vec![DPadRight],
            jump: vec![South],
            crouch: vec![East, RightStick],
            sprint: vec![LeftStick, LeftTrigger],
            interact: vec![West],
            noclip: vec![],
        }
    }
}

impl PadBindings {
    /// Binds `button` to `action` alone (`Bindings::bind_alone`); Start is refused.
    pub fn bind(&mut self, action: Action, button: PadButton) -> bool {
        if button == PadButton::Start {
            return false;
        }
        self.bind_alone(action, button);
        true
    }

    fn problems(&self) -> Vec<(Pointer, String)> {
        let name = |button: PadButton| format!("{button:?}");
        self.reserved_problems("pad", &[PadButton::Start], name, "button (pause)")
    }
}

/// A keyboard key, written by its winit key code name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Key(pub KeyCode);

/// Every key a game action may be bound to.
const BINDABLE: &[KeyCode] = &[
    KeyCode::KeyA,
    KeyCode::KeyB,
    KeyCode::KeyC,
    KeyCode::KeyD,
    KeyCode::KeyE,
    KeyCode::KeyF,
    KeyCode::KeyG,
    KeyCode::KeyH,
    KeyCode::KeyI,
    KeyCode::KeyJ,
    KeyCode::KeyK,
    KeyCode::KeyL,
    KeyCode::KeyM,
    KeyCode::KeyN,
    KeyCode::KeyO,
    KeyCode::KeyP,
    KeyCode::KeyQ,
    KeyCode::KeyR,
    KeyCode::KeyS,
    KeyCode::KeyT,
    KeyCode::KeyU,
    KeyCode::KeyW,
    KeyCode::KeyX,
    KeyCode::KeyY,
    KeyCode::KeyZ,
    KeyCode::Digit0,
    KeyCode::Digit1,
    KeyCode::Digit2,
    KeyCode::Digit3,
    KeyCode::Digit4,
    KeyCode::Digit5,
    KeyCode::Digit6,
    KeyCode::Digit7,
    KeyCode::Digit8,
    KeyCode::Digit9,
    KeyCode::Space,
    KeyCode::Tab,
    KeyCode::CapsLock,
    KeyCode::ShiftLeft,
    KeyCode::ShiftRight,
    KeyCode::ControlLeft,
    KeyCode::ControlRight,
    KeyCode::AltLeft,
    KeyCode::AltRight,
    KeyCode::ArrowUp,
    KeyCode::ArrowDown,
    KeyCode::ArrowLeft,
    KeyCode::ArrowRight,
    KeyCode::Backquote,
    KeyCode::Minus,
    KeyCode::Equal,
    KeyCode::BracketLeft,
    KeyCode::BracketRight,
    KeyCode::Semicolon,
    KeyCode::Quote,
    KeyCode::Comma,
    KeyCode::Period,
    KeyCode::Slash,
    KeyCode::Backslash,
    KeyCode::Enter,
    KeyCode::Backspace,
    KeyCode::Numpad0,
    KeyCode::Numpad1,
    KeyCode::Numpad2,
    KeyCode::Numpad3,
    KeyCode::Numpad4,
    KeyCode::Numpad5,
    KeyCode::Numpad6,
    KeyCode::Numpad7,
    KeyCode::Numpad8,
    KeyCode::Numpad9,
    KeyCode::Escape,
    KeyCode::F3,
    KeyCode::F4,
    KeyCode::F11,
    KeyCode::F12,
    KeyCode::KeyV,
];

impl Key {
    /// The key code's name as winit spells it (`KeyW`).
    pub fn name(self) -> String {
        format!("{:?}", self.0)
    }

    /// What the settings screen shows: `W`, `1`, `Space`, `ShiftLeft`.
    pub fn label(self) -> String {
        let name = self.name();
        name.strip_prefix("Key")
            .or_else(|| name.strip_prefix("Digit"))
            .unwrap_or(&name)
            .to_string()
    }

    /// Whether a game action may take this key.
    pub fn bindable(code: KeyCode) -> bool {
        BINDABLE.contains(&code) && !RESERVED_KEYS.contains(&code)
    }
}

impl Serialize for Key {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(&self.name())
    }
}

impl<'de> Deserialize<'de> for Key {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let name = String::deserialize(deserializer)?;
        BINDABLE
            .iter()
            .copied()
            .find(|code| format!("{code:?}") == name)
            .map(Key)
            .ok_or_else(|| {
                serde::de::Error::custom(format!(
                    "unknown key '{name}' (keys are named as winit's KeyCode: KeyW, Space, ShiftLeft, ArrowUp, Digit1...)"
                ))
            })
    }
}

/// The best finish of each level the player has won, by the level file's name.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct BestTimes(pub BTreeMap<String, Best>);

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Best {
    pub seconds: f64,
    pub shards: u32,
    pub times_seen: u32,
}

impl BestTimes {
    /// The key a level's best time is kept under: its file name.
    pub fn key(level: &Path) -> String {
        level.file_name().map_or_else(
            || level.display().to_string(),
            |name| name.to_string_lossy().into_owned(),
        )
    }

    pub fn get(&self, level: &Path) -> Option<Best> {
        self.0.get(&Self::key(level)).copied()
    }

    /// Keeps `finish` if it is the level's first or a faster one; says whether it was.
    pub fn offer(&mut self, level: &Path, finish: Best) -> bool {
        let best = self.0.entry(Self::key(level)).or_insert(finish);
        if finish.seconds < best.seconds {
            *best = finish;
        }
        *best == finish
    }
}

/// The folder the settings and best times live in: `$GLOAM_CONFIG_DIR`, else `gloam` in the
/// platform's config folder (`$XDG_CONFIG_HOME` or `~/.config`, `%APPDATA%`,
/// `~/Library/Application Support`).
pub fn config_dir() -> Option<PathBuf> {
    if let Some(dir) = std::env::var_os("GLOAM_CONFIG_DIR").filter(|dir| !dir.is_empty()) {
        return Some(PathBuf::from(dir));
    }
    dirs::config_dir().map(|base| base.join("gloam"))
}

/// The folder F12 writes screenshots to: `Gloam` in the user's pictures folder
/// (`XDG_PICTURES_DIR`, `~/Pictures` on Windows and macOS), else `gloam/screenshots` in the
/// data folder (`$XDG_DATA_HOME` or `~/.local/share`) where there is no pictures folder.
pub fn screenshot_dir() -> Option<PathBuf> {
    dirs::picture_dir()
        .map(|pictures| pictures.join("Gloam"))
        .or_else(|| dirs::data_dir().map(|data| data.join("gloam").join("screenshots")))
}

pub const SETTINGS_FILE: &str = "settings.ron";
pub const BEST_TIMES_FILE: &str = "best-times.ron";

/// A user file as read: its contents (the defaults when missing or broken) and, when it
/// was broken, the one line that says so.
pub struct Loaded<T> {
    pub value: T,
    pub warning: Option<String>,
}

/// Reads `path`: missing gives the defaults quietly; unreadable or invalid gives the
/// defaults and a warning naming the place, with the file renamed aside to `<name>.broken`.
pub fn load<T: DeserializeOwned + Default + Checked>(path: &Path) -> Loaded<T> {
    let text = match std::fs::read_to_string(path) {
        Ok(text) => text,
        Err(error) if error.kind() == std::io::ErrorKind::NotFound => {
            return Loaded {
                value: T::default(),
                warning: None,
            };
        }
        Err(error) => {
            return Loaded {
                value: T::default(),
                warning: Some(format!(
                    "{}: cannot read ({error}); using the defaults",
                    path.display()
                )),
            };
        }
    };
    match parse::<T>(path, &text) {
        Ok(value) => Loaded {
            value,
            warning: None,
        },
        Err(diagnostic) => {
            let aside = path.with_file_name(format!(
                "{}.broken",
                path.file_name()
                    .map_or_else(String::new, |name| name.to_string_lossy().into_owned())
            ));
            let kept = match std::fs::rename(path, &aside) {
                Ok(()) => format!("kept aside as {}", aside.display()),
                Err(error) => format!("could not move it aside ({error})"),
            };
            Loaded {
                value: T::default(),
                warning: Some(format!("{diagnostic}; {kept}; using the defaults")),
            }
        }
    }
}

/// A file's own checks beyond its schema (ranges, reserved keys).
pub trait Checked {
    fn problems(&self) -> Vec<(Pointer, String)>;
}

impl Checked for Settings {
    fn problems(&self) -> Vec<(Pointer, String)> {
        let mut problems = Settings::problems(self);
        problems.extend(self.keys.problems());
        problems.extend(self.pad.problems());
        problems
    }
}

impl Checked for BestTimes {
    fn problems(&self) -> Vec<(Pointer, String)> {
        self.0
            .iter()
            .filter(|(_, best)| !(best.seconds.is_finite() && best.seconds >= 0.0))
            .map(|(level, best)| {
                (
                    Pointer::root().key(level),
                    format!("{level}: time {} is not a time", best.seconds),
                )
            })
            .collect()
    }
}

/// Parses `text` as a `T`, reporting the first problem at its place in the file.
pub fn parse<T: DeserializeOwned + Checked>(path: &Path, text: &str) -> Result<T, Diagnostic> {
    let value: T = ron::from_str(text).map_err(|error| Diagnostic {
        file: path.to_owned(),
        line: error.span.start.line.max(1),
        column: error.span.start.col.max(1),
        message: error.code.to_string(),
    })?;
    match value.problems().into_iter().next() {
        None => Ok(value),
        Some((pointer, message)) => Err(Diagnostic::at_pointer(path, text, &pointer, message)),
    }
}

/// Writes `value` to `path` atomically, as pretty RON.
pub fn save<T: Serialize>(path: &Path, value: &T) -> anyhow::Result<()> {
    let config = ron::ser::PrettyConfig::new()
        .indentor("    ".to_owned())
        .new_line("\n".to_owned());
    let text = ron::ser::to_string_pretty(value, config)
        .map_err(|error| anyhow::anyhow!("{}: cannot write ({error})", path.display()))?;
    write_atomically(path, (text + "\n").as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("gloam-settings-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("scratch folder");
        dir
    }

    #[test]
    fn settings_round_trip_through_the_file() {
        let dir = scratch("round-trip");
        let path = dir.join(SETTINGS_FILE);
        let mut settings = Settings {
            mouse_sensitivity: 1.7,
            invert_y: true,
            field_of_view: 85.0,
            brightness: 1.5,
            frame_time_target_ms: None,
            fullscreen: true,
            vsync: false,
            ui_scale: 1.3,
            ..Settings::default()
        };
        assert!(settings.keys.bind(Action::Sprint, KeyCode::AltLeft));
        assert!(settings.pad.bind(Action::Interact, PadButton::RightBumper));
        save(&path, &settings).expect("save");
        let loaded = load::<Settings>(&path);
        assert_eq!(loaded.warning, None);
        assert_eq!(loaded.value, settings);
        // A file from before fullscreen and vsync were kept loads with their defaults.
        std::fs::write(&path, "(field_of_view: 90.0)").unwrap();
        let older = load::<Settings>(&path);
        assert_eq!(older.warning, None);
        assert_eq!((older.value.fullscreen, older.value.vsync), (false, true));
        assert_eq!(older.value.pad, PadBindings::default());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_missing_file_is_the_defaults_without_a_word() {
        let dir = scratch("missing");
        let loaded = load::<Settings>(&dir.join(SETTINGS_FILE));
        assert_eq!(loaded.value, Settings::default());
        assert_eq!(loaded.warning, None);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_broken_file_is_named_at_its_place_kept_aside_and_the_defaults_used() {
        let dir = scratch("broken");
        let path = dir.join(SETTINGS_FILE);
        let text = "(\n    mouse_sensitivity: 1.0,\n    field_of_veiw: 90.0,\n)\n";
        std::fs::write(&path, text).expect("write");
        let loaded = load::<Settings>(&path);
        assert_eq!(loaded.value, Settings::default());
        let warning = loaded.warning.expect("a warning");
        assert!(
            warning.starts_with(&format!("{}:3:", path.display())),
            "{warning}"
        );
        assert!(warning.contains("field_of_veiw"), "{warning}");
        assert!(!warning.contains('\n'), "one line: {warning}");
        assert!(!path.exists(), "the broken file is moved aside");
        let aside = dir.join("settings.ron.broken");
        assert_eq!(std::fs::read_to_string(aside).expect("kept"), text);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn values_out_of_range_and_unknown_or_reserved_keys_are_broken_files() {
        let dir = Path::new("settings.ron");
        for (text, expect) in [
            (
                "(field_of_view: 300.0)",
                "field_of_view 300 is outside 50..=110",
            ),
            ("(brightness: -1.0)", "brightness -1 is outside"),
            ("(ui_scale: 0.1)", "ui_scale 0.1 is outside 0.5..=2"),
            ("(keys: (forward: [\"KeyWW\"]))", "unknown key 'KeyWW'"),
            (
                "(keys: (jump: [\"Escape\"]))",
                "Escape is the window's own key",
            ),
            ("(frame_time_target_ms: Some(0.0))", "outside 1..=1000"),
            ("(pad: (jump: [Start]))", "Start is the window's own button"),
            ("(pad: (jump: [Triangle]))", "Triangle"),
        ] {
            let error = parse::<Settings>(dir, text).expect_err(text).to_string();
            assert!(error.contains(expect), "{text}: {error}");
            assert!(error.starts_with("settings.ron:1:"), "{text}: {error}");
        }
    }

    #[test]
    fn binding_a_key_moves_it_from_the_action_that_had_it() {
        let mut keys = KeyBindings::default();
        assert!(keys.bind(Action::Interact, KeyCode::KeyW));
        assert_eq!(keys.action(Key(KeyCode::KeyW)), Some(Action::Interact));
        assert!(keys.forward.is_empty());
        assert_eq!(keys.action(Key(KeyCode::KeyE)), None);
        assert!(!keys.bind(Action::MoveUp, KeyCode::Escape));
        assert_eq!(keys.action(Key(KeyCode::Space)), Some(Action::MoveUp));
    }

    #[test]
    fn binding_a_pad_button_moves_it_and_start_stays_the_window_s() {
        let mut pad = PadBindings::default();
        assert!(pad.bind(Action::Sprint, PadButton::East));
        assert_eq!(pad.sprint, [PadButton::East]);
        assert_eq!(pad.crouch, [PadButton::RightStick], "B left crouch");
        assert!(!pad.bind(Action::MoveUp, PadButton::Start));
        assert_eq!(pad.jump, [PadButton::South]);
        // Every action but noclip has a button out of the box, and no two share one.
        let mut seen = std::collections::HashSet::new();
        for (action, name) in ACTION_NAMES {
            let buttons = PadBindings::default().of(action).clone();
            assert!(buttons.is_empty() == (action == Action::Noclip), "{name}");
            assert!(buttons.iter().all(|&b| seen.insert(b)), "{name}");
        }
    }

    #[test]
    fn best_times_keep_the_fastest_finish() {
        let mut best = BestTimes::default();
        let level = Path::new("levels/first-light.ron");
        let finish = |seconds| Best {
            seconds,
            shards: 3,
            times_seen: 0,
        };
        assert!(best.offer(level, finish(70.0)));
        assert!(best.offer(level, finish(61.5)));
        assert!(!best.offer(level, finish(65.0)));
        assert_eq!(best.get(level).map(|b| b.seconds), Some(61.5));
        let dir = scratch("best");
        let path = dir.join(BEST_TIMES_FILE);
        save(&path, &best).expect("save");
        assert_eq!(load::<BestTimes>(&path).value, best);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
