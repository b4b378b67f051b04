//! Animations (`lodestar render --frames N`): the camera's view at each frame, from the
//! scene's keyframes, and the seed each frame renders with.
//!
//! Frames rendered coherently share one seed, so every pass of every frame draws the
//! same random numbers (instant radiosity's virtual lights do not move), and keep every
//! learner (Q, W, light selection, the focal guide) from the frame before; otherwise
//! each frame starts from empty learners with a seed of its own, as separate renders
//! would.

use glam::Vec3;

/// The view (eye, target) of frame `frame` of `frames` on the polyline through
/// `keyframes`, spread evenly over the frames; `None` without keyframes.
pub fn keyframe_view(keyframes: &[(Vec3, Vec3)], frame: u32, frames: u32) -> Option<(Vec3, Vec3)> {
    let (first, last) = (keyframes.first()?, keyframes.last()?);
    if keyframes.len() == 1 || frames <= 1 {
        return Some(*first);
    }
    let t = frame.min(frames - 1) as f32 / (frames - 1) as f32 * (keyframes.len() - 1) as f32;
    let index = (t.floor() as usize).min(keyframes.len() - 2);
    if frame + 1 >= frames {
        return Some(*last);
    }
    let (a, b) = (keyframes[index], keyframes[index + 1]);
    let s = t - index as f32;
    Some((a.0.lerp(b.0, s), a.1.lerp(b.1, s)))
}

/// The seed of frame `frame` of a render seeded `seed`: the same for every frame when
/// `coherent`, a fresh one for each otherwise.
pub fn frame_seed(seed: u64, frame: u32, coherent: bool) -> u64 {
    if coherent {
        seed
    } else {
        seed ^ (frame as u64 + 1).wrapping_mul(0xd1b5_4a32_d192_ed03)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_run_from_the_first_keyframe_to_the_last_through_the_others() {
        let keys = [(Vec3::ZERO, Vec3::Z), (Vec3::X, Vec3::Z), (Vec3::new(1.0, 2.0, 0.0), Vec3::Z)];
        assert_eq!(keyframe_view(&keys, 0, 5), Some(keys[0]));
        assert_eq!(keyframe_view(&keys, 2, 5), Some(keys[1]));
        assert_eq!(keyframe_view(&keys, 4, 5), Some(keys[2]));
        let (eye, _) = keyframe_view(&keys, 1, 5).unwrap();
        assert!((eye - Vec3::new(0.5, 0.0, 0.0)).length() < 1e-6);
        assert_eq!(keyframe_view(&keys, 9, 5), Some(keys[2]), "frames past the end hold the last view");
        assert_eq!(keyframe_view(&[], 0, 5), None);
        assert_eq!(keyframe_view(&keys, 0, 1), Some(keys[0]));
    }

    #[test]
    fn coherent_frames_share_the_seed_and_others_do_not() {
        assert_eq!(frame_seed(7, 0, true), frame_seed(7, 5, true));
        assert_ne!(frame_seed(7, 0, false), frame_seed(7, 1, false));
        assert_ne!(frame_seed(7, 0, false), 7);
    }
}
