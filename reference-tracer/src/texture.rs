//! Textures: RGB values over a surface's (u, v) parameters, looked up per hit. Images
//! are filtered bilinearly and repeat outside [0, 1]²; (u, v) = (0, 0) is an image's
//! bottom-left corner (the convention of OBJ, PLY, pbrt and Mitsuba).

use std::path::Path;

use glam::{Vec2, Vec3};

use crate::color::luminance;
use crate::output::read_image;

/// A texture, ready to evaluate.
#[derive(Clone, Debug)]
pub struct Texture {
    pattern: Pattern,
    uv_scale: Vec2,
    uv_offset: Vec2,
}

#[derive(Clone, Debug)]
enum Pattern {
    /// Linear RGB, row-major from the top row, and the alpha channel if the file has one.
    Image {
        width: usize,
        height: usize,
        texels: Vec<Vec3>,
        alpha: Option<Vec<f32>>,
    },
    Checkerboard {
        even: Vec3,
        odd: Vec3,
    },
}

/// Decodes one 8-bit sRGB value to linear.
pub fn srgb_to_linear(value: u8) -> f32 {
    let v = value as f32 / 255.0;
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

impl Texture {
    /// An image texture from `texels` (row-major, top row first), already linear.
    pub fn image(width: usize, height: usize, texels: Vec<Vec3>) -> Result<Self, String> {
        if width == 0 || height == 0 || texels.len() != width * height {
            return Err(format!("{width}×{height} image with {} texels", texels.len()));
        }
        if let Some(i) = texels.iter().position(|t| !(t.is_finite() && t.min_element() >= 0.0)) {
            return Err(format!(
                "texel ({}, {}) is {:?}: must be finite and non-negative",
                i % width,
                i / width,
                texels[i]
            ));
        }
        let pattern = Pattern::Image { width, height, texels, alpha: None };
        Ok(Self { pattern, uv_scale: Vec2::ONE, uv_offset: Vec2::ZERO })
    }

    /// Reads an image file: 8-bit formats (PNG, JPEG, TGA, BMP) decoded by `srgb` or as
    /// linear values in [0, 1], keeping an alpha channel for [`opacity`](Self::opacity);
    /// EXR, HDR and PFM as linear floats.
    pub fn load(path: &Path, srgb: bool) -> Result<Self, String> {
        let extension = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        match extension.as_deref() {
            Some("exr" | "hdr" | "pfm") => {
                let image = read_image(path)?;
                Self::image(image.width, image.height, image.pixels)
            }
            Some("png" | "jpg" | "jpeg" | "tga" | "bmp") => {
                let image = image::open(path).map_err(|e| format!("cannot read image: {e}"))?;
                let has_alpha = image.color().has_alpha();
                let rgba = image.into_rgba8();
                let (width, height) = (rgba.width() as usize, rgba.height() as usize);
                let decode = |v: u8| if srgb { srgb_to_linear(v) } else { v as f32 / 255.0 };
                let texels = rgba.pixels().map(|p| Vec3::new(decode(p.0[0]), decode(p.0[1]), decode(p.0[2]))).collect();
                let mut texture = Self::image(width, height, texels)?;
                if has_alpha {
                    if let Pattern::Image { alpha, .. } = &mut texture.pattern {
                        *alpha = Some(rgba.pixels().map(|p| p.0[3] as f32 / 255.0).collect());
                    }
                }
                Ok(texture)
            }
            _ => Err("unsupported texture format (expected .png, .jpg, .tga, .bmp, .exr, .hdr or .pfm)".into()),
        }
    }

    /// Squares of `even` and `odd` colour, one per unit of (s, t).
    pub fn checkerboard(even: Vec3, odd: Vec3) -> Self {
        Self { pattern: Pattern::Checkerboard { even, odd }, uv_scale: Vec2::ONE, uv_offset: Vec2::ZERO }
    }

    /// The same texture looked up at `scale · (u, v) + offset`.
    pub fn with_uv_transform(mut self, scale: Vec2, offset: Vec2) -> Self {
        self.uv_scale = scale;
        self.uv_offset = offset;
        self
    }

    /// The value at surface parameters `uv`.
    pub fn eval(&self, uv: Vec2) -> Vec3 {
        let st = uv * self.uv_scale + self.uv_offset;
        match &self.pattern {
            Pattern::Checkerboard { even, odd } => {
                let parity = (st.x.floor() as i64 + st.y.floor() as i64).rem_euclid(2);
                if parity == 0 {
                    *even
                } else {
                    *odd
                }
            }
            Pattern::Image { width, height, texels, .. } => {
                bilinear(*width, *height, st, |i| texels[i]).unwrap_or(Vec3::ZERO)
            }
        }
    }

    /// Opacity in [0, 1] at `uv`: an image's alpha channel where it has one, else the
    /// luminance of the value.
    pub fn opacity(&self, uv: Vec2) -> f32 {
        let st = uv * self.uv_scale + self.uv_offset;
        let value = match &self.pattern {
            Pattern::Image { width, height, alpha: Some(alpha), .. } => {
                bilinear(*width, *height, st, |i| alpha[i]).unwrap_or(0.0)
            }
            _ => luminance(self.eval(uv)),
        };
        value.clamp(0.0, 1.0)
    }

    /// The mean value over [0, 1]² (exact for images at scale 1; averaged over a grid
    /// otherwise), for estimates that need one colour per material.
    pub fn mean(&self) -> Vec3 {
        match &self.pattern {
            Pattern::Image { texels, .. } if self.uv_scale == Vec2::ONE => {
                texels.iter().copied().sum::<Vec3>() / texels.len() as f32
            }
            _ => {
                let n = 64;
                let mut sum = Vec3::ZERO;
                for j in 0..n {
                    for i in 0..n {
                        sum += self.eval(Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32));
                    }
                }
                sum / (n * n) as f32
            }
        }
    }
}

/// Bilinear interpolation of a `width × height` grid (row-major, top row first) at `st`,
/// repeating outside [0, 1]²; `None` for a non-finite `st`.
fn bilinear<T>(width: usize, height: usize, st: Vec2, at: impl Fn(usize) -> T) -> Option<T>
where
    T: std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
{
    // Texel centres sit at half-integer positions; v runs bottom to top.
    let x = st.x * width as f32 - 0.5;
    let y = (1.0 - st.y) * height as f32 - 0.5;
    if !(x.is_finite() && y.is_finite()) {
        return None;
    }
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let wrap = |i: f32, n: usize| (i as i64).rem_euclid(n as i64) as usize;
    let (xa, xb) = (wrap(x0, width), wrap(x0 + 1.0, width));
    let (ya, yb) = (wrap(y0, height), wrap(y0 + 1.0, height));
    let top = at(ya * width + xa) * (1.0 - fx) + at(ya * width + xb) * fx;
    let bottom = at(yb * width + xa) * (1.0 - fx) + at(yb * width + xb) * fx;
    Some(top * (1.0 - fy) + bottom * fy)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_lookup_hits_texel_centres_and_repeats() {
        // 2×2: top row red, green; bottom row blue, white.
        let texels = vec![Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE];
        let t = Texture::image(2, 2, texels).unwrap();
        assert!((t.eval(Vec2::new(0.25, 0.75)) - Vec3::X).length() < 1e-6, "top-left centre");
        assert!((t.eval(Vec2::new(0.75, 0.25)) - Vec3::ONE).length() < 1e-6, "bottom-right centre");
        assert!((t.eval(Vec2::new(1.25, -0.25)) - Vec3::X).length() < 1e-6, "repeats");
        let middle = t.eval(Vec2::new(0.5, 0.5));
        assert!((middle - (Vec3::X + Vec3::Y + Vec3::Z + Vec3::ONE) / 4.0).length() < 1e-6);
        assert_eq!(t.eval(Vec2::new(f32::NAN, 0.0)), Vec3::ZERO);
    }

    #[test]
    fn checkerboard_alternates_and_averages_to_the_middle() {
        let t = Texture::checkerboard(Vec3::splat(0.2), Vec3::splat(0.8))
            .with_uv_transform(Vec2::new(4.0, 2.0), Vec2::ZERO);
        assert_eq!(t.eval(Vec2::new(0.1, 0.1)), Vec3::splat(0.2));
        assert_eq!(t.eval(Vec2::new(0.3, 0.1)), Vec3::splat(0.8));
        assert_eq!(t.eval(Vec2::new(0.3, 0.6)), Vec3::splat(0.2));
        assert_eq!(t.eval(Vec2::new(-0.1, 0.1)), Vec3::splat(0.8));
        assert!((t.mean() - Vec3::splat(0.5)).length() < 1e-6);
    }

    #[test]
    fn srgb_decoding_matches_the_curve() {
        assert_eq!(srgb_to_linear(0), 0.0);
        assert!((srgb_to_linear(255) - 1.0).abs() < 1e-6);
        assert!((srgb_to_linear(188) - 0.5).abs() < 5e-3);
    }

    #[test]
    fn bad_images_are_errors() {
        assert!(Texture::image(0, 1, vec![]).is_err());
        assert!(Texture::image(1, 1, vec![Vec3::splat(f32::NAN)]).unwrap_err().contains("texel (0, 0)"));
    }
}
