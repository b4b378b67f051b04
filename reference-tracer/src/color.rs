//! Linear Rec.709 RGB helpers.

use glam::Vec3;

/// Relative luminance of a linear Rec.709 colour.
pub fn luminance(rgb: Vec3) -> f32 {
    rgb.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// Whether a colour is finite and non-negative in every channel.
pub fn is_valid_radiance(rgb: Vec3) -> bool {
    rgb.is_finite() && rgb.min_element() >= 0.0
}
