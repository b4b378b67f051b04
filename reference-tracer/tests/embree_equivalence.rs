//! Embree 4 against obvhs (with the `embree` feature): on 10⁵ random rays over every
//! shipped scene (each folder of `scenes/`) both report the same primitive and t within
//! 1e-5 relative (plus 1e-6 of the coordinates' magnitude over the cosine: their
//! rounding, at grazing hits), ties at shared edges or coincident surfaces (Embree's
//! triangle is hit at the same t as well) excepted and counted; the same occlusion
//! answers; and renders of cornell with each intersector agree within noise.
#![cfg(feature = "embree")]

mod support;

use std::path::Path;

use glam::Vec3;
use guiding_core::{Intersector, Pcg32, Ray};
use guiding_embree::EmbreeIntersector;
use guiding_obvhs::{BvhKind, ObvhsIntersector, ShearedRay};
use reference_tracer::integrator::Method;
use reference_tracer::scene::Scene;
use reference_tracer::scene_intersector::IntersectorChoice;

fn random_direction(rng: &mut Pcg32) -> Vec3 {
    loop {
        let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        if let Some(unit) = v.try_normalize().filter(|_| v.length_squared() <= 1.0) {
            return unit;
        }
    }
}

#[test]
fn embree_and_obvhs_agree_on_every_shipped_scene() {
    // Every folder of scenes/ with a scene file (JSON, pbrt or Mitsuba), so a scene added
    // later is covered without editing this test.
    let folder = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    let mut files: Vec<_> = std::fs::read_dir(&folder)
        .unwrap()
        .filter_map(|entry| {
            let dir = entry.unwrap().path();
            ["scene.json", "scene.pbrt", "scene.xml"].iter().map(|f| dir.join(f)).find(|f| f.is_file())
        })
        .collect();
    files.sort();
    assert!(files.len() >= 8, "shipped scenes: {files:?}");
    for file in &files {
        let name = file.parent().and_then(|p| p.file_name()).unwrap().to_string_lossy().into_owned();
        let name = name.as_str();
        let scene = Scene::load(file).unwrap();
        let obvhs = ObvhsIntersector::build(&scene.triangles, BvhKind::Cwbvh);
        let embree = EmbreeIntersector::build(&scene.triangles).unwrap();
        let (low, high) = scene
            .triangles
            .iter()
            .flat_map(|t| t.vertices)
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
        let mut rng = Pcg32::new(5, name.len() as u64);
        let (mut hits, mut ties, mut occlusion_differences) = (0, 0, 0);
        let rays = 100_000;
        for i in 0..rays {
            // Half from points inside the bounds, half leaving the surfaces (offset from
            // them as a renderer spawns rays, so neither library re-hits the start).
            let direction = random_direction(&mut rng);
            let origin = if i % 2 == 0 {
                low + (high - low) * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32())
            } else {
                let index = (rng.next_u32() as usize) % scene.triangles.len();
                let [v0, v1, v2] = scene.triangles[index].vertices;
                let (a, b) = (rng.next_f32(), rng.next_f32());
                let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
                let normal = scene.normals[index];
                let side = if normal.dot(direction) >= 0.0 { 1.0 } else { -1.0 };
                v0 + a * (v1 - v0) + b * (v2 - v0) + normal * (side * 1e-5 * (high - low).length())
            };
            let ray = Ray::new(origin, direction);
            match (obvhs.intersect(&ray), embree.intersect(&ray)) {
                (None, None) => {}
                (Some(a), Some(b)) => {
                    // 1e-5 relative, plus the rounding of coordinates (a few ulps of their
                    // magnitude), which moves t by that over the cosine at grazing hits.
                    let cosine = scene.normals[a.primitive as usize].dot(ray.direction).abs().max(1e-3);
                    let tolerance = 1e-5 * a.t + 1e-6 * ray.origin.abs().max_element().max(1.0) / cosine;
                    assert!(
                        (a.t - b.t).abs() <= tolerance,
                        "{name}: t {} vs {} for {ray:?}: {a:?} {b:?} cos {cosine} {:?}",
                        a.t,
                        b.t,
                        scene.triangles[a.primitive as usize].vertices
                    );
                    if a.primitive != b.primitive {
                        // A tie: the ray meets Embree's triangle at the same t too (a shared
                        // edge, or coincident surfaces), by obvhs's own watertight test.
                        let other = ShearedRay::new(ray.origin, ray.direction).intersect(
                            scene.triangles[b.primitive as usize].vertices,
                            0.0,
                            f32::INFINITY,
                        );
                        assert!(
                            other.is_some_and(|h| (h.t - a.t).abs() <= tolerance),
                            "{name}: primitive {} vs {} for {ray:?}",
                            a.primitive,
                            b.primitive
                        );
                        ties += 1;
                    }
                    hits += 1;
                }
                (a, b) => panic!("{name}: obvhs {a:?}, Embree {b:?} for {ray:?}"),
            }
            let segment = Ray { t_max: 0.5 * (high - low).length() * rng.next_f32(), ..ray };
            occlusion_differences += (obvhs.occluded(&segment) != embree.occluded(&segment)) as u32;
        }
        println!("{name}: {hits} hits of {rays} rays, {ties} ties at shared edges, {occlusion_differences} occlusion differences");
        assert!(hits > rays / 4, "{name}: only {hits} hits");
        assert!(occlusion_differences * 1000 <= rays, "{name}: {occlusion_differences} occlusion differences");
        assert!(embree.take_errors().is_empty());
    }
}

#[test]
fn cornell_renders_the_same_with_either_intersector() {
    let scene = support::repository_scene("cornell", 32, 32);
    let render = |choice| {
        let session = reference_tracer::session::prepare(&scene, choice, None).unwrap();
        let settings = reference_tracer::render::RenderSettings {
            integrator: support::settings(Method::Nee),
            budget: reference_tracer::render::Budget::SamplesPerPixel(64),
            seed: 9,
            train_seconds: 0.0,
            schedule: reference_tracer::schedule::Schedule::Online,
            combine: reference_tracer::film::Combine::default(),
            training_share: reference_tracer::schedule::DEFAULT_TRAINING_SHARE,
        };
        let (_, statistics) = reference_tracer::render::render(
            &session.scene,
            session.cpu().intersector(),
            reference_tracer::render::Learners::<guiding_core::HemisphereGrid>::default(),
            &settings,
            |_| {},
        );
        support::mean_estimate(&statistics)
    };
    let (obvhs, embree) = (render(IntersectorChoice::default()), render(IntersectorChoice::Embree));
    support::assert_agree("obvhs vs Embree", &obvhs, &embree);
}
