//! A session: one scene with its intersector, plan and every learner, built once (the
//! composition root of the tracer), rendered on the CPU or the GPU through a
//! [`Backend`].

mod build;

use guiding_core::{EfficiencyRoulette, EnvTileGuide, FocalGuide, LightGuide, NextEventGate, StrategyShares};

use crate::backend::{Backend, CpuBackend, Device};
use crate::integrator::Method;
use crate::learners::SessionLearners;
use crate::output::Image;
use crate::plan::GuidePlan;
use crate::render::{Progress, RenderSettings, RenderStatistics};
use crate::scene::Scene;

pub use build::{environment_tiles, prepare, prepare_with_lights, LightRequest};

/// The learned guide share's default cost of guiding (`--guide-share-cost`).
pub const GUIDE_SHARE_COST: f32 = 0.3;

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

/// A scene loaded with its intersector, its plan and its learners, and the backends
/// that render it.
pub struct Session {
    /// The scene.
    pub scene: Scene,
    /// Every learner built for it.
    pub learners: SessionLearners,
    /// What was built and why.
    pub plan: GuidePlan,
    /// Set-up timings.
    pub times: SetupTimes,
    /// Where [`render`](Self::render) traces paths.
    pub device: Device,
    cpu: CpuBackend,
    /// The GPU tracer, started at the first GPU render.
    #[cfg(feature = "gpu")]
    gpu: crate::gpu::GpuBackend,
}

impl Session {
    /// The CPU backend, and with it the scene's intersector.
    pub fn cpu(&self) -> &CpuBackend {
        &self.cpu
    }

    /// Renders at `resolution` (the same vertical field of view) when one is given.
    pub fn resize(&mut self, resolution: Option<[u32; 2]>) {
        if let Some([width, height]) = resolution {
            self.scene.camera = self.scene.camera.with_resolution(width, height);
        }
    }

    /// Bytes of every structure `method` learns with: the directional and focal guides and
    /// the learned roulette (guided methods), the light guide and the environment guide (as built by the plan).
    pub fn learned_bytes(&self, method: Method) -> usize {
        let learners = &self.learners;
        let guided = method.uses_guide();
        let directions = learners.guide_for(method).map_or(0, |g| g.stats().memory_bytes)
            + learners.guide_shares.as_ref().filter(|_| guided).map_or(0, StrategyShares::memory_bytes);
        let lights = learners.light_guide.as_ref().map_or(0, LightGuide::memory_bytes)
            + learners.gate.as_ref().map_or(0, NextEventGate::memory_bytes);
        let environment = learners.environment_guide.as_ref().map_or(0, EnvTileGuide::memory_bytes);
        let focal = learners.focal_guide.as_ref().filter(|_| guided).map_or(0, FocalGuide::memory_bytes);
        let roulette = learners.roulette.as_ref().filter(|_| guided).map_or(0, EfficiencyRoulette::memory_bytes);
        directions + focal + lights + environment + roulette
    }

    /// Renders with the learners built (the directional guide only for guided
    /// methods) on the session's device, calling `on_pass` after every pass.
    pub fn render(
        &mut self,
        settings: &RenderSettings,
        mut on_pass: impl FnMut(&Progress<'_>),
    ) -> Result<(Image, RenderStatistics), String> {
        self.check_method(settings)?;
        self.learners.build_for(&self.scene, settings)?;
        let backend: &mut dyn Backend = match self.device {
            Device::Cpu => &mut self.cpu,
            #[cfg(feature = "gpu")]
            Device::Gpu => &mut self.gpu,
            #[cfg(not(feature = "gpu"))]
            Device::Gpu => {
                return Err("this lodestar was built without the GPU tracer (cargo build --release -p \
                            reference-tracer --features gpu)"
                    .into())
            }
        };
        backend.render(&self.scene, &mut self.learners, settings, &mut on_pass)
    }

    /// Refuses a method this scene (or device) cannot render, with what is missing.
    fn check_method(&self, settings: &RenderSettings) -> Result<(), String> {
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
        Ok(())
    }
}
