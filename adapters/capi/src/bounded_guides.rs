//! The structures made over the scene's bounds rather than its mesh: the irradiance
//! volume, the Gaussian mixture and the spatial × directional tree. Each has its own
//! config (filled by its default call) and create call; all give a `LodestarGuide`.
//! A point outside the box locates the region nearest to it.

use glam::Vec3;
use guiding_core::volume::SphereLayout;
use guiding_core::{
    Error, GaussianMixture, GaussianMixtureSettings, IrradianceVolume, IrradianceVolumeSettings,
    SpatialDirectionalTree, SpatialDirectionalTreeSettings,
};

use crate::arguments::{borrow, check_struct_size, finite, point, Output};
use crate::config::{budget, flag, resolution, update_rule_from_c, update_rule_to_c};
use crate::guide::LodestarGuide;
use crate::status::{guarded, Failure, LodestarStatus};
use crate::structure::GuideStructure;
use crate::types::LodestarVec3;

/// Shapes an irradiance volume (`lodestar_guide_create_volume`). Fill it with
/// `lodestar_volume_config_default`, then change what you need.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LodestarVolumeConfig {
    /// `sizeof(LodestarVolumeConfig)`: set by the default call.
    pub struct_size: u32,
    /// Share of the budget the initial grid of leaves takes, (0, 1]; splitting spends the rest.
    pub initial_share: f32,
    /// Memory budget for every table and the octree, bytes.
    pub budget_bytes: u64,
    /// The initial grid's cells along x, y, z (1..=1024 each); all 0 sizes it from the budget.
    pub resolution: [u32; 3],
    /// Bands in z and sectors in φ of each leaf's sphere of patches, 1..=256 each.
    pub sphere_resolution: [u32; 2],
    /// A leaf splits in eight once its updates reach this many per patch, > 0.
    pub split_updates_per_patch: f32,
    /// Q of every patch before learning, radiance, ≥ `q_floor`.
    pub initial_q: f32,
    /// Lower bound of every stored Q, radiance, > 0.
    pub q_floor: f32,
    /// Share of each leaf's sampling probability spread uniformly, [0, 1].
    pub uniform_mix: f32,
    /// One of `LodestarLearningRate`.
    pub learning_rate: u32,
    /// α for `EXPONENTIAL`, the decay exponent for `GLOBAL`; ignored otherwise.
    pub learning_rate_parameter: f32,
    /// One of `LodestarIntegralEstimator`.
    pub integral_estimator: u32,
}

impl LodestarVolumeConfig {
    fn from_settings(s: &IrradianceVolumeSettings) -> Self {
        let (learning_rate, learning_rate_parameter, integral_estimator) = update_rule_to_c(&s.update_rule);
        Self {
            struct_size: size_of::<Self>() as u32,
            initial_share: s.initial_share,
            budget_bytes: s.budget_bytes as u64,
            resolution: s.resolution.unwrap_or([0; 3]),
            sphere_resolution: s.layout.resolution,
            split_updates_per_patch: s.split_updates_per_patch,
            initial_q: s.initial_q,
            q_floor: s.q_floor,
            uniform_mix: s.uniform_mix,
            learning_rate,
            learning_rate_parameter,
            integral_estimator,
        }
    }

    fn settings(&self) -> Result<IrradianceVolumeSettings, Failure> {
        check_struct_size(self.struct_size, size_of::<Self>(), "LodestarVolumeConfig")?;
        let settings = IrradianceVolumeSettings {
            budget_bytes: budget(self.budget_bytes)?,
            initial_share: finite(self.initial_share, "config->initial_share")?,
            resolution: resolution(self.resolution),
            layout: SphereLayout { resolution: self.sphere_resolution },
            split_updates_per_patch: finite(self.split_updates_per_patch, "config->split_updates_per_patch")?,
            initial_q: finite(self.initial_q, "config->initial_q")?,
            q_floor: finite(self.q_floor, "config->q_floor")?,
            uniform_mix: finite(self.uniform_mix, "config->uniform_mix")?,
            update_rule: update_rule_from_c(self.learning_rate, self.learning_rate_parameter, self.integral_estimator)?,
        };
        settings.validate().map_err(|e| Failure::from_core(&e, "config"))?;
        Ok(settings)
    }
}

/// Shapes a Gaussian mixture guide (`lodestar_guide_create_mixture`). Fill it with
/// `lodestar_mixture_config_default`, then change what you need.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LodestarMixtureConfig {
    /// `sizeof(LodestarMixtureConfig)`: set by the default call.
    pub struct_size: u32,
    /// Lobes per mixture, 1..=8.
    pub lobes: u32,
    /// Memory budget for every mixture and its batch statistics, bytes.
    pub budget_bytes: u64,
    /// Cells along x, y, z (1..=1024 each); all 0 fills the budget with near-cubic cells.
    pub resolution: [u32; 3],
    /// 1: six regions per cell, one per sign of the normal's largest axis; 0: one.
    pub split_by_normal: u32,
    /// Q per steradian before learning, radiance, > 0.
    pub initial_q: f32,
    /// Share of the sampling density spread uniformly over the sphere, [0, 1].
    pub uniform_mix: f32,
    /// One of `LodestarLearningRate`.
    pub learning_rate: u32,
    /// α for `EXPONENTIAL`, the decay exponent for `GLOBAL`; ignored otherwise.
    pub learning_rate_parameter: f32,
    /// One of `LodestarIntegralEstimator`.
    pub integral_estimator: u32,
}

impl LodestarMixtureConfig {
    fn from_settings(s: &GaussianMixtureSettings) -> Self {
        let (learning_rate, learning_rate_parameter, integral_estimator) = update_rule_to_c(&s.update_rule);
        Self {
            struct_size: size_of::<Self>() as u32,
            lobes: s.lobes as u32,
            budget_bytes: s.budget_bytes as u64,
            resolution: s.resolution.unwrap_or([0; 3]),
            split_by_normal: s.split_by_normal as u32,
            initial_q: s.initial_q,
            uniform_mix: s.uniform_mix,
            learning_rate,
            learning_rate_parameter,
            integral_estimator,
        }
    }

    fn settings(&self) -> Result<GaussianMixtureSettings, Failure> {
        check_struct_size(self.struct_size, size_of::<Self>(), "LodestarMixtureConfig")?;
        let settings = GaussianMixtureSettings {
            budget_bytes: budget(self.budget_bytes)?,
            resolution: resolution(self.resolution),
            lobes: self.lobes as usize,
            split_by_normal: flag(self.split_by_normal, "split_by_normal")?,
            initial_q: finite(self.initial_q, "config->initial_q")?,
            uniform_mix: finite(self.uniform_mix, "config->uniform_mix")?,
            update_rule: update_rule_from_c(self.learning_rate, self.learning_rate_parameter, self.integral_estimator)?,
        };
        settings.validate().map_err(|e| Failure::from_core(&e, "config"))?;
        Ok(settings)
    }
}

/// Shapes a spatial × directional tree (`lodestar_guide_create_tree`). Fill it with
/// `lodestar_tree_config_default`, then change what you need.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LodestarTreeConfig {
    /// `sizeof(LodestarTreeConfig)`: set by the default call.
    pub struct_size: u32,
    /// Deepest directional level, 1..=20.
    pub max_directional_depth: u32,
    /// Memory budget for both trees and the building statistics, bytes.
    pub budget_bytes: u64,
    /// c of the spatial split rule: a leaf splits past max(`min_split_records`, c·√R)
    /// records, R the whole tree's, > 0.
    pub spatial_threshold: f32,
    /// The least records that let a leaf split, ≥ 1.
    pub min_split_records: u32,
    /// A directional cell holding more than this share of its leaf's flux splits in
    /// four, (0, 1).
    pub flux_fraction: f32,
    /// Deepest spatial level, 0..=24.
    pub max_spatial_depth: u32,
    /// Share of the sampling density spread uniformly over the normal's hemisphere, [0, 1].
    pub uniform_mix: f32,
    /// 1: sample only the normal's hemisphere (directions below are mirrored, with the
    /// exact pdf); 0: the whole sphere.
    pub fold_to_hemisphere: u32,
    /// One of `LodestarLearningRate`.
    pub learning_rate: u32,
    /// α for `EXPONENTIAL`, the decay exponent for `GLOBAL`; ignored otherwise.
    pub learning_rate_parameter: f32,
    /// One of `LodestarIntegralEstimator` (`PATH_CONTINUATION` by default).
    pub integral_estimator: u32,
    /// A leaf also splits when no world axis holds this share of its epoch's records'
    /// normals, [0, 1]; 0 never.
    pub mixed_normal_share: f32,
    /// 1: where the normal lies along a leaf's axis, sample the tree's density times
    /// cos θ; 0: the density alone.
    pub cosine_product: u32,
    /// 1: one spatial tree per world axis, each for the surfaces whose normal lies
    /// nearest it (surfaces facing different ways never share a leaf); 0: one spatial
    /// tree whose leaves turn to their records' normals.
    pub trees_per_axis: u32,
    /// 1: fit each directional cell to the root mean square of the arriving radiance
    /// (variance-aware guiding; needs `integral_estimator` `PATH_CONTINUATION`); 0: to
    /// its mean.
    pub second_moment: u32,
}

impl LodestarTreeConfig {
    fn from_settings(s: &SpatialDirectionalTreeSettings) -> Self {
        let (learning_rate, learning_rate_parameter, integral_estimator) = update_rule_to_c(&s.update_rule);
        Self {
            struct_size: size_of::<Self>() as u32,
            max_directional_depth: s.max_directional_depth,
            budget_bytes: s.budget_bytes as u64,
            spatial_threshold: s.spatial_threshold,
            min_split_records: s.min_split_records,
            flux_fraction: s.flux_fraction,
            max_spatial_depth: s.max_spatial_depth,
            uniform_mix: s.uniform_mix,
            fold_to_hemisphere: s.fold_to_hemisphere as u32,
            learning_rate,
            learning_rate_parameter,
            integral_estimator,
            mixed_normal_share: s.mixed_normal_share,
            cosine_product: s.cosine_product as u32,
            trees_per_axis: s.trees_per_axis as u32,
            second_moment: s.second_moment as u32,
        }
    }

    fn settings(&self) -> Result<SpatialDirectionalTreeSettings, Failure> {
        check_struct_size(self.struct_size, size_of::<Self>(), "LodestarTreeConfig")?;
        let settings = SpatialDirectionalTreeSettings {
            budget_bytes: budget(self.budget_bytes)?,
            spatial_threshold: finite(self.spatial_threshold, "config->spatial_threshold")?,
            min_split_records: self.min_split_records,
            mixed_normal_share: finite(self.mixed_normal_share, "config->mixed_normal_share")?,
            flux_fraction: finite(self.flux_fraction, "config->flux_fraction")?,
            max_directional_depth: self.max_directional_depth,
            max_spatial_depth: self.max_spatial_depth,
            uniform_mix: finite(self.uniform_mix, "config->uniform_mix")?,
            fold_to_hemisphere: flag(self.fold_to_hemisphere, "fold_to_hemisphere")?,
            cosine_product: flag(self.cosine_product, "cosine_product")?,
            trees_per_axis: flag(self.trees_per_axis, "trees_per_axis")?,
            second_moment: flag(self.second_moment, "second_moment")?,
            update_rule: update_rule_from_c(self.learning_rate, self.learning_rate_parameter, self.integral_estimator)?,
        };
        settings.validate().map_err(|e| Failure::from_core(&e, "config"))?;
        Ok(settings)
    }
}

/// Checks the bounds and output, builds with `build` and hands the guide out.
///
/// # Safety
/// `out_guide` must be NULL or valid for writing one pointer.
unsafe fn create_over_bounds(
    low: LodestarVec3,
    high: LodestarVec3,
    out_guide: *mut *mut LodestarGuide,
    build: impl FnOnce(Vec3, Vec3) -> Result<GuideStructure, Error>,
) -> Result<(), Failure> {
    // SAFETY: the caller's contract.
    let out = unsafe { Output::new(out_guide, "out_guide") }?;
    let (low, high) = (point(low, "low")?, point(high, "high")?);
    if !low.cmple(high).all() {
        return Err(Failure::new(
            LodestarStatus::InvalidArgument,
            format!("`low` = {low} is not below `high` = {high} on every axis"),
        ));
    }
    let structure = build(low, high).map_err(|e| Failure::from_core(&e, "building"))?;
    out.write(LodestarGuide { structure }.into_raw());
    Ok(())
}

/// Fills `out_config` with guiding-core's irradiance volume defaults (2 MiB, 16 × 16
/// patches per sphere, simple averaging).
///
/// # Safety
/// `out_config` must be NULL or writable for a `LodestarVolumeConfig`.
#[no_mangle]
pub unsafe extern "C" fn lodestar_volume_config_default(out_config: *mut LodestarVolumeConfig) -> LodestarStatus {
    guarded("lodestar_volume_config_default", || {
        // SAFETY: the caller's contract.
        unsafe { Output::new(out_config, "out_config") }?
            .write(LodestarVolumeConfig::from_settings(&IrradianceVolumeSettings::default()));
        Ok(())
    })
}

/// Creates an irradiance volume over the box `low`..`high` (scene units; the scene's
/// bounds): an octree whose leaves hold full-sphere tables of Q. Regions carry the
/// surface normal `locate` was given. On success `*out_guide` owns the new guide.
///
/// # Safety
/// `config` must be NULL or a valid config; `out_guide` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_create_volume(
    config: *const LodestarVolumeConfig,
    low: LodestarVec3,
    high: LodestarVec3,
    out_guide: *mut *mut LodestarGuide,
) -> LodestarStatus {
    guarded("lodestar_guide_create_volume", || {
        // SAFETY (both): the caller's contract.
        let settings = unsafe { borrow(config, "config") }?.settings()?;
        unsafe {
            create_over_bounds(low, high, out_guide, |l, h| {
                IrradianceVolume::new(l, h, settings).map(GuideStructure::Volume)
            })
        }
    })
}

/// Fills `out_config` with guiding-core's mixture defaults (2 MiB, 2 lobes, six regions
/// per cell).
///
/// # Safety
/// `out_config` must be NULL or writable for a `LodestarMixtureConfig`.
#[no_mangle]
pub unsafe extern "C" fn lodestar_mixture_config_default(out_config: *mut LodestarMixtureConfig) -> LodestarStatus {
    guarded("lodestar_mixture_config_default", || {
        // SAFETY: the caller's contract.
        unsafe { Output::new(out_config, "out_config") }?
            .write(LodestarMixtureConfig::from_settings(&GaussianMixtureSettings::default()));
        Ok(())
    })
}

/// Creates a Gaussian mixture guide over the box `low`..`high` (scene units): a grid of
/// cells, each with von Mises–Fisher mixtures fitted between passes (call
/// `lodestar_guide_rebuild`). On success `*out_guide` owns the new guide.
///
/// # Safety
/// `config` must be NULL or a valid config; `out_guide` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_create_mixture(
    config: *const LodestarMixtureConfig,
    low: LodestarVec3,
    high: LodestarVec3,
    out_guide: *mut *mut LodestarGuide,
) -> LodestarStatus {
    guarded("lodestar_guide_create_mixture", || {
        // SAFETY (both): the caller's contract.
        let settings = unsafe { borrow(config, "config") }?.settings()?;
        unsafe {
            create_over_bounds(low, high, out_guide, |l, h| {
                GaussianMixture::new(l, h, settings).map(GuideStructure::Mixture)
            })
        }
    })
}

/// Fills `out_config` with guiding-core's tree defaults (16 MiB, c = 32, ρ = 0.01, the
/// path's continuation as the integral).
///
/// # Safety
/// `out_config` must be NULL or writable for a `LodestarTreeConfig`.
#[no_mangle]
pub unsafe extern "C" fn lodestar_tree_config_default(out_config: *mut LodestarTreeConfig) -> LodestarStatus {
    guarded("lodestar_tree_config_default", || {
        // SAFETY: the caller's contract.
        unsafe { Output::new(out_config, "out_config") }?
            .write(LodestarTreeConfig::from_settings(&SpatialDirectionalTreeSettings::default()));
        Ok(())
    })
}

/// Creates a spatial × directional tree over the box `low`..`high` (scene units): it
/// refines in space and direction where records land, at each `lodestar_guide_rebuild`.
/// Teach it with `lodestar_guide_update_sampled` or a path recorder (it learns target/pdf).
/// On success `*out_guide` owns the new guide.
///
/// # Safety
/// `config` must be NULL or a valid config; `out_guide` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn lodestar_guide_create_tree(
    config: *const LodestarTreeConfig,
    low: LodestarVec3,
    high: LodestarVec3,
    out_guide: *mut *mut LodestarGuide,
) -> LodestarStatus {
    guarded("lodestar_guide_create_tree", || {
        // SAFETY (both): the caller's contract.
        let settings = unsafe { borrow(config, "config") }?.settings()?;
        unsafe {
            create_over_bounds(low, high, out_guide, |l, h| {
                SpatialDirectionalTree::new(l, h, settings).map(GuideStructure::Tree)
            })
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_round_trip_to_the_core_defaults() {
        let volume = IrradianceVolumeSettings::default();
        assert_eq!(LodestarVolumeConfig::from_settings(&volume).settings().unwrap(), volume);
        let mixture = GaussianMixtureSettings::default();
        assert_eq!(LodestarMixtureConfig::from_settings(&mixture).settings().unwrap(), mixture);
        let tree = SpatialDirectionalTreeSettings::default();
        assert_eq!(LodestarTreeConfig::from_settings(&tree).settings().unwrap(), tree);
    }

    #[test]
    fn bad_fields_name_themselves() {
        let mut volume = LodestarVolumeConfig::from_settings(&IrradianceVolumeSettings::default());
        volume.sphere_resolution = [0, 16];
        let failure = volume.settings().unwrap_err();
        assert_eq!(failure.status, LodestarStatus::InvalidConfig, "{}", failure.message);
        let mut mixture = LodestarMixtureConfig::from_settings(&GaussianMixtureSettings::default());
        mixture.lobes = 9;
        assert!(mixture.settings().unwrap_err().message.contains("lobes"));
        let mut tree = LodestarTreeConfig::from_settings(&SpatialDirectionalTreeSettings::default());
        tree.fold_to_hemisphere = 3;
        assert!(tree.settings().unwrap_err().message.contains("fold_to_hemisphere"));
        tree.fold_to_hemisphere = 1;
        tree.flux_fraction = f32::NAN;
        assert_eq!(tree.settings().unwrap_err().status, LodestarStatus::NonFiniteArgument);
        tree.flux_fraction = 0.01;
        tree.mixed_normal_share = 1.5;
        let failure = tree.settings().unwrap_err();
        assert_eq!(failure.status, LodestarStatus::InvalidConfig, "{}", failure.message);
        assert!(failure.message.contains("mixed_normal_share"), "{}", failure.message);
        tree.mixed_normal_share = 0.97;
        tree.trees_per_axis = 2;
        assert!(tree.settings().unwrap_err().message.contains("trees_per_axis"));
        tree.trees_per_axis = 0;
        tree.second_moment = 7;
        assert!(tree.settings().unwrap_err().message.contains("second_moment"));
    }
}
