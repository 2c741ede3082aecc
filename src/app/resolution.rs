//! Frame step `present`'s partner: adaptive internal resolution. The shell feeds it each
//! frame's time; it moves the render's resolution one step down a fixed ladder when frames
//! run over the target, and one step up when the frames, scaled by the pixel count of the
//! step above, would still fit with room to spare. The gap between the two thresholds and
//! a cool-down after every change are the hysteresis: a frame time between them changes
//! nothing, so the resolution does not flicker.
//!
//! On the first run (no settings file yet) the target itself is chosen from a short
//! measurement (`FirstRunProbe`, `first_run_target`): the first frames are rendered at the
//! full configured resolution and timed, and the target is the shortest this machine holds
//! without giving up much of the image.

use super::settings::{DEFAULT_TARGET_MS, ranges::FRAME_TIME_TARGETS};

/// The ladder of scales (per axis) of the configured resolution.
pub const SCALES: [f32; 6] = [1.0, 0.85, 0.7, 0.6, 0.5, 0.4];

/// Frames in the window whose median decides, and frames to wait after a change.
const WINDOW: usize = 15;

/// Step down when the median frame is over the target by this factor.
const OVER: f64 = 1.1;
/// Step up when the next step's predicted frame is under the target by this factor.
const UNDER: f64 = 0.85;

#[derive(Clone, Debug)]
pub struct ResolutionController {
    pub target_ms: f64,
    step: usize,
    recent: Vec<f64>,
}

impl ResolutionController {
    pub fn new(target_ms: f64) -> ResolutionController {
        ResolutionController {
            target_ms,
            step: 0,
            recent: Vec::with_capacity(WINDOW),
        }
    }

    pub fn scale(&self) -> f32 {
        SCALES[self.step]
    }

    /// The internal resolution for a configured `width` x `height`: the ladder's step of
    /// the game's rule for that size (`film::render_scale_for`; at least 16 x 16).
    pub fn size(&self, width: u32, height: u32) -> (u32, u32) {
        let scale = self.scale() * crate::film::render_scale_for(width, height);
        let scaled = |n: u32| ((n as f32 * scale).round() as u32).max(16.min(n));
        (scaled(width), scaled(height))
    }

    /// Takes one frame's time; Some(new scale) when the step changes.
    pub fn observe(&mut self, frame_ms: f64) -> Option<f32> {
        self.recent.push(frame_ms);
        if self.recent.len() < WINDOW {
            return None;
        }
        let mut sorted = self.recent.clone();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[WINDOW / 2];
        self.recent.clear();
        if median > self.target_ms * OVER && self.step + 1 < SCALES.len() {
            self.step += 1;
            return Some(self.scale());
        }
        if self.step > 0 {
            // Frame time is mostly tracing, which scales with the pixel count.
            let ratio = (SCALES[self.step - 1] / SCALES[self.step]).powi(2) as f64;
            if median * ratio < self.target_ms * UNDER {
                self.step -= 1;
                return Some(self.scale());
            }
        }
        None
    }
}

/// The share of the configured resolution, each way, a first-run target must hold for the
/// image's sake (the ladder's second step), and the least it may fall to before the default
/// target gives way to the longest.
const FIRST_RUN_KEEPS: f32 = 0.85;
const FIRST_RUN_FLOOR: f32 = 0.5;

/// The frame-time target for a machine whose frames take `full_ms` (median) at the full
/// configured resolution: the shortest target offered, up to the default, that it holds at
/// `FIRST_RUN_KEEPS` of the resolution (frame time scales with the pixels); else the
/// default if it holds that at `FIRST_RUN_FLOOR` or more (a slow machine trades pixels
/// before smoothness); else the longest offered.
pub fn first_run_target(full_ms: f64) -> f64 {
    let offered = FRAME_TIME_TARGETS.iter().flatten().copied();
    let at = |scale: f32| full_ms * f64::from(scale * scale);
    offered
        .clone()
        .filter(|&target| target <= DEFAULT_TARGET_MS)
        .find(|&target| at(FIRST_RUN_KEEPS) <= target)
        .or((at(FIRST_RUN_FLOOR) <= DEFAULT_TARGET_MS).then_some(DEFAULT_TARGET_MS))
        .unwrap_or_else(|| offered.fold(DEFAULT_TARGET_MS, f64::max))
}

/// Times the first frames of a first run at the full resolution: the first
/// `FirstRunProbe::WARM_UP` (caches filling, the first BVH refits) are left out, the median
/// of the next `FirstRunProbe::MEASURED` is the answer.
#[derive(Clone, Debug, Default)]
pub struct FirstRunProbe {
    frames: Vec<f64>,
}

impl FirstRunProbe {
    pub const WARM_UP: usize = 10;
    pub const MEASURED: usize = 21;

    /// Takes one frame's time; Some(the median) once enough frames are in.
    pub fn observe(&mut self, frame_ms: f64) -> Option<f64> {
        self.frames.push(frame_ms);
        if self.frames.len() < Self::WARM_UP + Self::MEASURED {
            return None;
        }
        let mut measured = self.frames.split_off(Self::WARM_UP);
        self.frames.clear();
        measured.sort_by(f64::total_cmp);
        Some(measured[measured.len() / 2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A frame whose time is proportional to the pixels rendered.
    fn run(controller: &mut ResolutionController, full_ms: f64, frames: usize) -> usize {
        let mut changes = 0;
        for _ in 0..frames {
            let scale = controller.scale() as f64;
            if controller.observe(full_ms * scale * scale).is_some() {
                changes += 1;
            }
        }
        changes
    }

    #[test]
    fn steps_down_until_the_target_holds_then_stays() {
        let mut controller = ResolutionController::new(33.0);
        // 80 ms at full resolution: 0.6 gives 28.8 ms, the first step under 36.3.
        run(&mut controller, 80.0, 200);
        assert_eq!(controller.scale(), 0.6);
        // Steady there: no change in many frames (0.7 would predict 39 ms, over 28).
        assert_eq!(run(&mut controller, 80.0, 300), 0);
        assert_eq!(controller.size(480, 270), (288, 162));
        // A window past 640 x 360's pixels starts from the game's rule for its size.
        assert_eq!(ResolutionController::new(33.0).size(1280, 720), (640, 360));
        assert_eq!(controller.size(1280, 720), (384, 216));
    }

    #[test]
    fn steps_back_up_when_frames_get_cheap() {
        let mut controller = ResolutionController::new(33.0);
        run(&mut controller, 200.0, 200);
        assert_eq!(controller.scale(), 0.4);
        run(&mut controller, 10.0, 200);
        assert_eq!(controller.scale(), 1.0);
    }

    #[test]
    fn a_frame_time_between_the_thresholds_changes_nothing() {
        let mut controller = ResolutionController::new(33.0);
        // 34 ms: over the target but under 1.1x it.
        assert_eq!(run(&mut controller, 34.0, 300), 0);
        assert_eq!(controller.scale(), 1.0);
        // One slow frame in a window is not enough.
        for frame in 0..WINDOW {
            let ms = if frame == 3 { 500.0 } else { 20.0 };
            assert_eq!(controller.observe(ms), None);
        }
    }

    #[test]
    fn the_first_run_target_is_the_shortest_held_with_most_of_the_image() {
        // A fast machine: 60 fps at 85% or more.
        assert_eq!(first_run_target(8.0), 16.7);
        assert_eq!(first_run_target(23.0), 16.7);
        // 30 ms at full resolution (this 2-core machine's menu): 40 fps at 85%.
        assert_eq!(first_run_target(30.0), 25.0);
        assert_eq!(first_run_target(45.0), DEFAULT_TARGET_MS);
        // Slower: the default still, at a lower resolution, rather than 20 fps...
        assert_eq!(first_run_target(120.0), DEFAULT_TARGET_MS);
        // ...until even half the resolution cannot hold it.
        assert_eq!(first_run_target(140.0), 50.0);
        // Every answer is a target the settings offer.
        for ms in [0.5, 5.0, 17.0, 29.0, 60.0, 1000.0, f64::INFINITY] {
            assert!(
                FRAME_TIME_TARGETS.contains(&Some(first_run_target(ms))),
                "{ms}"
            );
        }
    }

    #[test]
    fn the_probe_answers_the_median_of_its_measured_frames_after_the_warm_up() {
        let mut probe = FirstRunProbe::default();
        for frame in 0..FirstRunProbe::WARM_UP {
            // Slow first frames are not counted.
            assert_eq!(probe.observe(500.0 + frame as f64), None);
        }
        let mut answer = None;
        for frame in 0..FirstRunProbe::MEASURED {
            assert_eq!(answer, None);
            answer = probe.observe(if frame % 5 == 0 { 90.0 } else { 20.0 });
        }
        assert_eq!(answer, Some(20.0));
    }
}
