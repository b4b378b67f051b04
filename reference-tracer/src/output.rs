//! Image files: linear EXR, PFM and Radiance HDR in; linear EXR, PFM and an sRGB PNG
//! preview out. Rows run top to bottom in memory.

use std::path::Path;

use glam::Vec3;

/// A linear RGB image.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Row-major pixels, top row first.
    pub pixels: Vec<Vec3>,
}

impl Image {
    /// Mean of every pixel.
    pub fn mean(&self) -> Vec3 {
        let sum =
            self.pixels.iter().fold([0.0f64; 3], |s, p| [s[0] + p.x as f64, s[1] + p.y as f64, s[2] + p.z as f64]);
        let n = self.pixels.len().max(1) as f64;
        Vec3::new((sum[0] / n) as f32, (sum[1] / n) as f32, (sum[2] / n) as f32)
    }
}

fn extension(path: &Path) -> Option<String> {
    path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase)
}

/// Reads an `.exr`, `.hdr` or `.pfm` file.
pub fn read_image(path: &Path) -> Result<Image, String> {
    match extension(path).as_deref() {
        Some("exr") => read_exr(path),
        Some("hdr") => {
            let image = image::open(path).map_err(|e| format!("cannot read HDR: {e}"))?.into_rgb32f();
            let (width, height) = (image.width() as usize, image.height() as usize);
            let pixels = image.pixels().map(|p| Vec3::from(p.0)).collect();
            Ok(Image { width, height, pixels })
        }
        Some("pfm") => read_pfm(path),
        _ => Err("unsupported image format (expected .exr, .hdr or .pfm)".into()),
    }
}

fn read_exr(path: &Path) -> Result<Image, String> {
    use exr::prelude::read_first_rgba_layer_from_file;
    let image = read_first_rgba_layer_from_file(
        path,
        |resolution, _| Image {
            width: resolution.width(),
            height: resolution.height(),
            pixels: vec![Vec3::ZERO; resolution.width() * resolution.height()],
        },
        |image: &mut Image, position, (r, g, b, _a): (f32, f32, f32, f32)| {
            image.pixels[position.y() * image.width + position.x()] = Vec3::new(r, g, b);
        },
    )
    .map_err(|e| format!("cannot read EXR: {e}"))?;
    Ok(image.layer_data.channel_data.pixels)
}

fn read_pfm(path: &Path) -> Result<Image, String> {
    // pxm asserts instead of erroring on a few malformed headers (a zero scale): keep any
    // such panic inside and report it as a bad file.
    let loaded = std::panic::catch_unwind(|| pxm::PXM::load(path)).map_err(|_| "malformed PFM header".to_string())?;
    let pxm::PXM::PFM(pfm) = loaded.map_err(|e| format!("cannot read PFM: {e}"))?;
    let pixels = if pfm.color {
        pfm.data.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect()
    } else {
        pfm.data.iter().map(|&v| Vec3::splat(v)).collect()
    };
    Ok(Image { width: pfm.width, height: pfm.height, pixels })
}

/// Writes a linear 32-bit float RGB EXR.
pub fn write_exr(path: &Path, image: &Image) -> Result<(), String> {
    exr::prelude::write_rgb_file(path, image.width, image.height, |x, y| {
        let p = image.pixels[y * image.width + x];
        (p.x, p.y, p.z)
    })
    .map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// Writes a little-endian colour PFM.
pub fn write_pfm(path: &Path, image: &Image) -> Result<(), String> {
    let data = image.pixels.iter().flat_map(|p| p.to_array()).collect();
    let pfm = pxm::PFMBuilder::new()
        .size(image.width.max(1), image.height.max(1))
        .color(true)
        .scale(-1.0)
        .data(data)
        .build()
        .map_err(|e| format!("cannot encode {}: {e}", path.display()))?;
    let mut file = std::fs::File::create(path).map_err(|e| format!("cannot create {}: {e}", path.display()))?;
    pfm.write_into(&mut file).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// The sRGB transfer function of a linear value, clamped to [0, 1].
fn srgb_encode(linear: f32) -> u8 {
    let v = if linear.is_nan() { 0.0 } else { linear.clamp(0.0, 1.0) };
    let encoded = if v <= 0.003_130_8 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 };
    (encoded * 255.0 + 0.5) as u8
}

/// Writes an 8-bit sRGB PNG preview (no tone mapping: values clip at 1).
pub fn write_png(path: &Path, image: &Image) -> Result<(), String> {
    let bytes = image.pixels.iter().flat_map(|p| [srgb_encode(p.x), srgb_encode(p.y), srgb_encode(p.z)]).collect();
    let buffer = image::RgbImage::from_raw(image.width as u32, image.height as u32, bytes)
        .ok_or_else(|| format!("cannot encode {}", path.display()))?;
    buffer.save(path).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient() -> Image {
        let (width, height) = (5, 3);
        let pixels = (0..width * height).map(|i| Vec3::new(i as f32, 0.5 * i as f32, 1e-3 * i as f32)).collect();
        Image { width, height, pixels }
    }

    #[test]
    fn exr_and_pfm_round_trip_with_rows_top_first() {
        let folder = std::env::temp_dir().join(format!("lodestar-output-{}", std::process::id()));
        std::fs::create_dir_all(&folder).unwrap();
        let image = gradient();
        for name in ["a.exr", "a.pfm"] {
            let path = folder.join(name);
            if name.ends_with("exr") {
                write_exr(&path, &image).unwrap();
            } else {
                write_pfm(&path, &image).unwrap();
            }
            assert_eq!(read_image(&path).unwrap(), image, "{name}");
        }
        write_png(&folder.join("a.png"), &image).unwrap();
        assert!(read_image(&folder.join("a.png")).is_err());
        std::fs::write(folder.join("bad.pfm"), b"PF\n2 2\n0\n").unwrap();
        assert!(read_image(&folder.join("bad.pfm")).is_err());
        std::fs::remove_dir_all(&folder).ok();
    }

    #[test]
    fn srgb_encoding() {
        assert_eq!(srgb_encode(0.0), 0);
        assert_eq!(srgb_encode(1.0), 255);
        assert_eq!(srgb_encode(5.0), 255);
        assert_eq!(srgb_encode(f32::NAN), 0);
        assert_eq!(srgb_encode(0.5), 188);
    }
}
