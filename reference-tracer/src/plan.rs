//! [`GuidePlan`]: which learners a render builds, decided from facts of the scene, so a
//! scene gets nothing it does not need.

use crate::integrator::{EnvironmentSampling, LightSelection};
use crate::material::Surface;
use crate::scene::Scene;

/// Fewest emissive triangles for which `--light-selection auto` learns light selection:
/// with a handful of lights, power selection is already close and the learned tables
/// would only cost time.
pub const LEARNED_SELECTION_MIN_LIGHTS: usize = 8;

/// Lights `--light-split auto` aims at for guided methods: each emissive triangle of a
/// scene with few is cut into parts, so that learned selection can pick the part of an
/// emitter a region actually sees.
pub const AUTO_SPLIT_LIGHTS: usize = 64;

/// Most segments per edge `--light-split auto` cuts an emissive triangle into.
pub const AUTO_SPLIT_MAX: u32 = 8;

/// Segments per edge that make `emissive_triangles` triangles at least
/// [`AUTO_SPLIT_LIGHTS`] lights (at most [`AUTO_SPLIT_MAX`]; 1 where there are that many).
pub fn auto_light_split(emissive_triangles: usize) -> u32 {
    if emissive_triangles == 0 {
        return 1;
    }
    let split = (AUTO_SPLIT_LIGHTS as f64 / emissive_triangles as f64).sqrt().ceil() as u32;
    split.clamp(1, AUTO_SPLIT_MAX)
}

/// What the plan decides from: facts of the scene.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SceneFacts {
    /// Triangles with a diffuse material.
    pub diffuse_triangles: usize,
    /// Triangles with a rough conductor.
    pub glossy_triangles: usize,
    /// Triangles with a delta material (mirror, glass): nothing to guide there.
    pub delta_triangles: usize,
    /// Emissive triangles.
    pub area_lights: usize,
    /// Lights next-event estimation picks from: the emissive triangles, or the parts
    /// they are cut into.
    pub light_parts: usize,
    /// Whether there is an environment.
    pub environment: bool,
    /// Whether the environment has a sun.
    pub sun: bool,
    /// Length of the scene's bounding-box diagonal (scene units).
    pub extent: f32,
}

impl SceneFacts {
    /// The facts of `scene`.
    pub fn of(scene: &Scene) -> Self {
        let mut facts = SceneFacts {
            area_lights: scene.lights.len() / (scene.lights.split_count() as usize).pow(2),
            light_parts: scene.lights.len(),
            environment: scene.environment.is_some(),
            sun: scene.environment.as_ref().is_some_and(|e| e.sun.is_some()),
            ..Default::default()
        };
        for index in 0..scene.triangles.len() {
            let material = scene.material(index as u32);
            match material.surface {
                _ if material.is_delta() => facts.delta_triangles += 1,
                Surface::Diffuse { .. } => facts.diffuse_triangles += 1,
                _ => facts.glossy_triangles += 1,
            }
        }
        let (low, high) = scene.bounds();
        facts.extent = if low.x <= high.x { (high - low).length() } else { 0.0 };
        facts
    }

    /// The facts in one line.
    pub fn describe(&self) -> String {
        let environment = match (self.environment, self.sun) {
            (false, _) => "no environment",
            (true, false) => "an environment",
            (true, true) => "an environment with a sun",
        };
        format!(
            "scene: {} diffuse, {} glossy, {} delta triangles; {} emissive; {environment}; extent {:.3}",
            self.diffuse_triangles, self.glossy_triangles, self.delta_triangles, self.area_lights, self.extent
        )
    }
}

/// The learners a render uses and why.
#[derive(Clone, Debug, PartialEq)]
pub struct GuidePlan {
    /// A directional guide for the guided methods.
    pub directions: bool,
    /// How next-event estimation picks area lights (a light guide is built for `Learned`).
    pub light_selection: LightSelection,
    /// How next-event estimation samples the environment (an environment-tile guide is
    /// built for `Tiles`; nothing is built without an environment).
    pub environment_sampling: EnvironmentSampling,
    /// One line per decision, for the user.
    pub reasons: Vec<String>,
}

impl GuidePlan {
    /// Decides from the scene: `directions` for guided methods (unless every surface is
    /// a mirror or glass, where nothing could use it); `requested` light
    /// selection, or (None, auto) learned selection when next-event estimation runs over
    /// at least [`LEARNED_SELECTION_MIN_LIGHTS`] emissive triangles, power otherwise;
    /// `requested_environment` sampling, or (None, auto) tiles whenever next-event
    /// estimation meets an environment.
    pub fn new(
        scene: &Scene,
        directions: bool,
        uses_nee: bool,
        requested: Option<LightSelection>,
        requested_environment: Option<EnvironmentSampling>,
    ) -> Self {
        let facts = SceneFacts::of(scene);
        let lights = facts.light_parts;
        let lights_named = match scene.lights.split_count() {
            1 => format!("{lights} emissive triangles"),
            n => format!("{} emissive triangles cut into {} parts each: {lights} lights", facts.area_lights, n * n),
        };
        let guidable = facts.diffuse_triangles + facts.glossy_triangles > 0;
        let mut reasons = vec![facts.describe()];
        reasons.push(match (directions, guidable) {
            (true, true) => "directions: guided (guided method)".to_string(),
            (true, false) => "directions: none (every surface is a mirror or glass: nothing to guide)".to_string(),
            (false, _) => "directions: none (unguided method, or --guide none)".to_string(),
        });
        let directions = directions && guidable;
        let light_selection = match requested {
            Some(selection) => {
                reasons.push(format!("light selection: {} (asked for)", selection.name()));
                selection
            }
            None if !uses_nee || lights == 0 => {
                reasons.push(format!(
                    "light selection: none needed ({lights} area lights, next-event estimation: {uses_nee})"
                ));
                LightSelection::Power
            }
            None if lights < LEARNED_SELECTION_MIN_LIGHTS => {
                reasons.push(format!("light selection: power ({lights_named}; no learned selection)"));
                LightSelection::Power
            }
            None => {
                reasons.push(format!("light selection: learned ({lights_named})"));
                LightSelection::Learned
            }
        };
        let environment_sampling = match (&scene.environment, requested_environment) {
            (None, _) => {
                reasons.push("environment: none, nothing built for it".to_string());
                EnvironmentSampling::Luminance
            }
            (Some(_), _) if !uses_nee => {
                reasons.push("environment: reached by scattering only (no next-event estimation)".to_string());
                EnvironmentSampling::Luminance
            }
            (Some(environment), requested) => {
                let sampling = requested.unwrap_or(EnvironmentSampling::Tiles);
                let sun = if environment.sun.is_some() { " and a separate sun" } else { "" };
                let why = if requested.is_some() { "asked for" } else { "auto" };
                reasons.push(match sampling {
                    EnvironmentSampling::Tiles => format!("environment: learned tiles{sun} ({why})"),
                    EnvironmentSampling::Luminance => format!("environment: by luminance{sun} ({why})"),
                });
                sampling
            }
        };
        Self { directions, light_selection, environment_sampling, reasons }
    }

    /// Adds a line about what was built (sizes, once known).
    pub fn note(&mut self, line: String) {
        self.reasons.push(line);
    }

    /// The plan in one line.
    pub fn describe(&self) -> String {
        self.reasons.join("; ")
    }
}
