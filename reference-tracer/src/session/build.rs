//! Building a session: the scene loaded, its BVH, the plan, and the learners the plan
//! asks for.

use std::path::Path;
use std::time::Instant;

use guiding_core::environment::{EnvironmentTiles, SunDisk};
use guiding_core::{
    EnvTileGuide, EnvTileGuideSettings, FocalGuideSettings, LightGuide, LightGuideSettings, NextEventGate,
    NextEventGateSettings,
};

use super::{Session, SetupTimes, GUIDE_SHARE_COST};
use crate::backend::{CpuBackend, Device};
use crate::directional_guide::{DirectionalGuide, DirectionalGuideSettings};
use crate::integrator::{EnvironmentSampling, LightSelection};
use crate::learners::SessionLearners;
use crate::plan::{auto_light_split, GuidePlan};
use crate::scene::Scene;
use crate::scene_intersector::{IntersectorChoice, SceneIntersector};

/// Loads a scene, builds the BVH and (when `guide` is given) the directional guide.
pub fn prepare(
    path: &Path,
    intersector: IntersectorChoice,
    guide: Option<DirectionalGuideSettings>,
) -> Result<Session, String> {
    let plain = LightRequest::new(Some(LightSelection::Power), Some(EnvironmentSampling::Luminance), true);
    prepare_with_lights(path, intersector, guide, plain)
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
) -> Result<Session, String> {
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
    Ok(Session {
        scene,
        learners: SessionLearners {
            guide,
            guide_settings,
            importance_guide: None,
            focal_guide: None,
            guide_shares: None,
            roulette: None,
            focal_settings: FocalGuideSettings::default(),
            guide_share_cost: GUIDE_SHARE_COST,
            light_guide,
            gate,
            environment_guide,
        },
        plan,
        times,
        device: Device::Cpu,
        cpu: CpuBackend::new(intersector),
        #[cfg(feature = "gpu")]
        gpu: Default::default(),
    })
}
