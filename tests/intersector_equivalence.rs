//! guiding-obvhs's BVH intersector against a brute-force loop over every triangle, on ≥ 1e5 rays
//! per case: random triangle soups, closed meshes seen from inside (every ray must hit:
//! watertightness), rays aimed exactly at shared edges and vertices, and axis-parallel or
//! nearly axis-parallel directions, tiny and huge scenes far from the origin. Same
//! primitive, t within 1e-5 relative (the reference's winner refined to its plane's t,
//! as the adapter does), same occlusion answer.

// The box helpers of guiding-core's own tests, shared rather than copied.
#[path = "../guiding-core/tests/support/mod.rs"]
mod support;

use glam::Vec3;
use guiding_core::{Intersector, Pcg32, Ray, Triangle};
use guiding_obvhs::{BvhKind, ObvhsIntersector, PackedTriangle, ShearedRay};
use support::{box_triangles, Winding};

fn closed_box(min: Vec3, max: Vec3) -> Vec<Triangle> {
    box_triangles(min, max, Winding::Outward)
}

const KINDS: [BvhKind; 2] = [BvhKind::Bvh2, BvhKind::Cwbvh];

/// The reference: every triangle by the watertight test, ties to the lower index; the
/// winner's t is then its plane's, in f64 (what the adapter reports).
fn brute_force(triangles: &[Triangle], ray: &Ray) -> Option<(u32, f32)> {
    let sheared = ShearedRay::new(ray.origin, ray.direction);
    let mut best: Option<(u32, f32)> = None;
    for (i, triangle) in triangles.iter().enumerate() {
        if let Some(hit) = sheared.intersect(triangle.vertices, ray.t_min, ray.t_max).filter(|h| h.t < ray.t_max) {
            if best.is_none_or(|(_, t)| hit.t < t) {
                best = Some((i as u32, hit.t));
            }
        }
    }
    best.map(|(i, t)| {
        let plane =
            PackedTriangle::new(triangles[i as usize].vertices).plane_t(ray.origin.into(), ray.direction.into());
        (i, plane.filter(|&p| p > ray.t_min && p < ray.t_max).unwrap_or(t))
    })
}

fn brute_force_occluded(triangles: &[Triangle], ray: &Ray) -> bool {
    let sheared = ShearedRay::new(ray.origin, ray.direction);
    triangles.iter().any(|t| sheared.occludes_packed(&PackedTriangle::new(t.vertices), ray.t_min, ray.t_max))
}

fn random_unit(rng: &mut Pcg32) -> Vec3 {
    loop {
        let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        let length = v.length();
        if length > 1e-3 && length <= 1.0 {
            return v / length;
        }
    }
}

/// A closed, consistently wound polyhedron: an octahedron subdivided `levels` times and
/// pushed onto the unit sphere, scaled and moved. Shared vertices are bit-identical.
fn closed_sphere(levels: u32, center: Vec3, radius: f32) -> Vec<Triangle> {
    let mut faces: Vec<[Vec3; 3]> = Vec::new();
    let axes = [Vec3::X, Vec3::Y, Vec3::Z];
    for &sx in &[1.0f32, -1.0] {
        for &sy in &[1.0f32, -1.0] {
            for &sz in &[1.0f32, -1.0] {
                let (a, b, c) = (axes[0] * sx, axes[1] * sy, axes[2] * sz);
                faces.push(if sx * sy * sz > 0.0 { [a, b, c] } else { [a, c, b] });
            }
        }
    }
    for _ in 0..levels {
        faces = faces
            .iter()
            .flat_map(|&[a, b, c]| {
                let (ab, bc, ca) = ((a + b).normalize(), (b + c).normalize(), (c + a).normalize());
                [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
            })
            .collect();
    }
    faces
        .iter()
        .map(|f| Triangle::new(center + f[0] * radius, center + f[1] * radius, center + f[2] * radius))
        .collect()
}

fn soup(rng: &mut Pcg32, count: usize) -> Vec<Triangle> {
    (0..count)
        .map(|_| {
            let center = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0 - 5.0;
            let size = 0.05 + rng.next_f32();
            Triangle::new(
                center + random_unit(rng) * size,
                center + random_unit(rng) * size,
                center + random_unit(rng) * size,
            )
        })
        .collect()
}

/// Every ray must hit something in both BVHs (they all start inside closed meshes).
fn assert_no_ray_escapes(triangles: &[Triangle], rays: &[Ray], what: &str) {
    for kind in KINDS {
        let bvh = ObvhsIntersector::build(triangles, kind);
        let misses = rays.iter().filter(|r| bvh.intersect(r).is_none()).count();
        assert_eq!(misses, 0, "{kind:?}: {what}");
    }
}

fn check_equivalent(triangles: &[Triangle], rays: &[Ray], case: &str) {
    for kind in KINDS {
        let bvh = ObvhsIntersector::build(triangles, kind);
        let mut hits = 0;
        for ray in rays {
            let expected = brute_force(triangles, ray);
            let found = bvh.intersect(ray).map(|h| (h.primitive, h.t));
            match (expected, found) {
                (None, None) => {}
                (Some((ep, et)), Some((fp, ft))) => {
                    hits += 1;
                    assert_eq!(ep, fp, "{case} {kind:?}: primitive differs for {ray:?}");
                    assert!((et - ft).abs() <= 1e-5 * et.abs().max(1e-6), "{case} {kind:?}: t {ft} vs {et}");
                }
                _ => panic!("{case} {kind:?}: brute force {expected:?}, BVH {found:?} for {ray:?}"),
            }
            let segment = Ray { t_max: ray.t_max.min(4.0), ..*ray };
            assert_eq!(
                bvh.occluded(&segment),
                brute_force_occluded(triangles, &segment),
                "{case} {kind:?}: occlusion {segment:?}"
            );
        }
        assert!(hits > rays.len() / 20, "{case}: too few hits ({hits}) to mean anything");
    }
}

#[test]
fn random_rays_through_a_triangle_soup() {
    let mut rng = Pcg32::new(1, 0);
    let triangles = soup(&mut rng, 2000);
    let rays: Vec<Ray> = (0..100_000)
        .map(|_| {
            Ray::new(Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 12.0 - 6.0, random_unit(&mut rng))
        })
        .collect();
    check_equivalent(&triangles, &rays, "soup");
}

#[test]
fn closed_meshes_seen_from_inside_are_watertight() {
    let mut rng = Pcg32::new(2, 0);
    let mut triangles = closed_box(Vec3::splat(-3.0), Vec3::splat(3.0));
    triangles.extend(closed_sphere(4, Vec3::new(0.5, -0.2, 0.3), 1.5));
    let inside_sphere = Vec3::new(0.5, -0.2, 0.3);
    let rays: Vec<Ray> = (0..100_000)
        .map(|i| {
            // Half from inside the sphere, half from between the sphere and the box.
            let origin =
                if i % 2 == 0 { inside_sphere + random_unit(&mut rng) * 0.5 } else { Vec3::new(-2.5, 2.5, -2.5) };
            Ray::new(origin, random_unit(&mut rng))
        })
        .collect();
    assert_no_ray_escapes(&triangles, &rays, "rays escaped a closed mesh");
    check_equivalent(&triangles, &rays, "closed");
}

#[test]
fn rays_aimed_at_shared_edges_and_vertices() {
    let mut rng = Pcg32::new(3, 0);
    let triangles = closed_box(Vec3::new(-1.0, -2.0, -1.5), Vec3::new(2.0, 1.0, 0.5));
    let edges: Vec<(Vec3, Vec3)> = triangles
        .iter()
        .flat_map(|t| {
            let [a, b, c] = t.vertices;
            [(a, b), (b, c), (c, a)]
        })
        .collect();
    let center = Vec3::new(0.5, -0.5, -0.5);
    let rays: Vec<Ray> = (0..100_000)
        .map(|i| {
            let (a, b) = edges[i % edges.len()];
            // Exact vertices every tenth ray, points along edges otherwise.
            let target = if i % 10 == 0 { a } else { a.lerp(b, rng.next_f32()) };
            let origin =
                if i % 3 == 0 { center + random_unit(&mut rng) * 0.3 } else { target + random_unit(&mut rng) * 5.0 };
            Ray::new(origin, (target - origin).normalize())
        })
        .collect();
    let from_inside: Vec<Ray> = rays.iter().step_by(3).copied().collect();
    assert_no_ray_escapes(&triangles, &from_inside, "rays from inside the box slipped through an edge");
    check_equivalent(&triangles, &rays, "edges");
}

#[test]
fn axis_parallel_and_nearly_parallel_directions() {
    let mut rng = Pcg32::new(4, 0);
    let mut triangles = closed_box(Vec3::splat(-2.0), Vec3::splat(2.0));
    triangles.extend(soup(&mut rng, 300).into_iter().map(|t| Triangle { vertices: t.vertices.map(|v| v * 0.3) }));
    let rays: Vec<Ray> = (0..100_000)
        .map(|i| {
            let origin = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 3.0 - 1.5;
            let axis = [Vec3::X, Vec3::Y, Vec3::Z][i % 3] * if i % 2 == 0 { 1.0 } else { -1.0 };
            let tilt = [0.0, 1e-9, 1e-7, 1e-5][(i / 6) % 4];
            let direction = (axis + random_unit(&mut rng) * tilt).normalize();
            Ray::new(origin, direction)
        })
        .collect();
    assert_no_ray_escapes(&triangles, &rays, "axis-parallel rays left a closed box");
    check_equivalent(&triangles, &rays, "axis");
}

#[test]
fn degenerate_inputs_never_panic() {
    let triangles = vec![
        Triangle::new(Vec3::ZERO, Vec3::X, Vec3::X),
        Triangle::new(Vec3::NAN, Vec3::X, Vec3::Y),
        Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y),
    ];
    for kind in KINDS {
        let bvh = ObvhsIntersector::build(&triangles, kind);
        assert_eq!(bvh.triangle_count(), 2);
        let hit = bvh.intersect(&Ray::new(Vec3::new(0.2, 0.2, 1.0), Vec3::NEG_Z)).unwrap();
        assert_eq!(hit.primitive, 2);
        for ray in [
            Ray::new(Vec3::NAN, Vec3::Z),
            Ray::new(Vec3::ZERO, Vec3::ZERO),
            Ray::new(Vec3::ZERO, Vec3::new(f32::INFINITY, 0.0, 0.0)),
            Ray::segment(Vec3::ZERO, Vec3::Z, 1.0, 0.5),
        ] {
            assert!(bvh.intersect(&ray).is_none());
            assert!(!bvh.occluded(&ray));
        }
        let empty = ObvhsIntersector::build(&[], kind);
        assert!(empty.intersect(&Ray::new(Vec3::ZERO, Vec3::Z)).is_none());
    }
}

#[test]
fn both_ends_of_the_segment_are_open() {
    let floor = [Triangle::new(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, -1.0))];
    let down = |t_min: f32, t_max: f32| Ray::segment(Vec3::Y, Vec3::NEG_Y, t_min, t_max);
    let just_past_one = f32::from_bits(1.0f32.to_bits() + 1);
    for kind in KINDS {
        let bvh = ObvhsIntersector::build(&floor, kind);
        assert_eq!(bvh.intersect(&down(0.0, just_past_one)).map(|h| h.t), Some(1.0), "{kind:?}");
        assert_eq!(bvh.intersect(&down(0.0, 1.0)), None, "{kind:?}: a hit at t_max");
        assert_eq!(bvh.intersect(&down(1.0, 2.0)), None, "{kind:?}: a hit at t_min");
        assert!(bvh.occluded(&down(0.0, just_past_one)), "{kind:?}");
        assert!(!bvh.occluded(&down(0.0, 1.0)), "{kind:?}: a blocker at t_max");
        assert!(!bvh.occluded(&down(1.0, 2.0)), "{kind:?}: a blocker at t_min");
    }
}

#[test]
fn tiny_and_huge_scenes_far_from_the_origin_are_watertight_too() {
    // obvhs's CWBVH skipped every node within t < 1e-4 of the ray origin: a third of the
    // rays escaped a box 2e-4 across before the adapter scaled scenes to a fixed size.
    let mut rng = Pcg32::new(77, 5);
    for (scale, offset) in [(1e-4f32, 0.0f32), (1e4, 0.0), (1.0, 1e5), (1e4, 1e5)] {
        let triangles = closed_box(Vec3::splat(offset - scale), Vec3::splat(offset + scale));
        let rays: Vec<Ray> = (0..100_000)
            .map(|_| {
                let inside =
                    Vec3::splat(offset) + (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * scale;
                Ray::new(inside, random_unit(&mut rng))
            })
            .collect();
        assert_no_ray_escapes(&triangles, &rays, &format!("box of half size {scale} at {offset}"));
        check_equivalent(&triangles, &rays, &format!("box of half size {scale} at {offset}"));
    }
}
