//! The estimators, and how next-event estimation picks lights and samples the environment.

/// Which estimator to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Unidirectional path tracing with BSDF sampling only.
    Pt,
    /// BSDF sampling plus next-event estimation, combined by the power heuristic.
    Nee,
    /// BSDF and guide sampling (one-sample MIS), learning online.
    Guided,
    /// Guided plus next-event estimation.
    GuidedNee,
    /// Light tracing: paths start on area lights, every vertex connects to the camera.
    Light,
    /// Light tracing guided by W, the importance learned from light paths by Eq. (1)
    /// with the roles of light and camera swapped.
    LightGuided,
    /// Bidirectional path tracing: a camera and a light subpath per sample, joined in
    /// every way, each strategy weighted by the power heuristic computed exactly.
    Bdpt,
    /// Bidirectional path tracing whose camera subpaths are guided by Q (learned from
    /// them), the guided densities in every strategy's weight.
    BdptGuided,
    /// Instant radiosity: the vertices of a few light subpaths per pass are virtual point
    /// lights, gathered at each camera ray's first surface that is not all delta, their
    /// geometry term clamped (biased; coherent from frame to frame).
    Vpl,
    /// Instant radiosity whose light subpaths are guided by W, learned from what each
    /// virtual point light gave the image.
    VplGuided,
}

impl Method {
    /// Every method, in the order the command line lists them.
    pub const ALL: [Method; 10] = [
        Method::Pt,
        Method::Nee,
        Method::Guided,
        Method::GuidedNee,
        Method::Light,
        Method::LightGuided,
        Method::Bdpt,
        Method::BdptGuided,
        Method::Vpl,
        Method::VplGuided,
    ];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Method::Pt => "pt",
            Method::Nee => "nee",
            Method::Guided => "guided",
            Method::GuidedNee => "guided-nee",
            Method::Light => "light",
            Method::LightGuided => "light-guided",
            Method::Bdpt => "bdpt",
            Method::BdptGuided => "bdpt-guided",
            Method::Vpl => "vpl",
            Method::VplGuided => "vpl-guided",
        }
    }

    /// Parses a command-line name.
    pub fn from_name(name: &str) -> Option<Method> {
        Method::ALL.into_iter().find(|m| m.name() == name)
    }

    /// Whether light sources are sampled directly.
    pub fn uses_nee(self) -> bool {
        matches!(self, Method::Nee | Method::GuidedNee)
    }

    /// Whether directions are drawn from a learned guide.
    pub fn uses_guide(self) -> bool {
        matches!(
            self,
            Method::Guided | Method::GuidedNee | Method::LightGuided | Method::BdptGuided | Method::VplGuided
        )
    }

    /// Whether paths start on the lights (light tracing).
    pub fn traces_light(self) -> bool {
        matches!(self, Method::Light | Method::LightGuided)
    }

    /// Whether a pass gathers from virtual point lights (instant radiosity).
    pub fn gathers_virtual_lights(self) -> bool {
        matches!(self, Method::Vpl | Method::VplGuided)
    }

    /// Whether each sample joins a camera subpath and a light subpath (bdpt).
    pub fn bidirectional(self) -> bool {
        matches!(self, Method::Bdpt | Method::BdptGuided)
    }

    /// Whether some of its samples land in other pixels than their own (connections
    /// to the camera from light subpaths).
    pub fn splats(self) -> bool {
        self.traces_light() || self.bidirectional()
    }
}

/// How next-event estimation samples the environment (sky and sun).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EnvironmentSampling {
    /// In proportion to luminance everywhere (the sun by its share of the power).
    Luminance,
    /// From an [`EnvTileGuide`](guiding_core::EnvTileGuide): per grid cell, tiles of the map (and the sun) by the
    /// light they were seen to bring there, with power and uniform defensive shares;
    /// learns during every pass.
    Tiles,
}

impl EnvironmentSampling {
    /// Every choice, in the order the command line lists them.
    pub const ALL: [EnvironmentSampling; 2] = [EnvironmentSampling::Luminance, EnvironmentSampling::Tiles];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            EnvironmentSampling::Luminance => "luminance",
            EnvironmentSampling::Tiles => "tiles",
        }
    }

    /// Parses a command-line name.
    pub fn from_name(name: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|s| s.name() == name)
            .ok_or_else(|| format!("unknown environment sampling `{name}` (luminance, tiles)"))
    }
}

/// How next-event estimation picks one of the scene's area lights (emissive triangles).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightSelection {
    /// Every light equally likely.
    Uniform,
    /// In proportion to power (luminance × area).
    Power,
    /// From a [`LightGuide`](guiding_core::LightGuide) learned from shadow rays (Eq. 3), with power and uniform
    /// defensive shares; learns during every pass.
    Learned,
}

impl LightSelection {
    /// Every choice, in the order the command line lists them.
    pub const ALL: [LightSelection; 3] = [LightSelection::Uniform, LightSelection::Power, LightSelection::Learned];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            LightSelection::Uniform => "uniform",
            LightSelection::Power => "power",
            LightSelection::Learned => "learned",
        }
    }

    /// Parses a command-line name.
    pub fn from_name(name: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|s| s.name() == name)
            .ok_or_else(|| format!("unknown light selection `{name}` (uniform, power, learned)"))
    }
}
