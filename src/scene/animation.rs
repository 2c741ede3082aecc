//! Evaluating glTF animation data: keyframe sampling and clip time.
//!
//! Pure maths over the imported model (`model::AnimationSampler`), used by the game's
//! fixed-step `animate` system and by tools that pose a scene at a given time. Follows the
//! glTF 2.0 specification, appendix C ("Animation sampler interpolation modes"):
//! - before the first keyframe the first value holds, after the last the last value holds;
//! - STEP holds key k's value on [t_k, t_k+1);
//! - LINEAR interpolates translations, scales and weights linearly and rotations by
//!   spherical linear interpolation along the shorter arc;
//! - CUBICSPLINE is the cubic Hermite spline through the keys with the file's in/out
//!   tangents scaled by the key interval, and rotations are normalised afterwards.

use glam::{Quat, Vec3};
use serde::{Deserialize, Serialize};

use super::model::{AnimationSampler, Interpolation};

/// What a clip does when its time runs past its end.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Playback {
    /// Wraps around to the start (walk cycles, idle loops).
    #[default]
    Loop,
    /// Holds the last pose (a door swinging open).
    Once,
}

/// The time within a clip of `duration` seconds that `elapsed` seconds of playback reach.
pub fn clip_time(elapsed: f64, duration: f32, playback: Playback) -> f32 {
    if duration <= 0.0 || !elapsed.is_finite() {
        return 0.0;
    }
    let duration = duration as f64;
    match playback {
        // rem_euclid keeps negative times (a clip played backwards) inside [0, duration).
        Playback::Loop => elapsed.rem_euclid(duration) as f32,
        Playback::Once => elapsed.clamp(0.0, duration) as f32,
    }
}

/// Where a time falls among a sampler's keyframes.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Segment {
    /// Before the first key, after the last, or a single-key sampler: hold key `k`.
    Hold(usize),
    /// Between key `k` and `k + 1`, a fraction `s` of the way, over `interval` seconds.
    Between { k: usize, s: f32, interval: f32 },
}

impl AnimationSampler {
    fn segment(&self, t: f32) -> Segment {
        let keys = self.times.len();
        debug_assert!(keys > 0, "import rejects samplers without keys");
        if keys == 1 || t <= self.times[0] || t.is_nan() {
            return Segment::Hold(0);
        }
        if t >= self.times[keys - 1] {
            return Segment::Hold(keys - 1);
        }
        // The last key at or before t (binary search: Fox's clips have ~100 keys per channel).
        let k = self.times.partition_point(|&time| time <= t) - 1;
        let interval = self.times[k + 1] - self.times[k];
        Segment::Between {
            k,
            s: if interval > 0.0 {
                (t - self.times[k]) / interval
            } else {
                0.0
            },
            interval,
        }
    }

    /// The value of element `element` (0 = in-tangent, 1 = value, 2 = out-tangent for cubic
    /// splines; always 0 otherwise) of key `k`, component `c`.
    #[inline]
    fn at(&self, k: usize, element: usize, c: usize) -> f32 {
        let per_key = match self.interpolation {
            Interpolation::CubicSpline => 3,
            _ => 1,
        };
        self.values[(k * per_key + element) * self.components + c]
    }

    fn value_element(&self) -> usize {
        match self.interpolation {
            Interpolation::CubicSpline => 1,
            _ => 0,
        }
    }

    /// Samples every component at time `t` (seconds within the clip) into `out`, which
    /// must hold `components` floats. Rotations come out as (x, y, z, w), normalised.
    pub fn sample_into(&self, t: f32, out: &mut [f32]) {
        debug_assert_eq!(out.len(), self.components);
        let value = self.value_element();
        match (self.segment(t), self.interpolation) {
            (Segment::Hold(k), _) => {
                for (c, slot) in out.iter_mut().enumerate() {
                    *slot = self.at(k, value, c);
                }
            }
            (Segment::Between { k, .. }, Interpolation::Step) => {
                for (c, slot) in out.iter_mut().enumerate() {
                    *slot = self.at(k, 0, c);
                }
            }
            (Segment::Between { k, s, .. }, Interpolation::Linear) => {
                if self.components == 4 {
                    // Rotation: slerp, which takes the shorter arc.
                    let from = self.quat_at(k, 0);
                    let to = self.quat_at(k + 1, 0);
                    out.copy_from_slice(&from.slerp(to, s).normalize().to_array());
                } else {
                    for (c, slot) in out.iter_mut().enumerate() {
                        let (a, b) = (self.at(k, 0, c), self.at(k + 1, 0, c));
                        *slot = a + (b - a) * s;
                    }
                }
            }
            (Segment::Between { k, s, interval }, Interpolation::CubicSpline) => {
                // Hermite basis (glTF spec, appendix C): p(s) = h00 v_k + h10 m_k
                // + h01 v_k+1 + h11 m_k+1 with m_k = interval x out-tangent of k and
                // m_k+1 = interval x in-tangent of k+1.
                let (s2, s3) = (s * s, s * s * s);
                let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
                let h10 = s3 - 2.0 * s2 + s;
                let h01 = -2.0 * s3 + 3.0 * s2;
                let h11 = s3 - s2;
                for (c, slot) in out.iter_mut().enumerate() {
                    *slot = h00 * self.at(k, 1, c)
                        + h10 * interval * self.at(k, 2, c)
                        + h01 * self.at(k + 1, 1, c)
                        + h11 * interval * self.at(k + 1, 0, c);
                }
                if self.components == 4 {
                    let q = Quat::from_slice(out).normalize();
                    out.copy_from_slice(&q.to_array());
                }
            }
        }
    }

    fn quat_at(&self, k: usize, element: usize) -> Quat {
        Quat::from_xyzw(
            self.at(k, element, 0),
            self.at(k, element, 1),
            self.at(k, element, 2),
            self.at(k, element, 3),
        )
    }

    /// A translation or scale sampler's value at `t`.
    pub fn sample_vec3(&self, t: f32) -> Vec3 {
        let mut out = [0.0; 3];
        self.sample_into(t, &mut out);
        Vec3::from_array(out)
    }

    /// A rotation sampler's value at `t`, normalised.
    pub fn sample_rotation(&self, t: f32) -> Quat {
        let mut out = [0.0; 4];
        self.sample_into(t, &mut out);
        Quat::from_array(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sampler(
        interpolation: Interpolation,
        times: &[f32],
        values: &[f32],
        components: usize,
    ) -> AnimationSampler {
        AnimationSampler {
            interpolation,
            times: times.to_vec(),
            values: values.to_vec(),
            components,
        }
    }

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).abs().max_element() < 1e-6
    }

    #[test]
    fn linear_translation_hits_keys_and_interpolates_between() {
        let s = sampler(
            Interpolation::Linear,
            &[1.0, 2.0, 4.0],
            &[0.0, 0.0, 0.0, 2.0, 4.0, 6.0, 2.0, 0.0, 6.0],
            3,
        );
        // Keys, clamped ends, midpoints (the second interval is 2 s long).
        assert!(close(s.sample_vec3(1.0), Vec3::ZERO));
        assert!(close(s.sample_vec3(2.0), Vec3::new(2.0, 4.0, 6.0)));
        assert!(close(s.sample_vec3(4.0), Vec3::new(2.0, 0.0, 6.0)));
        assert!(close(s.sample_vec3(0.0), Vec3::ZERO));
        assert!(close(s.sample_vec3(9.0), Vec3::new(2.0, 0.0, 6.0)));
        assert!(close(s.sample_vec3(1.5), Vec3::new(1.0, 2.0, 3.0)));
        assert!(close(s.sample_vec3(3.0), Vec3::new(2.0, 2.0, 6.0)));
        assert!(close(s.sample_vec3(3.5), Vec3::new(2.0, 1.0, 6.0)));
    }

    #[test]
    fn step_holds_each_key_until_the_next() {
        let s = sampler(
            Interpolation::Step,
            &[0.0, 1.0],
            &[1.0, 1.0, 1.0, 3.0, 3.0, 3.0],
            3,
        );
        assert!(close(s.sample_vec3(0.0), Vec3::ONE));
        assert!(close(s.sample_vec3(0.5), Vec3::ONE));
        assert!(close(s.sample_vec3(0.999), Vec3::ONE));
        assert!(close(s.sample_vec3(1.0), Vec3::splat(3.0)));
        assert!(close(s.sample_vec3(7.0), Vec3::splat(3.0)));
    }

    #[test]
    fn linear_rotation_is_slerp_along_the_shorter_arc() {
        let a = Quat::IDENTITY;
        let b = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
        // The second key is stored negated: the same rotation, on the far hemisphere.
        let values: Vec<f32> = a.to_array().into_iter().chain((-b).to_array()).collect();
        let s = sampler(Interpolation::Linear, &[0.0, 2.0], &values, 4);
        let mid = s.sample_rotation(1.0);
        let expected = Quat::from_rotation_y(std::f32::consts::FRAC_PI_4);
        assert!(mid.dot(expected).abs() > 1.0 - 1e-6, "{mid:?}");
        assert!((mid.length() - 1.0).abs() < 1e-6);
        // A quarter of the way along is a quarter of the angle (slerp, not nlerp).
        let quarter = s.sample_rotation(0.5);
        let expected = Quat::from_rotation_y(std::f32::consts::FRAC_PI_8);
        assert!(quarter.dot(expected).abs() > 1.0 - 1e-6, "{quarter:?}");
    }

    #[test]
    fn cubic_spline_matches_the_hermite_formula() {
        // One component; keys at t = 0 and t = 2 (interval 2): values 1 and 3, out-tangent
        // of key 0 = 0.5, in-tangent of key 1 = -1. Triples are (in, value, out).
        let s = sampler(
            Interpolation::CubicSpline,
            &[0.0, 2.0],
            &[9.0, 1.0, 0.5, -1.0, 3.0, 9.0],
            1,
        );
        let sample = |t: f32| {
            let mut out = [0.0];
            s.sample_into(t, &mut out);
            out[0]
        };
        assert_eq!(sample(0.0), 1.0);
        assert_eq!(sample(2.0), 3.0);
        assert_eq!(sample(-1.0), 1.0);
        assert_eq!(sample(5.0), 3.0);
        // Midpoint s = 0.5: h00 = 0.5, h10 = 0.125, h01 = 0.5, h11 = -0.125;
        // p = 0.5*1 + 0.125*2*0.5 + 0.5*3 + (-0.125)*2*(-1) = 2.375.
        assert!((sample(1.0) - 2.375).abs() < 1e-6, "{}", sample(1.0));
        // s = 0.25: h00 = 0.84375, h10 = 0.140625, h01 = 0.15625, h11 = -0.046875.
        let expected = 0.84375 + 0.140625 * 2.0 * 0.5 + 0.15625 * 3.0 + -0.046875 * 2.0 * -1.0;
        assert!((sample(0.5) - expected).abs() < 1e-6);
    }

    #[test]
    fn cubic_rotations_come_out_normalised() {
        let a = Quat::IDENTITY.to_array();
        let b = Quat::from_rotation_x(1.0).to_array();
        let tangent = [0.3, 0.0, 0.0, 0.0];
        let values: Vec<f32> = [tangent, a, tangent, tangent, b, tangent].concat();
        let s = sampler(Interpolation::CubicSpline, &[0.0, 1.0], &values, 4);
        for t in [0.1, 0.5, 0.9] {
            assert!((s.sample_rotation(t).length() - 1.0).abs() < 1e-6);
        }
        assert!(s.sample_rotation(1.0).dot(Quat::from_array(b)) > 1.0 - 1e-6);
    }

    #[test]
    fn weights_sample_every_target() {
        let s = sampler(Interpolation::Linear, &[0.0, 1.0], &[0.0, 1.0, 1.0, 0.0], 2);
        let mut out = [0.0; 2];
        s.sample_into(0.25, &mut out);
        assert_eq!(out, [0.25, 0.75]);
    }

    #[test]
    fn clip_time_loops_or_holds() {
        assert_eq!(clip_time(2.5, 1.0, Playback::Loop), 0.5);
        assert_eq!(clip_time(-0.25, 1.0, Playback::Loop), 0.75);
        assert_eq!(clip_time(2.5, 1.0, Playback::Once), 1.0);
        assert_eq!(clip_time(0.4, 1.0, Playback::Once), 0.4);
        assert_eq!(clip_time(3.0, 0.0, Playback::Loop), 0.0);
        assert_eq!(clip_time(f64::NAN, 1.0, Playback::Loop), 0.0);
    }
}
