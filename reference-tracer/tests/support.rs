//! Helpers for the tracer's tests: scenes written to temporary folders, renders in-process.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use reference_tracer::directional_guide::DirectionalGuideSettings;
use reference_tracer::integrator::{IntegratorSettings, Method};
use reference_tracer::output::Image;
use reference_tracer::render::{Budget, RenderSettings, RenderStatistics};
use reference_tracer::scene_intersector::IntersectorChoice;
pub use reference_tracer::schedule::Schedule;
use reference_tracer::session::{prepare_with_lights, LightRequest};

/// A fresh temporary folder for one test; each call its own, so tests running at once
/// that ask for the same name never share (or delete) each other's files. They all sit
/// in one folder per test process (`lodestar-tests/PID`), and the first call of a process
/// removes the folders of processes that have ended: a run leaves at most its own behind.
pub fn temp_folder(name: &str) -> PathBuf {
    static CALLS: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let root = std::env::temp_dir().join("lodestar-tests");
    if call == 0 {
        remove_finished_runs(&root);
    }
    let folder = root.join(std::process::id().to_string()).join(format!("{name}-{call}"));
    let _ = std::fs::remove_dir_all(&folder);
    std::fs::create_dir_all(&folder).unwrap();
    folder
}

/// Removes the folders under `root` named after processes that no longer run (`/proc`
/// has no entry for them); elsewhere, where there is no `/proc`, it removes nothing.
fn remove_finished_runs(root: &Path) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(root) else { return };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(|n| n.parse::<u32>().ok()) else { continue };
        if !Path::new("/proc").join(pid.to_string()).exists() {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

/// Writes `json` as scene.json in `folder` and returns its path.
pub fn write_scene(folder: &Path, json: &serde_json::Value) -> PathBuf {
    let path = folder.join("scene.json");
    std::fs::write(&path, serde_json::to_string_pretty(json).unwrap()).unwrap();
    path
}

/// The repository's scene `name`, with its camera resized and its meshes copied along.
pub fn repository_scene(name: &str, width: u32, height: u32) -> PathBuf {
    let source = scenes_folder().join(name);
    let folder = temp_folder(&format!("scene-{name}-{width}"));
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(source.join("scene.json")).unwrap()).unwrap();
    json["camera"]["width"] = width.into();
    json["camera"]["height"] = height.into();
    // Files outside the scene's folder (shared environment maps) are referred to where they are.
    if let Some(file) = json["environment"]["file"].as_str() {
        json["environment"]["file"] = source.join(file).display().to_string().into();
    }
    copy_folder(&source, &folder);
    write_scene(&folder, &json)
}

/// The repository's `scenes/`, or `LODESTAR_SCENES` where set: a test binary carried to
/// another machine (scripts/device-gpu-check.sh) finds its scenes there.
fn scenes_folder() -> PathBuf {
    match std::env::var_os("LODESTAR_SCENES") {
        Some(folder) => PathBuf::from(folder),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes"),
    }
}

fn copy_folder(from: &Path, to: &Path) {
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.file_type().unwrap().is_dir() {
            std::fs::create_dir_all(&target).unwrap();
            copy_folder(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), target).unwrap();
        }
    }
}

/// Per-pass image means (RGB averaged) of a render: their mean and standard error.
pub struct MeanEstimate {
    pub mean: f64,
    pub standard_error: f64,
}

/// Panics unless the two estimates agree within 4 combined standard errors.
pub fn assert_agree(label: &str, a: &MeanEstimate, b: &MeanEstimate) {
    let error = (a.standard_error.powi(2) + b.standard_error.powi(2)).sqrt();
    assert!(
        (a.mean - b.mean).abs() <= 4.0 * error,
        "{label}: {} ± {} vs {} ± {}",
        a.mean,
        a.standard_error,
        b.mean,
        b.standard_error
    );
}

pub fn mean_estimate(statistics: &RenderStatistics) -> MeanEstimate {
    let values: Vec<f64> = statistics.pass_means.iter().map(|m| (m[0] + m[1] + m[2]) / 3.0).collect();
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let variance = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    MeanEstimate { mean, standard_error: (variance / n).sqrt() }
}

/// Renders `scene` with `settings` for `spp` passes on the current thread pool.
pub fn render_scene(
    scene: &Path,
    integrator: IntegratorSettings,
    guide: Option<DirectionalGuideSettings>,
    spp: u32,
    seed: u64,
) -> RenderStatistics {
    render_image(scene, integrator, guide, spp, seed).1
}

/// [`render_scene`], keeping the image too.
pub fn render_image(
    scene: &Path,
    integrator: IntegratorSettings,
    guide: Option<DirectionalGuideSettings>,
    spp: u32,
    seed: u64,
) -> (Image, RenderStatistics) {
    render_scheduled(scene, integrator, guide, spp, seed, Schedule::Online)
}

/// [`render_image`] under a training `schedule`.
pub fn render_scheduled(
    scene: &Path,
    integrator: IntegratorSettings,
    guide: Option<DirectionalGuideSettings>,
    spp: u32,
    seed: u64,
    schedule: Schedule,
) -> (Image, RenderStatistics) {
    // Learned light selection and environment tiles get guides with the default settings.
    let lights = LightRequest::new(
        Some(integrator.light_selection),
        Some(integrator.environment_sampling),
        integrator.method.uses_nee(),
    );
    let mut session = prepare_with_lights(scene, IntersectorChoice::default(), guide, lights).unwrap();
    session.render(&render_settings(integrator, spp, seed, schedule), |_| {}).unwrap()
}

/// What a render of `spp` passes of `integrator` under `schedule` runs with.
pub fn render_settings(integrator: IntegratorSettings, spp: u32, seed: u64, schedule: Schedule) -> RenderSettings {
    RenderSettings {
        integrator,
        budget: Budget::SamplesPerPixel(spp),
        seed,
        train_seconds: 0.0,
        schedule,
        combine: reference_tracer::film::Combine::default(),
        training_share: reference_tracer::schedule::DEFAULT_TRAINING_SHARE,
    }
}

/// Mean squared difference of two images relative to their mean, over pixels and
/// channels.
pub fn relative_difference(a: &Image, b: &Image) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        for c in 0..3 {
            let mean = 0.5 * (p[c] + q[c]) as f64;
            sum += ((p[c] - q[c]) as f64).powi(2) / (mean * mean + 1e-2);
            count += 1;
        }
    }
    sum / count as f64
}

/// The mean of one quadrant of an image (channels summed).
pub fn quadrant_mean(image: &Image, qx: usize, qy: usize) -> f64 {
    let (w, h) = (image.width, image.height);
    let mut sum = 0.0;
    for y in qy * h / 2..(qy + 1) * h / 2 {
        for x in qx * w / 2..(qx + 1) * w / 2 {
            let p = image.pixels[y * w + x];
            sum += (p.x + p.y + p.z) as f64;
        }
    }
    sum / (w * h / 4) as f64
}

/// The standard error of one render's [`quadrant_mean`], estimated from two independent
/// renders `a` and `b` of one image: each pixel's variance is half its squared
/// difference, and the quadrant's pixels are independent.
pub fn quadrant_standard_error(a: &Image, b: &Image, qx: usize, qy: usize) -> f64 {
    let (w, h) = (a.width, a.height);
    let mut sum = 0.0;
    for y in qy * h / 2..(qy + 1) * h / 2 {
        for x in qx * w / 2..(qx + 1) * w / 2 {
            let (p, q) = (a.pixels[y * w + x], b.pixels[y * w + x]);
            sum += (((p.x + p.y + p.z) - (q.x + q.y + q.z)) as f64).powi(2) / 2.0;
        }
    }
    sum.sqrt() / (w * h / 4) as f64
}

/// Cornell with one box made of a lace that lets half the light through (a masked
/// material, opacity 0.5 everywhere), at `width` × `height`.
pub fn masked_cornell(width: u32, height: u32) -> PathBuf {
    let cornell = repository_scene("cornell", width, height);
    let mut json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&cornell).unwrap()).unwrap();
    json["textures"] =
        serde_json::json!({ "half": { "type": "checkerboard", "even": [0.5, 0.5, 0.5], "odd": [0.5, 0.5, 0.5] } });
    json["materials"]["lace"] =
        serde_json::json!({ "type": "diffuse", "albedo": [0.7, 0.7, 0.7], "opacity_texture": "half" });
    json["shapes"][5]["material"] = "lace".into();
    let folder = cornell.parent().unwrap();
    write_scene(folder, &json)
}

pub fn settings(method: Method) -> IntegratorSettings {
    IntegratorSettings { method, ..Default::default() }
}
