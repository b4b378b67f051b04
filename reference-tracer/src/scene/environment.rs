//! A scene's environment (a constant, a latitude-longitude map, a sky with a sun),
//! checked and built from its description.

use std::path::Path;

use glam::{Mat3, Vec2, Vec3};
use guiding_core::environment::SunDisk;

use super::{EnvironmentDescription, SceneError, SunDescription};
use crate::color::{is_valid_radiance, luminance};
use crate::environment::{Environment, LatLongMap, Sky, Sun};

pub(super) fn build_environment(
    env: &EnvironmentDescription,
    folder: &Path,
    path: &Path,
) -> Result<Environment, SceneError> {
    let (sky, sun) = match env {
        EnvironmentDescription::Constant { radiance, sun } => {
            let radiance = Vec3::from(*radiance);
            if !is_valid_radiance(radiance) {
                let message = format!("{radiance:?} must be finite and non-negative radiance");
                return Err(SceneError::new(path, "environment.radiance", message));
            }
            (Sky::Constant(radiance), sun)
        }
        EnvironmentDescription::Image { file, scale, rotation, sun } => {
            let scale = scale.unwrap_or(1.0);
            if !(scale.is_finite() && scale >= 0.0) {
                return Err(SceneError::new(
                    path,
                    "environment.scale",
                    format!("{scale} must be finite and non-negative"),
                ));
            }
            let image_path = folder.join(file);
            let fail = |message: String| {
                SceneError::new(path, "environment.file", format!("{}: {message}", image_path.display()))
            };
            let image = crate::output::read_image(&image_path).map_err(fail)?;
            if image.width == 0 || image.height == 0 {
                return Err(fail("image has zero size".into()));
            }
            if let Some(i) = image.pixels.iter().position(|&p| !is_valid_radiance(p)) {
                return Err(fail(format!(
                    "texel ({}, {}) is {:?}: radiance must be finite and non-negative",
                    i % image.width,
                    i / image.width,
                    image.pixels[i]
                )));
            }
            let mut texels: Vec<Vec3> = image.pixels.iter().map(|&p| p * scale).collect();
            if let Some(rows) = rotation {
                let to_world = Mat3::from_cols_array_2d(rows).transpose();
                let orthonormal = (to_world * to_world.transpose()).abs_diff_eq(Mat3::IDENTITY, 1e-3)
                    && (to_world.determinant() - 1.0).abs() < 1e-3;
                if !orthonormal {
                    let message = "must be a rotation (orthonormal, determinant 1)".to_string();
                    return Err(SceneError::new(path, "environment.rotation", message));
                }
                texels = rotate_lat_long(image.width, image.height, &texels, to_world);
            }
            (Sky::Image(LatLongMap::new(image.width, image.height, texels)), sun)
        }
    };
    let sun = match sun {
        Some(sun) => Some(build_sun(sun, path)?),
        None => None,
    };
    Ok(Environment::new(sky, sun))
}

/// The lat-long map that shows in direction d what `texels` show in direction
/// `to_world⁻¹ · d`: rotated about +y by whole texels, an exact shift of the columns;
/// otherwise resampled bilinearly (a slight blur).
pub(super) fn rotate_lat_long(width: usize, height: usize, texels: &[Vec3], to_world: Mat3) -> Vec<Vec3> {
    use guiding_core::environment::lat_long::{direction_of_uv, uv_of_direction};
    let about_y = (to_world * Vec3::Y).abs_diff_eq(Vec3::Y, 1e-6);
    if about_y {
        // The map's −z (u = 0.5) goes to the world's to_world·(−z): a shift in u.
        let u_shift = uv_of_direction(to_world * Vec3::NEG_Z).x - 0.5;
        let columns = u_shift * width as f32;
        if (columns - columns.round()).abs() < 1e-3 {
            let shift = (columns.round() as i64).rem_euclid(width as i64) as usize;
            let mut rotated = vec![Vec3::ZERO; texels.len()];
            for row in 0..height {
                for column in 0..width {
                    rotated[row * width + (column + shift) % width] = texels[row * width + column];
                }
            }
            return rotated;
        }
    }
    let to_local = to_world.transpose();
    let at = |x: i64, y: i64| {
        let y = y.clamp(0, height as i64 - 1) as usize;
        texels[y * width + x.rem_euclid(width as i64) as usize]
    };
    let mut rotated = Vec::with_capacity(texels.len());
    for row in 0..height {
        for column in 0..width {
            let uv = Vec2::new((column as f32 + 0.5) / width as f32, (row as f32 + 0.5) / height as f32);
            let source = uv_of_direction(to_local * direction_of_uv(uv));
            let (x, y) = (source.x * width as f32 - 0.5, source.y * height as f32 - 0.5);
            let (x0, y0) = (x.floor(), y.floor());
            let (fx, fy) = (x - x0, y - y0);
            let (x0, y0) = (x0 as i64, y0 as i64);
            let top = at(x0, y0) * (1.0 - fx) + at(x0 + 1, y0) * fx;
            let bottom = at(x0, y0 + 1) * (1.0 - fx) + at(x0 + 1, y0 + 1) * fx;
            rotated.push(top * (1.0 - fy) + bottom * fy);
        }
    }
    rotated
}

pub(super) fn build_sun(sun: &SunDescription, path: &Path) -> Result<Sun, SceneError> {
    let radiance = Vec3::from(sun.radiance);
    if !is_valid_radiance(radiance) {
        let message = format!("{radiance:?} must be finite and non-negative radiance");
        return Err(SceneError::new(path, "environment.sun.radiance", message));
    }
    let disk = SunDisk::new(Vec3::from(sun.direction), sun.angular_radius_deg.to_radians(), luminance(radiance))
        .map_err(|e| {
            let field = match &e {
                guiding_core::Error::InvalidSetting { name: "sun.direction", .. } => "environment.sun.direction",
                _ => "environment.sun.angular_radius_deg",
            };
            SceneError::new(path, field, e.to_string())
        })?;
    Ok(Sun { disk, radiance })
}
