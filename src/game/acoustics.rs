//! Sound through the level, by rays through the simulation's own copy of it
//! (`WorldQuery`): how loud and how dull a sound made at one place is at a listener's ears,
//! from where it seems to come, and how the room around the ears rings. One function for
//! what the player hears and what a warden hears.
//!
//! - The direct path (`hear`): rays from the ears to points across the source. Every
//!   surface a ray passes costs its transmission loss (`Surface::transmission_db`, per
//!   face: a wall's two faces cost it twice), averaged over the rays as powers, and takes
//!   the highs with it: the cut-off falls a decade for every 30 dB lost. Distance costs
//!   6 dB per doubling past 1 m (a point source in the open).
//! - Around corners: when the direct path is blocked, the shortest walkable way between
//!   the two (`NavGrid::path`) carries the sound too, diffracted: its length attenuates as
//!   distance does, the opening it bends through costs `DIFFRACTION_DB`, and it arrives
//!   from the last point of the way the ears see (a warden behind a doorway is heard
//!   from the doorway). The louder of the two paths is what is heard.
//! - The room (`reverb`): `REVERB_RAYS` rays in a fixed spread around the ears give the
//!   mean free path between the surfaces they meet and the mean absorption (a ray out to
//!   the open sky absorbs all);
//!   Eyring's formula then gives the decay time, RT60 = 0.161 V / (-S ln(1 - a)) with
//!   V / S = l / 4 (Kuttruff, "Room Acoustics", 2009), and the reflected share of the
//!   energy its wet level.
//!
//! The same questions the renderer's shadow rays answer, asked of the same level: after
//! Steam Audio's occlusion and transmission, and Wwise's diffraction through portals.

use glam::Vec3;

use super::nav::NavGrid;
use super::world_query::{Surface, WorldQuery};

/// How a sound made at one place is heard at the ears.
#[derive(Clone, Debug, PartialEq)]
pub struct Heard {
    /// Level against the sound's own at 1 m, decibels.
    pub level_db: f32,
    /// Every direct ray met a surface.
    pub occluded: bool,
    /// The highest frequency that comes through, Hz.
    pub cutoff_hz: f32,
    /// Metres the sound travelled (straight, or along the way round).
    pub path_length: f32,
    /// Where it seems to come from: the source, or the last opening on the way round.
    pub arrival: Vec3,
}

/// How the room around the ears rings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reverb {
    /// Seconds for the reverberation to fall by 60 dB.
    pub decay_s: f32,
    /// The reverberation's level against the direct sound's, decibels.
    pub wet_db: f32,
    /// The mean distance the rays flew before meeting a surface, metres.
    pub mean_free_path: f32,
}

/// Acoustics in one place (decibels, metres, hertz).
pub mod tuning {
    /// The cut-off of an unobstructed sound.
    pub const OPEN_CUTOFF_HZ: f32 = 20_000.0;
    /// The lowest cut-off a blocked sound falls to.
    pub const LOWEST_CUTOFF_HZ: f32 = 250.0;
    /// Decibels of transmission loss per decade the cut-off falls.
    pub const LOSS_PER_DECADE_DB: f32 = 30.0;
    /// What the way round costs for bending through its opening (diffraction over an
    /// edge).
    pub const DIFFRACTION_DB: f32 = 6.0;
    /// How far above the place it is made a sound starts (feet, a floor, a fallen
    /// bottle), metres: the floor under a sound is no wall between it and the ears.
    pub const SOURCE_LIFT: f32 = 0.3;
    /// How far across the source the direct rays aim, metres.
    pub const SOURCE_RADIUS: f32 = 0.25;
    /// Rays cast around the ears for the room, and how far each looks.
    pub const REVERB_RAYS: usize = 64;
    pub const REVERB_REACH: f32 = 60.0;
    /// Surfaces a direct ray may pass before it counts as silent.
    pub const MAX_FACES: usize = 8;
}

use tuning::*;

impl Surface {
    /// Sound lost passing one face of this surface, decibels (a solid's two faces cost it
    /// twice): masonry about 45 dB through a wall, a wooden door about 25, iron sheet 20,
    /// cloth a little (after the mass law's figures for such walls, Kuttruff ch. 10).
    pub fn transmission_db(self) -> f32 {
        match self {
            Surface::Stone => 22.5,
            Surface::Wood => 12.5,
            Surface::Iron => 10.0,
            Surface::Cloth => 2.0,
        }
    }

    /// The share of sound energy the surface absorbs (the rest it reflects), at mid
    /// frequencies: bare stone and plaster about 2-3%, wood 10%, iron 5%, cloth 50%.
    pub fn absorption(self) -> f32 {
        match self {
            Surface::Stone => 0.03,
            Surface::Wood => 0.1,
            Surface::Iron => 0.05,
            Surface::Cloth => 0.5,
        }
    }
}

/// How a sound made at `source` is heard at `ears` (see the module doc): the direct path,
/// or the way round when it is louder. `nav`, when there is one, carries it round corners.
pub fn hear(world: &dyn WorldQuery, nav: Option<&NavGrid>, source: Vec3, ears: Vec3) -> Heard {
    let direct = hear_direct(world, source, ears);
    if !direct.occluded {
        return direct;
    }
    louder(
        direct,
        nav.and_then(|nav| way_round(world, nav, source, ears)),
    )
}

/// The louder of the direct path and the way round (when there is one).
pub fn louder(direct: Heard, round: Option<Heard>) -> Heard {
    match round {
        Some(round) if round.level_db > direct.level_db => round,
        _ => direct,
    }
}

/// The direct path alone: rays from the ears to the source and across it, through
/// whatever is between.
pub fn hear_direct(world: &dyn WorldQuery, source: Vec3, ears: Vec3) -> Heard {
    let distance = source.distance(ears);
    // The direct rays: to the source and to five points across it (none below: a source
    // is lifted off the floor it stands on by its caller, and the floor is no wall).
    let mut power = 0.0f32;
    let mut blocked = 0;
    let targets = std::iter::once(Vec3::ZERO)
        .chain([Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::Z, Vec3::NEG_Z])
        .map(|offset| source + offset * SOURCE_RADIUS);
    let mut rays = 0;
    for target in targets {
        rays += 1;
        let loss = transmission_db(world, ears, target);
        if loss > 0.0 {
            blocked += 1;
        }
        power += 10f32.powf(-loss / 10.0);
    }
    let loss = -10.0 * (power / rays as f32).max(1e-12).log10();
    Heard {
        level_db: distance_db(distance) - loss,
        occluded: blocked == rays,
        cutoff_hz: cutoff(loss),
        path_length: distance,
        arrival: source,
    }
}

/// The way round alone: along the shortest walkable way between the two, diffracted
/// through the last opening the ears see; `None` when no way joins them. The costly part
/// of hearing (a search over the navigation grid): a listener hearing many sources each
/// step keeps it while neither end has moved far (`audio::Hearing`).
pub fn way_round(world: &dyn WorldQuery, nav: &NavGrid, source: Vec3, ears: Vec3) -> Option<Heard> {
    let way = nav.path(ears, source)?;
    let mut points = vec![ears];
    points.extend(way.iter().map(|p| Vec3::new(p.x, source.y.max(p.y), p.z)));
    points.push(source);
    let length: f32 = points.windows(2).map(|w| w[0].distance(w[1])).sum();
    // The last point of the way the ears see: the opening the sound bends through.
    let seen = (1..points.len())
        .rev()
        .find(|&i| transmission_db(world, ears, points[i]) == 0.0)
        .unwrap_or(0);
    Some(Heard {
        level_db: distance_db(length) - DIFFRACTION_DB,
        occluded: true,
        // Diffraction bends the lows round an edge better than the highs.
        cutoff_hz: cutoff(DIFFRACTION_DB),
        path_length: length,
        arrival: points[seen.max(1)],
    })
}

/// How the room around `ears` rings (see the module doc): every one of its rays at once.
pub fn reverb(world: &dyn WorldQuery, ears: Vec3) -> Reverb {
    reverb_of((0..REVERB_RAYS).map(|ray| reverb_ray(world, ears, ray)))
}

/// The room's ray `ray` (0..`REVERB_RAYS`) from `ears`: how far it flew and how much the
/// surface it met absorbs, or `None` out into the open. A listener that hears every step
/// casts a few of them a step and keeps the rest (`reverb_of`).
pub fn reverb_ray(world: &dyn WorldQuery, ears: Vec3, ray: usize) -> Option<(f32, f32)> {
    world
        .raycast(ears, spread_direction(ray, REVERB_RAYS), REVERB_REACH)
        .map(|hit| (hit.distance, hit.surface.absorption()))
}

/// The room from its rays (see the module doc).
pub fn reverb_of(rays: impl Iterator<Item = Option<(f32, f32)>>) -> Reverb {
    let (mut flown, mut hits, mut absorbed, mut count) = (0.0f32, 0, 0.0f32, 0);
    for ray in rays {
        count += 1;
        match ray {
            Some((distance, absorption)) => {
                flown += distance;
                hits += 1;
                absorbed += absorption;
            }
            // Out into the open: the sound never comes back (it absorbs all, and adds no
            // length to the paths between reflections).
            None => absorbed += 1.0,
        }
    }
    if hits == 0 {
        return Reverb {
            decay_s: 0.0,
            wet_db: -120.0,
            mean_free_path: REVERB_REACH,
        };
    }
    let mean_free_path = flown / hits as f32;
    let absorption = (absorbed / count as f32).clamp(0.001, 0.999);
    // Eyring: RT60 = 0.161 V / (-S ln(1 - a)), V / S = l / 4.
    let decay_s = 0.161 * (mean_free_path / 4.0) / -(1.0 - absorption).ln();
    Reverb {
        decay_s,
        wet_db: 10.0 * (1.0 - absorption).log10(),
        mean_free_path,
    }
}

/// Decibels a point source falls by at `distance` against 1 m.
fn distance_db(distance: f32) -> f32 {
    -20.0 * distance.max(1.0).log10()
}

/// The cut-off after `loss` decibels of transmission.
fn cutoff(loss: f32) -> f32 {
    (OPEN_CUTOFF_HZ * 10f32.powf(-loss / LOSS_PER_DECADE_DB)).max(LOWEST_CUTOFF_HZ)
}

/// The transmission loss along the straight line from `from` to `to`: each face met on
/// the way costs its surface's loss.
fn transmission_db(world: &dyn WorldQuery, from: Vec3, to: Vec3) -> f32 {
    let mut at = from;
    let mut loss = 0.0;
    for _ in 0..MAX_FACES {
        let to_go = to - at;
        let length = to_go.length();
        if length < 1e-3 {
            return loss;
        }
        let direction = to_go / length;
        match world.raycast(at, direction, length) {
            Some(hit) => {
                loss += hit.surface.transmission_db();
                // On past the face, by a millimetre.
                at += direction * (hit.distance + 1e-3);
            }
            None => return loss,
        }
    }
    // Past MAX_FACES faces nothing comes through.
    loss + 120.0
}

/// Direction `index` of `count` spread evenly over the sphere (a Fibonacci lattice): the
/// same every call, so a replay's sound is the same on any machine.
fn spread_direction(index: usize, count: usize) -> Vec3 {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let y = 1.0 - 2.0 * (index as f32 + 0.5) / count as f32;
    let ring = (1.0 - y * y).sqrt();
    let angle = golden * index as f32;
    Vec3::new(ring * angle.cos(), y, ring * angle.sin())
}
