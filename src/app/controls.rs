//! Frame step `simulate`'s input, as the window receives it: the player's keys, mouse and
//! gamepad become the game's `Input` resource, or, while a menu is open, `MenuInput`s; the
//! window's own keys (`WINDOW_KEYS`) pause, toggle fullscreen, vsync, the profiler and the
//! filters, open the editor and take screenshots.

use winit::event::ElementState;
use winit::event_loop::ActiveEventLoop;
use winit::keyboard::KeyCode;
use winit::window::{CursorGrabMode, Fullscreen};

use super::*;

/// What a key does beyond the game's actions (those are the player's, in `settings`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Binding {
    Pause,
    Fullscreen,
    Profiler,
    Filter,
    Vsync,
    Screenshot,
    /// Edit the level being played, as its file has it (in a play-test: back to the
    /// editor).
    Edit,
}

/// The window's own keys (`settings::RESERVED_KEYS`, which no game action may take).
pub(super) const WINDOW_KEYS: [(KeyCode, Binding); 7] = [
    (KeyCode::F2, Binding::Edit),
    (KeyCode::Escape, Binding::Pause),
    (KeyCode::F11, Binding::Fullscreen),
    (KeyCode::F3, Binding::Profiler),
    (KeyCode::F4, Binding::Filter),
    (KeyCode::F12, Binding::Screenshot),
    (KeyCode::KeyV, Binding::Vsync),
];

/// Radians of view turn per pixel of mouse motion, at sensitivity 1.
pub(super) const MOUSE_SENSITIVITY: f32 = 0.0025;

impl App {
    pub(super) fn set_capture(&mut self, capture: bool) {
        let Some(window) = &self.window else { return };
        if capture {
            let grabbed = window
                .set_cursor_grab(CursorGrabMode::Locked)
                .or_else(|_| window.set_cursor_grab(CursorGrabMode::Confined));
            self.captured = grabbed.is_ok();
        } else {
            let _ = window.set_cursor_grab(CursorGrabMode::None);
            self.captured = false;
        }
        window.set_cursor_visible(!self.captured);
    }

    pub(super) fn menu_input(&mut self, event_loop: &ActiveEventLoop, input: MenuInput) {
        let Some(menu) = &mut self.menu else { return };
        if let Some(command) = menu.input(input, &mut self.context) {
            self.command(event_loop, command);
        }
    }

    pub(super) fn key(&mut self, event_loop: &ActiveEventLoop, code: KeyCode, state: ElementState) {
        let pressed = state == ElementState::Pressed;
        if pressed {
            self.device = hints::Device::Keyboard;
        }
        if self.menu.is_some() {
            if !pressed {
                return;
            }
            let input = match code {
                _ if self.menu.as_ref().is_some_and(Menu::waiting_for_key) => MenuInput::Key(code),
                KeyCode::ArrowUp => MenuInput::Up,
                KeyCode::ArrowDown => MenuInput::Down,
                KeyCode::ArrowLeft => MenuInput::Left,
                KeyCode::ArrowRight => MenuInput::Right,
                KeyCode::Enter | KeyCode::NumpadEnter | KeyCode::Space => MenuInput::Activate,
                KeyCode::Escape => MenuInput::Back,
                _ => match WINDOW_KEYS.iter().find(|(key, _)| *key == code) {
                    Some(&(_, binding)) => return self.window_key(binding),
                    None => return,
                },
            };
            return self.menu_input(event_loop, input);
        }
        if let Some(action) = self.context.settings.keys.action(settings::Key(code)) {
            // A recording being watched plays its own input.
            if self.options.watch.is_some() {
                return;
            }
            if pressed {
                self.keys_held.insert(action);
            } else {
                self.keys_held.remove(&action);
            }
            let Some(game) = &mut self.game else { return };
            let mut input = game.engine.world.resource_mut::<Input>();
            if pressed {
                input.held.insert(action);
                input.pressed.insert(action);
            } else if !self.gamepad.held.contains(&action) {
                // A pad still holding it keeps it held.
                input.held.remove(&action);
            }
            return;
        }
        let Some(&(_, binding)) = WINDOW_KEYS.iter().find(|(key, _)| *key == code) else {
            return;
        };
        if !pressed {
            return;
        }
        if binding == Binding::Edit || (binding == Binding::Pause && self.play_test) {
            let switch = match (self.play_test, &self.game) {
                (true, _) => shell::Switch::BackToEditor("play-test left".to_owned()),
                (false, Some(game)) => shell::Switch::Edit(game.level.clone()),
                (false, None) => return,
            };
            return self.switch_to(event_loop, switch);
        }
        if binding == Binding::Pause {
            return self.pause();
        }
        self.window_key(binding);
    }

    /// The gamepads since the last frame: in a menu their buttons steer it (the d-pad
    /// moves and changes, A chooses, B and Start go back; a button to bind goes to the
    /// gamepad page); in play the actions they hold join the keyboard's, Start pauses, and
    /// the right stick turns the view for the frame's `seconds`.
    pub(super) fn read_gamepad(&mut self, event_loop: &ActiveEventLoop, seconds: f32) {
        let pressed = self.gamepad.poll();
        let state = &self.gamepad.state;
        if !pressed.is_empty()
            || gamepad::past_dead_zone(state.left) != Vec2::ZERO
            || gamepad::past_dead_zone(state.right) != Vec2::ZERO
        {
            self.device = hints::Device::Gamepad;
        }
        if self.menu.is_some() {
            // Whatever the pads held was let go when the menu opened (`pause`).
            self.gamepad.held.clear();
            for button in pressed {
                let Some(menu) = &self.menu else { break };
                let Some(input) = gamepad::menu_input(button, menu.waiting_for_key()) else {
                    continue;
                };
                self.menu_input(event_loop, input);
            }
            return;
        }
        // A recording being watched plays its own input.
        if self.options.watch.is_some() {
            return;
        }
        if pressed.contains(&PadButton::Start) && self.attempt_running() {
            return self.pause();
        }
        let Some(game) = &mut self.game else { return };
        let now = gamepad::held_actions(&self.gamepad.state, &self.context.settings.pad);
        let mut input = game.engine.world.resource_mut::<Input>();
        gamepad::hand_over(&mut input, &self.gamepad.held, &now, &self.keys_held);
        let pitch = if self.context.settings.invert_y {
            -1.0
        } else {
            1.0
        };
        input.look +=
            gamepad::look_rate(self.gamepad.state.right) * seconds * Vec2::new(1.0, pitch);
        self.gamepad.held = now;
    }

    /// F11, F3, F4, F12 and V, in play and in menus alike.
    pub(super) fn window_key(&mut self, binding: Binding) {
        match binding {
            Binding::Fullscreen => {
                if let Some(window) = &self.window {
                    let fullscreen = window.fullscreen().is_none();
                    window.set_fullscreen(fullscreen.then_some(Fullscreen::Borderless(None)));
                    self.context.settings.fullscreen = fullscreen;
                    self.settings_changed();
                }
            }
            Binding::Profiler => self.overlay = !self.overlay,
            Binding::Filter => {
                if let Some(engine) = self.engine_mut() {
                    let accumulation = &mut engine.film;
                    accumulation.filter.mode = accumulation.filter.mode.next();
                    accumulation.filter.reset();
                    accumulation.reset = true;
                }
            }
            Binding::Vsync => {
                self.vsync = !self.vsync;
                if let Some(pixels) = &mut self.pixels {
                    pixels.enable_vsync(self.vsync);
                }
                self.context.settings.vsync = self.vsync;
                self.settings_changed();
            }
            Binding::Screenshot => self.screenshot = true,
            Binding::Pause | Binding::Edit => {}
        }
    }
}
