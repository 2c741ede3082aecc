//! Window step `present`, on the HUD: what a first-time player is told in the campaign's
//! first level. As the level starts, its goal ("Take the 3 shards, then find the way
//! out."); the first time the player stands lit, the crouch key; and every prompt names
//! the key bound to its action, not the default one (`Controls::label`), or the gamepad
//! button while the player plays with a pad. Hints only inform: nothing the game does
//! depends on them.

use super::settings::{KeyBindings, PadBindings};
use crate::game::Action;

/// The device the player last used, whose controls the prompts name.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Device {
    #[default]
    Keyboard,
    Gamepad,
}

/// The player's bindings, and the device the prompts speak of.
#[derive(Clone, Copy, Debug)]
pub struct Controls<'a> {
    pub keys: &'a KeyBindings,
    pub pad: &'a PadBindings,
    pub device: Device,
}

impl Controls<'_> {
    /// What to press for `action` on the device in use: its first key (`key_label`) or
    /// its first gamepad button, or "(unbound)".
    pub fn label(&self, action: Action) -> String {
        match self.device {
            Device::Keyboard => key_label(self.keys, action),
            Device::Gamepad => self.pad.of(action).first().map_or_else(
                || "(unbound)".to_owned(),
                |button| button.label().to_owned(),
            ),
        }
    }
}

/// Seconds of each attempt the goal is shown for.
const GOAL_SECONDS: f32 = 8.0;
/// Seconds a verb's hint stays up.
const HINT_SECONDS: f32 = 5.0;
/// The light gem's reading (0 dark .. 1 lit) above which standing tall is a risk: the
/// crouch hint's cue. At 0.5 the body reads as half seen (`game::exposure::curve`).
const LIT_GEM: f32 = 0.5;

/// One level's hints, shown once each while it is played.
#[derive(Clone, Debug, Default)]
pub struct Hints {
    /// Level seconds when the crouch hint came up.
    crouch_shown_at: Option<f32>,
}

pub use crate::game::status::Moment;

impl Hints {
    /// The hint line to show now, if any.
    pub fn line(&mut self, moment: Moment, controls: &Controls) -> Option<String> {
        if self.crouch_shown_at.is_none()
            && moment.seconds >= GOAL_SECONDS
            && moment.gem > LIT_GEM
            && !moment.crouched
        {
            self.crouch_shown_at = Some(moment.seconds);
        }
        if moment.seconds < GOAL_SECONDS {
            return Some(match moment.shards {
                0 => "Find the way out.".to_owned(),
                1 => "Take the shard, then find the way out.".to_owned(),
                n => format!("Take the {n} shards, then find the way out."),
            });
        }
        let shown = self.crouch_shown_at?;
        (moment.seconds - shown < HINT_SECONDS).then(|| {
            format!(
                "{}  crouch: lit, lower is harder to see",
                controls.label(Action::MoveDown)
            )
        })
    }
}

/// The first key bound to `action` as the settings screen shows it, or "(unbound)".
pub fn key_label(keys: &KeyBindings, action: Action) -> String {
    keys.of(action)
        .first()
        .map_or_else(|| "(unbound)".to_owned(), |key| key.label())
}

#[cfg(test)]
mod tests {
    use super::*;
    use winit::keyboard::KeyCode;

    fn moment(seconds: f32, gem: f32, crouched: bool) -> Moment {
        Moment {
            seconds,
            gem,
            crouched,
            shards: 3,
        }
    }

    fn keyboard(keys: &KeyBindings) -> Controls<'_> {
        Controls {
            keys,
            pad: &PAD,
            device: Device::Keyboard,
        }
    }

    static PAD: std::sync::LazyLock<PadBindings> = std::sync::LazyLock::new(PadBindings::default);

    #[test]
    fn the_goal_comes_first_then_the_crouch_key_once_when_lit() {
        let keys = KeyBindings::default();
        let keys = keyboard(&keys);
        let mut hints = Hints::default();
        assert_eq!(
            hints.line(moment(0.5, 0.9, false), &keys).as_deref(),
            Some("Take the 3 shards, then find the way out.")
        );
        // In the dark, or crouched in the light, nothing.
        assert_eq!(hints.line(moment(9.0, 0.1, false), &keys), None);
        assert_eq!(hints.line(moment(10.0, 0.9, true), &keys), None);
        // Standing lit: the crouch key, for a while, and never again.
        let line = hints.line(moment(11.0, 0.9, false), &keys).unwrap();
        assert!(line.starts_with("C  crouch"), "{line}");
        assert!(hints.line(moment(15.0, 0.1, false), &keys).is_some());
        assert_eq!(hints.line(moment(16.5, 0.9, false), &keys), None);
        assert_eq!(hints.line(moment(40.0, 0.9, false), &keys), None);
    }

    #[test]
    fn prompts_name_the_key_the_player_bound() {
        let mut keys = KeyBindings::default();
        assert_eq!(key_label(&keys, Action::Interact), "E");
        assert!(keys.bind(Action::Interact, KeyCode::KeyF));
        assert_eq!(key_label(&keys, Action::Interact), "F");
        assert!(keys.bind(Action::MoveDown, KeyCode::ControlLeft));
        let mut hints = Hints::default();
        let line = hints
            .line(moment(12.0, 0.9, false), &keyboard(&keys))
            .unwrap();
        assert!(line.starts_with("ControlLeft  crouch"), "{line}");
    }

    #[test]
    fn with_a_gamepad_in_hand_prompts_name_its_buttons() {
        fn gamepad<'a>(keys: &'a KeyBindings, pad: &'a PadBindings) -> Controls<'a> {
            Controls {
                keys,
                pad,
                device: Device::Gamepad,
            }
        }
        let keys = KeyBindings::default();
        let mut pad = PadBindings::default();
        assert_eq!(gamepad(&keys, &pad).label(Action::Interact), "X");
        assert_eq!(gamepad(&keys, &pad).label(Action::MoveDown), "B");
        assert_eq!(gamepad(&keys, &pad).label(Action::Noclip), "(unbound)");
        let bumper = crate::app::settings::PadButton::LeftBumper;
        assert!(pad.bind(Action::MoveDown, bumper));
        let mut hints = Hints::default();
        let line = hints
            .line(moment(12.0, 0.9, false), &gamepad(&keys, &pad))
            .unwrap();
        assert!(line.starts_with("LB  crouch"), "{line}");
    }
}
