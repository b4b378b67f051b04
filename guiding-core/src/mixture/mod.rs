//! Q as a parametric mixture (feature `mixture`): von Mises–Fisher lobes fitted online by
//! weighted stepwise EM from the same (direction, target) stream the table rules see,
//! with exact sampling and pdf, and guards for degenerate lobes (κ → 0 or ∞, weights
//! → 0), and the [`GaussianMixture`] guide made of them: one mixture per region of a
//! grid over the scene.

mod guide;
mod merge;
mod serialize;
mod settings;
mod vmf;
mod vmf_mixture;

pub use guide::{GaussianMixture, MixtureDistribution, MixtureRegion};
pub use settings::GaussianMixtureSettings;

pub use vmf::{VmfLobe, MAX_CONCENTRATION, MIN_CONCENTRATION};
pub use vmf_mixture::{VmfMixture, MAX_LOBES, MIN_LOBE_WEIGHT};
