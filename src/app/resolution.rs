//! Frame step `present`'s partner: adaptive internal resolution. The shell feeds it each
//! frame's time; it moves the render's resolution one step down a fixed ladder when frames
//! run over the target, and one step up when the frames, scaled by the pixel count of the
//! step above, would still fit with room to spare. The gap between the two thresholds and
//! a cool-down after every change are the hysteresis: a frame time between them changes
//! nothing, so the resolution does not flicker.

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

    /// The internal resolution for a configured `width` x `height` (at least 16 x 16).
    pub fn size(&self, width: u32, height: u32) -> (u32, u32) {
        let scaled = |n: u32| ((n as f32 * self.scale()).round() as u32).max(16.min(n));
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
}
