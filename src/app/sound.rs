//! Present, beside the frame: the game's sound out. Opens the audio device the first time
//! a level starts (`audio::Device`; where there is none, one warning and silence), gives
//! each level's engine the player's ears (`audio::Hearing`), and after each frame sends
//! the commands its steps made. A menu over the level pauses the sound with the level;
//! the settings' volumes go to the mixer as they change.

use std::path::Path;

use crate::audio::{Command, Device, Hearing, Volumes};
use crate::frame::Engine;

#[derive(Default)]
pub struct GameSound {
    device: Option<Device>,
    /// The device was asked for (it is asked once).
    tried: bool,
    paused: bool,
}

impl GameSound {
    /// A level starts in `engine` (loaded from `level`): the device opened if it is not
    /// yet, the last level's voices stopped, and the engine given ears. Returns the
    /// warning to show when the device would not open.
    pub fn start(&mut self, engine: &mut Engine, level: &Path, volumes: Volumes) -> Option<String> {
        let mut warning = None;
        if !self.tried {
            self.tried = true;
            match Device::open() {
                Ok(device) => self.device = Some(device),
                Err(line) => warning = Some(line),
            }
        }
        if let Some(device) = &self.device {
            device.send(vec![
                Command::Clear,
                Command::Volumes(volumes),
                Command::Pause(false),
            ]);
            self.paused = false;
            engine.hearing = Some(Hearing::for_level(level));
        }
        warning
    }

    /// After a frame: its steps' commands sent, and the sound paused or resumed with the
    /// level (`paused`: a menu holds it, or no level is playing).
    pub fn frame(&mut self, engine: Option<&mut Engine>, paused: bool) {
        let Some(device) = &self.device else { return };
        let hearing = engine.and_then(|engine| engine.hearing.as_mut());
        let mut commands = Vec::new();
        if let Some(hearing) = hearing {
            // A sound file that would not read or decode, said once as it is first asked
            // for.
            for warning in hearing.warnings.drain(..) {
                eprintln!("gloam: warning: {warning}");
            }
            commands = hearing.take();
        }
        if paused != self.paused {
            self.paused = paused;
            commands.push(Command::Pause(paused));
        }
        device.send(commands);
    }

    /// The level is left (for the main menu): its voices stop.
    pub fn stop(&mut self) {
        if let Some(device) = &self.device {
            device.send(vec![Command::Clear]);
        }
    }

    pub fn set_volumes(&self, volumes: Volumes) {
        if let Some(device) = &self.device {
            device.send(vec![Command::Volumes(volumes)]);
        }
    }
}
