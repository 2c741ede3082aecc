//! Window input, read once a frame before the fixed steps run: gamepads, through gilrs.
//!
//! Per frame (`Gamepad::poll`, from `App::redraw`):
//! 1. gilrs' events since the last frame update one `PadState` for every pad together
//!    (buttons down, both sticks), and the buttons pressed are returned in order, for the
//!    menus and for binding a button;
//! 2. in a menu, `menu_input` turns each button pressed into a menu input;
//! 3. in play, `held_actions` turns the state into the game's actions (the buttons the
//!    settings bind, `settings::PadBindings`, and the left stick past its dead zone as the
//!    four moves), and `look_rate` turns the right stick into a turn rate.
//!
//! The game never sees gilrs: the shell merges these actions into `game::Input` beside the
//! keyboard's. A machine where gilrs cannot start (no udev, no permission to read the
//! devices) plays with the keyboard and says so once; no pad is no message at all.

use std::collections::HashSet;

use glam::Vec2;

use super::menu::MenuInput;
use super::settings::{PadBindings, PadButton};
use crate::game::{Action, Input};

/// How far a stick must lean (of 1) before it counts: worn sticks rest up to about a fifth
/// off centre.
pub const STICK_DEAD_ZONE: f32 = 0.25;
/// The fastest turn the right stick gives, radians per second (at sensitivity 1), held
/// all the way over: about half a turn a second.
pub const LOOK_SPEED: f32 = 3.0;

/// Every pad's buttons and sticks, as one controller.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PadState {
    pub buttons: HashSet<PadButton>,
    /// The left stick, x right and y up, each in -1..=1.
    pub left: Vec2,
    /// The right stick, x right and y up.
    pub right: Vec2,
}

/// `stick` with the dead zone taken out: zero inside it, then rising from zero at its edge
/// to full at full lean, in the same direction.
pub fn past_dead_zone(stick: Vec2) -> Vec2 {
    let lean = stick.length().min(1.0);
    if lean <= STICK_DEAD_ZONE {
        return Vec2::ZERO;
    }
    stick.normalize() * ((lean - STICK_DEAD_ZONE) / (1.0 - STICK_DEAD_ZONE))
}

/// The game's actions `state` holds under `bindings`: bound buttons down, and the left
/// stick leaning past its dead zone mostly towards a direction (both moves on a diagonal).
pub fn held_actions(state: &PadState, bindings: &PadBindings) -> HashSet<Action> {
    let mut held: HashSet<Action> = Action::ALL
        .into_iter()
        .filter(|&action| (bindings.of(action).iter()).any(|button| state.buttons.contains(button)))
        .collect();
    let stick = past_dead_zone(state.left);
    if stick != Vec2::ZERO {
        // A direction counts within 67.5 degrees of its axis: each of the eight
        // directions gets a 45-degree sector.
        let direction = stick.normalize();
        let sector = (67.5_f32).to_radians().cos();
        for (axis, action) in [
            (Vec2::Y, Action::MoveForward),
            (Vec2::NEG_Y, Action::MoveBack),
            (Vec2::X, Action::MoveRight),
            (Vec2::NEG_X, Action::MoveLeft),
        ] {
            if direction.dot(axis) > sector {
                held.insert(action);
            }
        }
    }
    held
}

/// Brings the game's `input` from the actions the pads held at the last frame, `before`,
/// to those they hold `now`: each newly held one is held and pressed once; each let go is
/// released, unless a key (`keys_down`) still holds it.
pub fn hand_over(
    input: &mut Input,
    before: &HashSet<Action>,
    now: &HashSet<Action>,
    keys_down: &HashSet<Action>,
) {
    for &action in now.difference(before) {
        input.held.insert(action);
        input.pressed.insert(action);
    }
    for action in before.difference(now) {
        if !keys_down.contains(action) {
            input.held.remove(action);
        }
    }
}

/// The turn the right stick asks for, radians per second as (yaw right, pitch up), before
/// the player's sensitivity: the lean past the dead zone, squared for fine aim near the
/// centre, times `LOOK_SPEED`.
pub fn look_rate(right: Vec2) -> Vec2 {
    let stick = past_dead_zone(right);
    stick * stick.length() * LOOK_SPEED
}

/// What a pad button does in the menus: the d-pad moves and changes, A chooses, B and
/// Start go back; while a page waits for a button to bind, every button goes to it.
pub fn menu_input(button: PadButton, waiting_for_button: bool) -> Option<MenuInput> {
    if waiting_for_button {
        return Some(MenuInput::Pad(button));
    }
    Some(match button {
        PadButton::DPadUp => MenuInput::Up,
        PadButton::DPadDown => MenuInput::Down,
        PadButton::DPadLeft => MenuInput::Left,
        PadButton::DPadRight => MenuInput::Right,
        PadButton::South => MenuInput::Activate,
        PadButton::East | PadButton::Start => MenuInput::Back,
        _ => return None,
    })
}

/// gilrs' name for a button, as the settings write it; None for buttons the game does not
/// use (Mode, C, Z and unknown ones).
fn pad_button(button: gilrs::Button) -> Option<PadButton> {
    use gilrs::Button as B;
    Some(match button {
        B::South => PadButton::South,
        B::East => PadButton::East,
        B::West => PadButton::West,
        B::North => PadButton::North,
        B::LeftTrigger => PadButton::LeftBumper,
        B::RightTrigger => PadButton::RightBumper,
        B::LeftTrigger2 => PadButton::LeftTrigger,
        B::RightTrigger2 => PadButton::RightTrigger,
        B::LeftThumb => PadButton::LeftStick,
        B::RightThumb => PadButton::RightStick,
        B::DPadUp => PadButton::DPadUp,
        B::DPadDown => PadButton::DPadDown,
        B::DPadLeft => PadButton::DPadLeft,
        B::DPadRight => PadButton::DPadRight,
        B::Select => PadButton::Select,
        B::Start => PadButton::Start,
        _ => return None,
    })
}

/// The pads, and what the game holds because of them.
pub struct Gamepad {
    /// None where gilrs could not start.
    gilrs: Option<gilrs::Gilrs>,
    pub state: PadState,
    /// The actions the pads held at the last frame, so a release lets go of only those.
    pub held: HashSet<Action>,
}

impl Gamepad {
    /// Starts gilrs; where it cannot, the pads are off and the warning says why.
    pub fn open() -> (Gamepad, Option<String>) {
        let (gilrs, warning) = match gilrs::Gilrs::new() {
            Ok(gilrs) => (Some(gilrs), None),
            Err(gilrs::Error::NotImplemented(_)) => (
                None,
                Some("no gamepad support on this platform; playing with the keyboard".into()),
            ),
            Err(error) => (
                None,
                Some(format!(
                    "gamepads are off ({error}); playing with the keyboard"
                )),
            ),
        };
        let pad = Gamepad {
            gilrs,
            state: PadState::default(),
            held: HashSet::new(),
        };
        (pad, warning)
    }

    /// Takes gilrs' events since the last call into `state`; returns the buttons pressed,
    /// in order.
    pub fn poll(&mut self) -> Vec<PadButton> {
        let Some(gilrs) = &mut self.gilrs else {
            return Vec::new();
        };
        let mut pressed = Vec::new();
        while let Some(gilrs::Event { event, .. }) = gilrs.next_event() {
            match event {
                gilrs::EventType::ButtonPressed(button, _) => {
                    if let Some(button) = pad_button(button)
                        && self.state.buttons.insert(button)
                    {
                        pressed.push(button);
                    }
                }
                gilrs::EventType::ButtonReleased(button, _) => {
                    if let Some(button) = pad_button(button) {
                        self.state.buttons.remove(&button);
                    }
                }
                gilrs::EventType::AxisChanged(axis, value, _) => {
                    let value = if value.is_finite() {
                        value.clamp(-1.0, 1.0)
                    } else {
                        0.0
                    };
                    match axis {
                        gilrs::Axis::LeftStickX => self.state.left.x = value,
                        gilrs::Axis::LeftStickY => self.state.left.y = value,
                        gilrs::Axis::RightStickX => self.state.right.x = value,
                        gilrs::Axis::RightStickY => self.state.right.y = value,
                        _ => {}
                    }
                }
                // A pad unplugged lets go of everything it held.
                gilrs::EventType::Disconnected => self.state = PadState::default(),
                _ => {}
            }
        }
        pressed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state(buttons: &[PadButton], left: Vec2) -> PadState {
        PadState {
            buttons: buttons.iter().copied().collect(),
            left,
            right: Vec2::ZERO,
        }
    }

    #[test]
    fn bound_buttons_and_the_left_stick_hold_the_game_s_actions() {
        let bindings = PadBindings::default();
        let held = |s: &PadState| {
            let mut actions: Vec<Action> = held_actions(s, &bindings).into_iter().collect();
            actions.sort_by_key(|a| a.bit());
            actions
        };
        assert!(held(&state(&[], Vec2::ZERO)).is_empty());
        // A stick resting a little off centre holds nothing.
        assert!(held(&state(&[], Vec2::new(0.15, -0.2))).is_empty());
        assert_eq!(
            held(&state(&[], Vec2::new(0.0, 0.9))),
            [Action::MoveForward]
        );
        assert_eq!(held(&state(&[], Vec2::new(-0.8, 0.1))), [Action::MoveLeft]);
        // A diagonal holds both moves.
        assert_eq!(
            held(&state(&[], Vec2::new(0.6, -0.6))),
            [Action::MoveBack, Action::MoveRight]
        );
        assert_eq!(
            held(&state(&[PadButton::South, PadButton::West], Vec2::ZERO)),
            [Action::MoveUp, Action::Interact]
        );
        // Start is the window's (pause), never an action.
        assert!(held(&state(&[PadButton::Start], Vec2::ZERO)).is_empty());
    }

    #[test]
    fn the_pad_and_the_keyboard_hold_an_action_together() {
        let set = |actions: &[Action]| actions.iter().copied().collect::<HashSet<_>>();
        let mut input = Input::default();
        let keys = set(&[Action::MoveForward]);
        input.held = keys.clone();
        // The stick pushes forward too, and crouch goes down: crouch is pressed once.
        let now = set(&[Action::MoveForward, Action::MoveDown]);
        hand_over(&mut input, &set(&[]), &now, &keys);
        assert_eq!(input.held, now);
        assert_eq!(input.pressed, set(&[Action::MoveForward, Action::MoveDown]));
        // The pad lets go of both: W is still down, so forward stays held.
        input.pressed.clear();
        hand_over(&mut input, &now, &set(&[]), &keys);
        assert_eq!(input.held, keys);
        assert!(input.pressed.is_empty());
    }

    #[test]
    fn pad_buttons_steer_the_menus_and_go_to_a_page_waiting_for_one() {
        assert_eq!(
            menu_input(PadButton::DPadDown, false),
            Some(MenuInput::Down)
        );
        assert_eq!(
            menu_input(PadButton::South, false),
            Some(MenuInput::Activate)
        );
        assert_eq!(menu_input(PadButton::Start, false), Some(MenuInput::Back));
        assert_eq!(menu_input(PadButton::RightBumper, false), None);
        assert_eq!(
            menu_input(PadButton::South, true),
            Some(MenuInput::Pad(PadButton::South))
        );
    }

    #[test]
    fn the_right_stick_turns_smoothly_from_its_dead_zone_to_full_speed() {
        assert_eq!(look_rate(Vec2::new(0.2, 0.1)), Vec2::ZERO);
        let full = look_rate(Vec2::new(1.0, 0.0));
        assert!(
            (full.x - LOOK_SPEED).abs() < 1e-5 && full.y == 0.0,
            "{full}"
        );
        // Past the dead zone the rate starts from nothing and grows with the square.
        let just_past = look_rate(Vec2::new(STICK_DEAD_ZONE + 0.01, 0.0)).x;
        assert!(just_past > 0.0 && just_past < 0.01, "{just_past}");
        let half = look_rate(Vec2::new(
            0.0,
            STICK_DEAD_ZONE + 0.5 * (1.0 - STICK_DEAD_ZONE),
        ));
        assert!((half.y - 0.25 * LOOK_SPEED).abs() < 1e-4, "{half}");
        // A stick reporting more than full (some pads do on the diagonal) is held to full.
        assert!((look_rate(Vec2::new(1.0, 1.0)).length() - LOOK_SPEED).abs() < 1e-4);
    }
}
