//! [`GuidePlan`]: which learners a render builds, decided from facts of the scene, so a
//! scene gets nothing it does not need.

use crate::integrator::{EnvironmentSampling, LightSelection};
use crate::scene::Scene;

/// Fewest emissive triangles for which `--light-selection auto` learns light selection:
/// with a handful of lights, power selection is already close and the learned tables
/// would only cost time.
pub const LEARNED_SELECTION_MIN_LIGHTS: usize = 8;

/// The learners a render uses and why.
#[derive(Clone, Debug, PartialEq)]
pub struct GuidePlan {
    /// A directional guide (hemisphere grid) for the guided methods.
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
    /// Decides from the scene: `directions` for guided methods; `requested` light
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
        let lights = scene.lights.len();
        let mut reasons = vec![if directions {
            "directions: hemisphere grid (guided method)".to_string()
        } else {
            "directions: none (unguided method)".to_string()
        }];
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
                reasons.push(format!("light selection: power ({lights} emissive triangles; no light guide)"));
                LightSelection::Power
            }
            None => {
                reasons.push(format!("light selection: learned ({lights} emissive triangles)"));
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

    /// The plan in one line.
    pub fn describe(&self) -> String {
        self.reasons.join("; ")
    }
}
