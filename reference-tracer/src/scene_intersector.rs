//! Which ray tracing library the tracer uses: obvhs (always built) or Embree 4 (with the
//! `embree` feature).

use guiding_core::{Hit, Intersector, Ray, Triangle};
use guiding_obvhs::{BvhKind, ObvhsIntersector};

/// The intersector a render asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IntersectorChoice {
    /// obvhs, with the given hierarchy.
    Obvhs(BvhKind),
    /// Embree 4 (robust build, high quality); needs the `embree` feature.
    Embree,
}

impl Default for IntersectorChoice {
    fn default() -> Self {
        IntersectorChoice::Obvhs(BvhKind::default())
    }
}

impl IntersectorChoice {
    /// Reads `obvhs` (CWBVH), `obvhs-bvh2` or `embree`.
    pub fn from_name(name: &str) -> Result<Self, String> {
        match name {
            "obvhs" | "obvhs-cwbvh" => Ok(IntersectorChoice::Obvhs(BvhKind::Cwbvh)),
            "obvhs-bvh2" => Ok(IntersectorChoice::Obvhs(BvhKind::Bvh2)),
            "embree" => Ok(IntersectorChoice::Embree),
            _ => Err(format!("unknown intersector `{name}` (obvhs, obvhs-bvh2, embree)")),
        }
    }
}

/// A built intersector of either library.
pub enum SceneIntersector {
    /// obvhs.
    Obvhs(ObvhsIntersector),
    /// Embree 4.
    #[cfg(feature = "embree")]
    Embree(guiding_embree::EmbreeIntersector),
}

impl SceneIntersector {
    /// Builds the chosen intersector over `triangles`.
    pub fn build(triangles: &[Triangle], choice: IntersectorChoice) -> Result<Self, String> {
        match choice {
            IntersectorChoice::Obvhs(kind) => Ok(SceneIntersector::Obvhs(ObvhsIntersector::build(triangles, kind))),
            #[cfg(feature = "embree")]
            IntersectorChoice::Embree => guiding_embree::EmbreeIntersector::build(triangles)
                .map(SceneIntersector::Embree)
                .map_err(|e| format!("building the Embree scene: {e}")),
            #[cfg(not(feature = "embree"))]
            IntersectorChoice::Embree => Err("this lodestar was built without Embree: rebuild with \
                 `cargo build --release -p reference-tracer --features embree` after scripts/provision-embree.sh"
                .into()),
        }
    }
}

impl Intersector for SceneIntersector {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        match self {
            SceneIntersector::Obvhs(i) => i.intersect(ray),
            #[cfg(feature = "embree")]
            SceneIntersector::Embree(i) => i.intersect(ray),
        }
    }

    fn occluded(&self, ray: &Ray) -> bool {
        match self {
            SceneIntersector::Obvhs(i) => i.occluded(ray),
            #[cfg(feature = "embree")]
            SceneIntersector::Embree(i) => i.occluded(ray),
        }
    }
}
