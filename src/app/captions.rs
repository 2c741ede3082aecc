//! Present, over the frame: captions for the sounds that matter to play, with where each
//! comes from as the player stands and faces ("a warden's footsteps, behind you"), for
//! the sounds the player hears through the level (`game::acoustics`). Each
//! frame takes the simulation's sound events (`game::SoundEvents::take`, every step since
//! the last frame); a caption shows for `SHOWN_SECONDS`, the same words again refresh it
//! rather than stack, and the newest `MAX_LINES` are drawn. On by default; Settings turns
//! them off.

use glam::Vec3;

use crate::game::SoundEvent;

/// How long a caption stays, seconds of play.
pub const SHOWN_SECONDS: f64 = 3.0;
/// The most captions shown at once (the newest).
pub const MAX_LINES: usize = 3;

/// The captions on screen, each with the play time it was last heard.
#[derive(Default, Debug)]
pub struct Captions {
    lines: Vec<(String, f64)>,
}

impl Captions {
    /// Takes in `events` heard at `now` (seconds of play) by a listener at `ear` facing
    /// `yaw` (radians about +Y, 0 looking down -Z). `heard_db` says how loud a sound made
    /// at a point is at the ears against its level at 1 m (`game::acoustics::hear`: walls
    /// muffle, doorways let through); a caption shows a sound heard at least as loud as it
    /// would be `caption.within` metres away in the open.
    pub fn hear(
        &mut self,
        events: &[SoundEvent],
        (ear, yaw): (Vec3, f32),
        now: f64,
        heard_db: impl Fn(Vec3) -> f32,
    ) {
        for event in events {
            let within = event.caption.within;
            if within <= 0.0 || event.at.distance(ear) > 4.0 * within {
                continue;
            }
            let quietest = -20.0 * within.max(1.0).log10();
            if heard_db(event.at) + event.gain_db < quietest {
                continue;
            }
            let line = format!("{}, {}", event.caption.text, direction(ear, yaw, event.at));
            self.lines.retain(|(shown, _)| *shown != line);
            self.lines.push((line, now));
        }
        self.lines.retain(|(_, heard)| now - heard < SHOWN_SECONDS);
    }

    /// The lines to draw, oldest first.
    pub fn lines(&self) -> impl Iterator<Item = &str> {
        let skip = self.lines.len().saturating_sub(MAX_LINES);
        self.lines.iter().skip(skip).map(|(line, _)| line.as_str())
    }

    pub fn clear(&mut self) {
        self.lines.clear();
    }
}

/// Where `at` lies for a listener at `ear` facing `yaw`: above or below when it is more
/// than 2.5 m up or down and no further away across, else ahead, right, behind you or
/// left (quarters about the facing).
pub fn direction(ear: Vec3, yaw: f32, at: Vec3) -> &'static str {
    let to = at - ear;
    let across = Vec3::new(to.x, 0.0, to.z);
    if to.y.abs() > 2.5 && to.y.abs() > across.length() {
        return if to.y > 0.0 { "above" } else { "below" };
    }
    if across.length() < 0.5 {
        return "close by";
    }
    let forward = Vec3::new(-yaw.sin(), 0.0, -yaw.cos());
    let right = Vec3::new(yaw.cos(), 0.0, -yaw.sin());
    let (ahead, side) = (across.dot(forward), across.dot(right));
    if ahead.abs() >= side.abs() {
        if ahead >= 0.0 { "ahead" } else { "behind you" }
    } else if side > 0.0 {
        "right"
    } else {
        "left"
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::game::sound_events::{Caption, SoundMaker};

    fn event(at: Vec3, text: &'static str, within: f32) -> SoundEvent {
        SoundEvent {
            sound: "warden-step-1".into(),
            at,
            gain_db: 0.0,
            by: SoundMaker::Warden("warden 1".into()),
            caption: Caption { text, within },
        }
    }

    #[test]
    fn directions_follow_the_facing() {
        let ear = Vec3::new(0.0, 1.6, 0.0);
        // Facing -Z (yaw 0): -Z is ahead, +X right, +Z behind, -X left.
        assert_eq!(direction(ear, 0.0, Vec3::new(0.0, 0.0, -5.0)), "ahead");
        assert_eq!(direction(ear, 0.0, Vec3::new(5.0, 0.0, 0.0)), "right");
        assert_eq!(direction(ear, 0.0, Vec3::new(0.0, 0.0, 5.0)), "behind you");
        assert_eq!(direction(ear, 0.0, Vec3::new(-5.0, 0.0, 0.0)), "left");
        // Turned a quarter left (yaw +90 degrees): -X is ahead now.
        let left = std::f32::consts::FRAC_PI_2;
        assert_eq!(direction(ear, left, Vec3::new(-5.0, 0.0, 0.0)), "ahead");
        assert_eq!(direction(ear, left, Vec3::new(0.0, 0.0, -5.0)), "right");
        assert_eq!(direction(ear, 0.0, Vec3::new(1.0, 6.0, 0.0)), "above");
        assert_eq!(direction(ear, 0.0, Vec3::new(0.0, -3.0, 0.5)), "below");
    }

    #[test]
    fn captions_show_what_is_near_refresh_and_fade() {
        let mut captions = Captions::default();
        let ear = Vec3::new(0.0, 1.6, 0.0);
        let steps = event(Vec3::new(0.0, 0.0, 6.0), "a warden's footsteps", 12.0);
        let far = event(Vec3::new(0.0, 0.0, -40.0), "a warden's footsteps", 12.0);
        let own = event(Vec3::new(0.0, 0.0, 1.0), "footsteps", 0.0);
        let open = |at: Vec3| -20.0 * at.distance(ear).max(1.0).log10();
        captions.hear(&[steps.clone(), far, own], (ear, 0.0), 10.0, open);
        assert_eq!(
            captions.lines().collect::<Vec<_>>(),
            ["a warden's footsteps, behind you"]
        );
        // The same words again refresh the line instead of stacking it.
        captions.hear(&[steps.clone()], (ear, 0.0), 12.0, open);
        assert_eq!(captions.lines().count(), 1);
        captions.hear(&[], (ear, 0.0), 14.5, open);
        assert_eq!(captions.lines().count(), 1, "heard again at 12 s");
        captions.hear(&[], (ear, 0.0), 15.1, open);
        assert_eq!(captions.lines().count(), 0, "gone 3 s after");
        // Only the newest lines are drawn.
        let around = [(6.0, 0.0), (-6.0, 0.0), (0.0, -6.0), (0.0, 6.0)];
        let many: Vec<SoundEvent> = around
            .iter()
            .map(|&(x, z)| event(Vec3::new(x, 0.0, z), "a lamp goes out", 12.0))
            .collect();
        captions.hear(&many, (ear, 0.0), 20.0, open);
        assert_eq!(
            captions.lines().collect::<Vec<_>>(),
            [
                "a lamp goes out, left",
                "a lamp goes out, ahead",
                "a lamp goes out, behind you"
            ]
        );
        // Behind a wall that takes 45 dB, the same footsteps are not heard.
        captions.clear();
        let walled = |at: Vec3| open(at) - 45.0;
        captions.hear(&[steps], (ear, 0.0), 30.0, walled);
        assert_eq!(captions.lines().count(), 0);
    }
}
