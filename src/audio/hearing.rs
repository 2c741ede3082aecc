//! Frame line, after each fixed step (`Stage::Audio`): what the player's ears hear of the
//! step, as the mixer's commands. Owns the clips (read once, by path), which voice plays
//! which source, the room's rays spread over steps, and the tension under play.
//!
//! Per step, with the ears at the player's eye, facing the way the player does:
//! 1. every sound the step made (`game::SoundEvents`) starts as a one-shot where it was
//!    made, heard through the level (`game::acoustics`: the walls between, the way
//!    round), a warden's words on the voices bus;
//! 2. every looping sound source in the level (`game::SoundSource`) is heard the same
//!    way: started the first time, moved after (its mix glides across the next block).
//!    Its way round (a search of the navigation grid, the costly part) is kept while
//!    neither end leaves its metre; at most `WAYS_ROUND_PER_STEP` searches run a step,
//!    the events' first, then the stalest sources';
//! 3. `ROOM_RAYS_PER_STEP` of the room's rays (`acoustics::reverb_ray`), so the whole
//!    room is asked every `REVERB_RAYS / ROOM_RAYS_PER_STEP` steps and its decay and wet
//!    level follow the ears from room to room;
//! 4. the level's ambience bed, and the tension: a low layer while a warden is curious or
//!    searching, a high one while one is alerted, each fading in and out over about a
//!    second.
//!
//! Nothing here reads a clock or depends on the thread count: a replay's commands, and
//! so its sound, are the same on any machine.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use bevy_ecs::prelude::*;
use glam::Vec3;

use super::mixer::{Bus, Clip, Command, Mix};
use crate::game::acoustics::tuning::{REVERB_RAYS, SOURCE_LIFT};
use crate::game::acoustics::{hear_direct, louder, reverb_of, reverb_ray, way_round};
use crate::game::{
    GlobalTransform, LevelInfo, NavGrid, Player, PlayerEye, SoundEvents, SoundMaker, SoundSource,
    SwitchedOff, ViewCamera, Warden, WardenState, WorldGeometry,
};
use crate::scene::sound_kit::{RATE, read_wav, resample};

/// Room rays cast each step.
pub const ROOM_RAYS_PER_STEP: usize = 8;
/// A voice held silent (a switched-off source, a tension layer at rest), decibels.
const SILENT_DB: f32 = -120.0;
/// A sound heard quieter than this against its level at 1 m is not started, decibels.
const INAUDIBLE_DB: f32 = -80.0;
/// The tension layers' level at full, decibels, and how fast they fade (the share of the
/// way to their target covered each step: about a second).
const TENSION_DB: f32 = -8.0;
const TENSION_FADE: f32 = 1.0 / 60.0;

/// The searches for a way round each step at most, the step's events first. A search of
/// the navigation grid costs up to about 0.8 ms across the keep: 32 sources searched
/// every step took 8.5 ms a step (p50); one search a step holds 32 sources to 0.18 ms
/// p50 and 0.95 ms p99, and a source's way round is at most 32 steps old. An event past
/// it is heard by its direct path alone.
const WAYS_ROUND_PER_STEP: usize = 1;

/// A source's way round to the ears, found when the two stood in the metres of `key`.
struct WayRound {
    key: (glam::IVec3, glam::IVec3),
    found_at: u64,
    heard: Option<crate::game::acoustics::Heard>,
}

/// The metre cell a point lies in: a way round is kept while both ends stay in theirs.
fn metre(at: Vec3) -> glam::IVec3 {
    at.floor().as_ivec3()
}

/// The listener's hearing, step by step (see the module doc).
pub struct Hearing {
    /// The sound kit's folder (`assets/sounds`): the events' files.
    kit: PathBuf,
    /// The level file's folder: its sources' paths are relative to it.
    level_folder: PathBuf,
    clips: BTreeMap<PathBuf, Option<Clip>>,
    /// Each looping source's voice.
    sources: BTreeMap<Entity, u64>,
    /// Each source's way round, as last found.
    ways_round: BTreeMap<Entity, WayRound>,
    /// Steps heard.
    steps: u64,
    started: bool,
    next_voice: u64,
    room: [Option<(f32, f32)>; REVERB_RAYS],
    next_ray: usize,
    /// The tension layers' voices and their levels now (linear, 0..1).
    tension: [(u64, f32); 2],
    commands: Vec<Command>,
    /// Files that would not read, each said once.
    pub warnings: Vec<String>,
}

impl Hearing {
    /// Hearing for the level loaded from `level`, the sound kit in `kit`.
    pub fn new(level: &Path, kit: PathBuf) -> Hearing {
        Hearing {
            kit,
            level_folder: level.parent().unwrap_or(Path::new(".")).to_owned(),
            clips: BTreeMap::new(),
            sources: BTreeMap::new(),
            ways_round: BTreeMap::new(),
            steps: 0,
            started: false,
            next_voice: 1,
            room: [None; REVERB_RAYS],
            next_ray: 0,
            tension: [(0, 0.0); 2],
            commands: Vec::new(),
            warnings: Vec::new(),
        }
    }

    /// Hearing for the level loaded from `level`, with the project's sound kit
    /// (`assets/sounds` beside its levels folder, `scene::files::assets_folder`).
    pub fn for_level(level: &Path) -> Hearing {
        let mut hearing = Hearing::new(
            level,
            crate::scene::files::assets_folder(level).join("sounds"),
        );
        hearing.read_kit();
        hearing
    }

    /// Reads every file of the sound kit now, as the level loads, so no step waits on a
    /// file the first time a sound is made (about 4 MB, read once).
    pub fn read_kit(&mut self) {
        let Ok(entries) = std::fs::read_dir(&self.kit) else {
            return;
        };
        let mut files: Vec<PathBuf> = entries
            .filter_map(|entry| entry.ok().map(|entry| entry.path()))
            .filter(|path| path.extension().is_some_and(|ext| ext == "wav"))
            .collect();
        files.sort();
        for file in files {
            self.clip(&file);
        }
    }

    /// The commands of every step since the last call, in order.
    pub fn take(&mut self) -> Vec<Command> {
        std::mem::take(&mut self.commands)
    }

    fn voice(&mut self) -> u64 {
        self.next_voice += 1;
        self.next_voice
    }

    /// The clip at `path`, read the first time it is asked for (`None`, said once in
    /// `warnings`, when it will not read).
    fn clip(&mut self, path: &Path) -> Option<Clip> {
        if let Some(clip) = self.clips.get(path) {
            return clip.clone();
        }
        let clip = match load_clip(path) {
            Ok(clip) => Some(clip),
            Err(error) => {
                self.warnings.push(format!("{error:#}"));
                None
            }
        };
        self.clips.insert(path.to_owned(), clip.clone());
        clip
    }

    /// One fixed step's hearing (see the module doc).
    pub fn step(&mut self, world: &mut World) {
        let Some((ears, yaw)) = listener(world) else {
            return;
        };
        if !self.started {
            self.start(world);
        }
        let mut sources =
            world.query::<(Entity, &SoundSource, &GlobalTransform, Has<SwitchedOff>)>();
        // A switched-off source (a doused lamp's hum) is silent until it is on again.
        let placed: Vec<(Entity, crate::scene::level::SoundDef, Vec3, bool)> = sources
            .iter(world)
            .map(|(entity, source, at, off)| {
                (entity, source.0.clone(), at.0.translation.into(), off)
            })
            .collect();
        let mut wardens = world.query::<&Warden>();
        let alarm = wardens
            .iter(world)
            .map(|warden| match warden.state {
                WardenState::Patrol => 0,
                WardenState::Suspicious | WardenState::Searching => 1,
                WardenState::Alert | WardenState::Caught => 2,
            })
            .max()
            .unwrap_or(0);
        let Some(geometry) = world.get_resource::<WorldGeometry>() else {
            return;
        };
        let geometry = geometry.0.as_ref();
        let nav = world.get_resource::<NavGrid>();
        let events = world
            .get_resource::<SoundEvents>()
            .map_or(&[][..], |sounds| sounds.events.as_slice());

        // 1. The step's events, first to the searches for a way round (each is heard once).
        let mut searches = 0;
        for event in events {
            let at = event.at + Vec3::Y * SOURCE_LIFT;
            let direct = hear_direct(geometry, at, ears);
            let heard = match nav {
                Some(nav) if direct.occluded && searches < WAYS_ROUND_PER_STEP => {
                    searches += 1;
                    louder(direct, way_round(geometry, nav, at, ears))
                }
                _ => direct,
            };
            if heard.level_db + event.gain_db < INAUDIBLE_DB {
                continue;
            }
            let path = self.kit.join(format!("{}.wav", event.sound));
            let Some(clip) = self.clip(&path) else {
                continue;
            };
            let bus = match event.by {
                SoundMaker::Warden(_) if is_word(&event.sound) => Bus::Voices,
                _ => Bus::Effects,
            };
            let voice = self.voice();
            self.commands.push(Command::Play {
                voice,
                clip,
                looping: false,
                bus,
                mix: Mix::heard(&heard, event.gain_db, (ears, yaw)),
            });
        }
        // A source gone from the level (despawned) stops.
        let gone: Vec<Entity> = self
            .sources
            .keys()
            .filter(|entity| placed.iter().all(|(e, ..)| e != *entity))
            .copied()
            .collect();
        for entity in gone {
            if let Some(voice) = self.sources.remove(&entity) {
                self.commands.push(Command::Stop { voice });
            }
            self.ways_round.remove(&entity);
        }
        // 2. The level's sources: the direct path every step, the way round kept while
        // neither end leaves its metre (the stalest found again, as the searches left
        // allow).
        let mut stale: Vec<(u64, Entity)> = Vec::new();
        for (entity, _, at, _) in &placed {
            let key = (metre(ears), metre(*at));
            match self.ways_round.get(entity) {
                Some(way) if way.key == key => {}
                Some(way) => stale.push((way.found_at, *entity)),
                None => stale.push((0, *entity)),
            }
        }
        stale.sort();
        stale.truncate(WAYS_ROUND_PER_STEP - searches);
        for (entity, def, at, off) in placed {
            let direct = hear_direct(geometry, at, ears);
            let heard = if direct.occluded {
                let refresh = stale.iter().any(|&(_, e)| e == entity);
                if refresh && let Some(nav) = nav {
                    self.ways_round.insert(
                        entity,
                        WayRound {
                            key: (metre(ears), metre(at)),
                            found_at: self.steps,
                            heard: way_round(geometry, nav, at, ears),
                        },
                    );
                }
                let round = self
                    .ways_round
                    .get(&entity)
                    .and_then(|way| way.heard.clone());
                louder(direct, round)
            } else {
                direct
            };
            let gain_db = if off { SILENT_DB } else { def.gain_db };
            let mix = Mix::heard(&heard, gain_db, (ears, yaw));
            match self.sources.get(&entity) {
                Some(&voice) => self.commands.push(Command::Set { voice, mix }),
                None => {
                    let voice = self.voice();
                    self.sources.insert(entity, voice);
                    let path = self.level_folder.join(&def.asset);
                    if let Some(clip) = self.clip(&path) {
                        self.commands.push(Command::Play {
                            voice,
                            clip,
                            looping: def.looping,
                            bus: Bus::Effects,
                            mix,
                        });
                    }
                }
            }
        }
        self.steps += 1;
        // 3. The room, a few rays a step.
        for _ in 0..ROOM_RAYS_PER_STEP {
            let ray = self.next_ray % REVERB_RAYS;
            self.room[ray] = reverb_ray(geometry, ears, ray);
            self.next_ray += 1;
        }
        if self.next_ray >= REVERB_RAYS {
            let asked = self.next_ray.min(REVERB_RAYS);
            self.commands
                .push(Command::Room(reverb_of(self.room[..asked].iter().copied())));
        }
        // 4. The tension.
        for (layer, (voice, level)) in self.tension.iter_mut().enumerate() {
            let target = if alarm == layer + 1 { 1.0 } else { 0.0 };
            if *level == target {
                continue;
            }
            let mut moved = *level + (target - *level) * TENSION_FADE;
            if (moved - target).abs() < 1e-3 {
                moved = target;
            }
            *level = moved;
            let gain_db = if moved > 0.0 {
                TENSION_DB + 20.0 * moved.log10()
            } else {
                SILENT_DB
            };
            self.commands.push(Command::Set {
                voice: *voice,
                mix: Mix::centred(gain_db),
            });
        }
    }

    /// The first step: the level's ambience bed and the tension layers (silent until a
    /// warden stirs).
    fn start(&mut self, world: &World) {
        self.started = true;
        let bed = world
            .get_resource::<LevelInfo>()
            .and_then(|info| info.environment.ambience.clone());
        if let Some(bed) = bed {
            let path = self.level_folder.join(&bed.asset);
            if let Some(clip) = self.clip(&path) {
                let voice = self.voice();
                self.commands.push(Command::Play {
                    voice,
                    clip,
                    looping: true,
                    bus: Bus::Ambience,
                    mix: Mix::centred(bed.gain_db),
                });
            }
        }
        for (layer, name) in ["tension-low", "tension-high"].into_iter().enumerate() {
            let path = self.kit.join(format!("{name}.wav"));
            let voice = self.voice();
            self.tension[layer] = (voice, 0.0);
            if let Some(clip) = self.clip(&path) {
                self.commands.push(Command::Play {
                    voice,
                    clip,
                    looping: true,
                    bus: Bus::Ambience,
                    mix: Mix::centred(SILENT_DB),
                });
            }
        }
    }
}

/// Where the ears are and which way they face (radians about +Y, 0 looking down -Z): the
/// player's eye, else the view's camera (a level with no player, as `bench` flies it).
fn listener(world: &mut World) -> Option<(Vec3, f32)> {
    let mut eyes = world.query_filtered::<&GlobalTransform, With<PlayerEye>>();
    if let Some(eye) = eyes.iter(world).next() {
        let ears = Vec3::from(eye.0.translation);
        let mut players = world.query::<&Player>();
        let yaw = players.iter(world).next().map_or(0.0, |player| player.yaw);
        return Some((ears, yaw));
    }
    let mut views = world.query_filtered::<&GlobalTransform, With<ViewCamera>>();
    let view = views.iter(world).next()?;
    let forward = view.0.transform_vector3(Vec3::NEG_Z);
    Some((view.0.translation.into(), (-forward.x).atan2(-forward.z)))
}

/// A warden's spoken cue (its words, on the voices bus), not its boots or armour.
fn is_word(sound: &str) -> bool {
    !(sound.starts_with("warden-step") || sound == "warden-armour")
}

/// Reads a sound file as a clip: WAV by the sound kit's own reader, any other format kira
/// reads (FLAC, Ogg Vorbis, MP3) by kira's decoder; channels mixed down, resampled to
/// `RATE`.
pub fn load_clip(path: &Path) -> anyhow::Result<Clip> {
    let bytes = std::fs::read(path)
        .map_err(|error| anyhow::anyhow!("cannot read sound '{}': {error}", path.display()))?;
    let (rate, samples): (u32, Vec<f64>) = match read_wav(&bytes) {
        Ok(read) => read,
        Err(_) => {
            let decoded = kira::sound::static_sound::StaticSoundData::from_cursor(
                std::io::Cursor::new(bytes),
            )
            .map_err(|error| {
                anyhow::anyhow!("sound '{}' does not decode: {error}", path.display())
            })?;
            let mono = decoded
                .frames
                .iter()
                .map(|frame| f64::from(frame.left + frame.right) * 0.5)
                .collect();
            (decoded.sample_rate, mono)
        }
    };
    let samples = if rate == RATE {
        samples
    } else {
        resample(&samples, rate, RATE)
    };
    Ok(samples.iter().map(|&s| s as f32).collect::<Arc<[f32]>>())
}
