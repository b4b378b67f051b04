//! The pinhole camera.

use glam::{Vec2, Vec3};
use guiding_core::Ray;

/// A pinhole camera with a vertical field of view; pixel (0, 0) is the top-left corner.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    eye: Vec3,
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    tan_half_fov_y: f32,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
}

impl Camera {
    /// A camera at `eye` looking at `target`; `up` need not be orthogonal to the view.
    /// Returns `None` when the view direction is zero or parallel to `up`.
    pub fn look_at(eye: Vec3, target: Vec3, up: Vec3, fov_y_deg: f32, width: u32, height: u32) -> Option<Self> {
        let forward = (target - eye).try_normalize()?;
        let right = forward.cross(up).try_normalize()?;
        let up = right.cross(forward);
        let tan_half_fov_y = (0.5 * fov_y_deg.to_radians()).tan();
        Some(Self { eye, forward, right, up, tan_half_fov_y, width, height })
    }

    /// The primary ray through image point (x, y) in pixels from the top-left corner
    /// (a pixel's area is [x, x+1) × [y, y+1)).
    pub fn ray(&self, image_point: Vec2) -> Ray {
        let aspect = self.width as f32 / self.height as f32;
        let ndc_x = (2.0 * image_point.x / self.width as f32 - 1.0) * aspect * self.tan_half_fov_y;
        let ndc_y = (1.0 - 2.0 * image_point.y / self.height as f32) * self.tan_half_fov_y;
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
    }
}
