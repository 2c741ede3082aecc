//! The sound out: the mixer (`audio::Mixer`) the window plays and headless runs render,
//! the device's reader at another rate, sound files in the formats kira decodes, and a
//! replay's sound (`gloam play --headless --replay REC --audio OUT.wav`): the same bytes
//! on one and two threads, and audible.

mod common;

use std::process::Command as Process;
use std::sync::Arc;

use gloam::audio::device::Resampled;
use gloam::audio::{Bus, Clip, Command, Mix, Mixer, Stereo, Volumes, load_clip};
use gloam::game::acoustics::Reverb;
use gloam::scene::sound_kit::{RATE, read_wav};

/// One second of a 440 Hz tone with its odd harmonics (a bright sound), at -6 dBFS.
fn tone() -> Clip {
    (0..RATE as usize)
        .map(|i| {
            let t = i as f32 / RATE as f32;
            (1..8)
                .step_by(2)
                .map(|k| (std::f32::consts::TAU * 440.0 * k as f32 * t).sin() / k as f32)
                .sum::<f32>()
                * 0.4
        })
        .collect::<Arc<[f32]>>()
}

fn power(samples: &[f32]) -> f64 {
    samples.iter().map(|&s| f64::from(s).powi(2)).sum::<f64>() / samples.len().max(1) as f64
}

fn db(power: f64) -> f64 {
    10.0 * power.max(1e-20).log10()
}

/// The power-weighted mean frequency of `samples`' first 0.1 s, by a plain DFT over its
/// 10 Hz bins up to 10 kHz (enough to tell a dull sound from a bright one).
fn centroid(samples: &[f32]) -> f64 {
    let n = samples.len().min(4800);
    let (mut weighted, mut total) = (0.0, 0.0);
    for bin in 1..1000 {
        let f = bin as f64 * 10.0;
        let (mut re, mut im) = (0.0, 0.0);
        for (i, &s) in samples[..n].iter().enumerate() {
            let phase = std::f64::consts::TAU * f * i as f64 / f64::from(RATE);
            re += f64::from(s) * phase.cos();
            im += f64::from(s) * phase.sin();
        }
        let p = re * re + im * im;
        weighted += f * p;
        total += p;
    }
    weighted / total
}

fn play(mixer: &mut Mixer, voice: u64, looping: bool, mix: Mix) {
    mixer.apply(Command::Play {
        voice,
        clip: tone(),
        looping,
        bus: Bus::Effects,
        mix,
    });
}

#[test]
fn a_voice_is_heard_where_it_arrives_from_and_as_dull_as_its_cut_off() {
    let mut mixer = Mixer::new();
    let right = Mix {
        gain_db: 0.0,
        cutoff_hz: 20_000.0,
        pan: (0.2, 0.98),
    };
    play(&mut mixer, 1, false, right);
    let mut out = Stereo::default();
    out.record(&mut mixer, 9600);
    let (left, right_ear) = (db(power(&out.left)), db(power(&out.right)));
    assert!(
        right_ear - left > 10.0,
        "a sound from the right: left {left:.1} dB, right {right_ear:.1} dB"
    );

    let heard = |cutoff_hz: f32| {
        let mut mixer = Mixer::new();
        play(
            &mut mixer,
            1,
            false,
            Mix::centred(0.0).with_cutoff(cutoff_hz),
        );
        let mut out = Stereo::default();
        out.record(&mut mixer, 9600);
        (db(power(&out.left)), centroid(&out.left[4800..]))
    };
    let (open, bright) = heard(20_000.0);
    let (muffled, dull) = heard(600.0);
    assert!(
        dull < bright * 0.8 && muffled < open,
        "open: {open:.1} dB, centroid {bright:.0} Hz; behind a wall: {muffled:.1} dB, {dull:.0} Hz"
    );
}

#[test]
fn one_shots_end_loops_go_on_pause_holds_and_a_level_left_stops_its_loops() {
    let mut mixer = Mixer::new();
    play(&mut mixer, 1, false, Mix::centred(0.0));
    play(&mut mixer, 2, true, Mix::centred(0.0));
    let mut out = Stereo::default();
    out.record(&mut mixer, RATE as usize + 100);
    assert_eq!(mixer.voices(), 1, "the one-shot ended after its second");

    mixer.apply(Command::Pause(true));
    let mut held = Stereo::default();
    held.record(&mut mixer, 4800);
    assert!(held.rms_dbfs() < -119.0, "paused: {} dBFS", held.rms_dbfs());
    mixer.apply(Command::Pause(false));
    let mut resumed = Stereo::default();
    resumed.record(&mut mixer, 4800);
    assert!(
        resumed.rms_dbfs() > -30.0,
        "resumed: {} dBFS",
        resumed.rms_dbfs()
    );

    // Leaving a level: its loop stops, a one-shot started just before rings out.
    play(&mut mixer, 3, false, Mix::centred(0.0));
    mixer.apply(Command::Clear);
    assert_eq!(mixer.voices(), 1);

    // The volumes: the effects bus at a tenth is 20 dB down; master at 0 is silence.
    let level = |volumes: Volumes| {
        let mut mixer = Mixer::new();
        mixer.apply(Command::Volumes(volumes));
        play(&mut mixer, 1, true, Mix::centred(0.0));
        let mut out = Stereo::default();
        out.record(&mut mixer, 4800);
        out.rms_dbfs()
    };
    let full = level(Volumes::default());
    let tenth = level(Volumes {
        effects: 0.1,
        ..Volumes::default()
    });
    assert!((full - tenth - 20.0).abs() < 0.5, "{full} against {tenth}");
    let muted = level(Volumes {
        master: 0.0,
        ..Volumes::default()
    });
    assert!(muted < -119.0, "{muted}");
}

#[test]
fn a_room_rings_on_after_the_sound_stops_for_its_decay() {
    let tail = |decay_s: f32| {
        let mut mixer = Mixer::new();
        mixer.apply(Command::Room(Reverb {
            decay_s,
            wet_db: -1.0,
            mean_free_path: 5.0,
        }));
        mixer.apply(Command::Play {
            voice: 1,
            clip: tone()[..4800].iter().copied().collect(),
            looping: false,
            bus: Bus::Effects,
            mix: Mix::centred(0.0),
        });
        let mut out = Stereo::default();
        out.record(&mut mixer, 4800 + 24_000);
        // From 0.2 s to 0.5 s after the sound ended.
        db(power(&out.left[4800 + 9600..4800 + 24_000]))
    };
    let (hall, cellar) = (tail(2.5), tail(0.3));
    assert!(
        hall > cellar + 20.0,
        "a 2.5 s hall's tail {hall:.1} dB, a 0.3 s cellar's {cellar:.1} dB"
    );
}

#[test]
fn the_device_reader_plays_the_mixer_at_any_rate() {
    let mixed = |mixer: &mut Mixer| {
        play(mixer, 1, true, Mix::centred(-6.0));
    };
    let mut reference = Mixer::new();
    mixed(&mut reference);
    let mut out = Stereo::default();
    out.record(&mut reference, 2000);

    // At the mixer's own rate: its samples, one late.
    let mut same = Mixer::new();
    mixed(&mut same);
    let mut reader = Resampled::new(same);
    let read: Vec<(f32, f32)> = (0..2000).map(|_| reader.next(1.0)).collect();
    assert_eq!(read[0], (0.0, 0.0));
    for i in 1..2000 {
        assert_eq!(read[i], (out.left[i - 1], out.right[i - 1]), "frame {i}");
    }

    // At 44.1 kHz: as loud, and a second of it is a second of the mixer's.
    let mut other = Mixer::new();
    mixed(&mut other);
    let mut reader = Resampled::new(other);
    let step = f64::from(RATE) / 44_100.0;
    let read: Vec<f32> = (0..44_100).map(|_| reader.next(step).0).collect();
    let mut second = Stereo::default();
    let mut again = Mixer::new();
    mixed(&mut again);
    second.record(&mut again, RATE as usize);
    let (resampled, native) = (db(power(&read)), db(power(&second.left)));
    assert!(
        (resampled - native).abs() < 0.3,
        "44.1 kHz {resampled:.2} dB against 48 kHz {native:.2} dB"
    );
}

/// A level's sound may be FLAC, Ogg Vorbis or MP3 as well as WAV: the kit's lamp hum
/// converted by sox reads as the same sound (its length and level).
#[test]
fn sound_files_read_in_every_format_a_level_may_name() {
    let wav = common::repo().join("assets/sounds/lamp-hum.wav");
    let reference = load_clip(&wav).unwrap();
    let dir = common::scratch_dir("audio-formats");
    for format in ["flac", "ogg"] {
        let converted = dir.join(format!("lamp-hum.{format}"));
        let status = Process::new("sox").arg(&wav).arg(&converted).status();
        if !status.is_ok_and(|s| s.success()) {
            println!("skipped: sox is not installed to convert a WAV to {format}");
            return;
        }
        let clip = load_clip(&converted).unwrap_or_else(|error| panic!("{error:#}"));
        let frames = (clip.len() as f64 - reference.len() as f64).abs();
        assert!(
            frames < 0.01 * reference.len() as f64 + 2048.0,
            "{format}: {} samples against {}",
            clip.len(),
            reference.len()
        );
        let (a, b) = (db(power(&clip)), db(power(&reference)));
        assert!((a - b).abs() < 0.5, "{format}: {a:.2} dB against {b:.2} dB");
    }
    let broken = dir.join("broken.ogg");
    std::fs::write(&broken, b"OggS but not really").unwrap();
    let error = format!("{:#}", load_clip(&broken).unwrap_err());
    assert!(error.contains("broken.ogg"), "{error}");
}

/// The whole run's sound, as the player heard it: the same bytes on one and two threads,
/// audible, and a WAV of the run's length.
#[test]
fn a_replays_sound_is_the_same_on_any_thread_count_and_audible() {
    let dir = common::scratch_dir("replay-audio");
    let recording = common::repo().join("tests/recordings/first-light-won.json");
    let render = |threads: &str| {
        let out = dir.join(format!("run-{threads}.wav"));
        let status = Process::new(env!("CARGO_BIN_EXE_gloam"))
            .args(["play", "--headless", "--replay"])
            .arg(&recording)
            .arg("--audio")
            .arg(&out)
            .args(["--threads", threads])
            .status()
            .unwrap();
        assert!(status.success());
        std::fs::read(&out).unwrap()
    };
    let (one, two) = (render("1"), render("2"));
    assert!(one == two, "the WAVs differ between 1 and 2 threads");
    let (rate, samples) = read_wav(&one).unwrap();
    assert_eq!(rate, RATE);
    let seconds = samples.len() as f64 / f64::from(RATE);
    let rms = 10.0 * (samples.iter().map(|s| s * s).sum::<f64>() / samples.len() as f64).log10();
    println!("first-light-won: {seconds:.1} s of sound at {rms:.1} dBFS RMS");
    assert!(seconds > 60.0, "{seconds} s");
    assert!(rms > -50.0, "{rms} dBFS");
}

/// A shipped level's ears at the start: the wind's bed and the tension layers (silent)
/// start, every lamp hums where it hangs; a doused lamp's hum falls silent.
#[test]
fn the_first_levels_lamps_hum_until_doused_and_its_wind_blows() {
    use bevy_ecs::prelude::{Entity, Name};
    use gloam::audio::Hearing;
    use gloam::frame::Engine;
    use gloam::game::{SoundSource, SwitchedOff, spawn_player};
    use gloam::render::RenderSettings;

    let level = common::repo().join("levels/first-light.ron");
    let scene = gloam::scene::Scene::load(&level).unwrap();
    let mut engine = Engine::new(&scene, RenderSettings::real_time(8, 8));
    spawn_player(&mut engine.world).unwrap();
    engine.hearing = Some(Hearing::for_level(&level));
    engine.step();
    let started = engine.hearing.as_mut().unwrap().take();
    let plays: Vec<(u64, Bus, bool, f32)> = started
        .iter()
        .filter_map(|command| match command {
            Command::Play {
                voice,
                bus,
                looping,
                mix,
                ..
            } => Some((*voice, *bus, *looping, mix.gain_db)),
            _ => None,
        })
        .collect();
    let sources = engine
        .world
        .query::<&SoundSource>()
        .iter(&engine.world)
        .count();
    assert_eq!(sources, 5, "first-light's five lamps hum");
    let effects = plays.iter().filter(|p| p.1 == Bus::Effects && p.2).count();
    let ambience = plays.iter().filter(|p| p.1 == Bus::Ambience).count();
    assert_eq!((effects, ambience), (5, 3), "{plays:?}");
    // The hall's lamps are heard from the start (about 5 m off, -14 dB and the walls).
    assert!(
        plays
            .iter()
            .any(|p| p.1 == Bus::Effects && p.3 > -30.0 && p.3 < 0.0),
        "{plays:?}"
    );

    let lamp: Entity = engine
        .world
        .query::<(Entity, &Name, &SoundSource)>()
        .iter(&engine.world)
        .find(|(_, name, _)| name.as_str() == "cellar lamp")
        .map(|(entity, _, _)| entity)
        .unwrap();
    let silent = |engine: &mut Engine| {
        engine.step();
        let commands = engine.hearing.as_mut().unwrap().take();
        commands
            .iter()
            .filter(|command| matches!(command, Command::Set { mix, .. } if mix.gain_db < -100.0))
            .count()
    };
    // A lamp far behind many walls may be all but silent already.
    let before = silent(&mut engine);
    engine.world.entity_mut(lamp).insert(SwitchedOff);
    let after = silent(&mut engine);
    assert_eq!(
        after,
        before + 1,
        "the doused lamp's hum, alone, falls silent"
    );
}
