//! The lights' mirror images behind a scene's flat near-mirrors, for the focal guide.
//!
//! Light a polished floor or a mirror reflects from a lamp reaches a diffuse point as if
//! it came from the lamp's image behind the mirror. A diffuse vertex that sees the
//! reflection finds it only by chance (Veach Ajar's brightest samples: the lamp in the
//! glossy floor, reached from a diffuse bounce), and no learned box marks the image,
//! since every segment ends at the mirror. The focal guide is told of the images as
//! known boxes ([`guiding_core::focal::KnownBox`]); each of its cells learns whether
//! aiming at them pays from there.

use std::collections::{BTreeMap, HashMap};

use glam::Vec3;
use guiding_core::focal::{KnownBox, MAX_KNOWN_BOXES};

use crate::color::luminance;
use crate::material::Surface;
use crate::scene::Scene;

/// The roughest conductor (GGX α) whose planes mirror the lights for the command line's
/// focal guide: Veach Ajar's floor is 0.1.
pub const DEFAULT_FOCAL_MIRROR_ALPHA: f32 = 0.2;

/// The images' mass together as a share of the learned boxes' (Veach Ajar, 60 s: 0.5
/// took the guided-nee relMSE of seed 42 from 1.54 to 1.01).
pub const MIRROR_IMAGE_SHARE: f32 = 0.5;

/// A plane counts as a mirror when its near-mirror triangles cover at least this share
/// of the square of the scene's extent (a floor, a wall mirror; not a pot's facets).
const MIN_MIRROR_AREA: f32 = 0.0025;

/// Most mirror planes taken (the largest).
const MAX_MIRRORS: usize = 8;

/// A plane of near-mirror triangles: unit normal n and offset d (points p with n·p = d),
/// and the triangles' area.
#[derive(Clone, Copy, Debug)]
struct MirrorPlane {
    normal: Vec3,
    offset: f32,
    area: f32,
}

/// The boxes around every light's mirror image behind each flat mirror of `scene`
/// (conductors at most GGX α `max_alpha`), each weighted by the light's power (W); the
/// most powerful [`MAX_KNOWN_BOXES`]. Empty where `max_alpha` is below 0 or nothing
/// qualifies.
pub fn light_mirror_images(scene: &Scene, max_alpha: f32) -> Vec<KnownBox> {
    if max_alpha.is_nan() || max_alpha < 0.0 || scene.triangles.is_empty() {
        return Vec::new();
    }
    let (low, high) = scene.bounds();
    let extent = (high - low).max_element();
    if !(extent.is_finite() && extent > 0.0) {
        return Vec::new();
    }
    let mirrors = mirror_planes(scene, max_alpha, extent);
    let mut images = Vec::new();
    for light in lights(scene) {
        for mirror in &mirrors {
            if let Some(image) = mirror_image(&light, mirror) {
                images.push(image);
            }
        }
    }
    images.sort_by(|a: &KnownBox, b| b.weight.total_cmp(&a.weight));
    images.truncate(MAX_KNOWN_BOXES);
    images
}

/// The planes of `scene` that near-mirror triangles cover widely, largest first.
fn mirror_planes(scene: &Scene, max_alpha: f32, extent: f32) -> Vec<MirrorPlane> {
    // Ordered maps: the images come out in the same order every run, so renders repeat.
    let mut planes: BTreeMap<[i64; 4], MirrorPlane> = BTreeMap::new();
    for (index, triangle) in scene.triangles.iter().enumerate() {
        let material = &scene.materials[scene.triangle_materials[index] as usize];
        let near_mirror = matches!(material.surface, Surface::Conductor { alpha, .. } if alpha <= max_alpha);
        if !near_mirror || material.is_emissive() {
            continue;
        }
        // One orientation per plane, whichever way its triangles wind.
        let mut normal = scene.normals[index];
        if normal[normal.abs().max_position()] < 0.0 {
            normal = -normal;
        }
        let area = triangle.area();
        let offset = normal.dot(triangle.vertices[0]);
        if !(area > 0.0 && normal.is_finite() && offset.is_finite()) {
            continue;
        }
        let quantum = 1e-4 * extent;
        let key = [
            (normal.x * 512.0).round() as i64,
            (normal.y * 512.0).round() as i64,
            (normal.z * 512.0).round() as i64,
            (offset / quantum).round() as i64,
        ];
        planes.entry(key).or_insert(MirrorPlane { normal, offset, area: 0.0 }).area += area;
    }
    let mut planes: Vec<MirrorPlane> =
        planes.into_values().filter(|p| p.area >= MIN_MIRROR_AREA * extent * extent).collect();
    planes.sort_by(|a, b| b.area.total_cmp(&a.area));
    planes.truncate(MAX_MIRRORS);
    planes
}

/// One light: the vertices of its emissive triangles, their front normals and its power.
#[derive(Default)]
struct Light {
    vertices: Vec<Vec3>,
    normals: Vec<Vec3>,
    power: f32,
}

/// The scene's emissive triangles grouped into lights: triangles of one material that
/// share a vertex are one light (a lamp's quad, an emissive sphere), which gets one box.
fn lights(scene: &Scene) -> Vec<Light> {
    let emissive: Vec<usize> = (0..scene.triangles.len())
        .filter(|&t| scene.materials[scene.triangle_materials[t] as usize].is_emissive())
        .collect();
    // Union-find over the emissive triangles, joined through shared vertices.
    let mut parent: Vec<usize> = (0..emissive.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut first_at: HashMap<(u32, [u32; 3]), usize> = HashMap::new();
    for (k, &t) in emissive.iter().enumerate() {
        for v in scene.triangles[t].vertices {
            let key = (scene.triangle_materials[t], v.to_array().map(f32::to_bits));
            let other = *first_at.entry(key).or_insert(k);
            let (a, b) = (root(&mut parent, k), root(&mut parent, other));
            parent[a] = b;
        }
    }
    let mut lights: BTreeMap<usize, Light> = BTreeMap::new();
    for (k, &t) in emissive.iter().enumerate() {
        let light = lights.entry(root(&mut parent, k)).or_default();
        let triangle = &scene.triangles[t];
        light.vertices.extend(triangle.vertices);
        light.normals.push(scene.normals[t]);
        let emission = scene.materials[scene.triangle_materials[t] as usize].emission;
        light.power += luminance(emission) * triangle.area() * std::f32::consts::PI;
    }
    lights.into_values().filter(|l| l.power > 0.0 && l.power.is_finite()).collect()
}

/// The box around `light`'s image behind `mirror`: `None` where the light is not wholly
/// on one side of the plane or sends none of its light towards it.
fn mirror_image(light: &Light, mirror: &MirrorPlane) -> Option<KnownBox> {
    let distances: Vec<f32> = light.vertices.iter().map(|&v| mirror.normal.dot(v) - mirror.offset).collect();
    let side = if distances.iter().all(|&d| d > 0.0) {
        1.0
    } else if distances.iter().all(|&d| d < 0.0) {
        -1.0
    } else {
        return None;
    };
    // Towards the light's side; an emitter facing straight away from the plane lights none of it.
    let towards_light = mirror.normal * side;
    if light.normals.iter().all(|n| n.dot(towards_light) > 0.999) {
        return None;
    }
    let (low, high) =
        light.vertices.iter().zip(&distances).fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(low, high), (&v, &d)| {
            let image = v - 2.0 * d * mirror.normal;
            (low.min(image), high.max(image))
        });
    (low.is_finite() && high.is_finite()).then_some(KnownBox { low, high, weight: light.power })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn light(vertices: &[Vec3], normal: Vec3) -> Light {
        Light { vertices: vertices.to_vec(), normals: vec![normal], power: 3.0 }
    }

    /// A polished floor under a lamp of two triangles, a small polished tile and a
    /// diffuse wall: one image, of the whole lamp, below the floor.
    fn scene(floor_alpha: f32, lamp_faces_down: bool) -> Scene {
        let lamp = if lamp_faces_down {
            "[[-0.5, 2, -0.5], [0.5, 2, -0.5], [0.5, 2, 0.5], [-0.5, 2, 0.5]]"
        } else {
            "[[-0.5, 2, 0.5], [0.5, 2, 0.5], [0.5, 2, -0.5], [-0.5, 2, -0.5]]"
        };
        let text = format!(
            r#"{{"format": 1,
            "camera": {{"eye": [0, 1, 5], "target": [0, 1, 0], "up": [0, 1, 0], "fov_y_deg": 40, "width": 8, "height": 8}},
            "materials": {{
                "polished": {{"type": "conductor", "specular": [0.9, 0.9, 0.9], "alpha": {floor_alpha}}},
                "white": {{"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}},
                "lamp": {{"type": "diffuse", "albedo": [0, 0, 0], "emission": [10, 10, 10]}}}},
            "shapes": [
                {{"type": "quad", "material": "polished", "corners": [[-3, 0, 3], [3, 0, 3], [3, 0, -3], [-3, 0, -3]]}},
                {{"type": "quad", "material": "polished", "corners": [[2, 1, 0], [2.01, 1, 0], [2.01, 1.01, 0], [2, 1.01, 0]]}},
                {{"type": "quad", "material": "white", "corners": [[-3, 0, -3], [3, 0, -3], [3, 3, -3], [-3, 3, -3]]}},
                {{"type": "quad", "material": "lamp", "corners": {lamp}}}]}}"#
        );
        Scene::from_json(std::path::Path::new("mirror_images_test.json"), &text).expect("a scene")
    }

    #[test]
    fn a_polished_floor_mirrors_the_lamp_above_it() {
        let images = light_mirror_images(&scene(0.05, true), DEFAULT_FOCAL_MIRROR_ALPHA);
        assert_eq!(images.len(), 1, "{images:?}");
        let image = images[0];
        assert_eq!((image.low, image.high), (Vec3::new(-0.5, -2.0, -0.5), Vec3::new(0.5, -2.0, 0.5)));
        // Power: luminance 10 × area 1 × π.
        assert!((image.weight - 10.0 * std::f32::consts::PI).abs() < 1e-3, "{}", image.weight);
        assert!(light_mirror_images(&scene(0.05, false), DEFAULT_FOCAL_MIRROR_ALPHA).is_empty(), "facing away");
        assert!(light_mirror_images(&scene(0.5, true), DEFAULT_FOCAL_MIRROR_ALPHA).is_empty(), "too rough");
        assert!(light_mirror_images(&scene(0.05, true), -1.0).is_empty(), "switched off");
    }

    #[test]
    fn a_lamp_above_a_floor_has_its_image_below() {
        let floor = MirrorPlane { normal: Vec3::Y, offset: 0.0, area: 10.0 };
        let lamp = [Vec3::new(-1.0, 2.0, -1.0), Vec3::new(1.0, 2.0, -1.0), Vec3::new(1.0, 2.0, 1.0)];
        let image = mirror_image(&light(&lamp, -Vec3::Y), &floor).expect("an image");
        assert_eq!((image.low, image.high), (Vec3::new(-1.0, -2.0, -1.0), Vec3::new(1.0, -2.0, 1.0)));
        assert_eq!(image.weight, 3.0);
        // A lamp facing away from the floor lights none of it; one crossing it has no image.
        assert!(mirror_image(&light(&lamp, Vec3::Y), &floor).is_none());
        let crossing = [Vec3::new(0.0, -1.0, 0.0), Vec3::new(0.0, 1.0, 0.0), Vec3::new(1.0, 1.0, 0.0)];
        assert!(mirror_image(&light(&crossing, Vec3::Z), &floor).is_none());
        // A vertical lamp (Veach Ajar's) lights the floor with half its hemisphere.
        let upright = [Vec3::new(0.0, 0.2, 0.0), Vec3::new(1.0, 0.2, 0.0), Vec3::new(1.0, 2.8, 0.0)];
        let image = mirror_image(&light(&upright, -Vec3::Z), &floor).expect("an image");
        assert_eq!((image.low.y, image.high.y), (-2.8, -0.2));
    }
}
