//! Load time, asset generation: the sound kit. Every file under `assets/sounds/` is made
//! here by `gloam generate sounds`: synthesised by our own DSP (noise, filters, damped
//! modes, envelopes), except the wardens' spoken cues, which espeak-ng (Debian's
//! `espeak-ng`, GPL-3.0-or-later; its output is ours to ship) speaks and we then shape.
//!
//! All are 48 kHz mono 16-bit PCM WAV: the sources are placed in the level and spread
//! over the listener's ears by the game, so a file carries one voice. The loops end where
//! they begin (whole periods of every tone, and a crossfade of their noise), so they play
//! without a click.
//!
//! The synthesis is physical modelling at its simplest (Cook, "Real Sound Synthesis for
//! Interactive Applications", 2002; Farnell, "Designing Sound", 2010): an impact is a
//! burst of filtered noise plus the decaying modes of what was struck; glass breaking is
//! many small impacts scattered in time; wind is noise through a slowly wandering
//! band-pass. Each surface is told apart by where its modes lie and how fast they die:
//! stone clicks and thuds, wood knocks hollow, iron rings, cloth only rustles.
//!
//! Levels are set in the generator (`Sound::peak_db`), not normalised away: a crouched
//! step is quieter than a sprint in the file itself.

use std::f64::consts::TAU;
use std::path::{Path, PathBuf};

use anyhow::{Context as _, bail};

/// Samples per second of every sound.
pub const RATE: u32 = 48_000;

/// A surface a body walks on, as the kit's materials are grouped for sound.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Surface {
    Stone,
    Wood,
    Iron,
    Cloth,
}

impl Surface {
    /// How `material` sounds struck or walked on, by what the kit calls it: wood, cloth
    /// (banners, cloaks, rugs), iron and the other metals; anything else is stone (plaster,
    /// tiles, glass).
    pub fn of(material: &crate::scene::model::Material) -> Surface {
        let name = material.name.to_ascii_lowercase();
        let named = |words: &[&str]| words.iter().any(|word| name.contains(word));
        if named(&["wood", "plank", "crate"]) {
            Surface::Wood
        } else if named(&["cloth", "cloak", "rug", "carpet", "banner"]) {
            Surface::Cloth
        } else if named(&["iron", "brass", "steel", "metal"]) || material.metallic >= 0.5 {
            Surface::Iron
        } else {
            Surface::Stone
        }
    }

    pub const ALL: [Surface; 4] = [Surface::Stone, Surface::Wood, Surface::Iron, Surface::Cloth];

    pub fn name(self) -> &'static str {
        match self {
            Surface::Stone => "stone",
            Surface::Wood => "wood",
            Surface::Iron => "iron",
            Surface::Cloth => "cloth",
        }
    }
}

/// How the player moves, as footsteps tell it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Gait {
    Crouch,
    Walk,
    Sprint,
}

impl Gait {
    pub const ALL: [Gait; 3] = [Gait::Crouch, Gait::Walk, Gait::Sprint];

    pub fn name(self) -> &'static str {
        match self {
            Gait::Crouch => "crouch",
            Gait::Walk => "walk",
            Gait::Sprint => "sprint",
        }
    }
}

/// Variants of each footstep, alternated in play so a walk does not tick like a clock.
pub const STEP_VARIANTS: u32 = 2;

/// How one file is made.
#[derive(Clone, Debug)]
enum Recipe {
    Footstep(Surface, Gait, u32),
    Landing,
    BottleTopple,
    BottleBreak,
    LampDouse,
    LampLight,
    Shard,
    GateChains,
    WardenStep(u32),
    WardenArmour,
    /// Spoken by espeak-ng: the words, and the voice's pitch (0-99).
    Voice(&'static str, u32),
    Wind,
    LampHum,
    Candle,
    TensionLow,
    TensionHigh,
}

/// One file of the kit.
#[derive(Clone, Debug)]
pub struct Sound {
    /// The file name under `assets/sounds/`, without `.wav`.
    pub name: String,
    /// Plays as a loop (ambience, tension), else once.
    pub looping: bool,
    /// The peak the file is scaled to, dB below full scale.
    pub peak_db: f64,
    recipe: Recipe,
}

impl Sound {
    /// Whether an external program makes it (checked by its length and level, not bytes).
    pub fn spoken(&self) -> bool {
        matches!(self.recipe, Recipe::Voice(..))
    }

    pub fn file_name(&self) -> String {
        format!("{}.wav", self.name)
    }
}

/// The name of footstep file `variant` (from 1) on `surface` at `gait`.
pub fn footstep_name(surface: Surface, gait: Gait, variant: u32) -> String {
    format!("step-{}-{}-{variant}", surface.name(), gait.name())
}

/// The kit: every sound the game plays, in one list (the generator, SOURCES.md's table and
/// the tests all read this).
pub fn sounds() -> Vec<Sound> {
    let sound = |name: &str, looping, peak_db, recipe| Sound {
        name: name.to_owned(),
        looping,
        peak_db,
        recipe,
    };
    let mut list = Vec::new();
    for surface in Surface::ALL {
        for gait in Gait::ALL {
            for variant in 1..=STEP_VARIANTS {
                // A sprint lands 10 dB over a walk, a crouch creeps 12 dB under it.
                let peak = match gait {
                    Gait::Crouch => -22.0,
                    Gait::Walk => -10.0,
                    Gait::Sprint => -3.0,
                };
                list.push(sound(
                    &footstep_name(surface, gait, variant),
                    false,
                    peak,
                    Recipe::Footstep(surface, gait, variant),
                ));
            }
        }
    }
    list.extend([
        sound("landing", false, -1.0, Recipe::Landing),
        sound("bottle-topple", false, -6.0, Recipe::BottleTopple),
        sound("bottle-break", false, -1.0, Recipe::BottleBreak),
        sound("lamp-douse", false, -8.0, Recipe::LampDouse),
        sound("lamp-light", false, -8.0, Recipe::LampLight),
        sound("shard", false, -6.0, Recipe::Shard),
        sound("gate-chains", false, -3.0, Recipe::GateChains),
        sound("warden-step-1", false, -6.0, Recipe::WardenStep(1)),
        sound("warden-step-2", false, -6.0, Recipe::WardenStep(2)),
        sound("warden-armour", false, -12.0, Recipe::WardenArmour),
        sound(
            "warden-curious",
            false,
            -4.0,
            Recipe::Voice("Hm? What was that?", 30),
        ),
        sound(
            "warden-searching",
            false,
            -4.0,
            Recipe::Voice("Who's there? Show yourself.", 35),
        ),
        sound(
            "warden-alarm",
            false,
            -2.0,
            Recipe::Voice("There! Intruder!", 45),
        ),
        sound(
            "warden-gives-up",
            false,
            -6.0,
            Recipe::Voice("Must have been the wind.", 25),
        ),
        sound("wind", true, -14.0, Recipe::Wind),
        sound("lamp-hum", true, -20.0, Recipe::LampHum),
        sound("candle", true, -20.0, Recipe::Candle),
        sound("tension-low", true, -12.0, Recipe::TensionLow),
        sound("tension-high", true, -10.0, Recipe::TensionHigh),
    ]);
    list
}

/// Writes every sound into `out` (`assets/sounds`), returning the files written. A voice
/// needs espeak-ng: without it the synthesised files are still written, the committed
/// voices are left as they are, and the error says what to install.
pub fn generate_sounds(out: &Path) -> anyhow::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut written = Vec::new();
    let mut unspoken = Vec::new();
    for sound in sounds() {
        let path = out.join(sound.file_name());
        let samples = match render(&sound) {
            Ok(samples) => samples,
            Err(error) if sound.spoken() => {
                unspoken.push(format!("{}: {error:#}", sound.name));
                continue;
            }
            Err(error) => return Err(error),
        };
        crate::scene::files::write_atomically(&path, &wav_bytes(&samples))?;
        written.push(path);
    }
    if let Some(first) = unspoken.first() {
        bail!(
            "wrote {} sounds, but not the {} voices ({first}); kept the ones in {}",
            written.len(),
            unspoken.len(),
            out.display()
        );
    }
    Ok(written)
}

/// The sound as 16-bit samples at `RATE`, scaled to its peak.
pub fn render(sound: &Sound) -> anyhow::Result<Vec<i16>> {
    let mut signal = match &sound.recipe {
        Recipe::Footstep(surface, gait, variant) => footstep(*surface, *gait, *variant),
        Recipe::Landing => landing(),
        Recipe::BottleTopple => bottle_topple(),
        Recipe::BottleBreak => bottle_break(),
        Recipe::LampDouse => lamp_douse(),
        Recipe::LampLight => lamp_light(),
        Recipe::Shard => shard(),
        Recipe::GateChains => gate_chains(),
        Recipe::WardenStep(variant) => warden_step(*variant),
        Recipe::WardenArmour => warden_armour(),
        Recipe::Voice(words, pitch) => voice(words, *pitch)?,
        Recipe::Wind => wind(),
        Recipe::LampHum => lamp_hum(),
        Recipe::Candle => candle(),
        Recipe::TensionLow => tension_low(),
        Recipe::TensionHigh => tension_high(),
    };
    if !sound.looping {
        fade_out(&mut signal, 0.01);
    }
    Ok(to_pcm(&signal, sound.peak_db))
}

// ---------------------------------------------------------------------------------------
// The sounds.

/// A footstep: the heel's strike and the toe's roll on `surface`, harder and brighter the
/// faster the gait.
fn footstep(surface: Surface, gait: Gait, variant: u32) -> Vec<f64> {
    let seed = 0x5_7e95 + surface as u64 * 97 + gait as u64 * 13 + variant as u64;
    let mut rng = Rng::new(seed);
    let mut out = silence(0.3);
    // (heel's weight, toe's weight, toe's delay s, brightness)
    let (heel, toe, delay, bright) = match gait {
        Gait::Crouch => (0.5, 0.35, 0.11, 0.6),
        Gait::Walk => (1.0, 0.5, 0.07, 1.0),
        Gait::Sprint => (1.0, 0.25, 0.035, 1.4),
    };
    for (at, weight) in [(0.004, heel), (0.004 + delay, toe)] {
        let weight = weight * rng.around(1.0, 0.15);
        let start = seconds(at + rng.around(0.0, 0.004).abs());
        strike(
            &mut out,
            start,
            surface,
            weight,
            bright * rng.around(1.0, 0.08),
            &mut rng,
        );
    }
    if gait == Gait::Crouch {
        // Crouched, the sole rolls down slowly: the edge of the strike is softened.
        lowpass(&mut out, 1800.0);
    }
    out
}

/// One contact of a sole (or a body) with `surface`, added at `start`.
fn strike(
    out: &mut [f64],
    start: usize,
    surface: Surface,
    weight: f64,
    bright: f64,
    rng: &mut Rng,
) {
    match surface {
        Surface::Stone => {
            // Band-passed noise keeps about a quarter of white noise's level: the click
            // is weighted up to stand over the thud, as a hard floor sounds.
            burst(2600.0 * bright, 1.4, 0.0005, 0.012, 2.5 * weight).add(out, start, rng);
            let thud = [(110.0, 0.03, 0.3 * weight), (190.0, 0.02, 0.15 * weight)];
            modes(out, start, &thud);
            burst(5200.0 * bright, 0.8, 0.002, 0.04, 0.5 * weight).add(out, start, rng);
        }
        Surface::Wood => {
            burst(1400.0 * bright, 1.2, 0.0005, 0.01, 0.6 * weight).add(out, start, rng);
            let f = rng.around(1.0, 0.04);
            modes(
                out,
                start,
                &[
                    (170.0 * f, 0.07, 0.7 * weight),
                    (410.0 * f, 0.05, 0.45 * weight),
                    (780.0 * f, 0.03, 0.3 * weight),
                ],
            );
        }
        Surface::Iron => {
            burst(3000.0 * bright, 1.5, 0.0005, 0.008, 0.5 * weight).add(out, start, rng);
            let f = rng.around(1.0, 0.03);
            modes(
                out,
                start,
                &[
                    (140.0 * f, 0.05, 0.5 * weight),
                    (640.0 * f, 0.22, 0.3 * weight),
                    (1530.0 * f, 0.16, 0.22 * weight),
                    (2790.0 * f, 0.1, 0.15 * weight),
                    (4020.0 * f, 0.07, 0.1 * weight),
                ],
            );
        }
        Surface::Cloth => {
            burst(600.0 * bright, 0.7, 0.008, 0.05, 0.8 * weight).add(out, start, rng);
            modes(out, start, &[(90.0, 0.03, 0.3 * weight)]);
        }
    }
}

/// A body landing from a jump or a fall: a heavy thud and the knees' give.
fn landing() -> Vec<f64> {
    let mut rng = Rng::new(0x1a9d);
    let mut out = silence(0.6);
    modes(
        &mut out,
        0,
        &[(62.0, 0.12, 1.0), (118.0, 0.07, 0.5), (240.0, 0.04, 0.2)],
    );
    burst(450.0, 0.9, 0.001, 0.05, 0.8).add(&mut out, 0, &mut rng);
    burst(2500.0, 1.2, 0.001, 0.02, 0.3).add(&mut out, 0, &mut rng);
    // Cloth and gear settling just after.
    burst(900.0, 0.8, 0.02, 0.08, 0.15).add(&mut out, seconds(0.06), &mut rng);
    out
}

/// Glass struck lightly: its small high modes.
fn glass_tap(out: &mut [f64], start: usize, weight: f64, rng: &mut Rng) {
    let f = rng.around(1.0, 0.05);
    modes(
        out,
        start,
        &[
            (1850.0 * f, 0.09, 0.5 * weight),
            (4230.0 * f, 0.06, 0.35 * weight),
            (6950.0 * f, 0.04, 0.2 * weight),
        ],
    );
    burst(5000.0, 1.0, 0.0003, 0.004, 0.3 * weight).add(out, start, rng);
}

/// A bottle rocking on its base and falling over: taps coming faster, then the body on
/// the floor and a short roll.
fn bottle_topple() -> Vec<f64> {
    let mut rng = Rng::new(0xb077);
    let mut out = silence(0.9);
    for (at, weight) in [(0.0, 0.4), (0.17, 0.5), (0.29, 0.6), (0.37, 0.7)] {
        glass_tap(&mut out, seconds(at), weight, &mut rng);
    }
    let fall = seconds(0.45);
    glass_tap(&mut out, fall, 1.0, &mut rng);
    modes(&mut out, fall, &[(230.0, 0.05, 0.4)]);
    // The roll: a rumble of band-passed noise with a wobble.
    let roll = seconds(0.5);
    let mut rumble = silence(0.35);
    burst(900.0, 1.5, 0.05, 0.12, 0.15).add(&mut rumble, 0, &mut rng);
    for (i, sample) in rumble.iter_mut().enumerate() {
        *sample *= 0.6 + 0.4 * (TAU * 9.0 * i as f64 / RATE as f64).sin();
    }
    mix(&mut out, roll, &rumble);
    out
}

/// A bottle breaking on the floor: the crack, a thump, and shards scattering, many small
/// glass impacts whose onsets thin out over half a second.
fn bottle_break() -> Vec<f64> {
    let mut rng = Rng::new(0xb4ea);
    let mut out = silence(1.4);
    burst(3500.0, 0.6, 0.0003, 0.03, 1.0).add(&mut out, 0, &mut rng);
    modes(&mut out, 0, &[(150.0, 0.06, 0.6), (320.0, 0.04, 0.3)]);
    for _ in 0..48 {
        // Exponentially distributed onsets: most shards fly at once, a few skitter on.
        let at = -0.12 * (1.0 - rng.unit()).ln();
        if at > 1.2 {
            continue;
        }
        let start = seconds(at);
        let weight = 0.5 * rng.unit().powi(2) + 0.05;
        let f = 2500.0 + 6500.0 * rng.unit();
        modes(
            &mut out,
            start,
            &[
                (f, 0.02 + 0.06 * rng.unit(), weight),
                (f * 1.73, 0.015 + 0.03 * rng.unit(), 0.6 * weight),
            ],
        );
        burst(6000.0, 1.0, 0.0002, 0.003, 0.4 * weight).add(&mut out, start, &mut rng);
    }
    out
}

/// Pinching out a lamp's flame: a short sizzle falling away.
fn lamp_douse() -> Vec<f64> {
    let mut rng = Rng::new(0xd0_5e);
    let mut out = silence(0.8);
    burst(4200.0, 0.7, 0.01, 0.25, 0.8).add(&mut out, 0, &mut rng);
    burst(1200.0, 1.0, 0.005, 0.08, 0.4).add(&mut out, 0, &mut rng);
    // The wick's smoke: a faint breath after.
    burst(700.0, 0.7, 0.1, 0.2, 0.1).add(&mut out, seconds(0.15), &mut rng);
    out
}

/// Lighting a lamp: a match struck, then the flame catching with a soft whoomp whose
/// band rises as it takes.
fn lamp_light() -> Vec<f64> {
    let mut rng = Rng::new(0x11_647);
    let mut out = silence(0.9);
    burst(3200.0, 1.5, 0.002, 0.03, 0.6).add(&mut out, 0, &mut rng);
    burst(5000.0, 0.8, 0.01, 0.08, 0.35).add(&mut out, seconds(0.03), &mut rng);
    let start = seconds(0.18);
    let length = seconds(0.6);
    let mut filter = Biquad::bandpass(200.0, 0.7);
    for i in 0..length {
        let t = i as f64 / length as f64;
        if i % 32 == 0 {
            filter.set_bandpass(200.0 + 1300.0 * t.sqrt(), 0.7);
        }
        let envelope = (t * 8.0).min(1.0) * (1.0 - t).powi(2);
        out[start + i] += 0.9 * envelope * filter.process(rng.signed());
    }
    out
}

/// Picking up a shard: a small bell (the inharmonic partials of a struck bar, Rossing,
/// "The Science of Sound"), answered a fifth higher.
fn shard() -> Vec<f64> {
    let mut out = silence(1.6);
    let bell = |f: f64, weight: f64| {
        [
            (f, 1.1, weight),
            (f * 2.756, 0.7, 0.5 * weight),
            (f * 5.404, 0.45, 0.3 * weight),
            (f * 8.933, 0.3, 0.15 * weight),
        ]
    };
    modes(&mut out, 0, &bell(880.0, 1.0));
    modes(&mut out, seconds(0.09), &bell(1320.0, 0.6));
    out
}

/// The gate's chains running over the windlass: links clinking at the ratchet's pace over
/// a low grind.
fn gate_chains() -> Vec<f64> {
    let mut rng = Rng::new(0x6a7e);
    let length = 2.4;
    let mut out = silence(length);
    let mut at = 0.02;
    while at < length - 0.3 {
        let start = seconds(at);
        let f = rng.around(1.0, 0.15);
        let weight = rng.around(0.45, 0.2);
        modes(
            &mut out,
            start,
            &[
                (1180.0 * f, 0.07, weight),
                (2650.0 * f, 0.05, 0.6 * weight),
                (4100.0 * f, 0.03, 0.35 * weight),
            ],
        );
        burst(3000.0, 1.0, 0.0005, 0.006, 0.3 * weight).add(&mut out, start, &mut rng);
        at += rng.around(0.085, 0.02);
    }
    let mut grind = silence(length);
    burst(220.0, 1.2, 0.2, 0.9, 1.2).add(&mut grind, 0, &mut rng);
    for (i, sample) in grind.iter_mut().enumerate() {
        let t = i as f64 / RATE as f64;
        *sample *= 0.7 + 0.3 * (TAU * 11.0 * t).sin();
    }
    mix(&mut out, 0, &grind);
    fade_in(&mut out, 0.05);
    out
}

/// A warden's boot on stone: heavier and lower than the player's, with a hobnail click.
fn warden_step(variant: u32) -> Vec<f64> {
    let mut rng = Rng::new(0x3a_d3 + variant as u64);
    let mut out = silence(0.35);
    let f = rng.around(1.0, 0.05);
    modes(
        &mut out,
        0,
        &[(85.0 * f, 0.07, 1.0), (160.0 * f, 0.04, 0.45)],
    );
    burst(1800.0 * f, 1.2, 0.0005, 0.015, 0.8).add(&mut out, 0, &mut rng);
    burst(6000.0, 1.5, 0.0002, 0.004, 0.3).add(&mut out, seconds(0.002), &mut rng);
    strike(&mut out, seconds(0.06), Surface::Stone, 0.4, 0.9, &mut rng);
    out
}

/// A warden's armour moving: mail rings jingling and a plate's dull clank.
fn warden_armour() -> Vec<f64> {
    let mut rng = Rng::new(0xa7_a0);
    let mut out = silence(0.5);
    modes(&mut out, 0, &[(690.0, 0.08, 0.5), (1870.0, 0.05, 0.3)]);
    for _ in 0..26 {
        let at = 0.3 * rng.unit().powf(1.5);
        let f = 3000.0 + 5000.0 * rng.unit();
        let weight = 0.1 + 0.25 * rng.unit();
        modes(
            &mut out,
            seconds(at),
            &[(f, 0.02 + 0.03 * rng.unit(), weight)],
        );
    }
    out
}

/// Words spoken by espeak-ng in a low male voice, then band-limited as through a helmet
/// and resampled to `RATE`.
fn voice(words: &str, pitch: u32) -> anyhow::Result<Vec<f64>> {
    let output = std::process::Command::new("espeak-ng")
        .args([
            "-v",
            "en-gb+m3",
            "-s",
            "150",
            "-p",
            &pitch.to_string(),
            "--stdout",
        ])
        .arg(words)
        .output()
        .context("espeak-ng is not installed (Debian: apt install espeak-ng)")?;
    if !output.status.success() {
        bail!(
            "espeak-ng failed: {}",
            String::from_utf8_lossy(&output.stderr).trim()
        );
    }
    let (rate, samples) = read_wav(&output.stdout).context("espeak-ng's output")?;
    let mut out = resample(&samples, rate, RATE);
    highpass(&mut out, 220.0);
    lowpass(&mut out, 3800.0);
    Ok(out)
}

/// Wind outside: noise through a band-pass whose centre and strength wander with a few
/// slow, unrelated swells.
fn wind() -> Vec<f64> {
    let mut rng = Rng::new(0x71d);
    looped(6.0, 0.5, |length| {
        let mut out = vec![0.0; length];
        let mut filter = Biquad::bandpass(500.0, 1.5);
        for (i, sample) in out.iter_mut().enumerate() {
            let t = i as f64 / RATE as f64;
            let swell = 0.5
                + 0.25 * (TAU * 0.11 * t).sin()
                + 0.15 * (TAU * 0.23 * t + 1.3).sin()
                + 0.1 * (TAU * 0.51 * t + 0.4).sin();
            if i % 64 == 0 {
                filter.set_bandpass(300.0 + 600.0 * swell, 1.5 + swell);
            }
            *sample = swell * filter.process(rng.signed());
        }
        out
    })
}

/// An oil lamp's hum: the flame's low roar (100 Hz and its harmonics, whole periods in the
/// loop) over a soft hiss.
fn lamp_hum() -> Vec<f64> {
    let mut rng = Rng::new(0x4a_3);
    looped(1.0, 0.25, |length| {
        let mut hiss = vec![0.0; length];
        burst(2500.0, 0.5, 0.0, 1e9, 0.05).add(&mut hiss, 0, &mut rng);
        hiss.iter()
            .enumerate()
            .map(|(i, h)| {
                let t = i as f64 / RATE as f64;
                tones(t, &[(100.0, 0.6), (200.0, 0.25), (300.0, 0.1)]) + h
            })
            .collect()
    })
}

/// A candle: the flame's flutter and a rare crackle of the wick.
fn candle() -> Vec<f64> {
    let mut rng = Rng::new(0xca_d1e);
    looped(3.0, 0.3, |length| {
        let mut out = vec![0.0; length];
        let mut flutter = Biquad::lowpass(140.0, 0.7);
        for sample in out.iter_mut() {
            *sample = 2.0 * flutter.process(rng.signed());
        }
        let seconds_long = length as f64 / RATE as f64;
        for _ in 0..5 {
            let at = rng.unit() * (seconds_long - 0.05);
            burst(3500.0, 1.0, 0.0003, 0.004, 0.25).add(&mut out, seconds(at), &mut rng);
        }
        out
    })
}

/// The tension's low layer: a slow-beating drone on A (55 Hz against 55.25 Hz and a fifth
/// above), whole periods in its six seconds.
fn tension_low() -> Vec<f64> {
    let mut rng = Rng::new(0x7e_5);
    looped(6.0, 0.5, |length| {
        let mut air = vec![0.0; length];
        burst(160.0, 0.7, 0.0, 1e9, 0.4).add(&mut air, 0, &mut rng);
        air.iter()
            .enumerate()
            .map(|(i, a)| {
                let t = i as f64 / RATE as f64;
                let swell = 0.75 + 0.25 * (TAU * t / 6.0).sin();
                let drone = [(55.0, 0.5), (55.25, 0.4), (82.5, 0.25), (110.0, 0.1)];
                swell * tones(t, &drone) + a
            })
            .collect()
    })
}

/// The tension's high layer, for searching and alarm: a heartbeat at 90 a minute under a
/// tremolo of two strings a semitone apart (440 and 466.25 Hz).
fn tension_high() -> Vec<f64> {
    looped(4.0, 0.0, |length| {
        let mut out = vec![0.0; length];
        for beat in 0..6 {
            let at = beat as f64 / 1.5;
            modes(
                &mut out,
                seconds(at),
                &[(48.0, 0.09, 1.0), (96.0, 0.05, 0.3)],
            );
            modes(&mut out, seconds(at + 0.22), &[(44.0, 0.08, 0.7)]);
        }
        for (i, sample) in out.iter_mut().enumerate() {
            let t = i as f64 / RATE as f64;
            let tremolo = 0.5 + 0.5 * (TAU * 6.0 * t).sin();
            *sample += 0.12 * tremolo * tones(t, &[(440.0, 1.0), (466.25, 0.8)]);
        }
        out
    })
}

// ---------------------------------------------------------------------------------------
// The DSP.

/// The sum at `t` seconds of sines (frequency Hz, amplitude), added in order.
fn tones(t: f64, partials: &[(f64, f64)]) -> f64 {
    partials
        .iter()
        .map(|&(frequency, amplitude)| amplitude * (TAU * frequency * t).sin())
        .sum()
}

/// splitmix64 (Steele, Lea and Flood 2014): the same numbers on every machine.
struct Rng(u64);

impl Rng {
    fn new(seed: u64) -> Rng {
        Rng(seed)
    }

    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [-1, 1).
    fn signed(&mut self) -> f64 {
        2.0 * self.unit() - 1.0
    }

    /// `centre` give or take `spread` of it.
    fn around(&mut self, centre: f64, spread: f64) -> f64 {
        centre * (1.0 + spread * self.signed())
    }
}

fn seconds(at: f64) -> usize {
    (at * RATE as f64).round() as usize
}

fn silence(length: f64) -> Vec<f64> {
    vec![0.0; seconds(length)]
}

/// Adds `signal` into `out` from `start` (what falls past the end is dropped).
fn mix(out: &mut [f64], start: usize, signal: &[f64]) {
    for (o, s) in out.iter_mut().skip(start).zip(signal) {
        *o += s;
    }
}

/// Adds damped sinusoids (frequency Hz, time to fall by 1/e s, amplitude) from `start`:
/// the modes of a struck object.
fn modes(out: &mut [f64], start: usize, list: &[(f64, f64, f64)]) {
    for &(frequency, decay, amplitude) in list {
        if frequency >= RATE as f64 / 2.0 {
            continue;
        }
        let fall = (-1.0 / (decay * RATE as f64)).exp();
        let step = TAU * frequency / RATE as f64;
        let mut gain = amplitude;
        for (i, o) in out.iter_mut().skip(start).enumerate() {
            *o += gain * (step * i as f64).sin();
            gain *= fall;
            if gain.abs() < 1e-6 {
                break;
            }
        }
    }
}

/// Band-passed noise (centre Hz, Q) with a linear attack of `attack` s, then a fall by 1/e
/// every `decay` s, at `amplitude`: the scrape, hiss or crack of a contact.
#[derive(Clone, Copy)]
struct Burst {
    centre: f64,
    q: f64,
    attack: f64,
    decay: f64,
    amplitude: f64,
}

fn burst(centre: f64, q: f64, attack: f64, decay: f64, amplitude: f64) -> Burst {
    Burst {
        centre,
        q,
        attack,
        decay,
        amplitude,
    }
}

impl Burst {
    /// Adds the burst into `out` from `start`.
    fn add(self, out: &mut [f64], start: usize, rng: &mut Rng) {
        let mut filter = Biquad::bandpass(self.centre.min(RATE as f64 * 0.45), self.q);
        let attack_samples = (self.attack * RATE as f64).max(1.0);
        let fall = (-1.0 / (self.decay * RATE as f64)).exp();
        let mut gain = self.amplitude;
        for (i, o) in out.iter_mut().skip(start).enumerate() {
            let rise = (i as f64 / attack_samples).min(1.0);
            *o += rise * gain * filter.process(rng.signed());
            if i as f64 >= attack_samples {
                gain *= fall;
            }
            if gain < 1e-6 {
                break;
            }
        }
    }
}

fn lowpass(signal: &mut [f64], cutoff: f64) {
    let mut filter = Biquad::lowpass(cutoff, std::f64::consts::FRAC_1_SQRT_2);
    signal.iter_mut().for_each(|s| *s = filter.process(*s));
}

fn highpass(signal: &mut [f64], cutoff: f64) {
    let mut filter = Biquad::highpass(cutoff, std::f64::consts::FRAC_1_SQRT_2);
    signal.iter_mut().for_each(|s| *s = filter.process(*s));
}

fn fade_in(signal: &mut [f64], length: f64) {
    let n = seconds(length).min(signal.len()).max(1);
    for (i, s) in signal.iter_mut().take(n).enumerate() {
        *s *= i as f64 / n as f64;
    }
}

fn fade_out(signal: &mut [f64], length: f64) {
    let n = seconds(length).min(signal.len()).max(1);
    let total = signal.len();
    for (i, s) in signal.iter_mut().skip(total - n).enumerate() {
        *s *= 1.0 - (i + 1) as f64 / n as f64;
    }
}

/// A loop of `length` s: `make` draws `length` + `crossfade` s, and the overhang is faded
/// into the start, so the last sample leads into the first as the draw went on.
fn looped(length: f64, crossfade: f64, make: impl FnOnce(usize) -> Vec<f64>) -> Vec<f64> {
    let (n, fade) = (seconds(length), seconds(crossfade));
    let drawn = make(n + fade);
    let mut out = drawn[..n].to_vec();
    for i in 0..fade {
        let w = i as f64 / fade as f64;
        out[i] = drawn[i] * w + drawn[n + i] * (1.0 - w);
    }
    out
}

/// A second-order section (Bristow-Johnson's "Audio EQ Cookbook" coefficients), in
/// transposed direct form II.
#[derive(Clone, Debug)]
pub(crate) struct Biquad {
    b: [f64; 3],
    a: [f64; 2],
    z: [f64; 2],
}

impl Biquad {
    fn from_cookbook(b: [f64; 3], a: [f64; 3]) -> Biquad {
        Biquad {
            b: b.map(|x| x / a[0]),
            a: [a[1] / a[0], a[2] / a[0]],
            z: [0.0; 2],
        }
    }

    fn terms(frequency: f64, q: f64) -> (f64, f64) {
        let w = TAU * frequency / RATE as f64;
        (w.cos(), w.sin() / (2.0 * q))
    }

    fn bandpass(frequency: f64, q: f64) -> Biquad {
        let (cos, alpha) = Biquad::terms(frequency, q);
        Biquad::from_cookbook([alpha, 0.0, -alpha], [1.0 + alpha, -2.0 * cos, 1.0 - alpha])
    }

    /// Moves a band-pass to a new centre, keeping its state (a sweep).
    fn set_bandpass(&mut self, frequency: f64, q: f64) {
        let z = self.z;
        *self = Biquad::bandpass(frequency, q);
        self.z = z;
    }

    /// Moves a low-pass to a new cut-off, keeping its state (no click as it moves).
    pub(crate) fn set_lowpass(&mut self, frequency: f64, q: f64) {
        let z = self.z;
        *self = Biquad::lowpass(frequency, q);
        self.z = z;
    }

    pub(crate) fn lowpass(frequency: f64, q: f64) -> Biquad {
        let (cos, alpha) = Biquad::terms(frequency, q);
        Biquad::from_cookbook(
            [(1.0 - cos) / 2.0, 1.0 - cos, (1.0 - cos) / 2.0],
            [1.0 + alpha, -2.0 * cos, 1.0 - alpha],
        )
    }

    fn highpass(frequency: f64, q: f64) -> Biquad {
        let (cos, alpha) = Biquad::terms(frequency, q);
        Biquad::from_cookbook(
            [(1.0 + cos) / 2.0, -(1.0 + cos), (1.0 + cos) / 2.0],
            [1.0 + alpha, -2.0 * cos, 1.0 - alpha],
        )
    }

    pub(crate) fn process(&mut self, x: f64) -> f64 {
        let y = self.b[0] * x + self.z[0];
        self.z[0] = self.b[1] * x - self.a[0] * y + self.z[1];
        self.z[1] = self.b[2] * x - self.a[1] * y;
        y
    }
}

/// Linear interpolation from `from` Hz to `to` Hz (speech holds little above the helmet's
/// band, so no more is needed).
pub(crate) fn resample(samples: &[f64], from: u32, to: u32) -> Vec<f64> {
    if samples.is_empty() {
        return Vec::new();
    }
    let length = (samples.len() as u64 * to as u64 / from as u64) as usize;
    (0..length)
        .map(|i| {
            let at = i as f64 * from as f64 / to as f64;
            let left = at.floor() as usize;
            let w = at - left as f64;
            let a = samples[left.min(samples.len() - 1)];
            let b = samples[(left + 1).min(samples.len() - 1)];
            a + (b - a) * w
        })
        .collect()
}

/// Scales `signal` so its peak is `peak_db` below full scale, as 16-bit samples.
fn to_pcm(signal: &[f64], peak_db: f64) -> Vec<i16> {
    let peak = signal.iter().fold(0.0f64, |m, s| m.max(s.abs()));
    let scale = if peak > 0.0 {
        10f64.powf(peak_db / 20.0) / peak
    } else {
        0.0
    };
    signal
        .iter()
        .map(|s| (s * scale * 32767.0).round().clamp(-32768.0, 32767.0) as i16)
        .collect()
}

// ---------------------------------------------------------------------------------------
// WAV files.

/// A 48 kHz mono 16-bit PCM WAV file of `samples`.
pub fn wav_bytes(samples: &[i16]) -> Vec<u8> {
    wav_file(1, samples)
}

/// A 48 kHz stereo 16-bit PCM WAV file of the two channels.
pub fn stereo_wav_bytes(left: &[i16], right: &[i16]) -> Vec<u8> {
    let interleaved: Vec<i16> = left.iter().zip(right).flat_map(|(&l, &r)| [l, r]).collect();
    wav_file(2, &interleaved)
}

/// A 48 kHz 16-bit PCM WAV file of `channels` interleaved channels.
fn wav_file(channels: u16, samples: &[i16]) -> Vec<u8> {
    let data = samples.len() as u32 * 2;
    let frame = 2 * channels;
    let mut bytes = Vec::with_capacity(44 + data as usize);
    bytes.extend_from_slice(b"RIFF");
    bytes.extend_from_slice(&(36 + data).to_le_bytes());
    bytes.extend_from_slice(b"WAVEfmt ");
    bytes.extend_from_slice(&16u32.to_le_bytes());
    bytes.extend_from_slice(&1u16.to_le_bytes()); // PCM
    bytes.extend_from_slice(&channels.to_le_bytes());
    bytes.extend_from_slice(&RATE.to_le_bytes());
    bytes.extend_from_slice(&(RATE * frame as u32).to_le_bytes());
    bytes.extend_from_slice(&frame.to_le_bytes());
    bytes.extend_from_slice(&16u16.to_le_bytes());
    bytes.extend_from_slice(b"data");
    bytes.extend_from_slice(&data.to_le_bytes());
    for sample in samples {
        bytes.extend_from_slice(&sample.to_le_bytes());
    }
    bytes
}

/// Why a WAV file does not read.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum WavError {
    #[error("not a RIFF WAVE file")]
    NotWave,
    #[error("byte {0}: the file ends inside a chunk")]
    Truncated(usize),
    #[error("not 16-bit PCM (format {format}, {bits} bits)")]
    Unsupported { format: u16, bits: u16 },
    #[error("no `fmt ` chunk before the samples")]
    NoFormat,
    #[error("no `data` chunk")]
    NoData,
}

/// The sample rate and the samples (channels mixed down, -1..1) of a 16-bit PCM WAV file.
pub fn read_wav(bytes: &[u8]) -> Result<(u32, Vec<f64>), WavError> {
    if bytes.len() < 12 || &bytes[0..4] != b"RIFF" || &bytes[8..12] != b"WAVE" {
        return Err(WavError::NotWave);
    }
    let u16_at = |at: usize| u16::from_le_bytes([bytes[at], bytes[at + 1]]);
    let u32_at =
        |at: usize| u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
    let mut at = 12;
    let mut format = None;
    while at + 8 <= bytes.len() {
        let id = &bytes[at..at + 4];
        let size = u32_at(at + 4) as usize;
        let body = at + 8;
        // espeak-ng writes its stream with the sizes left at 0x7fffffff: the data runs to
        // the end of what was written.
        let end = body.saturating_add(size).min(bytes.len());
        if id == b"fmt " {
            if end < body + 16 {
                return Err(WavError::Truncated(at));
            }
            let (code, channels, rate, bits) = (
                u16_at(body),
                u16_at(body + 2),
                u32_at(body + 4),
                u16_at(body + 14),
            );
            if code != 1 || bits != 16 || channels == 0 {
                return Err(WavError::Unsupported { format: code, bits });
            }
            format = Some((channels as usize, rate));
        } else if id == b"data" {
            let (channels, rate) = format.ok_or(WavError::NoFormat)?;
            let frames = bytes[body..end].chunks_exact(2 * channels);
            let samples = frames
                .map(|frame| {
                    frame
                        .chunks_exact(2)
                        .map(|s| i16::from_le_bytes([s[0], s[1]]) as f64 / 32768.0)
                        .sum::<f64>()
                        / channels as f64
                })
                .collect();
            return Ok((rate, samples));
        }
        at = body + size + (size & 1);
    }
    Err(WavError::NoData)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn committed() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("assets")
            .join("sounds")
    }

    fn level_db(samples: &[f64]) -> f64 {
        let power = samples.iter().map(|s| s * s).sum::<f64>() / samples.len().max(1) as f64;
        10.0 * power.max(1e-20).log10()
    }

    #[test]
    fn committed_sounds_match_the_generator() {
        for sound in sounds() {
            let path = committed().join(sound.file_name());
            let bytes = std::fs::read(&path).unwrap_or_else(|error| {
                panic!(
                    "{} is missing ({error}); run `gloam generate sounds`",
                    path.display()
                )
            });
            if sound.spoken() {
                // espeak-ng's voice may differ by version: its length and level are held.
                let Ok(fresh) = render(&sound) else {
                    assert!(
                        std::env::var_os("CI").is_none(),
                        "CI must install espeak-ng (.ci/run does)"
                    );
                    println!(
                        "notice: espeak-ng is not installed; {} not checked",
                        sound.name
                    );
                    continue;
                };
                let (_, kept) = read_wav(&bytes).unwrap();
                let fresh: Vec<f64> = fresh.iter().map(|&s| s as f64 / 32768.0).collect();
                let ratio = fresh.len() as f64 / kept.len() as f64;
                assert!(
                    (0.8..1.25).contains(&ratio),
                    "{}: length x{ratio}",
                    sound.name
                );
                let difference = (level_db(&fresh) - level_db(&kept)).abs();
                assert!(
                    difference < 3.0,
                    "{}: level {difference} dB apart",
                    sound.name
                );
            } else {
                let fresh = wav_bytes(&render(&sound).unwrap());
                assert!(
                    fresh == bytes,
                    "{} differs from the generator's output; run `gloam generate sounds`",
                    path.display()
                );
            }
        }
    }

    #[test]
    fn the_kit_fits_in_five_megabytes_and_sources_lists_every_file() {
        let sources = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/SOURCES.md"),
        )
        .unwrap();
        let mut total = 0;
        for entry in std::fs::read_dir(committed()).unwrap() {
            let entry = entry.unwrap();
            total += entry.metadata().unwrap().len();
            let name = entry.file_name().to_string_lossy().into_owned();
            assert!(
                sounds().iter().any(|s| s.file_name() == name),
                "assets/sounds/{name} is made by nothing"
            );
        }
        assert!(total <= 5_000_000, "assets/sounds holds {total} bytes");
        let names = |list: Vec<&str>| list.join(",");
        let steps = format!(
            "`sounds/step-{{{}}}-{{{}}}-{{{}}}.wav`",
            names(Surface::ALL.iter().map(|s| s.name()).collect()),
            names(Gait::ALL.iter().map(|g| g.name()).collect()),
            (1..=STEP_VARIANTS)
                .map(|v| v.to_string())
                .collect::<Vec<_>>()
                .join(",")
        );
        assert!(
            sources.contains(&steps),
            "assets/SOURCES.md does not list {steps}"
        );
        for sound in sounds().iter().filter(|s| !s.name.starts_with("step-")) {
            let file = format!("`sounds/{}`", sound.file_name());
            assert!(
                sources.contains(&file),
                "assets/SOURCES.md does not list {file}"
            );
        }
    }

    #[test]
    fn loops_end_where_they_begin() {
        for sound in sounds().iter().filter(|s| s.looping) {
            let samples = render(sound).unwrap();
            let (first, last) = (samples[0] as f64, samples[samples.len() - 1] as f64);
            // The step across the seam is no bigger than the largest step inside the loop.
            let largest = samples
                .windows(2)
                .map(|w| (w[1] as f64 - w[0] as f64).abs())
                .fold(0.0, f64::max);
            assert!(
                (first - last).abs() <= largest,
                "{}: seam {first} -> {last}",
                sound.name
            );
        }
    }

    #[test]
    fn a_sprint_is_louder_and_brighter_than_a_walk_and_a_crouch_quieter() {
        // (level dB, brightness: the power of the first difference over the power, which
        // grows with the spectrum's centroid)
        let measured = |surface, gait| {
            let sound = sounds()
                .into_iter()
                .find(|s| s.name == footstep_name(surface, gait, 1))
                .unwrap();
            let samples: Vec<f64> = render(&sound).unwrap().iter().map(|&s| s as f64).collect();
            let power: f64 = samples.iter().map(|s| s * s).sum();
            let slope: f64 = samples.windows(2).map(|w| (w[1] - w[0]).powi(2)).sum();
            (level_db(&samples), slope / power)
        };
        for surface in Surface::ALL {
            let crouch = measured(surface, Gait::Crouch);
            let walk = measured(surface, Gait::Walk);
            let sprint = measured(surface, Gait::Sprint);
            let name = surface.name();
            assert!(
                crouch.0 + 6.0 < walk.0 && walk.0 + 3.0 < sprint.0,
                "{name} levels"
            );
            assert!(crouch.1 < walk.1 && walk.1 < sprint.1, "{name} brightness");
        }
    }

    #[test]
    fn the_kit_materials_sound_as_what_they_are() {
        let sounds_as = |name: &str, metallic: f32| {
            let mut material = crate::scene::model::Material::default();
            material.name = name.into();
            material.metallic = metallic;
            Surface::of(&material)
        };
        assert_eq!(sounds_as("floor tiles", 0.0), Surface::Stone);
        assert_eq!(sounds_as("plaster", 0.0), Surface::Stone);
        assert_eq!(sounds_as("dark wood", 0.0), Surface::Wood);
        assert_eq!(sounds_as("iron", 1.0), Surface::Iron);
        assert_eq!(sounds_as("mirror", 1.0), Surface::Iron);
        assert_eq!(sounds_as("banner cloth", 0.0), Surface::Cloth);
    }

    #[test]
    fn a_broken_wav_is_refused_with_its_reason() {
        assert_eq!(read_wav(b"OggS"), Err(WavError::NotWave));
        let mut bytes = wav_bytes(&[1, 2, 3]);
        assert_eq!(read_wav(&bytes).unwrap().1.len(), 3);
        bytes[20] = 3; // IEEE float
        assert!(matches!(
            read_wav(&bytes),
            Err(WavError::Unsupported { .. })
        ));
        assert_eq!(read_wav(&bytes[..30]), Err(WavError::Truncated(12)));
    }
}
