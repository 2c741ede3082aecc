//! Audio, after the simulation: what the ears hear, mixed. Owns the offline mixer that
//! `gloam listen` renders with: each source's samples at the level, cut-off and direction
//! `game::acoustics::hear` found for it, and the room's reverberation from
//! `game::acoustics::reverb`, into 48 kHz stereo.
//!
//! Per source: gain (its `level_db` plus its own `gain_db`), a low-pass at its cut-off,
//! then an equal-power pan by where it arrives from against the way the ears face. The
//! sources' sum also feeds one reverberator (Schroeder, "Natural sounding artificial
//! reverberation", 1962: four parallel combs, their feedback set for the decay time,
//! then two all-passes, with other delays for each ear so the tail is wide), at the
//! room's wet level.

use glam::Vec3;

use crate::game::acoustics::{Heard, Reverb};
use crate::scene::sound_kit::{Biquad, RATE};

/// Two channels of samples at `RATE`, -1..1.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stereo {
    pub left: Vec<f32>,
    pub right: Vec<f32>,
}

impl Stereo {
    pub fn silence(frames: usize) -> Stereo {
        Stereo {
            left: vec![0.0; frames],
            right: vec![0.0; frames],
        }
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

/// Adds `samples` (mono at `RATE`, looped to fill `out` when `looping`) as heard through
/// `heard`, `gain_db` on top, by ears at `ears` facing `yaw` (radians about +Y, 0 looking
/// down -Z). Returns the mono signal it added, for the reverb's send.
pub fn add_source(
    out: &mut Stereo,
    samples: &[f64],
    looping: bool,
    heard: &Heard,
    gain_db: f32,
    (ears, yaw): (Vec3, f32),
) -> Vec<f32> {
    let frames = out.left.len();
    let gain = 10f64.powf(f64::from(heard.level_db + gain_db) / 20.0);
    let mut filter = Biquad::lowpass(
        f64::from(heard.cutoff_hz).min(RATE as f64 * 0.45),
        std::f64::consts::FRAC_1_SQRT_2,
    );
    let (left, right) = pan(heard.arrival - ears, yaw);
    let mut dry = vec![0.0f32; frames];
    for (i, sample) in dry.iter_mut().enumerate() {
        let x = match (samples.len(), looping) {
            (0, _) => 0.0,
            (n, true) => samples[i % n],
            (n, false) if i < n => samples[i],
            _ => 0.0,
        };
        *sample = (gain * filter.process(x)) as f32;
    }
    for ((l, r), s) in out.left.iter_mut().zip(&mut out.right).zip(&dry) {
        *l += left * s;
        *r += right * s;
    }
    dry
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

/// Adds `room`'s reverberation of `send` (the dry sources' sum) to `out`.
pub fn add_reverb(out: &mut Stereo, send: &[f32], room: &Reverb) {
    let wet = 10f32.powf(room.wet_db / 20.0) * 0.25;
    // Comb and all-pass delays in samples (mutually prime, as Schroeder chose them), a
    // little longer for the right ear.
    const COMBS: [usize; 4] = [1557, 1617, 1491, 1422];
    const ALLPASSES: [usize; 2] = [225, 556];
    const SPREAD: usize = 23;
    for (channel, spread) in [(&mut out.left, 0), (&mut out.right, SPREAD)] {
        let mut tail = vec![0.0f32; send.len()];
        for delay in COMBS.map(|d| d + spread) {
            // Each pass round the comb falls by 60 dB over the decay time.
            let feedback = 10f32.powf(-3.0 * delay as f32 / (RATE as f32 * room.decay_s.max(0.05)));
            let mut line = vec![0.0f32; delay];
            for (i, (t, s)) in tail.iter_mut().zip(send).enumerate() {
                let slot = i % delay;
                let delayed = line[slot];
                line[slot] = s + feedback * delayed;
                *t += delayed;
            }
        }
        for delay in ALLPASSES.map(|d| d + spread) {
            let mut line = vec![0.0f32; delay];
            for (i, t) in tail.iter_mut().enumerate() {
                let slot = i % delay;
                let delayed = line[slot];
                let input = *t;
                line[slot] = input + 0.5 * delayed;
                *t = delayed - 0.5 * input;
            }
        }
        for (c, t) in channel.iter_mut().zip(&tail) {
            *c += wet * t;
        }
    }
}
