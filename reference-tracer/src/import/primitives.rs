//! Analytic shapes of other formats (Mitsuba's rectangle, disk, cube and sphere) as
//! triangles in world space, with the normals that decide their front (the local
//! shape's outward normal, transformed) and their texture coordinates.

use std::f32::consts::PI;

use glam::{Mat3, Mat4, Vec2, Vec3};

use crate::scene::ShapeDescription;

/// Segments around a disk or sphere: a 128-gon keeps 99.96 % of the disk's area, so an
/// emitter's power changes by less than that.
const SEGMENTS: usize = 128;

/// Triangles in local space.
struct LocalMesh {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    uvs: Vec<Vec2>,
    indices: Vec<u32>,
}

/// The square [-1, 1]² at z = 0 facing +z.
fn rectangle() -> LocalMesh {
    LocalMesh {
        positions: vec![
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ],
        normals: vec![Vec3::Z; 4],
        uvs: vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y],
        indices: vec![0, 1, 2, 0, 2, 3],
    }
}

/// The unit disk at z = 0 facing +z, as a fan of [`SEGMENTS`] triangles whose polygon
/// has the disk's area (its vertices sit slightly outside the circle).
fn disk() -> LocalMesh {
    let n = SEGMENTS;
    // Area of a regular n-gon of circumradius r: n r² sin(2π/n) / 2 = π.
    let radius = (2.0 * PI / (n as f32 * (2.0 * PI / n as f32).sin())).sqrt();
    let mut positions = vec![Vec3::ZERO];
    let mut uvs = vec![Vec2::ZERO];
    for k in 0..n {
        let phi = 2.0 * PI * k as f32 / n as f32;
        positions.push(Vec3::new(radius * phi.cos(), radius * phi.sin(), 0.0));
        uvs.push(Vec2::new(1.0, k as f32 / n as f32));
    }
    let indices = (0..n as u32).flat_map(|k| [0, 1 + k, 1 + (k + 1) % n as u32]).collect();
    LocalMesh { normals: vec![Vec3::Z; positions.len()], positions, uvs, indices }
}

/// The cube [-1, 1]³ with outward faces.
fn cube() -> LocalMesh {
    let mut mesh = LocalMesh { positions: vec![], normals: vec![], uvs: vec![], indices: vec![] };
    for axis in 0..3 {
        for side in [-1.0f32, 1.0] {
            let mut normal = Vec3::ZERO;
            normal[axis] = side;
            // Two tangents with t1 × t2 = normal.
            let t1 = {
                let mut t = Vec3::ZERO;
                t[(axis + 1) % 3] = 1.0;
                t
            };
            let t2 = normal.cross(t1);
            let base = mesh.positions.len() as u32;
            for (i, (a, b)) in [(-1.0f32, -1.0f32), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)].into_iter().enumerate() {
                mesh.positions.push(normal + t1 * a + t2 * b);
                mesh.normals.push(normal);
                mesh.uvs.push([Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y][i]);
            }
            mesh.indices.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
        }
    }
    mesh
}

/// The unit sphere, [`SEGMENTS`] around and half as many from pole to pole, outward.
fn sphere() -> LocalMesh {
    let (columns, rows) = (SEGMENTS, SEGMENTS / 2);
    let mut mesh = LocalMesh { positions: vec![], normals: vec![], uvs: vec![], indices: vec![] };
    for row in 0..=rows {
        let theta = PI * row as f32 / rows as f32;
        for column in 0..=columns {
            let phi = 2.0 * PI * column as f32 / columns as f32;
            let p = Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
            mesh.positions.push(p);
            mesh.normals.push(p);
            mesh.uvs.push(Vec2::new(column as f32 / columns as f32, row as f32 / rows as f32));
        }
    }
    let stride = columns as u32 + 1;
    for row in 0..rows as u32 {
        for column in 0..columns as u32 {
            let (a, b) = (row * stride + column, (row + 1) * stride + column);
            // Counter-clockwise seen from outside (normals decide the front anyway).
            if row > 0 {
                mesh.indices.extend([a, b, a + 1]);
            }
            if row + 1 < rows as u32 {
                mesh.indices.extend([a + 1, b, b + 1]);
            }
        }
    }
    mesh
}

/// The analytic shapes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Primitive {
    /// [-1, 1]² at z = 0, facing +z.
    Rectangle,
    /// The unit disk at z = 0, facing +z.
    Disk,
    /// [-1, 1]³, outward.
    Cube,
    /// The unit sphere at the origin, outward.
    Sphere,
}

/// `primitive` moved to the world by `to_world`, with `material`; `flip` turns its
/// front to the other side.
pub fn primitive_shape(primitive: Primitive, to_world: Mat4, flip: bool, material: &str) -> ShapeDescription {
    let local = match primitive {
        Primitive::Rectangle => rectangle(),
        Primitive::Disk => disk(),
        Primitive::Cube => cube(),
        Primitive::Sphere => sphere(),
    };
    let normal_matrix = Mat3::from_mat4(to_world).inverse().transpose();
    let sign = if flip { -1.0 } else { 1.0 };
    ShapeDescription::Triangles {
        positions: local.positions.iter().map(|&p| to_world.transform_point3(p).to_array()).collect(),
        normals: Some(
            local.normals.iter().map(|&n| (normal_matrix * n * sign).normalize_or_zero().to_array()).collect(),
        ),
        uvs: Some(local.uvs.iter().map(|t| t.to_array()).collect()),
        indices: local.indices,
        front_from_normals: true,
        material: material.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use guiding_core::Triangle;

    fn area_and_centroid(shape: &ShapeDescription) -> (f32, Vec3) {
        let ShapeDescription::Triangles { positions, indices, .. } = shape else { unreachable!() };
        let mut area = 0.0;
        let mut centroid = Vec3::ZERO;
        for t in indices.chunks_exact(3) {
            let v: Vec<Vec3> = t.iter().map(|&i| Vec3::from(positions[i as usize])).collect();
            let a = Triangle::new(v[0], v[1], v[2]).area();
            area += a;
            centroid += a * (v[0] + v[1] + v[2]) / 3.0;
        }
        (area, centroid / area)
    }

    #[test]
    fn shapes_keep_their_areas() {
        let scale = Mat4::from_scale(Vec3::splat(2.0));
        for (primitive, expected) in [
            (Primitive::Rectangle, 16.0),
            (Primitive::Disk, 4.0 * PI),
            (Primitive::Cube, 96.0),
            (Primitive::Sphere, 16.0 * PI),
        ] {
            let (area, centroid) = area_and_centroid(&primitive_shape(primitive, scale, false, "m"));
            let tolerance = if primitive == Primitive::Sphere { 2e-3 } else { 1e-4 };
            assert!((area / expected - 1.0).abs() < tolerance, "{primitive:?}: {area} vs {expected}");
            assert!(centroid.length() < 1e-4, "{primitive:?}: centred");
        }
    }

    #[test]
    fn normals_follow_the_transform_and_flip() {
        // A mirror (negative determinant) still takes +z to where the normal goes.
        let to_world = Mat4::from_scale(Vec3::new(-1.0, 1.0, 3.0));
        let ShapeDescription::Triangles { normals, .. } = primitive_shape(Primitive::Rectangle, to_world, false, "m")
        else {
            unreachable!()
        };
        assert_eq!(normals.unwrap()[0], [0.0, 0.0, 1.0]);
        let ShapeDescription::Triangles { normals, .. } = primitive_shape(Primitive::Disk, to_world, true, "m") else {
            unreachable!()
        };
        assert_eq!(normals.unwrap()[0], [0.0, 0.0, -1.0]);
    }
}
