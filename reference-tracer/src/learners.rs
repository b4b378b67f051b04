//! The learners of a session, owned: each built once, the plan's at load and the
//! method's own (the focal guide, the learned shares, W) at the first render that needs
//! it. A render borrows them typed ([`crate::render::Learners`]).

use guiding_core::{
    EfficiencyRoulette, EnvTileGuide, FocalGuide, FocalGuideSettings, LightGuide, NextEventGate, StrategyShares,
};

use crate::directional_guide::{DirectionalGuide, DirectionalGuideSettings};
use crate::integrator::{Method, Roulette};
use crate::mirror_images::{light_mirror_images, MIRROR_IMAGE_SHARE};
use crate::render::RenderSettings;
use crate::scene::Scene;

/// Every learner of a session, each built once: the plan's at load, the method's own
/// (the focal guide, the learned shares, W) at the first render that needs it.
pub struct SessionLearners {
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
    /// The efficiency-aware roulette's learned cells, built at the first render that ends
    /// its paths by it.
    pub roulette: Option<EfficiencyRoulette>,
    /// The focal guide's settings.
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
}

impl SessionLearners {
    /// The directional guide `method` renders with: the session's, where the method is
    /// guided (an unguided render of a session that holds one leaves it alone).
    pub fn guide_for(&self, method: Method) -> Option<&DirectionalGuide> {
        self.guide.as_ref().filter(|_| method.uses_guide())
    }

    /// [`guide_for`](Self::guide_for), to learn into.
    pub fn guide_for_mut(&mut self, method: Method) -> Option<&mut DirectionalGuide> {
        self.guide.as_mut().filter(|_| method.uses_guide())
    }

    /// Builds, at the first render of `settings`' method that needs them, the learners
    /// that method brings: the focal guide, the learned shares and W.
    pub(crate) fn build_for(&mut self, scene: &Scene, settings: &RenderSettings) -> Result<(), String> {
        let integrator = &settings.integrator;
        let method = integrator.method;
        let guided = method.uses_guide();
        if guided && integrator.focal_probability > 0.0 && self.focal_guide.is_none() {
            let (low, high) = scene.bounds();
            let mut focal = FocalGuide::new(low, high, self.focal_settings).map_err(|e| e.to_string())?;
            let images = light_mirror_images(scene, integrator.focal_mirror_alpha);
            focal.set_known_boxes(&images, MIRROR_IMAGE_SHARE).map_err(|e| e.to_string())?;
            self.focal_guide = Some(focal);
        }
        let learns_share = guided && integrator.learned_guide_share && self.guide.is_some();
        if learns_share && self.guide_shares.is_none() {
            let (low, high) = scene.bounds();
            let (resolution, cost) = (self.focal_settings.share_resolution, self.guide_share_cost);
            let shares = StrategyShares::new(low, high, resolution).and_then(|s| s.with_cost(cost));
            self.guide_shares = Some(shares.map_err(|e| format!("--guide-share-cost: {e}"))?);
        }
        if let (Roulette::Efficiency { cells }, None, true) = (integrator.roulette, &self.roulette, guided) {
            let (low, high) = scene.bounds();
            let roulette = EfficiencyRoulette::new(low, high, cells).map_err(|e| format!("--roulette-cells: {e}"))?;
            self.roulette = Some(roulette);
        }
        // W guides the light subpaths of bdpt-guided and vpl-guided.
        let bidirectional_guided =
            guided && ((method.bidirectional() && integrator.guide_light_subpaths) || method.gathers_virtual_lights());
        if bidirectional_guided && self.importance_guide.is_none() {
            if let Some(guide_settings) = self.guide_settings {
                self.importance_guide = Some(DirectionalGuide::build(scene, guide_settings)?);
            }
        }
        Ok(())
    }
}
