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
    /// The fastest this build has: Embree where the `embree` feature is compiled in
    /// (nee 1.16–1.22× obvhs's paths/s on cornell 128² and door 160×120, guided-nee
    /// 1.30–1.34×), else obvhs.
    pub fn fastest() -> Self {
        if cfg!(feature = "embree") {
            IntersectorChoice::Embree
        } else {
            IntersectorChoice::default()
        }
    }

    /// Reads `auto` ([`fastest`](Self::fastest)), `obvhs` (CWBVH), `obvhs-bvh2` or `embree`.
    pub fn from_name(name: &str) -> Result<Self, String> {
        match name {
            "auto" => Ok(Self::fastest()),
            "obvhs" | "obvhs-cwbvh" => Ok(IntersectorChoice::Obvhs(BvhKind::Cwbvh)),
            "obvhs-bvh2" => Ok(IntersectorChoice::Obvhs(BvhKind::Bvh2)),
            "embree" => Ok(IntersectorChoice::Embree),
            _ => Err(format!("unknown intersector `{name}` (auto, obvhs, obvhs-bvh2, embree)")),
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

    fn intersect_many(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        match self {
            SceneIntersector::Obvhs(i) => i.intersect_many(rays, hits),
            #[cfg(feature = "embree")]
            SceneIntersector::Embree(i) => i.intersect_many(rays, hits),
        }
    }

    fn occluded_many(&self, rays: &[Ray], occluded: &mut [bool]) {
        match self {
            SceneIntersector::Obvhs(i) => i.occluded_many(rays, occluded),
            #[cfg(feature = "embree")]
            SceneIntersector::Embree(i) => i.occluded_many(rays, occluded),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_is_embree_exactly_where_it_is_built_in() {
        let auto = IntersectorChoice::from_name("auto").unwrap();
        assert_eq!(auto, IntersectorChoice::fastest());
        let expected =
            if cfg!(feature = "embree") { IntersectorChoice::Embree } else { IntersectorChoice::Obvhs(BvhKind::Cwbvh) };
        assert_eq!(auto, expected);
        // The fastest choice builds in this configuration.
        let triangle = Triangle::new(glam::Vec3::ZERO, glam::Vec3::X, glam::Vec3::Y);
        assert!(SceneIntersector::build(&[triangle], auto).is_ok());
        assert!(IntersectorChoice::from_name("optix").unwrap_err().contains("auto"));
    }
}
