//! The options translated into the settings of the guides, learners and integrator.

use guiding_core::{
    EnvTileGuideSettings, FocalGuideSettings, HemisphereGridSettings, IntegralEstimator, LightGuideSettings,
    NextEventGateSettings, PatchLayout, UpdateRule,
};

use super::options::GuideShare;
use super::options::{GuideChoice, RouletteKind, TraceOptions};
use crate::backend::Device;
use crate::directional_guide::{DirectionalGuideSettings, GuideChoices, GuideStructure, TreeChoices};
use crate::integrator::{IntegratorSettings, Method, Roulette, DEFAULT_GUIDE_MIN_ALPHA};
use crate::plan::GuidePlan;
use crate::schedule::Schedule;
use crate::session::LightRequest;

impl TraceOptions {
    /// The settings of `structure` from the options (budget, update rule and the
    /// structure's own).
    pub(super) fn guide_settings(
        &self,
        structure: GuideStructure,
        method: Method,
    ) -> Result<DirectionalGuideSettings, String> {
        if !(self.tree_mib.is_finite() && self.tree_mib > 0.0) {
            return Err(format!("--tree-mib {} must be positive", self.tree_mib));
        }
        let choices = GuideChoices {
            hemisphere: self.hemisphere_settings()?,
            integral: self.integral,
            // Guided without next-event estimation learns the grid from the path's own
            // continuation by default (see `without_nee_defaults`), as bdpt-guided always
            // does.
            continuation_by_default: self.without_nee_defaults(method) || method.bidirectional(),
            initial_q: self.initial_q,
            uniform_mix: self.uniform_mix,
            mixture_lobes: self.mixture_lobes,
            tree: TreeChoices {
                budget_bytes: (self.tree_mib * (1 << 20) as f64) as usize,
                threshold: self.tree_threshold,
                flux_fraction: self.tree_flux_fraction,
                fold: self.tree_fold,
                mixed_share: self.tree_mixed_share,
                cosine: self.tree_cosine,
                per_axis: self.tree_per_axis,
                second_moment: self.tree_second_moment,
            },
        };
        DirectionalGuideSettings::from_choices(structure, &choices)
    }

    /// The one `--guide` of `render` and `reference`.
    pub(super) fn single_guide(&self) -> Result<GuideChoice, String> {
        match self.guide.as_slice() {
            [choice] => Ok(*choice),
            _ => Err("--guide takes one structure here (several only with compare)".into()),
        }
    }

    /// The directional guide's most share: `--p-guide`, else 0.5 on the CPU (where each
    /// region learns its own share up to it) and 0.3 on the GPU (a fixed share).
    pub(super) fn p_guide(&self) -> f32 {
        match (self.p_guide, self.device) {
            (Some(p), _) => p,
            (None, Device::Gpu) => 0.3,
            (None, _) => 0.5,
        }
    }

    /// The most of a seconds budget the iterative schedule trains `method` for:
    /// `--train-share`, else 0.5 for guided on the CPU and
    /// [`DEFAULT_TRAINING_SHARE`](crate::schedule::DEFAULT_TRAINING_SHARE) otherwise.
    pub(super) fn train_share(&self, method: Method) -> f64 {
        match self.train_share {
            Some(share) => share,
            None if self.without_nee_defaults(method) => 0.5,
            None => crate::schedule::DEFAULT_TRAINING_SHARE,
        }
    }

    /// Whether `method` takes the CPU's defaults for guiding without next-event
    /// estimation in the image: next-event estimation in the training passes only
    /// (`--nee-kickstart`), the guide at every vertex, the focal guide at most 0.25, and
    /// the grid learning from the path's continuation. Measured with `lodestar render
    /// --integrator guided --seconds 20`, relMSE ÷ pt's, seeds 41 and 42: door 160×120
    /// 0.61/0.50, cornell 128² 0.36/0.35, glossy 128² 0.65/0.73, many_lights 160×120
    /// 0.71/0.80 (geometric mean 0.57). Without the focal guide: 0.48/0.53, 0.25/0.25,
    /// 0.57/0.61 and 1.21/1.23 (0.55: equal within noise, but guided lost to pt on many
    /// small lights, which only the focal guide aims at). With guided-nee's defaults: 1.27/1.14,
    /// 0.47/0.49, 0.47/0.55, 0.61/0.61 (0.65).
    fn without_nee_defaults(&self, method: Method) -> bool {
        method == Method::Guided && self.device == Device::Cpu
    }

    /// The focal guide's most share: `--p-focal`, else 0.5 (at most 1 − p_guide) on the
    /// CPU (0.25 for guided without next-event estimation) and 0 on the GPU.
    pub(super) fn p_focal(&self, method: Method) -> f32 {
        match (self.p_focal, self.device) {
            (Some(p), _) => p,
            (None, Device::Gpu) => 0.0,
            (None, _) if self.without_nee_defaults(method) => 0.25f32.min(1.0 - self.p_guide()),
            (None, _) => 0.5f32.min(1.0 - self.p_guide()),
        }
    }

    /// `--guide-share`, else learned on the CPU and fixed on the GPU.
    pub(super) fn guide_share(&self) -> GuideShare {
        match (self.guide_share, self.device) {
            (Some(share), _) => share,
            (None, Device::Gpu) => GuideShare::Fixed,
            (None, _) => GuideShare::Learned,
        }
    }

    /// `--schedule`, else iterative on the CPU and online on the GPU.
    pub(super) fn schedule(&self) -> Schedule {
        match (self.schedule, self.device) {
            (Some(schedule), _) => schedule,
            (None, Device::Gpu) => Schedule::Online,
            (None, _) => Schedule::Iterative,
        }
    }

    /// `--roulette`, else efficiency for guided-nee and guided on the CPU (the GPU tracer
    /// has no learned roulette) and throughput for every other method.
    pub(super) fn roulette(&self, method: Method) -> RouletteKind {
        match (self.roulette, self.device, method) {
            (Some(kind), _, _) => kind,
            (None, Device::Cpu, Method::GuidedNee | Method::Guided) => RouletteKind::Efficiency,
            (None, _, _) => RouletteKind::Throughput,
        }
    }

    pub(super) fn focal_settings(&self, method: Method) -> Result<FocalGuideSettings, String> {
        let p_focal = self.p_focal(method);
        if !(0.0..=1.0 - self.p_guide()).contains(&p_focal) {
            return Err(format!("--p-focal {p_focal} must be in [0, 1 − p_guide = {}]", 1.0 - self.p_guide()));
        }
        if !(self.focal_learn > 0.0 && self.focal_learn <= 1.0) {
            return Err(format!("--focal-learn {} must be in (0, 1]", self.focal_learn));
        }
        let defaults = FocalGuideSettings::default();
        let settings = FocalGuideSettings {
            max_boxes: self.focal_boxes.unwrap_or(defaults.max_boxes),
            focal_ratio: self.focal_ratio.unwrap_or(defaults.focal_ratio),
            split_share: self.focal_split.unwrap_or(defaults.split_share),
            share_resolution: self.focal_cells,
            share_cost: self.focal_share_cost.unwrap_or(defaults.share_cost),
            merge_ratio: self.focal_merge.unwrap_or(defaults.merge_ratio),
            deposits_per_segment: self.focal_deposits.unwrap_or(defaults.deposits_per_segment),
            boxes_per_cell: self.focal_boxes_per_cell.unwrap_or(defaults.boxes_per_cell),
            ..defaults
        };
        settings.validate().map_err(|e| format!("focal guide: {e}"))?;
        Ok(settings)
    }

    pub(super) fn hemisphere_settings(&self) -> Result<HemisphereGridSettings, String> {
        if !(self.guide_mib.is_finite() && self.guide_mib > 0.0) {
            return Err(format!("--guide-mib {} must be positive", self.guide_mib));
        }
        if !(0.0..=1.0).contains(&self.p_guide()) {
            return Err(format!("--p-guide {} must be in [0, 1]", self.p_guide()));
        }
        let defaults = HemisphereGridSettings::default();
        let settings = HemisphereGridSettings {
            budget_bytes: (self.guide_mib * (1 << 20) as f64) as usize,
            layout: PatchLayout { mapping: self.mapping, resolution: self.patches },
            update_rule: UpdateRule {
                learning_rate: self.learning_rate,
                integral: self.integral.unwrap_or(IntegralEstimator::BsdfSampled),
            },
            initial_q: self.initial_q.unwrap_or(defaults.initial_q),
            uniform_mix: self.uniform_mix.unwrap_or(defaults.uniform_mix),
            max_normal_angle_deg: self.max_normal_angle.unwrap_or(defaults.max_normal_angle_deg),
            sampling_exponent: self.sampling_exponent.unwrap_or(defaults.sampling_exponent),
            cosine_product: self.cosine_product.unwrap_or(self.device == Device::Cpu),
            ..defaults
        };
        settings.validate().map_err(|e| e.to_string())?;
        Ok(settings)
    }

    pub(super) fn integrator(&self, method: Method, plan: &GuidePlan) -> IntegratorSettings {
        let guide_depth = match (self.guide_depth, self.device) {
            (Some(depth), _) => depth,
            (None, Device::Gpu) => u32::MAX,
            (None, _) if self.without_nee_defaults(method) => u32::MAX,
            (None, _) => 1,
        };
        // Light tracing and bdpt learn their directional guide alone: no focal guide, no
        // learned share, no next-event estimation to kick-start from.
        let light = method.splats() || method.gathers_virtual_lights();
        IntegratorSettings {
            method,
            max_depth: self.max_depth.max(1),
            rr_depth: self.rr_depth,
            guide_probability: self.p_guide(),
            guide_depth,
            focal_probability: if light { 0.0 } else { self.p_focal(method) },
            focal_learning_share: self.focal_learn,
            learned_guide_share: !light && self.guide_share() == GuideShare::Learned,
            density_weighted_learning: true,
            nee_weighs_guide: false,
            guide_diffuse_lobes: self.guide_diffuse_lobes.unwrap_or(true),
            guide_min_alpha: self.guide_min_alpha.unwrap_or(DEFAULT_GUIDE_MIN_ALPHA),
            focal_mirror_alpha: self.focal_mirror_alpha,
            learn: true,
            nee_kickstart: !light && self.nee_kickstart.unwrap_or(self.without_nee_defaults(method)),
            light_selection: plan.light_selection,
            environment_sampling: plan.environment_sampling,
            connection_roulette: self.connection_roulette,
            guide_light_subpaths: self.guide_light_subpaths.unwrap_or(true),
            vpl_paths: self.vpl_paths,
            vpl_min_distance: self.vpl_min_distance,
            roulette: match self.roulette(method) {
                RouletteKind::Efficiency if method.uses_guide() && !light => {
                    Roulette::Efficiency { cells: self.roulette_cells }
                }
                _ => Roulette::Throughput,
            },
            splitting: self.splitting.unwrap_or(false),
            lanes: self.lanes,
        }
    }

    /// The directional guide's settings if `method` guides and `choice` is not `none`
    /// (the plan may still leave it out).
    pub(super) fn directional_guide(
        &self,
        method: Method,
        choice: GuideChoice,
    ) -> Result<Option<DirectionalGuideSettings>, String> {
        match choice.structure() {
            Some(structure) if method.uses_guide() => self.guide_settings(structure, method).map(Some),
            _ => Ok(None),
        }
    }

    /// What to build for light selection under `method`.
    pub(super) fn light_request(&self, method: Method) -> Result<LightRequest, String> {
        if !(self.light_guide_mib.is_finite() && self.light_guide_mib > 0.0) {
            return Err(format!("--light-guide-mib {} must be positive", self.light_guide_mib));
        }
        if !(self.nee_gate.is_finite() && self.nee_gate >= 0.0) {
            return Err(format!("--nee-gate {} must be finite and at least 0", self.nee_gate));
        }
        if !(self.nee_gate_floor > 0.0 && self.nee_gate_floor <= 1.0) {
            return Err(format!("--nee-gate-floor {} must be in (0, 1]", self.nee_gate_floor));
        }
        let budget_bytes = (self.light_guide_mib * (1 << 20) as f64) as usize;
        // The gate learns, so unguided methods (the baselines) and the GPU tracer (which
        // has no light guide) shoot every shadow ray.
        let gated = method.uses_guide() && self.device == Device::Cpu;
        let settings = LightGuideSettings { budget_bytes, rule: self.light_rule, ..Default::default() };
        settings.validate().map_err(|e| e.to_string())?;
        let gate = (gated && self.nee_gate > 0.0).then_some(NextEventGateSettings {
            scale: self.nee_gate,
            floor: self.nee_gate_floor,
            ..Default::default()
        });
        if !(self.env_guide_mib.is_finite() && self.env_guide_mib > 0.0) {
            return Err(format!("--env-guide-mib {} must be positive", self.env_guide_mib));
        }
        let environment_settings = EnvTileGuideSettings {
            budget_bytes: (self.env_guide_mib * (1 << 20) as f64) as usize,
            tiles: self.env_tiles,
            power_mix: self.env_power_mix,
            ..Default::default()
        };
        environment_settings.validate().map_err(|e| format!("environment guide: {e}"))?;
        // Like the gate, the parts are learned: baselines and the GPU use whole triangles.
        let split = if gated { self.light_split.0 } else { Some(1) };
        Ok(LightRequest {
            split,
            gate,
            selection: self.light_selection.0,
            settings,
            environment: self.env_sampling.0,
            environment_settings,
            next_event_estimation: method.uses_nee(),
        })
    }
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;
    use crate::integrator::{EnvironmentSampling, LightSelection};

    #[derive(Parser)]
    struct Command {
        #[command(flatten)]
        options: TraceOptions,
    }

    fn options(args: &[&str]) -> TraceOptions {
        Command::try_parse_from(std::iter::once("lodestar").chain(args.iter().copied())).unwrap().options
    }

    fn plan() -> GuidePlan {
        GuidePlan {
            directions: true,
            light_selection: LightSelection::Power,
            environment_sampling: EnvironmentSampling::Luminance,
            reasons: Vec::new(),
        }
    }

    fn grid_integral(options: &TraceOptions, method: Method) -> IntegralEstimator {
        match options.guide_settings(GuideStructure::Hemisphere, method).unwrap() {
            DirectionalGuideSettings::Hemisphere(grid) => grid.update_rule.integral,
            other => panic!("not a grid: {other:?}"),
        }
    }

    #[test]
    fn the_mirror_images_option_takes_finite_numbers_and_reaches_the_integrator() {
        let alpha = |args: &[&str]| options(args).integrator(Method::GuidedNee, &plan()).focal_mirror_alpha;
        assert_eq!(alpha(&[]), crate::mirror_images::DEFAULT_FOCAL_MIRROR_ALPHA);
        assert_eq!(alpha(&["--focal-mirror-alpha", "-1"]), -1.0);
        for bad in ["nan", "inf", "x"] {
            let parsed = Command::try_parse_from(["lodestar", "--focal-mirror-alpha", bad]);
            let error = parsed.err().map(|e| e.to_string()).unwrap_or_default();
            assert!(error.contains("--focal-mirror-alpha"), "{bad}: {error}");
        }
    }

    #[test]
    fn guided_without_nee_takes_its_own_defaults_on_the_cpu_only() {
        let cpu = options(&[]);
        let guided = cpu.integrator(Method::Guided, &plan());
        assert!(guided.nee_kickstart);
        assert_eq!((guided.guide_depth, guided.focal_probability), (u32::MAX, 0.25));
        assert_eq!(grid_integral(&cpu, Method::Guided), IntegralEstimator::PathContinuation);
        let guided_nee = cpu.integrator(Method::GuidedNee, &plan());
        assert!(!guided_nee.nee_kickstart);
        assert_eq!((guided_nee.guide_depth, guided_nee.focal_probability), (1, 0.5));
        assert_eq!(grid_integral(&cpu, Method::GuidedNee), IntegralEstimator::BsdfSampled);
        assert_eq!((cpu.train_share(Method::Guided), cpu.train_share(Method::GuidedNee)), (0.5, 0.15));
        let gpu = options(&["--device", "gpu"]);
        assert_eq!(gpu.train_share(Method::Guided), 0.15);
        assert!(!gpu.integrator(Method::Guided, &plan()).nee_kickstart);
        assert_eq!(grid_integral(&gpu, Method::Guided), IntegralEstimator::BsdfSampled);
    }

    #[test]
    fn options_asked_for_win_over_the_guided_defaults() {
        let asked = options(&[
            "--nee-kickstart",
            "off",
            "--guide-depth",
            "2",
            "--p-focal",
            "0.4",
            "--integral",
            "sampled",
            "--train-share",
            "0.2",
        ]);
        assert_eq!(asked.train_share(Method::Guided), 0.2);
        let guided = asked.integrator(Method::Guided, &plan());
        assert!(!guided.nee_kickstart);
        assert_eq!((guided.guide_depth, guided.focal_probability), (2, 0.4));
        assert_eq!(grid_integral(&asked, Method::Guided), IntegralEstimator::BsdfSampled);
    }
}
