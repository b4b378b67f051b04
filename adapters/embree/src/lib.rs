//! # guiding-embree
//!
//! Lodestar's [`Intersector`](guiding_core::Intersector) over Embree 4: a scene of one
//! triangle geometry built with `RTC_SCENE_FLAG_ROBUST` and high build quality, so its
//! triangle test is watertight; closest hits by `rtcIntersect1`, occlusion by
//! `rtcOccluded1`. The device and scene are released on drop; every error Embree
//! reports through the device error callback becomes an [`EmbreeError`].
//!
//! Embree itself comes from the system (pkg-config `embree4`), from `EMBREE4_LIB_DIR`, or
//! from `scripts/provision-embree.sh`; see the README.
//!
//! ```
//! use glam::Vec3;
//! use guiding_core::{Intersector, Ray, Triangle};
//! use guiding_embree::EmbreeIntersector;
//!
//! let floor = [Triangle::new(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, -1.0))];
//! let embree = EmbreeIntersector::build(&floor)?;
//! let hit = embree.intersect(&Ray::new(Vec3::Y, Vec3::NEG_Y)).expect("straight down");
//! assert_eq!(hit.primitive, 0);
//! assert!((hit.t - 1.0).abs() < 1e-6);
//! assert!(embree.occluded(&Ray::segment(Vec3::Y, Vec3::NEG_Y, 0.0, 2.0)));
//! # Ok::<(), guiding_embree::EmbreeError>(())
//! ```

mod intersector;
pub mod sys;

pub use intersector::{EmbreeError, EmbreeIntersector};
