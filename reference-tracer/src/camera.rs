//! The pinhole camera.

use glam::{Vec2, Vec3};
use guiding_core::Ray;

/// Which image axis a field of view spans.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FovAxis {
    /// Top to bottom.
    Vertical,
    /// Left to right.
    Horizontal,
}

/// A pinhole camera; pixel (0, 0) is the top-left corner. Its field of view spans one
/// image axis, so another resolution (`with_resolution`) keeps that axis' view.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    eye: Vec3,
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    /// tan(fov / 2) along `fov_axis`.
    tan_half_fov: f32,
    fov_axis: FovAxis,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
}

impl Camera {
    /// A camera at `eye` looking at `target`; `up` need not be orthogonal to the view.
    /// Returns `None` when the view direction is zero or parallel to `up`.
    pub fn look_at(eye: Vec3, target: Vec3, up: Vec3, fov_y_deg: f32, width: u32, height: u32) -> Option<Self> {
        Self::oriented(eye, target, up, (fov_y_deg, FovAxis::Vertical), width, height, false)
    }

    /// [`look_at`](Self::look_at) with the field of view (degrees) along `fov.1`, and the
    /// image's right along up × forward instead of forward × up when `mirrored` (pbrt's
    /// left-handed camera).
    pub fn oriented(
        eye: Vec3,
        target: Vec3,
        up: Vec3,
        fov: (f32, FovAxis),
        width: u32,
        height: u32,
        mirrored: bool,
    ) -> Option<Self> {
        let forward = (target - eye).try_normalize()?;
        let mut right = forward.cross(up).try_normalize()?;
        let up = right.cross(forward);
        if mirrored {
            right = -right;
        }
        let tan_half_fov = (0.5 * fov.0.to_radians()).tan();
        Some(Self { eye, forward, right, up, tan_half_fov, fov_axis: fov.1, width, height })
    }

    /// The same view at another resolution: the field of view along its axis is kept (so
    /// an image of the same aspect shows the same picture).
    pub fn with_resolution(&self, width: u32, height: u32) -> Self {
        Self { width, height, ..*self }
    }

    /// Eye, unit forward, right and up directions, and tan(fov_y / 2) at this
    /// resolution: what [`ray`](Self::ray) computes with (for the GPU tracer).
    pub fn basis(&self) -> (Vec3, Vec3, Vec3, Vec3, f32) {
        (self.eye, self.forward, self.right, self.up, self.tan_half_fov_y())
    }

    fn tan_half_fov_y(&self) -> f32 {
        match self.fov_axis {
            FovAxis::Vertical => self.tan_half_fov,
            FovAxis::Horizontal => self.tan_half_fov * self.height as f32 / self.width as f32,
        }
    }

    /// The primary ray through image point (x, y) in pixels from the top-left corner
    /// (a pixel's area is [x, x+1) × [y, y+1)).
    pub fn ray(&self, image_point: Vec2) -> Ray {
        let aspect = self.width as f32 / self.height as f32;
        let tan_half_fov_y = self.tan_half_fov_y();
        let ndc_x = (2.0 * image_point.x / self.width as f32 - 1.0) * aspect * tan_half_fov_y;
        let ndc_y = (1.0 - 2.0 * image_point.y / self.height as f32) * tan_half_fov_y;
        let direction = (self.forward + self.right * ndc_x + self.up * ndc_y).normalize();
        Ray::new(self.eye, direction)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_ray_looks_at_the_target_and_corners_span_the_fov() {
        let camera =
            Camera::look_at(Vec3::new(0.0, 1.0, 4.0), Vec3::new(0.0, 1.0, 0.0), Vec3::Y, 90.0, 200, 100).unwrap();
        let center = camera.ray(Vec2::new(100.0, 50.0));
        assert!((center.direction - Vec3::NEG_Z).length() < 1e-6);
        let top = camera.ray(Vec2::new(100.0, 0.0));
        assert!((top.direction.y - top.direction.z.abs()).abs() < 1e-5, "45° up at the top edge");
        let left = camera.ray(Vec2::new(0.0, 50.0));
        assert!(left.direction.x < 0.0);
        assert!(Camera::look_at(Vec3::ZERO, Vec3::Y, Vec3::Y, 45.0, 1, 1).is_none());
        let (eye, target) = (Vec3::new(0.0, 1.0, 4.0), Vec3::new(0.0, 1.0, 0.0));
        let mirrored = Camera::oriented(eye, target, Vec3::Y, (90.0, FovAxis::Vertical), 200, 100, true).unwrap();
        let left = mirrored.ray(Vec2::new(0.0, 50.0));
        assert!(left.direction.x > 0.0, "mirrored: the left edge looks to +x");
        assert!(mirrored.ray(Vec2::new(100.0, 0.0)).direction.y > 0.0, "still upright");
        // A horizontal field of view keeps the sides where they are at any resolution.
        let wide = Camera::oriented(eye, target, Vec3::Y, (90.0, FovAxis::Horizontal), 200, 100, false).unwrap();
        for camera in [wide, wide.with_resolution(64, 64)] {
            let right = camera.ray(Vec2::new(camera.width as f32, camera.height as f32 / 2.0)).direction;
            assert!((right.x + right.z).abs() < 1e-5, "45° to the right: {right}");
        }
    }
}
