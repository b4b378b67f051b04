//! Orthonormal shading frames built from a single normal.

use glam::Vec3;

/// A right-handed orthonormal basis (tangent, bitangent, normal).
///
/// Built without branches on the normal's direction (Duff et al. 2017, "Building an
/// Orthonormal Basis, Revisited"), so the same normal always yields the same frame: a
/// sampler and its pdf that both build the frame agree bit for bit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// First tangent direction (local +x).
    pub tangent: Vec3,
    /// Second tangent direction (local +y).
    pub bitangent: Vec3,
    /// The normal (local +z).
    pub normal: Vec3,
}

impl Frame {
    /// The frame whose local +z is `normal`, which must be unit length.
    pub fn from_normal(normal: Vec3) -> Self {
        let sign = 1.0f32.copysign(normal.z);
        let a = -1.0 / (sign + normal.z);
        let b = normal.x * normal.y * a;
        let tangent = Vec3::new(1.0 + sign * normal.x * normal.x * a, sign * b, -sign * normal.x);
        let bitangent = Vec3::new(b, sign + normal.y * normal.y * a, -normal.y);
        Self { tangent, bitangent, normal }
    }

    /// World direction to local coordinates (z along the normal).
    pub fn to_local(&self, world: Vec3) -> Vec3 {
        Vec3::new(world.dot(self.tangent), world.dot(self.bitangent), world.dot(self.normal))
    }

    /// Local coordinates to a world direction.
    pub fn to_world(&self, local: Vec3) -> Vec3 {
        self.tangent * local.x + self.bitangent * local.y + self.normal * local.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_orthonormal_and_right_handed() {
        let normals = [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.3, -0.4, 0.866).normalize(),
            Vec3::new(1e-8, 0.0, -1.0).normalize(),
        ];
        for n in normals {
            let f = Frame::from_normal(n);
            assert!((f.tangent.length() - 1.0).abs() < 1e-5, "{n:?}");
            assert!((f.bitangent.length() - 1.0).abs() < 1e-5, "{n:?}");
            assert!(f.tangent.dot(f.bitangent).abs() < 1e-5, "{n:?}");
            assert!(f.tangent.dot(n).abs() < 1e-5, "{n:?}");
            assert!((f.tangent.cross(f.bitangent) - n).length() < 1e-5, "{n:?}");
            let w = Vec3::new(0.2, 0.5, -0.7);
            assert!((f.to_world(f.to_local(w)) - w).length() < 1e-5);
        }
    }
}
