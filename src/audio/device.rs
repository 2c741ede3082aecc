//! The audio device: the mixer (`audio::mixer`) played live through kira (which plays it
//! through cpal), on the device's own thread. The game sends each frame's commands down
//! a channel and never waits; the device's thread takes whatever has arrived before each
//! block and never waits either, so neither the frame nor the sound holds up the other.
//!
//! Where there is no device (a server, a container, Xvfb) the game plays silently: opening
//! fails with one line the caller prints as a warning, and alsa-lib's own complaints on
//! the way are kept off the terminal.

use std::sync::mpsc::{Receiver, Sender, channel};

use kira::sound::{Sound, SoundData};
use kira::{AudioManager, AudioManagerSettings, DefaultBackend, Frame, info::Info};

use super::mixer::{Command, Mixer};
use crate::scene::sound_kit::RATE;

/// Samples the mixer renders at a time on the device's thread.
const BLOCK: usize = 256;

/// The open device, and the way to it.
pub struct Device {
    /// Holds the stream open.
    _manager: AudioManager<DefaultBackend>,
    commands: Sender<Vec<Command>>,
}

impl Device {
    /// Opens the default output device, playing a new mixer.
    pub fn open() -> Result<Device, String> {
        quiet_alsa();
        let mut manager = AudioManager::<DefaultBackend>::new(AudioManagerSettings::default())
            .map_err(|error| format!("no audio device ({error}); playing silently"))?;
        let (commands, receiver) = channel();
        manager.play(Live::new(receiver)).map_err(|error| {
            format!("the audio device would not play ({error}); playing silently")
        })?;
        Ok(Device {
            _manager: manager,
            commands,
        })
    }

    /// Sends `commands` to the mixer (it applies them before its next block).
    pub fn send(&self, commands: Vec<Command>) {
        if !commands.is_empty() {
            // A device gone away takes its sound with it; the game goes on.
            let _ = self.commands.send(commands);
        }
    }
}

/// The mixer as kira's sound: commands taken before each block, then read at the
/// device's rate (`Resampled`).
struct Live {
    reader: Resampled,
    commands: Receiver<Vec<Command>>,
}

impl Live {
    fn new(commands: Receiver<Vec<Command>>) -> Live {
        Live {
            reader: Resampled::new(Mixer::new()),
            commands,
        }
    }
}

impl Sound for Live {
    fn process(&mut self, out: &mut [Frame], dt: f64, _info: &Info) {
        while let Ok(commands) = self.commands.try_recv() {
            for command in commands {
                self.reader.mixer.apply(command);
            }
        }
        let step = dt * f64::from(RATE);
        for frame in out {
            let (left, right) = self.reader.next(step);
            *frame = Frame { left, right };
        }
    }

    fn finished(&self) -> bool {
        false
    }
}

impl SoundData for Live {
    type Error = std::convert::Infallible;
    type Handle = ();

    fn into_sound(self) -> Result<(Box<dyn Sound>, ()), Self::Error> {
        Ok((Box::new(self), ()))
    }
}

/// A mixer rendered at `RATE` a block at a time, read at another rate by linear
/// interpolation (at `RATE` itself, the mixer's own samples, one sample late).
pub struct Resampled {
    pub mixer: Mixer,
    /// The last block, after the one sample before it: `[0]` is the previous block's last.
    left: Vec<f32>,
    right: Vec<f32>,
    /// Where in the block the next frame reads, in samples at `RATE`.
    at: f64,
}

impl Resampled {
    pub fn new(mixer: Mixer) -> Resampled {
        Resampled {
            mixer,
            left: vec![0.0; BLOCK + 1],
            right: vec![0.0; BLOCK + 1],
            at: BLOCK as f64,
        }
    }

    /// The next frame, `step` samples at `RATE` after the last (`RATE` / the device's
    /// rate).
    pub fn next(&mut self, step: f64) -> (f32, f32) {
        while self.at >= BLOCK as f64 {
            self.at -= BLOCK as f64;
            self.left[0] = self.left[BLOCK];
            self.right[0] = self.right[BLOCK];
            self.mixer.render(&mut self.left[1..], &mut self.right[1..]);
        }
        // `at` runs from the previous block's last sample (`[0]`) to this block's last: at
        // a whole `at` (the same rate) the frame is one of the mixer's own samples.
        let index = self.at as usize;
        let t = (self.at - index as f64) as f32;
        let read = |channel: &[f32]| channel[index + 1] * t + channel[index] * (1.0 - t);
        let frame = (read(&self.left), read(&self.right));
        self.at += step;
        frame
    }
}

/// Keeps alsa-lib's own error printing (for a missing card or configuration) off stderr,
/// for this thread, where the device is opened: the one warning says it instead.
#[cfg(target_os = "linux")]
fn quiet_alsa() {
    unsafe extern "C" fn quiet(
        _file: *const std::ffi::c_char,
        _line: std::ffi::c_int,
        _function: *const std::ffi::c_char,
        _error: std::ffi::c_int,
        _format: *const std::ffi::c_char,
        _arguments: *mut alsa_sys::__va_list_tag,
    ) {
    }
    // SAFETY: installs a handler that reads none of its arguments, for this thread.
    unsafe {
        alsa_sys::snd_lib_error_set_local(Some(quiet));
    }
}

#[cfg(not(target_os = "linux"))]
fn quiet_alsa() {}
