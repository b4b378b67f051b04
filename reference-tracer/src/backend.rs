//! Where a session's passes run: the [`Backend`] trait, the CPU's implementation of it
//! ([`CpuBackend`]: every core, the reference integrators), and the [`Device`] choice.
//! The GPU's implementation is `gpu::GpuBackend` (feature `gpu`).

use guiding_core::{Guide, HemisphereGrid};

use crate::directional_guide::GuideVisitor;
use crate::learners::SessionLearners;
use crate::output::Image;
use crate::render::{render, Learners, Progress, RenderSettings, RenderStatistics};
use crate::scene::Scene;
use crate::scene_intersector::SceneIntersector;

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

/// What a render gives back: the image and its statistics, or why it was refused.
pub type RenderResult = Result<(Image, RenderStatistics), String>;

/// A place that renders: it takes a scene, the session's learners and the render's
/// settings, traces every pass, and leaves what the learners learned in them.
pub trait Backend {
    /// Renders `settings` on `scene`, learning in `learners` as the method does, and calls
    /// `on_pass` after every pass. What this backend cannot render is refused with an
    /// error naming it, before any pass.
    fn render(
        &mut self,
        scene: &Scene,
        learners: &mut SessionLearners,
        settings: &RenderSettings,
        on_pass: &mut dyn FnMut(&Progress<'_>),
    ) -> RenderResult;
}

/// The CPU tracer: the scene's intersector, and every core through rayon.
pub struct CpuBackend {
    intersector: SceneIntersector,
}

impl CpuBackend {
    /// A backend that traces with `intersector`.
    pub fn new(intersector: SceneIntersector) -> Self {
        Self { intersector }
    }

    /// Its intersector.
    pub fn intersector(&self) -> &SceneIntersector {
        &self.intersector
    }
}

impl Backend for CpuBackend {
    fn render(
        &mut self,
        scene: &Scene,
        learners: &mut SessionLearners,
        settings: &RenderSettings,
        on_pass: &mut dyn FnMut(&Progress<'_>),
    ) -> RenderResult {
        // Every learner built goes to the render, which keeps those the method uses
        // (`Learners::used_by`).
        let borrowed = Learners {
            focal: learners.focal_guide.as_mut(),
            guide_shares: learners.guide_shares.as_mut(),
            lights: learners.light_guide.as_mut(),
            gate: learners.gate.as_mut(),
            environment: learners.environment_guide.as_mut(),
            roulette: learners.roulette.as_mut(),
            ..Learners::default()
        };
        let job = RenderJob { scene, intersector: &self.intersector, learners: borrowed, settings, on_pass };
        let importance = learners.importance_guide.as_mut();
        Ok(match learners.guide.as_mut() {
            Some(guide) => guide.visit(importance, job),
            // No directional guide: the grid's type stands in for the structure.
            None => job.run::<HemisphereGrid>(None, None),
        })
    }
}

/// A CPU render waiting for the directional guide's structure: every learner but the
/// guide and W, which [`DirectionalGuide::visit`](crate::directional_guide::DirectionalGuide::visit)
/// hands over typed.
struct RenderJob<'a, 'f> {
    scene: &'a Scene,
    intersector: &'a SceneIntersector,
    learners: Learners<'a, HemisphereGrid>,
    settings: &'a RenderSettings,
    on_pass: &'f mut dyn FnMut(&Progress<'_>),
}

impl RenderJob<'_, '_> {
    /// Renders with the guide `directions` and W `importance` of structure `G`.
    fn run<G: Guide>(self, directions: Option<&mut G>, importance: Option<&mut G>) -> (Image, RenderStatistics) {
        let Learners { focal, guide_shares, lights, gate, environment, roulette, .. } = self.learners;
        let learners = Learners { directions, importance, focal, guide_shares, lights, gate, environment, roulette };
        render(self.scene, self.intersector, learners, self.settings, self.on_pass)
    }
}

impl GuideVisitor for RenderJob<'_, '_> {
    type Output = (Image, RenderStatistics);

    fn visit<G: Guide>(self, guide: &mut G, importance: Option<&mut G>) -> Self::Output {
        self.run(Some(guide), importance)
    }
}
