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

    /// The same camera (field of view, size, up, handedness) at `eye`, looking at
    /// `target`; `None` when the view direction is zero or parallel to its up.
    pub fn looking(&self, eye: Vec3, target: Vec3) -> Option<Self> {
        let mirrored = self.right.dot(self.forward.cross(self.up)) < 0.0;
        let forward = (target - eye).try_normalize()?;
        let mut right = forward.cross(self.up).try_normalize()?;
        let up = right.cross(forward);
        if mirrored {
            right = -right;
        }
        Some(Self { eye, forward, right, up, ..*self })
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

/// Where a point in the scene lands on the image, for connecting a light path to the
/// camera: its pixel, the unit direction and distance from the point to the eye, and the
/// importance that connection carries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EyeConnection {
    /// The pixel (column, row) the point projects into.
    pub pixel: (u32, u32),
    /// Unit direction from the point to the eye.
    pub to_eye: Vec3,
    /// Distance from the point to the eye.
    pub distance: f32,
    /// W_e·cos θ_e / r²: the pinhole's importance towards the point (normalised over the
    /// whole image, W_e = 1/(A·cos⁴θ_e), A the image plane's area at distance 1) times
    /// the geometry term's camera side, per unit area at the point facing the eye. A
    /// light path's contribution to the image's mean is its throughput times the
    /// surface's f·cos there times this; to a pixel's value, that times the pixel count.
    pub importance: f32,
}

impl Camera {
    /// The connection of `point` to the eye, if the point lies in front of the camera
    /// and inside the image ([`ray`](Self::ray) inverted).
    pub fn connect(&self, point: Vec3) -> Option<EyeConnection> {
        let offset = self.eye - point;
        let distance = offset.length();
        if !(distance.is_finite() && distance > 0.0) {
            return None;
        }
        let to_eye = offset / distance;
        let (cos_eye, image_point) = self.project(-to_eye)?;
        let importance = self.direction_pdf_at(cos_eye) / (distance * distance);
        Some(EyeConnection { pixel: (image_point.x as u32, image_point.y as u32), to_eye, distance, importance })
    }

    /// Where the unit direction `view` from the eye meets the image: cos θ from the view
    /// axis and the image point in pixels ([`ray`](Self::ray) inverted), if it does.
    fn project(&self, view: Vec3) -> Option<(f32, Vec2)> {
        let cos_eye = view.dot(self.forward);
        if cos_eye <= 0.0 {
            return None;
        }
        let tan_half_fov_y = self.tan_half_fov_y();
        let aspect = self.width as f32 / self.height as f32;
        let (ndc_x, ndc_y) = (view.dot(self.right) / cos_eye, view.dot(self.up) / cos_eye);
        let x = (ndc_x / (aspect * tan_half_fov_y) + 1.0) * 0.5 * self.width as f32;
        let y = (1.0 - ndc_y / tan_half_fov_y) * 0.5 * self.height as f32;
        let inside = x >= 0.0 && y >= 0.0 && x < self.width as f32 && y < self.height as f32;
        inside.then_some((cos_eye, Vec2::new(x, y)))
    }

    /// Density per steradian with which [`ray`](Self::ray) at a uniform image point draws
    /// `direction` (unit, from the eye): 1/(A·cos³θ), A the image plane's area at
    /// distance 1; 0 outside the image.
    pub fn direction_pdf(&self, direction: Vec3) -> f32 {
        self.project(direction).map_or(0.0, |(cos_eye, _)| self.direction_pdf_at(cos_eye))
    }

    /// 1/(A·cos³θ) for a direction at cos θ = `cos_eye` from the view axis.
    fn direction_pdf_at(&self, cos_eye: f32) -> f32 {
        let tan_half_fov_y = self.tan_half_fov_y();
        let aspect = self.width as f32 / self.height as f32;
        let plane_area = 4.0 * aspect * tan_half_fov_y * tan_half_fov_y;
        1.0 / (plane_area * cos_eye * cos_eye * cos_eye)
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

    #[test]
    fn a_point_on_a_camera_ray_connects_back_to_its_pixel() {
        let (eye, target) = (Vec3::new(0.3, 1.0, 4.0), Vec3::new(0.0, 1.2, 0.0));
        for mirrored in [false, true] {
            let camera = Camera::oriented(eye, target, Vec3::Y, (50.0, FovAxis::Vertical), 64, 48, mirrored).unwrap();
            for (x, y) in [(0.5, 0.5), (10.25, 40.75), (63.5, 47.5), (32.0, 24.0)] {
                let ray = camera.ray(Vec2::new(x, y));
                let point = ray.origin + ray.direction * 3.7;
                let connection = camera.connect(point).expect("in view");
                assert_eq!(connection.pixel, (x as u32, y as u32), "mirrored {mirrored}");
                assert!((connection.to_eye + ray.direction).length() < 1e-5);
                assert!((connection.distance - 3.7).abs() < 1e-4);
            }
            assert!(camera.connect(eye - (target - eye)).is_none(), "behind the camera");
        }
        // The importance integrates to one over the image plane at distance 1: at its
        // centre, a unit of area facing the eye sees 1/A.
        let camera = Camera::look_at(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, 90.0, 100, 50).unwrap();
        let centre = camera.connect(Vec3::new(0.0, 0.0, -1.0)).unwrap();
        assert!((centre.importance - 1.0 / (4.0 * 2.0 * 1.0)).abs() < 1e-6, "{}", centre.importance);
    }

    #[test]
    fn direction_pdf_integrates_to_one_over_the_sphere() {
        let camera = Camera::look_at(Vec3::new(0.2, 1.0, 3.0), Vec3::ZERO, Vec3::Y, 60.0, 64, 48).unwrap();
        // Midpoint rule over equal-area cells of the sphere (uniform in z and φ).
        let (nz, nphi) = (1200, 2400);
        let cell = 4.0 * std::f64::consts::PI / (nz * nphi) as f64;
        let mut integral = 0.0f64;
        for i in 0..nz {
            let z = -1.0 + 2.0 * (i as f32 + 0.5) / nz as f32;
            let r = (1.0 - z * z).max(0.0).sqrt();
            for j in 0..nphi {
                let phi = 2.0 * std::f32::consts::PI * (j as f32 + 0.5) / nphi as f32;
                integral += camera.direction_pdf(Vec3::new(r * phi.cos(), r * phi.sin(), z)) as f64 * cell;
            }
        }
        assert!((integral - 1.0).abs() < 5e-3, "{integral}");
        // A connection's importance is this density over the squared distance.
        let ray = camera.ray(Vec2::new(10.3, 40.2));
        let connection = camera.connect(ray.origin + ray.direction * 2.5).unwrap();
        let expected = camera.direction_pdf(ray.direction) / (2.5 * 2.5);
        assert!((connection.importance - expected).abs() <= 1e-4 * expected);
        assert_eq!(camera.direction_pdf(-ray.direction), 0.0, "behind");
    }
}
