//! The GPU tracer against the CPU tracer (feature `gpu`): at equal spp their image means
//! agree within 4 standard errors (from per-pass means), and the relMSE between their
//! images is the noise level two CPU renders with different seeds show.
//!
//! Without a Vulkan adapter these tests say they were skipped, unless
//! `LODESTAR_REQUIRE_GPU=1` (the test command sets it), which makes a missing adapter a
//! failure: CI must not pass by skipping them.
#![cfg(feature = "gpu")]

mod support;

use std::path::Path;

use guiding_core::Guide;
use reference_tracer::backend::Device;
use reference_tracer::gpu::GpuContext;
use reference_tracer::integrator::{EnvironmentSampling, IntegratorSettings, LightSelection, Method};
use reference_tracer::metrics::image_error;
use reference_tracer::output::Image;
use reference_tracer::render::{Budget, RenderSettings, RenderStatistics};
use reference_tracer::scene_intersector::IntersectorChoice;
use reference_tracer::session::{prepare_with_lights, LightRequest};

/// Whether an adapter exists; panics when none does and one is required.
fn adapter_available(test: &str) -> bool {
    match GpuContext::new() {
        Ok(context) => {
            eprintln!("{test}: GPU {}", context.describe());
            true
        }
        Err(error) if std::env::var("LODESTAR_REQUIRE_GPU").as_deref() == Ok("1") => {
            panic!("{test}: LODESTAR_REQUIRE_GPU=1 but {error}")
        }
        Err(error) => {
            eprintln!("{test}: SKIPPED, no GPU: {error}");
            false
        }
    }
}

/// Lights picked by power, the environment by luminance: nothing learned but the guide.
fn power_lights() -> LightRequest {
    LightRequest::new(Some(LightSelection::Power), Some(EnvironmentSampling::Luminance), true)
}

fn integrator(method: Method) -> IntegratorSettings {
    IntegratorSettings {
        method,
        light_selection: LightSelection::Power,
        environment_sampling: EnvironmentSampling::Luminance,
        ..Default::default()
    }
}

fn render(scene: &Path, device: Device, method: Method, spp: u32, seed: u64) -> (Image, RenderStatistics) {
    let (integrator, lights) = (integrator(method), power_lights());
    let mut session = prepare_with_lights(scene, IntersectorChoice::default(), None, lights).unwrap();
    session.device = device;
    let settings = RenderSettings {
        integrator,
        budget: Budget::SamplesPerPixel(spp),
        seed,
        train_seconds: 0.0,
        schedule: reference_tracer::schedule::Schedule::Online,
        combine: reference_tracer::film::Combine::default(),
        training_share: reference_tracer::schedule::DEFAULT_TRAINING_SHARE,
    };
    session.render(&settings, |_| {}).unwrap()
}

/// GPU and CPU agree on `scene`'s mean, and their images differ by no more than two CPU
/// renders do.
fn check_agreement(name: &str, width: u32, height: u32, spp: u32) {
    let scene = support::repository_scene(name, width, height);
    for method in [Method::Nee, Method::Pt] {
        let (gpu_image, gpu) = render(&scene, Device::Gpu, method, spp, 3);
        let (cpu_image, cpu) = render(&scene, Device::Cpu, method, spp, 4);
        let (other_image, _) = render(&scene, Device::Cpu, method, spp, 5);
        let label = format!("{name} {}", method.name());
        support::assert_agree(
            &format!("{label}: GPU vs CPU"),
            &support::mean_estimate(&gpu),
            &support::mean_estimate(&cpu),
        );
        assert!(gpu_image.pixels.iter().all(|p| p.is_finite()), "{label}: non-finite GPU pixels");
        let between = image_error(&gpu_image, &cpu_image).unwrap().relmse;
        let noise = image_error(&other_image, &cpu_image).unwrap().relmse;
        eprintln!("{label}: relMSE GPU vs CPU {between:.4e}, CPU vs CPU {noise:.4e}");
        assert!(between <= 1.5 * noise, "{label}: relMSE GPU vs CPU {between} against the noise {noise}");
        assert_eq!(gpu.counters.paths, (width * height * spp) as u64);
    }
}

#[test]
fn cornell_renders_alike_on_gpu_and_cpu() {
    if adapter_available("cornell") {
        check_agreement("cornell", 48, 48, 64);
    }
}

#[test]
fn door_renders_alike_on_gpu_and_cpu() {
    if adapter_available("door") {
        check_agreement("door", 40, 30, 256);
    }
}

#[test]
fn unsupported_scenes_are_refused_with_a_reason() {
    if !adapter_available("unsupported") {
        return;
    }
    // The window scene's image environment is not on the GPU yet.
    let scene = support::repository_scene("window", 8, 8);
    let mut session = prepare_with_lights(&scene, IntersectorChoice::default(), None, power_lights()).unwrap();
    session.device = Device::Gpu;
    let settings = RenderSettings {
        integrator: IntegratorSettings { method: Method::Nee, ..Default::default() },
        budget: Budget::SamplesPerPixel(1),
        seed: 1,
        train_seconds: 0.0,
        schedule: reference_tracer::schedule::Schedule::Online,
        combine: reference_tracer::film::Combine::default(),
        training_share: reference_tracer::schedule::DEFAULT_TRAINING_SHARE,
    };
    let error = session.render(&settings, |_| {}).expect_err("refused");
    assert!(error.contains("image environment"), "{error}");
}

// ---------------------------------------------------------------------------------
// Guided rendering on the GPU, for each of the four directional guides.

use glam::Vec3;
use guiding_core::validation::{chi_square_test, ChiSquareReport, ChiSquareSettings};
use guiding_core::{
    DirectionSample, DirectionalDistribution, GaussianMixture, GaussianMixtureSettings, HemisphereGrid,
    IrradianceVolume, IrradianceVolumeSettings, MixtureRegion, ProbeId, SpatialDirectionalTree,
    SpatialDirectionalTreeSettings, TreeRegion, VolumeRegion,
};
use reference_tracer::directional_guide::{DirectionalGuide, DirectionalGuideSettings};
use reference_tracer::gpu::{GpuGuide, GpuTracer};

fn hemisphere(probes: usize) -> DirectionalGuideSettings {
    guiding_core::HemisphereGridSettings { probe_count: Some(probes), ..Default::default() }.into()
}

/// A volume of `budget_kib` KiB whose leaves split after `split` updates per patch.
fn volume(budget_kib: usize, split: f32) -> IrradianceVolumeSettings {
    IrradianceVolumeSettings { budget_bytes: budget_kib << 10, split_updates_per_patch: split, ..Default::default() }
}

/// A mixture of 0.5 MiB.
fn mixture() -> GaussianMixtureSettings {
    GaussianMixtureSettings { budget_bytes: 512 << 10, ..Default::default() }
}

/// A tree of 256 KiB.
fn tree() -> SpatialDirectionalTreeSettings {
    SpatialDirectionalTreeSettings { budget_bytes: 256 << 10, ..Default::default() }
}

/// Renders `scene` with a fresh directional guide built from `settings` on `device`;
/// returns the render and the guide it learned.
fn render_learning(
    scene: &Path,
    device: Device,
    method: Method,
    spp: u32,
    seed: u64,
    settings: DirectionalGuideSettings,
) -> (RenderStatistics, DirectionalGuide) {
    // The shader's tables learn each direction unweighted, its mixture and tree by target/pdf:
    // the CPU renders compared with them learn alike.
    let density_weighted_learning =
        matches!(settings, DirectionalGuideSettings::Mixture(_) | DirectionalGuideSettings::Tree(_));
    let integrator = IntegratorSettings { density_weighted_learning, nee_weighs_guide: true, ..integrator(method) };
    let lights = power_lights();
    let mut session = prepare_with_lights(scene, IntersectorChoice::default(), Some(settings), lights).unwrap();
    session.device = device;
    let settings = RenderSettings {
        integrator,
        budget: Budget::SamplesPerPixel(spp),
        seed,
        train_seconds: 0.0,
        schedule: reference_tracer::schedule::Schedule::Online,
        combine: reference_tracer::film::Combine::default(),
        training_share: reference_tracer::schedule::DEFAULT_TRAINING_SHARE,
    };
    let (_, statistics) = session.render(&settings, |_| {}).unwrap();
    (statistics, session.learners.guide.expect("a guide was built"))
}

/// [`render_learning`] with a hemisphere grid of `probes` probes.
fn render_guided(
    scene: &Path,
    device: Device,
    method: Method,
    spp: u32,
    seed: u64,
    probes: usize,
) -> (RenderStatistics, HemisphereGrid) {
    match render_learning(scene, device, method, spp, seed, hemisphere(probes)) {
        (statistics, DirectionalGuide::Hemisphere(grid)) => (statistics, *grid),
        _ => panic!("a hemisphere grid was built"),
    }
}

/// [`render_learning`] with an irradiance volume.
fn render_with_volume(
    scene: &Path,
    device: Device,
    method: Method,
    spp: u32,
    seed: u64,
    settings: IrradianceVolumeSettings,
) -> (RenderStatistics, IrradianceVolume) {
    match render_learning(scene, device, method, spp, seed, settings.into()) {
        (statistics, DirectionalGuide::Volume(volume)) => (statistics, volume),
        _ => panic!("a volume was built"),
    }
}

/// [`render_learning`] with a Gaussian mixture.
fn render_with_mixture(
    scene: &Path,
    device: Device,
    method: Method,
    spp: u32,
    seed: u64,
) -> (RenderStatistics, GaussianMixture) {
    match render_learning(scene, device, method, spp, seed, mixture().into()) {
        (statistics, DirectionalGuide::Mixture(mixture)) => (statistics, mixture),
        _ => panic!("a mixture was built"),
    }
}

/// [`render_learning`] with a spatial × directional tree.
fn render_with_tree(
    scene: &Path,
    device: Device,
    method: Method,
    spp: u32,
    seed: u64,
) -> (RenderStatistics, SpatialDirectionalTree) {
    match render_learning(scene, device, method, spp, seed, tree().into()) {
        (statistics, DirectionalGuide::Tree(tree)) => (statistics, tree),
        _ => panic!("a tree was built"),
    }
}

/// On cornell and door, for guided-nee and guided: renders on the GPU with `render`
/// (given device, method, spp, seed), checks the mean against CPU nee within 4 standard
/// errors, and hands the learned guide to `check` with its label, method and spp.
fn guided_renders_agree_with_cpu_nee<G>(
    seed: u64,
    render_with: impl Fn(&Path, Device, Method, u32, u64) -> (RenderStatistics, G),
    mut check: impl FnMut(&str, &Path, Method, u32, &G),
) {
    for (name, width, height, spp) in [("cornell", 32, 32, 96), ("door", 32, 24, 256)] {
        let scene = support::repository_scene(name, width, height);
        let (_, nee) = render(&scene, Device::Cpu, Method::Nee, spp * 2, seed);
        let reference = support::mean_estimate(&nee);
        for method in [Method::GuidedNee, Method::Guided] {
            let spp = if method == Method::Guided { spp * 4 } else { spp };
            let (statistics, guide) = render_with(&scene, Device::Gpu, method, spp, seed + 1);
            let label = format!("{name} gpu:{} vs cpu nee", method.name());
            support::assert_agree(&label, &support::mean_estimate(&statistics), &reference);
            check(&label, &scene, method, spp, &guide);
        }
    }
}

/// Accepted updates of `gpu` over `cpu`'s: within 5 % of one.
fn assert_updates_alike(label: &str, gpu: &impl Guide, cpu: &impl Guide) {
    let ratio = gpu.stats().accepted_updates as f64 / cpu.stats().accepted_updates as f64;
    eprintln!("{label}: updates GPU/CPU {ratio:.4}");
    assert!((ratio - 1.0).abs() < 0.05, "{label}: updates GPU/CPU {ratio}");
}

#[test]
fn guided_methods_on_the_gpu_agree_with_cpu_nee() {
    if !adapter_available("guided") {
        return;
    }
    let render_with = |scene: &Path, device, method, spp, seed| render_guided(scene, device, method, spp, seed, 400);
    guided_renders_agree_with_cpu_nee(9, render_with, |label, _, _, _, grid| {
        assert!(grid.stats().accepted_updates > 0, "{label}: the GPU learned nothing");
        assert!(grid.validate().is_ok(), "{label}");
    });
}

#[test]
fn the_volume_guides_on_the_gpu_without_bias_and_splits_like_the_cpu() {
    if !adapter_available("volume") {
        return;
    }
    let settings = volume(256, 8.0);
    let render_with =
        |scene: &Path, device, method, spp, seed| render_with_volume(scene, device, method, spp, seed, settings);
    guided_renders_agree_with_cpu_nee(41, render_with, |label, scene, method, spp, gpu| {
        let (_, cpu) = render_with(scene, Device::Cpu, method, spp, 44);
        let fresh = prepare_with_lights(scene, IntersectorChoice::default(), Some(settings.into()), power_lights());
        let Some(DirectionalGuide::Volume(fresh)) = fresh.unwrap().learners.guide else { panic!("a volume was built") };
        assert!(gpu.validate().is_ok(), "{label}");
        assert!(gpu.memory_bytes() <= settings.budget_bytes, "{label}: {} bytes", gpu.memory_bytes());
        // Leaves split on the host between GPU passes, as many as on the CPU.
        let (g, c) = (gpu.leaf_count(), cpu.leaf_count());
        eprintln!("{label}: leaves GPU {g}, CPU {c} (from {})", fresh.leaf_count());
        assert!(g > fresh.leaf_count(), "{label}: no leaf split");
        assert!((g as f64 / c as f64 - 1.0).abs() < 0.1, "{label}: leaves GPU {g} vs CPU {c}");
        assert_updates_alike(label, gpu, &cpu);
    });
}

#[test]
fn the_mixture_guides_on_the_gpu_without_bias_and_learns_like_the_cpu() {
    if !adapter_available("mixture") {
        return;
    }
    guided_renders_agree_with_cpu_nee(61, render_with_mixture, |label, scene, method, spp, gpu| {
        let (_, cpu) = render_with_mixture(scene, Device::Cpu, method, spp, 64);
        assert!(gpu.validate().is_ok(), "{label}");
        assert_eq!(gpu.stats().epochs, cpu.stats().epochs, "{label}: one M-step per pass");
        assert_updates_alike(label, gpu, &cpu);
    });
}

#[test]
fn the_tree_guides_on_the_gpu_without_bias_and_refines_like_the_cpu() {
    if !adapter_available("tree") {
        return;
    }
    guided_renders_agree_with_cpu_nee(91, render_with_tree, |label, scene, method, spp, gpu| {
        let (_, cpu) = render_with_tree(scene, Device::Cpu, method, spp, 94);
        assert!(gpu.validate().is_ok(), "{label}");
        assert!(gpu.memory_bytes() <= tree().budget_bytes, "{label}: {} bytes", gpu.memory_bytes());
        // The host refits after every pass, as the CPU's online schedule does, and the
        // records split space and directions as many times over.
        assert_eq!(gpu.stats().epochs, cpu.stats().epochs, "{label}: one refit per pass");
        let (g, c) = (gpu.leaf_count(), cpu.leaf_count());
        let (gn, cn) = (gpu.directional_node_count(), cpu.directional_node_count());
        eprintln!("{label}: leaves GPU {g}, CPU {c}; directional nodes GPU {gn}, CPU {cn}");
        assert!(g > 1 && gn > g, "{label}: the GPU's records refined nothing");
        assert!((g as f64 / c as f64 - 1.0).abs() < 0.25, "{label}: leaves GPU {g} vs CPU {c}");
        assert_updates_alike(label, gpu, &cpu);
    });
}

#[test]
fn the_gpus_tree_serves_the_cpu() {
    if !adapter_available("tree learning") {
        return;
    }
    let scene = support::repository_scene("cornell", 32, 32);
    let (_, gpu) = render_with_tree(&scene, Device::Gpu, Method::GuidedNee, 48, 101);
    assert!(gpu.leaf_count() > 1, "the GPU's tree did not refine");
    gpu_learned_guide_serves_the_cpu(tree().into(), &gpu.to_bytes(), 104);
}

/// Directions drawn on the GPU, replayed as a distribution whose pdf is guiding-core's.
struct GpuSamples<D> {
    samples: Vec<[f32; 4]>,
    next: std::cell::Cell<usize>,
    cpu: D,
}

impl<D: DirectionalDistribution> DirectionalDistribution for GpuSamples<D> {
    fn sample(&self, _u: glam::Vec2) -> DirectionSample {
        let [x, y, z, pdf] = self.samples[self.next.get() % self.samples.len()];
        self.next.set(self.next.get() + 1);
        DirectionSample { direction: Vec3::new(x, y, z), pdf }
    }

    fn pdf(&self, direction: Vec3) -> f32 {
        self.cpu.pdf(direction)
    }
}

/// Uploads `guide` (learned on the CPU), draws 10⁶ directions from `region` on the GPU
/// (about `normal` where the guide folds), checks each of the first thousand's pdf
/// against `cpu` (guiding-core's distribution of that region), and bins them all
/// about `axis` against `cpu`'s pdf.
fn gpu_sampler_report<D: DirectionalDistribution>(
    guide: GpuGuide<'_>,
    region: u32,
    normal: Vec3,
    cpu: D,
    axis: Vec3,
) -> ChiSquareReport {
    let scene = support::repository_scene("cornell", 24, 24);
    let session = prepare_with_lights(&scene, IntersectorChoice::default(), None, power_lights()).unwrap();
    let integrator = IntegratorSettings { method: Method::GuidedNee, ..Default::default() };
    let mut gpu = GpuTracer::new(GpuContext::new().unwrap(), &session.scene, &integrator, Some(guide)).unwrap();
    let settings = ChiSquareSettings::default();
    let samples = gpu.sample_guide(region, normal, settings.samples, 17).unwrap();
    // guiding-core maps a direction to its patch with an atan2 good to 2e-6 rad, the
    // shader with its own: a direction drawn within that of a patch's edge may fall in
    // the neighbour on the CPU. Such a sample must match the CPU a hair's breadth away,
    // and be rare.
    let mut at_edges = 0;
    for s in samples.iter().take(1000) {
        let direction = Vec3::new(s[0], s[1], s[2]);
        let matches = |pdf: f32| (s[3] - pdf).abs() <= 1e-3 * pdf;
        if matches(cpu.pdf(direction)) {
            continue;
        }
        let (t, b) = direction.any_orthonormal_pair();
        let nearby = [t, -t, b, -b].map(|offset| cpu.pdf((direction + 2e-5 * offset).normalize()));
        assert!(nearby.into_iter().any(matches), "GPU pdf {} vs CPU {:?} at {direction}", s[3], nearby);
        at_edges += 1;
    }
    assert!(at_edges <= 5, "{at_edges} of 1000 GPU samples fall on patch edges");
    let report = chi_square_test(&GpuSamples { samples, next: std::cell::Cell::new(0), cpu }, axis, &settings);
    eprintln!("GPU sampler, region {region}: {report:?}");
    report
}

#[test]
fn the_gpu_samplers_match_guiding_cores_pdfs() {
    if !adapter_available("samplers") {
        return;
    }
    let scene = support::repository_scene("cornell", 24, 24);
    // The hemisphere grid: the most-visited probe has the least uniform distribution.
    let (_, grid) = render_guided(&scene, Device::Cpu, Method::GuidedNee, 16, 5, 200);
    let visits = grid.probe_visit_counts();
    let probe = (0..grid.probe_count()).max_by_key(|&p| visits[p].load(std::sync::atomic::Ordering::Relaxed)).unwrap();
    let normal = grid.probe_normals()[probe];
    let cpu = grid.distribution(ProbeId(probe as u32));
    assert!(gpu_sampler_report((&grid).into(), probe as u32, normal, cpu, normal).passes(0.01));
    // The volume's most-visited leaf, folded about a normal off every axis so both
    // halves of the sphere contribute.
    let (_, learned) = render_with_volume(&scene, Device::Cpu, Method::GuidedNee, 16, 45, volume(256, 8.0));
    let visits = learned.leaf_visit_counts();
    let leaf = (0..learned.leaf_count()).max_by_key(|&l| visits[l].load(std::sync::atomic::Ordering::Relaxed)).unwrap();
    let normal = Vec3::new(0.3, 0.8, -0.52).normalize();
    let cpu = learned.distribution(VolumeRegion { leaf: leaf as u32, normal });
    assert!(gpu_sampler_report((&learned).into(), leaf as u32, normal, cpu, normal).passes(0.01));
    // The mixture region that saw the most samples, binned about its sharpest lobe.
    let (_, learned) = render_with_mixture(&scene, Device::Cpu, Method::GuidedNee, 32, 65);
    let observations = |r: usize| learned.mixture(r).observations();
    let region = (0..learned.region_count()).max_by_key(|&r| observations(r)).unwrap();
    let m = learned.mixture(region);
    let sharpest =
        (0..m.lobe_count()).max_by(|&a, &b| m.lobe(a).0.concentration().total_cmp(&m.lobe(b).0.concentration()));
    let (lobe, _) = m.lobe(sharpest.unwrap_or(0));
    eprintln!("mixture region {region}: {} samples, largest κ {}", observations(region), lobe.concentration());
    assert!(lobe.concentration() > 1.0, "the mixture learned no lobe");
    // Folded about a normal 50° from that lobe, so the lobe stays above the surface and
    // the fold still reaches the rest of the mixture.
    let side = lobe.mean().cross(Vec3::new(0.3, 0.8, -0.52)).normalize();
    let normal = (lobe.mean() + 1.2 * side).normalize();
    let cpu = learned.distribution(MixtureRegion { index: region as u32, normal });
    assert!(gpu_sampler_report((&learned).into(), region as u32, normal, cpu, lobe.mean()).passes(0.01));
    // The tree's most-refined leaf: about a normal along its square's axis (the half of
    // the square, by the cosine product) and about one off every axis (the fold).
    let (_, learned) = render_with_tree(&scene, Device::Cpu, Method::GuidedNee, 32, 105);
    let leaf = (0..learned.leaf_count() as u32).max_by_key(|&l| learned.directional_depth(l)).unwrap();
    let mut axis = Vec3::ZERO;
    axis[learned.leaf_axis(leaf).unwrap() as usize] = 1.0;
    eprintln!("tree leaf {leaf}: depth {}, axis {axis}", learned.directional_depth(leaf));
    assert!(learned.directional_depth(leaf) > 2, "the tree refined no leaf");
    for normal in [axis, -axis, Vec3::new(0.3, 0.8, -0.52).normalize()] {
        let region = TreeRegion { leaf, normal, upper_half: false };
        let cpu = learned.distribution(region);
        assert!(gpu_sampler_report((&learned).into(), leaf, normal, cpu, normal).passes(0.01), "about {normal}");
    }
}

/// Mean squared relative difference of per-region totals over the regions both learned
/// in: `totals` gives each region's total (or `None` where it saw too little).
fn total_difference(a: &[Option<f64>], b: &[Option<f64>]) -> f64 {
    let terms: Vec<f64> = a
        .iter()
        .zip(b)
        .filter_map(|(x, y)| Some(((x.as_ref()? - y.as_ref()?) / (0.5 * (x.as_ref()? + y.as_ref()?))).powi(2)))
        .collect();
    assert!(terms.len() > 20, "too few regions learned: {}", terms.len());
    terms.iter().sum::<f64>() / terms.len() as f64
}

/// Renders cornell four times with guided-nee (CPU thrice, GPU once) from fresh guides,
/// compares per-region totals GPU vs CPU against CPU vs CPU, and returns the GPU's guide.
/// Both sides average over three pairs: one pair's mean over a few dozen regions is too
/// noisy to compare (a single CPU pair against one GPU pair failed 2× by chance).
fn gpu_and_cpu_totals_agree<G>(
    seed: u64,
    render_with: impl Fn(&Path, Device, u64) -> G,
    totals: impl Fn(&G) -> Vec<Option<f64>>,
) -> G {
    let (between, noise, gpu) = totals_between_and_noise(seed, &render_with, &totals);
    eprintln!("per-region totals: GPU vs CPU {between:.4e}, CPU vs CPU {noise:.4e}");
    assert!(between <= 2.0 * noise + 1e-6, "GPU vs CPU {between} against CPU vs CPU {noise}");
    gpu
}

/// (GPU vs CPU, CPU vs CPU, the GPU's guide): each the mean of [`total_difference`] over
/// three pairs.
fn totals_between_and_noise<G>(
    seed: u64,
    render_with: &impl Fn(&Path, Device, u64) -> G,
    totals: &impl Fn(&G) -> Vec<Option<f64>>,
) -> (f64, f64, G) {
    let scene = support::repository_scene("cornell", 32, 32);
    let cpus: Vec<_> = (0..3).map(|i| totals(&render_with(&scene, Device::Cpu, seed + i))).collect();
    let gpu = render_with(&scene, Device::Gpu, seed + 3);
    let gpu_totals = totals(&gpu);
    let noise = [(0, 1), (1, 2), (0, 2)].iter().map(|&(a, b)| total_difference(&cpus[a], &cpus[b])).sum::<f64>() / 3.0;
    let between = cpus.iter().map(|cpu| total_difference(&gpu_totals, cpu)).sum::<f64>() / 3.0;
    (between, noise, gpu)
}

/// `bytes` (a GPU-learned guide) load into the guide `settings` builds, round-trip
/// exactly, and guide the CPU tracer (learning off) to the nee mean within 4 SE.
fn gpu_learned_guide_serves_the_cpu(settings: DirectionalGuideSettings, bytes: &[u8], seed: u64) {
    let scene = support::repository_scene("cornell", 32, 32);
    let mut session =
        prepare_with_lights(&scene, IntersectorChoice::default(), Some(settings), power_lights()).unwrap();
    let structure = session.learners.guide.take().expect("a guide was built").structure();
    let loaded = DirectionalGuide::from_bytes(structure, bytes).unwrap();
    let again = loaded.to_bytes();
    assert_eq!(again, bytes, "the GPU's learned state round-trips exactly");
    session.learners.guide = Some(loaded);
    let integrator = IntegratorSettings { method: Method::GuidedNee, learn: false, ..Default::default() };
    let render_settings = RenderSettings {
        integrator,
        budget: Budget::SamplesPerPixel(96),
        seed,
        train_seconds: 0.0,
        schedule: reference_tracer::schedule::Schedule::Online,
        combine: reference_tracer::film::Combine::default(),
        training_share: reference_tracer::schedule::DEFAULT_TRAINING_SHARE,
    };
    let (_, guided) = session.render(&render_settings, |_| {}).unwrap();
    let (_, nee) = render(&scene, Device::Cpu, Method::Nee, 192, seed + 1);
    support::assert_agree(
        "cpu guided-nee with the GPU's guide vs nee",
        &support::mean_estimate(&guided),
        &support::mean_estimate(&nee),
    );
}

fn learned(visits: u32) -> bool {
    visits > 200
}

#[test]
fn gpu_and_cpu_learn_the_same_q_tables_and_the_gpus_grid_serves_the_cpu() {
    if !adapter_available("grid learning") {
        return;
    }
    // The same probes (placement is deterministic), taught by the same method and spp.
    let render_with = |scene: &Path, device, seed| render_guided(scene, device, Method::GuidedNee, 48, seed, 200).1;
    let totals = |grid: &HemisphereGrid| {
        let (n, visits) = (grid.patch_count(), grid.probe_visit_counts());
        let q = |i: usize| f32::from_bits(grid.q_values()[i].load(std::sync::atomic::Ordering::Relaxed)) as f64;
        (0..grid.probe_count())
            .map(|p| {
                learned(visits[p].load(std::sync::atomic::Ordering::Relaxed))
                    .then(|| (0..n).map(|k| q(p * n + k)).sum())
            })
            .collect()
    };
    let gpu = gpu_and_cpu_totals_agree(21, render_with, totals);
    let scene = support::repository_scene("cornell", 32, 32);
    let cpu = render_with(&scene, Device::Cpu, 21);
    assert_eq!(gpu.probe_positions(), cpu.probe_positions());
    assert_updates_alike("grid", &gpu, &cpu);
    assert!(gpu.validate().is_ok());
    gpu_learned_guide_serves_the_cpu(hemisphere(200), &gpu.to_bytes(), 32);
}

#[test]
fn gpu_and_cpu_learn_the_same_volume_tables_and_the_gpus_volume_serves_the_cpu() {
    if !adapter_available("volume learning") {
        return;
    }
    // No splitting, so both keep the same leaves and the tables compare one to one.
    let settings = volume(512, 1e9);
    let render_with =
        |scene: &Path, device, seed| render_with_volume(scene, device, Method::GuidedNee, 48, seed, settings).1;
    let totals = |v: &IrradianceVolume| {
        let visits = v.leaf_visit_counts();
        (0..v.leaf_count())
            .map(|l| {
                let seen = learned(visits[l].load(std::sync::atomic::Ordering::Relaxed));
                seen.then(|| (0..v.patch_count()).map(|k| v.q(l as u32, k) as f64).sum())
            })
            .collect()
    };
    let gpu = gpu_and_cpu_totals_agree(51, render_with, totals);
    let cpu = render_with(&support::repository_scene("cornell", 32, 32), Device::Cpu, 51);
    assert_eq!(gpu.nodes(), cpu.nodes());
    assert_updates_alike("volume", &gpu, &cpu);
    gpu_learned_guide_serves_the_cpu(settings.into(), &gpu.to_bytes(), 54);
}

#[test]
fn gpu_and_cpu_learn_the_same_mixtures_and_the_gpus_mixture_serves_the_cpu() {
    if !adapter_available("mixture learning") {
        return;
    }
    let render_with = |scene: &Path, device, seed| render_with_mixture(scene, device, Method::GuidedNee, 48, seed).1;
    let totals = |m: &GaussianMixture| {
        (0..m.region_count())
            .map(|r| {
                let mixture = m.mixture(r);
                learned(mixture.observations()).then(|| mixture.total_weight() as f64)
            })
            .collect()
    };
    let gpu = gpu_and_cpu_totals_agree(71, render_with, totals);
    gpu_learned_guide_serves_the_cpu(mixture().into(), &gpu.to_bytes(), 74);
}

#[test]
fn gpu_training_passes_are_discarded_like_the_cpus() {
    if !adapter_available("training") {
        return;
    }
    let scene = support::repository_scene("cornell", 16, 16);
    let mut session =
        prepare_with_lights(&scene, IntersectorChoice::default(), Some(hemisphere(100)), power_lights()).unwrap();
    session.device = Device::Gpu;
    let settings = RenderSettings {
        integrator: integrator(Method::GuidedNee),
        budget: Budget::SamplesPerPixel(4),
        seed: 81,
        train_seconds: 0.5,
        schedule: reference_tracer::schedule::Schedule::Online,
        combine: reference_tracer::film::Combine::default(),
        training_share: reference_tracer::schedule::DEFAULT_TRAINING_SHARE,
    };
    let (_, statistics) = session.render(&settings, |_| {}).unwrap();
    assert!(statistics.training_passes > 0, "no training pass");
    assert_eq!(statistics.passes, 4, "the kept passes are the budget's");
}
