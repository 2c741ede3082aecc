//! The mixer every sound of a run goes through, live (on the audio device's thread,
//! `audio::device`) and offline (`gloam play --headless --replay --audio`, `gloam
//! listen`): voices that follow `Command`s, one fixed step's commands at a time, mixed
//! into 48 kHz stereo. The same commands give the same samples on any machine and any
//! thread count: the mixer runs on one thread, in a fixed order, and nothing in it reads
//! a clock.
//!
//! Per voice: its clip (mono at `RATE`), a gain (the level the acoustics found, plus its
//! own), a low-pass at the cut-off the walls left, and an equal-power pan by where it
//! arrives from. A new mix ramps from the last one across the next block, so a moving
//! source glides instead of clicking. Each voice feeds its bus (effects, voices,
//! ambience: the settings' volumes), and, pre-pan, one reverberator (Schroeder, "Natural
//! sounding artificial reverberation", 1962: four parallel combs whose feedback sets the
//! room's decay, then two all-passes, with other delays for each ear so the tail is
//! wide) at the room's wet level.

use std::sync::Arc;

use glam::Vec3;

use crate::game::acoustics::{Heard, Reverb};
use crate::scene::sound_kit::{Biquad, RATE};

/// A sound's samples: mono at `RATE`, -1..1.
pub type Clip = Arc<[f32]>;

/// Which volume of the settings a voice answers to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bus {
    /// Footsteps, objects, the level's own sources.
    Effects,
    /// The wardens' words.
    Voices,
    /// The level's bed and the tension under play.
    Ambience,
}

/// The settings' volumes, each 0..1 (linear gain); `volume` in settings.ron.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Volumes {
    pub master: f32,
    pub effects: f32,
    pub voices: f32,
    pub ambience: f32,
}

impl Default for Volumes {
    fn default() -> Volumes {
        Volumes {
            master: 1.0,
            effects: 1.0,
            voices: 1.0,
            ambience: 1.0,
        }
    }
}

impl Volumes {
    fn of(&self, bus: Bus) -> f32 {
        match bus {
            Bus::Effects => self.effects,
            Bus::Voices => self.voices,
            Bus::Ambience => self.ambience,
        }
    }
}

/// How a voice is heard: its gain, the highest frequency that comes through, and its
/// share in each ear.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mix {
    pub gain_db: f32,
    pub cutoff_hz: f32,
    /// Equal-power gains (left, right).
    pub pan: (f32, f32),
}

impl Mix {
    /// Heard as `heard` says, `gain_db` on top, by ears at `ears` facing `yaw` (radians
    /// about +Y, 0 looking down -Z).
    pub fn heard(heard: &Heard, gain_db: f32, (ears, yaw): (Vec3, f32)) -> Mix {
        Mix {
            gain_db: heard.level_db + gain_db,
            cutoff_hz: heard.cutoff_hz,
            pan: pan(heard.arrival - ears, yaw),
        }
    }

    /// The same mix with another cut-off.
    pub fn with_cutoff(self, cutoff_hz: f32) -> Mix {
        Mix { cutoff_hz, ..self }
    }

    /// Everywhere at once (a bed, the tension): both ears alike, nothing taken away.
    pub fn centred(gain_db: f32) -> Mix {
        Mix {
            gain_db,
            cutoff_hz: OPEN_CUTOFF_HZ,
            pan: (
                std::f32::consts::FRAC_1_SQRT_2,
                std::f32::consts::FRAC_1_SQRT_2,
            ),
        }
    }
}

/// What the mixer is told, one fixed step's worth at a time.
#[derive(Clone, Debug)]
pub enum Command {
    /// Starts `clip` as voice `voice` (a one-shot ends itself; a looping voice plays until
    /// stopped).
    Play {
        voice: u64,
        clip: Clip,
        looping: bool,
        bus: Bus,
        mix: Mix,
    },
    /// A voice heard another way (it moved, or the ears did).
    Set {
        voice: u64,
        mix: Mix,
    },
    Stop {
        voice: u64,
    },
    /// The room around the ears.
    Room(Reverb),
    Volumes(Volumes),
    /// Holds every voice where it is, silent, until resumed.
    Pause(bool),
    /// A level is left: its looping voices stop (one-shots ring out: the catch is heard
    /// over the restart).
    Clear,
}

/// The most voices at once: a new one-shot past it replaces the oldest one-shot (so the
/// audio thread never allocates for a voice).
pub const MAX_VOICES: usize = 96;
/// Samples of one fixed step at `RATE` (60 Hz).
pub const STEP_FRAMES: usize = RATE as usize / 60;
/// The cut-off that takes nothing away.
const OPEN_CUTOFF_HZ: f32 = 20_000.0;
/// Comb and all-pass delays in samples (mutually prime, as Schroeder chose them), and how
/// much longer each is for the right ear.
const COMBS: [usize; 4] = [1557, 1617, 1491, 1422];
const ALLPASSES: [usize; 2] = [225, 556];
const RIGHT_EAR_SPREAD: usize = 23;
/// The reverberator's level against the dry sound at a wet level of 0 dB (its four combs
/// add up).
const REVERB_SCALE: f32 = 0.25;

struct Voice {
    id: u64,
    clip: Clip,
    at: usize,
    looping: bool,
    bus: Bus,
    mix: Mix,
    /// The gains (left, right, send) the last block ended at; `None` before the first.
    gains: Option<[f32; 3]>,
    filter: Biquad,
    cutoff_hz: f32,
}

/// One ear's reverberator, its delay lines allocated once.
struct Reverberator {
    combs: Vec<(Vec<f32>, f32)>,
    allpasses: Vec<Vec<f32>>,
    /// Samples processed (the lines' write position).
    at: usize,
}

impl Reverberator {
    fn new(spread: usize) -> Reverberator {
        Reverberator {
            combs: COMBS.map(|d| (vec![0.0; d + spread], 0.0)).to_vec(),
            allpasses: ALLPASSES.map(|d| vec![0.0; d + spread]).to_vec(),
            at: 0,
        }
    }

    /// Each pass round a comb falls by 60 dB over the decay time.
    fn set_decay(&mut self, decay_s: f32) {
        for (line, feedback) in &mut self.combs {
            *feedback = 10f32.powf(-3.0 * line.len() as f32 / (RATE as f32 * decay_s.max(0.05)));
        }
    }

    fn process(&mut self, input: f32) -> f32 {
        let at = self.at;
        self.at += 1;
        let mut tail = 0.0;
        for (line, feedback) in &mut self.combs {
            let slot = at % line.len();
            let delayed = line[slot];
            line[slot] = input + *feedback * delayed;
            tail += delayed;
        }
        for line in &mut self.allpasses {
            let slot = at % line.len();
            let delayed = line[slot];
            line[slot] = tail + 0.5 * delayed;
            tail = delayed - 0.5 * tail;
        }
        tail
    }
}

/// The voices, the room and the volumes (see the module doc).
pub struct Mixer {
    voices: Vec<Voice>,
    ears: [Reverberator; 2],
    /// The reverberator's gain, linear (`REVERB_SCALE` at 0 dB wet).
    wet: f32,
    volumes: Volumes,
    paused: bool,
    /// The reverberator's input, one block at a time.
    send: Vec<f32>,
}

impl Default for Mixer {
    fn default() -> Mixer {
        Mixer::new()
    }
}

impl Mixer {
    pub fn new() -> Mixer {
        let mut ears = [Reverberator::new(0), Reverberator::new(RIGHT_EAR_SPREAD)];
        for ear in &mut ears {
            ear.set_decay(0.05);
        }
        Mixer {
            voices: Vec::with_capacity(MAX_VOICES),
            ears,
            wet: 0.0,
            volumes: Volumes::default(),
            paused: false,
            send: Vec::with_capacity(4096),
        }
    }

    /// Voices playing.
    pub fn voices(&self) -> usize {
        self.voices.len()
    }

    pub fn apply(&mut self, command: Command) {
        match command {
            Command::Play {
                voice,
                clip,
                looping,
                bus,
                mix,
            } => {
                if self.voices.len() == MAX_VOICES {
                    match self.voices.iter().position(|v| !v.looping) {
                        Some(oldest) => {
                            self.voices.remove(oldest);
                        }
                        None => return,
                    }
                }
                let cutoff_hz = clamp_cutoff(mix.cutoff_hz);
                self.voices.push(Voice {
                    id: voice,
                    clip,
                    at: 0,
                    looping,
                    bus,
                    mix,
                    gains: None,
                    filter: Biquad::lowpass(f64::from(cutoff_hz), std::f64::consts::FRAC_1_SQRT_2),
                    cutoff_hz,
                });
            }
            Command::Set { voice, mix } => {
                if let Some(v) = self.voices.iter_mut().find(|v| v.id == voice) {
                    v.mix = mix;
                }
            }
            Command::Stop { voice } => self.voices.retain(|v| v.id != voice),
            Command::Room(room) => {
                for ear in &mut self.ears {
                    ear.set_decay(room.decay_s);
                }
                self.wet = if room.decay_s > 0.0 {
                    10f32.powf(room.wet_db / 20.0) * REVERB_SCALE
                } else {
                    0.0
                };
            }
            Command::Volumes(volumes) => self.volumes = volumes,
            Command::Pause(paused) => self.paused = paused,
            Command::Clear => self.voices.retain(|v| !v.looping),
        }
    }

    /// Mixes the next `left.len()` samples (both slices the same length) into `left` and
    /// `right`, overwriting them.
    pub fn render(&mut self, left: &mut [f32], right: &mut [f32]) {
        left.fill(0.0);
        right.fill(0.0);
        if self.paused || left.is_empty() {
            return;
        }
        let frames = left.len().min(right.len());
        self.send.clear();
        self.send.resize(frames, 0.0);
        let volumes = self.volumes;
        for voice in &mut self.voices {
            let level = 10f32.powf(voice.mix.gain_db / 20.0) * volumes.of(voice.bus);
            let target = [level * voice.mix.pan.0, level * voice.mix.pan.1, level];
            let from = voice.gains.unwrap_or(target);
            voice.gains = Some(target);
            let cutoff_hz = clamp_cutoff(voice.mix.cutoff_hz);
            if cutoff_hz != voice.cutoff_hz {
                voice.cutoff_hz = cutoff_hz;
                voice
                    .filter
                    .set_lowpass(f64::from(cutoff_hz), std::f64::consts::FRAC_1_SQRT_2);
            }
            let step = 1.0 / frames as f32;
            for i in 0..frames {
                let Some(&x) = voice.clip.get(voice.at) else {
                    break;
                };
                voice.at += 1;
                if voice.looping && voice.at == voice.clip.len() {
                    voice.at = 0;
                }
                let y = voice.filter.process(f64::from(x)) as f32;
                let t = (i + 1) as f32 * step;
                let gain = |k: usize| from[k] + (target[k] - from[k]) * t;
                left[i] += gain(0) * y;
                right[i] += gain(1) * y;
                self.send[i] += gain(2) * y;
            }
        }
        self.voices
            .retain(|v| v.looping && !v.clip.is_empty() || v.at < v.clip.len());
        if self.wet > 0.0 {
            let [left_ear, right_ear] = &mut self.ears;
            for (i, &s) in self.send.iter().enumerate() {
                left[i] += self.wet * left_ear.process(s);
                right[i] += self.wet * right_ear.process(s);
            }
        }
        let master = volumes.master;
        for s in left.iter_mut().chain(right.iter_mut()) {
            *s *= master;
        }
    }
}

fn clamp_cutoff(cutoff_hz: f32) -> f32 {
    cutoff_hz.clamp(20.0, RATE as f32 * 0.45)
}

/// Equal-power gains (left, right) for a sound arriving along `to` (from the ears) for
/// ears facing `yaw`: the sideways share of the direction sets the pan.
fn pan(to: Vec3, yaw: f32) -> (f32, f32) {
    let across = Vec3::new(to.x, 0.0, to.z);
    let side = if across.length() < 1e-3 {
        0.0
    } else {
        let right = Vec3::new(yaw.cos(), 0.0, -yaw.sin());
        across.normalize().dot(right).clamp(-1.0, 1.0)
    };
    let angle = (side + 1.0) * std::f32::consts::FRAC_PI_4;
    (angle.cos(), angle.sin())
}

/// Two channels of samples at `RATE`, -1..1.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stereo {
    pub left: Vec<f32>,
    pub right: Vec<f32>,
}

impl Stereo {
    /// Appends the mixer's next `frames` samples.
    pub fn record(&mut self, mixer: &mut Mixer, frames: usize) {
        let start = self.left.len();
        self.left.resize(start + frames, 0.0);
        self.right.resize(start + frames, 0.0);
        mixer.render(&mut self.left[start..], &mut self.right[start..]);
    }

    /// The RMS level over both channels, dBFS (-120 for silence).
    pub fn rms_dbfs(&self) -> f32 {
        let count = self.left.len() + self.right.len();
        if count == 0 {
            return -120.0;
        }
        let power: f64 = self
            .left
            .iter()
            .chain(&self.right)
            .map(|&s| f64::from(s) * f64::from(s))
            .sum::<f64>()
            / count as f64;
        (10.0 * power.max(1e-12).log10()) as f32
    }

    /// As 16-bit samples, clipped to full scale (no normalisation: levels compare
    /// between runs).
    pub fn to_pcm(&self) -> (Vec<i16>, Vec<i16>) {
        let pcm = |channel: &[f32]| {
            channel
                .iter()
                .map(|s| (s * 32767.0).round().clamp(-32768.0, 32767.0) as i16)
                .collect()
        };
        (pcm(&self.left), pcm(&self.right))
    }
}
