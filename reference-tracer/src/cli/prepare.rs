//! A scene prepared for rendering: the intersector, the plan and every learner, built
//! once (the composition root of the tracer).

use std::path::Path;
use std::time::Instant;

use crate::scene_intersector::{IntersectorChoice, SceneIntersector};
use guiding_core::environment::{EnvironmentTiles, SunDisk};
use guiding_core::{
    EnvTileGuide, EnvTileGuideSettings, FocalGuide, FocalGuideSettings, Guide, HemisphereGrid, LightGuide,
    LightGuideSettings, NextEventGate, NextEventGateSettings, StrategyShares,
};

use super::options::GUIDE_SHARE_COST;
use crate::directional_guide::{DirectionalGuide, DirectionalGuideSettings, GuideVisitor};
use crate::integrator::{EnvironmentSampling, LightSelection, Method};
use crate::output::Image;
use crate::plan::{auto_light_split, GuidePlan};
use crate::render::{render, Learners, Progress, RenderSettings, RenderStatistics};
use crate::scene::Scene;

/// Timings of the set-up stages, seconds.
#[derive(Clone, Copy, Debug, Default)]
pub struct SetupTimes {
    /// Reading and checking the scene.
    pub load: f64,
    /// Building the BVH.
    pub bvh: f64,
    /// Placing probes and allocating the guide.
    pub guide: f64,
}

/// Where paths are traced.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Device {
    /// The CPU tracer on every core (rayon).
    #[default]
    Cpu,
    /// The GPU tracer (feature `gpu`).
    Gpu,
}

impl Device {
    /// Parses `cpu` or `gpu`.
    pub fn from_name(name: &str) -> Result<Self, String> {
        match name {
            "cpu" => Ok(Device::Cpu),
            "gpu" => Ok(Device::Gpu),
            _ => Err(format!("unknown device `{name}` (cpu, gpu)")),
        }
    }
}

/// How the directional guide's share of the scattering is set (`--guide-share`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GuideShare {
    /// `--p-guide` at every guided vertex.
    #[default]
    Fixed,
    /// Learned per region, up to `--p-guide`.
    Learned,
}

impl GuideShare {
    /// Parses `fixed` or `learned`.
    pub fn from_name(name: &str) -> Result<Self, String> {
        match name {
            "fixed" => Ok(GuideShare::Fixed),
            "learned" => Ok(GuideShare::Learned),
            _ => Err(format!("unknown guide share `{name}` (fixed, learned)")),
        }
    }
}

/// A scene loaded with its intersector and, for guided methods, its guide.
pub struct Prepared {
    /// The scene.
    pub scene: Scene,
    /// Its intersector.
    pub intersector: SceneIntersector,
    /// The directional guide, for guided methods.
    pub guide: Option<DirectionalGuide>,
    /// What `guide` was built from (a fresh one of the same settings learns W).
    pub guide_settings: Option<DirectionalGuideSettings>,
    /// W, the importance bdpt-guided's light subpaths learn and are guided by: a guide of
    /// the same structure and settings as `guide`, built at the first bdpt-guided render.
    pub importance_guide: Option<DirectionalGuide>,
    /// The focal guide, built at the first render of a guided method that aims at it.
    pub focal_guide: Option<FocalGuide>,
    /// The directional guide's learned shares, built at the first render that learns them.
    pub guide_shares: Option<StrategyShares>,
    /// Its settings.
    pub focal_settings: FocalGuideSettings,
    /// The learned guide share's cost of guiding (`--guide-share-cost`).
    pub guide_share_cost: f32,
    /// The learned light selection, when the plan asks for it and the scene has area lights.
    pub light_guide: Option<LightGuide>,
    /// The next-event gate, for guided methods on the CPU with area lights.
    pub gate: Option<NextEventGate>,
    /// The learned environment sampling, when the plan asks for it and the scene has an
    /// environment.
    pub environment_guide: Option<EnvTileGuide>,
    /// What was built and why.
    pub plan: GuidePlan,
    /// Set-up timings.
    pub times: SetupTimes,
    /// Where [`render`](Self::render) traces paths.
    pub device: Device,
    /// The scene on the GPU, once a GPU render has uploaded it.
    #[cfg(feature = "gpu")]
    pub(super) gpu: Option<crate::gpu::GpuTracer>,
}

impl Prepared {
    /// Renders at `resolution` (the same vertical field of view) when one is given.
    pub(super) fn resize(&mut self, resolution: Option<[u32; 2]>) {
        if let Some([width, height]) = resolution {
            self.scene.camera = self.scene.camera.with_resolution(width, height);
        }
    }

    #[cfg(feature = "gpu")]
    pub(super) fn render_on_gpu(
        &mut self,
        settings: &RenderSettings,
        on_pass: impl FnMut(&Progress<'_>),
    ) -> Result<(Image, RenderStatistics), String> {
        use crate::gpu::GpuGuide;
        let guide = self.guide.as_mut().filter(|_| settings.integrator.method.uses_guide());
        if guide.is_some() && settings.schedule != crate::schedule::Schedule::Online {
            return Err("the GPU tracer learns online only (--schedule online)".into());
        }
        if guide.is_some() && settings.integrator.guide_depth != u32::MAX {
            return Err("the GPU tracer guides every vertex (leave out --guide-depth)".into());
        }
        if settings.integrator.method.uses_guide() && settings.integrator.focal_probability > 0.0 {
            return Err("the GPU tracer has no focal guide yet (leave out --p-focal)".into());
        }
        if guide.is_some() && settings.integrator.learned_guide_share {
            return Err("the GPU tracer has no learned guide share (--guide-share fixed)".into());
        }
        // Refused before the GPU starts: a structure it has no buffers for.
        let uploaded = guide.as_deref().map(GpuGuide::of).transpose()?;
        if self.gpu.is_none() {
            let context = crate::gpu::GpuContext::new()?;
            eprintln!("gpu: {}", context.describe());
            let tracer = crate::gpu::GpuTracer::new(context, &self.scene, &settings.integrator, uploaded)?;
            self.gpu = Some(tracer);
        }
        let gpu = self.gpu.as_mut().ok_or("no GPU tracer")?;
        let result = gpu.render(settings, on_pass)?;
        if let Some(guide) = guide {
            gpu.download(guide)?;
        }
        Ok(result)
    }

    #[cfg(not(feature = "gpu"))]
    pub(super) fn render_on_gpu(
        &mut self,
        _settings: &RenderSettings,
        _on_pass: impl FnMut(&Progress<'_>),
    ) -> Result<(Image, RenderStatistics), String> {
        Err("this lodestar was built without the GPU tracer (cargo build --release -p reference-tracer --features gpu)"
            .into())
    }

    /// Bytes of every structure `method` learns with: the directional and focal guides
    /// (guided methods), the light guide and the environment guide (as built by the plan).
    pub fn learned_bytes(&self, method: Method) -> usize {
        let directions = self.guide.as_ref().filter(|_| method.uses_guide()).map_or(0, |g| g.stats().memory_bytes)
            + self.guide_shares.as_ref().filter(|_| method.uses_guide()).map_or(0, StrategyShares::memory_bytes);
        let lights = self.light_guide.as_ref().map_or(0, LightGuide::memory_bytes)
            + self.gate.as_ref().map_or(0, NextEventGate::memory_bytes);
        let environment = self.environment_guide.as_ref().map_or(0, EnvTileGuide::memory_bytes);
        let focal = self.focal_guide.as_ref().filter(|_| method.uses_guide()).map_or(0, FocalGuide::memory_bytes);
        directions + focal + lights + environment
    }

    /// Renders with the learners built (the directional guide only for guided
    /// methods), calling `on_pass` after every pass; the guide's structure picks the
    /// tracer's instance. On the GPU the scene is uploaded at the first render.
    pub fn render(
        &mut self,
        settings: &RenderSettings,
        on_pass: impl FnMut(&Progress<'_>),
    ) -> Result<(Image, RenderStatistics), String> {
        let method = settings.integrator.method;
        if method.splats() || method.gathers_virtual_lights() {
            let name = method.name();
            if self.device == Device::Gpu {
                return Err(format!("{name}: the GPU tracer has no light subpaths (use --device cpu)"));
            }
            if self.scene.environment.is_some() {
                return Err(format!(
                    "{name}: light paths start on area lights only, and this scene's environment would be \
                     missing from the image (use nee)"
                ));
            }
            if self.scene.lights.is_empty() {
                return Err(format!("{name}: the scene has no area light to start light paths from"));
            }
        }
        if method.traces_light() {
            let delta = crate::plan::SceneFacts::of(&self.scene).delta_triangles;
            if delta > 0 {
                return Err(format!(
                    "light: a light path cannot connect to the camera through a mirror or glass, so the \
                     scene's {delta} delta triangles (and all they show) would render black (use nee)"
                ));
            }
        }
        if self.device == Device::Gpu {
            if settings.integrator.nee_kickstart && settings.integrator.method == Method::Guided {
                return Err("--nee-kickstart on: the GPU tracer's guided method has no next-event estimation \
                            to learn from (use --nee-kickstart off)"
                    .into());
            }
            return self.render_on_gpu(settings, on_pass);
        }
        let guided = settings.integrator.method.uses_guide();
        if guided && settings.integrator.focal_probability > 0.0 && self.focal_guide.is_none() {
            let (low, high) = self.scene.bounds();
            let focal = FocalGuide::new(low, high, self.focal_settings).map_err(|e| e.to_string())?;
            self.focal_guide = Some(focal);
        }
        let learns_share = guided && settings.integrator.learned_guide_share && self.guide.is_some();
        if learns_share && self.guide_shares.is_none() {
            let (low, high) = self.scene.bounds();
            let (resolution, cost) = (self.focal_settings.share_resolution, self.guide_share_cost);
            let shares = StrategyShares::new(low, high, resolution).and_then(|s| s.with_cost(cost));
            self.guide_shares = Some(shares.map_err(|e| format!("--guide-share-cost: {e}"))?);
        }
        // W guides the light subpaths of bdpt-guided and vpl-guided.
        let bidirectional_guided = guided
            && ((method.bidirectional() && settings.integrator.guide_light_subpaths)
                || method.gathers_virtual_lights());
        if bidirectional_guided && self.importance_guide.is_none() {
            if let Some(guide_settings) = self.guide_settings {
                self.importance_guide = Some(DirectionalGuide::build(&self.scene, guide_settings)?);
            }
        }
        // Every learner built goes to the render, which keeps those the method uses
        // (`Learners::used_by`).
        let learners = Learners {
            focal: self.focal_guide.as_mut(),
            guide_shares: self.guide_shares.as_mut(),
            lights: self.light_guide.as_mut(),
            gate: self.gate.as_mut(),
            environment: self.environment_guide.as_mut(),
            ..Learners::default()
        };
        let job = RenderJob { scene: &self.scene, intersector: &self.intersector, learners, settings, on_pass };
        let importance = self.importance_guide.as_mut();
        Ok(match self.guide.as_mut() {
            Some(guide) => guide.visit(importance, job),
            // No directional guide: the grid's type stands in for the structure.
            None => job.run::<HemisphereGrid>(None, None),
        })
    }
}

/// Loads a scene, builds the BVH and (when `guide` is given) the directional guide.
pub fn prepare(
    path: &Path,
    intersector: IntersectorChoice,
    guide: Option<DirectionalGuideSettings>,
) -> Result<Prepared, String> {
    let plain = LightRequest::new(Some(LightSelection::Power), Some(EnvironmentSampling::Luminance), true);
    prepare_with_lights(path, intersector, guide, plain)
}

/// A CPU render waiting for the directional guide's structure: every learner but the
/// guide and W, which [`DirectionalGuide::visit`] hands over typed.
struct RenderJob<'a, F> {
    scene: &'a Scene,
    intersector: &'a SceneIntersector,
    learners: Learners<'a, HemisphereGrid>,
    settings: &'a RenderSettings,
    on_pass: F,
}

impl<F: FnMut(&Progress<'_>)> RenderJob<'_, F> {
    /// Renders with the guide `directions` and W `importance` of structure `G`.
    fn run<G: Guide>(self, directions: Option<&mut G>, importance: Option<&mut G>) -> (Image, RenderStatistics) {
        let Learners { focal, guide_shares, lights, gate, environment, .. } = self.learners;
        let learners = Learners { directions, importance, focal, guide_shares, lights, gate, environment };
        render(self.scene, self.intersector, learners, self.settings, self.on_pass)
    }
}

impl<F: FnMut(&Progress<'_>)> GuideVisitor for RenderJob<'_, F> {
    type Output = (Image, RenderStatistics);

    fn visit<G: Guide>(self, guide: &mut G, importance: Option<&mut G>) -> Self::Output {
        self.run(Some(guide), importance)
    }
}

/// How lights and the environment are to be sampled: choices, or `None` for the plan
/// to decide.
#[derive(Clone, Copy, Debug)]
pub struct LightRequest {
    /// Segments per edge each emissive triangle is cut into; `None` lets
    /// [`auto_light_split`] decide from the scene.
    pub split: Option<u32>,
    /// The selection asked for; `None` lets the [`GuidePlan`] decide.
    pub selection: Option<LightSelection>,
    /// The light guide's settings, if one is built.
    pub settings: LightGuideSettings,
    /// The next-event gate's settings, where one is to be built.
    pub gate: Option<NextEventGateSettings>,
    /// The environment sampling asked for; `None` lets the [`GuidePlan`] decide.
    pub environment: Option<EnvironmentSampling>,
    /// The environment-tile guide's settings, if one is built.
    pub environment_settings: EnvTileGuideSettings,
    /// Whether the method samples lights at all (no light guide otherwise).
    pub next_event_estimation: bool,
}

impl LightRequest {
    /// `selection` and `environment` asked for (or `None`: planned), default settings.
    pub fn new(
        selection: Option<LightSelection>,
        environment: Option<EnvironmentSampling>,
        next_event_estimation: bool,
    ) -> Self {
        Self {
            split: Some(1),
            selection,
            settings: LightGuideSettings::default(),
            gate: None,
            environment,
            environment_settings: EnvTileGuideSettings::default(),
            next_event_estimation,
        }
    }
}

/// The environment's tiles (`tiles` across × down its lat-long map) and sun disk, as an
/// environment-tile guide samples them (and needs them to be read back).
pub fn environment_tiles(
    environment: &crate::environment::Environment,
    tiles: [u32; 2],
) -> Result<(EnvironmentTiles, Option<SunDisk>), String> {
    let (width, height, luminance) = environment.sky.luminance_grid();
    let map = EnvironmentTiles::new(width, height, &luminance, tiles).map_err(|e| format!("environment tiles: {e}"))?;
    Ok((map, environment.sun.map(|sun| sun.disk)))
}

/// [`prepare`], with light and environment sampling planned from the scene: a light
/// guide over the scene's bounds is built when the plan selects lights as learned, an
/// environment-tile guide when it samples the environment by tiles.
pub fn prepare_with_lights(
    path: &Path,
    intersector: IntersectorChoice,
    guide: Option<DirectionalGuideSettings>,
    lights: LightRequest,
) -> Result<Prepared, String> {
    let start = Instant::now();
    let mut scene = Scene::load(path).map_err(|e| e.to_string())?;
    if lights.next_event_estimation {
        let split = lights.split.unwrap_or_else(|| auto_light_split(scene.lights.len()));
        if split > 1 {
            scene.split_lights(split);
        }
    }
    let load = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let intersector = SceneIntersector::build(&scene.triangles, intersector)?;
    let bvh_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let mut plan =
        GuidePlan::new(&scene, guide.is_some(), lights.next_event_estimation, lights.selection, lights.environment);
    let guide_settings = guide.filter(|_| plan.directions);
    let guide = match guide {
        Some(settings) if plan.directions => {
            let guide = DirectionalGuide::build(&scene, settings)?;
            plan.note(guide.describe());
            Some(guide)
        }
        _ => None,
    };
    let (low, high) = scene.bounds();
    let light_guide = match lights.settings {
        settings
            if plan.light_selection == LightSelection::Learned
                && lights.next_event_estimation
                && !scene.lights.is_empty() =>
        {
            let light_guide = LightGuide::new(low, high, &scene.lights.powers(), settings)
                .map_err(|e| format!("light guide: {e}"))?;
            let [x, y, z] = light_guide.resolution();
            plan.note(format!(
                "light guide: {x}×{y}×{z} cells × {} lights, {} KiB",
                light_guide.light_count(),
                light_guide.memory_bytes() >> 10
            ));
            Some(light_guide)
        }
        _ => None,
    };
    let gate = match lights.gate {
        Some(settings) if lights.next_event_estimation && !scene.lights.is_empty() => {
            let gate = NextEventGate::new(low, high, settings).map_err(|e| format!("next-event gate: {e}"))?;
            let [x, y, z] = gate.resolution();
            plan.note(format!(
                "next-event gate ×{}: {x}×{y}×{z} cells, {} KiB",
                settings.scale,
                gate.memory_bytes() >> 10
            ));
            Some(gate)
        }
        _ => None,
    };
    let environment_guide = match &scene.environment {
        Some(environment)
            if plan.environment_sampling == EnvironmentSampling::Tiles && lights.next_event_estimation =>
        {
            let settings = lights.environment_settings;
            let (tiles, sun) = environment_tiles(environment, settings.tiles)?;
            let environment_guide =
                EnvTileGuide::new(low, high, tiles, sun, settings).map_err(|e| format!("environment guide: {e}"))?;
            let [x, y, z] = environment_guide.resolution();
            let [u, v] = environment_guide.tiles().tiles();
            plan.note(format!(
                "environment guide: {x}×{y}×{z} cells × {u}×{v} tiles{}, {} KiB tables + {} KiB texel CDFs",
                if environment_guide.sun().is_some() { " + sun" } else { "" },
                environment_guide.table_bytes() >> 10,
                environment_guide.tiles().memory_bytes() >> 10
            ));
            Some(environment_guide)
        }
        _ => None,
    };
    let times = SetupTimes { load, bvh: bvh_seconds, guide: start.elapsed().as_secs_f64() };
    Ok(Prepared {
        scene,
        intersector,
        guide,
        guide_settings,
        importance_guide: None,
        light_guide,
        gate,
        environment_guide,
        focal_guide: None,
        guide_shares: None,
        focal_settings: FocalGuideSettings::default(),
        guide_share_cost: GUIDE_SHARE_COST,
        plan,
        times,
        device: Device::Cpu,
        #[cfg(feature = "gpu")]
        gpu: None,
    })
}
