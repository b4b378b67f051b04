//! The uniform block the shader reads (`Params`, whose WGSL declaration is generated
//! here from the Rust struct) and the codes its fields carry for the method, the guide
//! structure and the learning rate.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use guiding_core::LearningRate;

use crate::integrator::Method;

/// Declares a `#[repr(C)]` uniform block and, from the same list, its WGSL `struct`
/// (`WGSL`) and each field's byte offset in Rust (`OFFSETS`), which a test holds against
/// the offsets WGSL's layout rules give: one list, so the two sides cannot drift. Fields
/// come in 16-byte rows (four scalars, or a `vec3` and a scalar), as WGSL aligns a `vec3`.
macro_rules! uniform_block {
    ($(#[$meta:meta])* $name:ident { $($(#[$field_meta:meta])* $field:ident: $rust:ty => $wgsl:literal,)* }) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
        #[repr(C)]
        pub(super) struct $name {
            $($(#[$field_meta])* pub(super) $field: $rust,)*
        }

        impl $name {
            /// The block's WGSL declaration.
            pub(super) const WGSL: &'static str =
                concat!("struct ", stringify!($name), " {\n", $("    ", stringify!($field), ": ", $wgsl, ",\n",)* "};\n");

            /// Each field's name and byte offset in the Rust struct.
            #[cfg(test)]
            pub(super) const OFFSETS: &'static [(&'static str, usize)] =
                &[$((stringify!($field), core::mem::offset_of!($name, $field)),)*];
        }
    };
}

uniform_block! {
    /// The uniform block of the shader: the image, the method, the camera, the scene's
    /// scale, and the guide structure's shape and learning rule.
    Params {
        /// Image width, pixels.
        width: u32 => "u32",
        /// Image height, pixels.
        height: u32 => "u32",
        /// The pass (sample) index; `sample_guide` reads it as the region.
        pass_index: u32 => "u32",
        /// The pass's seed.
        seed: u32 => "u32",
        /// Most scattering vertices per path.
        max_depth: u32 => "u32",
        /// Russian roulette after this many vertices.
        rr_depth: u32 => "u32",
        /// The method (the shader's METHOD_*).
        method: u32 => "u32",
        /// Area light triangles.
        light_count: u32 => "u32",
        /// Camera position, scene units.
        eye: [f32; 3] => "vec3<f32>",
        /// Ray offset from a surface, scene units (relative to the scene's size).
        ray_epsilon: f32 => "f32",
        /// Unit view direction.
        forward: [f32; 3] => "vec3<f32>",
        /// tan(vertical field of view / 2).
        tan_half_fov_y: f32 => "f32",
        /// Unit right vector of the image plane.
        right: [f32; 3] => "vec3<f32>",
        /// Probability of sampling the guide instead of the BSDF.
        guide_probability: f32 => "f32",
        /// Unit up vector of the image plane.
        up: [f32; 3] => "vec3<f32>",
        /// The guide's share spread uniformly (its settings' `uniform_mix`).
        uniform_mix: f32 => "f32",
        /// The constant environment's radiance (zero for none or an image).
        environment_radiance: [f32; 3] => "vec3<f32>",
        /// Probability that next-event estimation picks the environment.
        environment_choice: f32 => "f32",
        /// 1 where a guide is uploaded.
        guide_present: u32 => "u32",
        /// 1 where the guide learns this pass.
        guide_learns: u32 => "u32",
        /// The guide's regions: probes, leaves or mixture regions.
        guide_regions: u32 => "u32",
        /// Entries per region: patches, or lobes for the mixture.
        guide_patches: u32 => "u32",
        /// Patch rows (cos θ bands) of the hemisphere grid and the volume.
        patch_rows: u32 => "u32",
        /// Patch columns (φ sectors).
        patch_columns: u32 => "u32",
        /// Buckets of the hemisphere grid's hashed probe lookup (a power of two).
        lookup_buckets: u32 => "u32",
        /// Rings of cells the probe lookup searches.
        search_rings: u32 => "u32",
        /// The probe lookup's grid origin, scene units.
        lookup_origin: [f32; 3] => "vec3<f32>",
        /// The probe lookup's cell size, scene units.
        lookup_cell_size: f32 => "f32",
        /// The least Q a table entry keeps (radiance).
        q_floor: f32 => "f32",
        /// Cosine of the largest angle between a hit's normal and its probe's.
        max_normal_cos: f32 => "f32",
        /// The learning rate (the shader's LEARNING_RATE_*).
        learning_rate: u32 => "u32",
        /// The exponential learning rate's α.
        learning_rate_alpha: f32 => "f32",
        /// The volume's or mixture's grid cells per axis.
        grid_cells: [u32; 3] => "vec3<u32>",
        /// Which structure guides (the shader's GUIDE_*).
        guide_kind: u32 => "u32",
        /// The grid's low corner, scene units.
        grid_low: [f32; 3] => "vec3<f32>",
        /// The mixture's regions per grid cell.
        regions_per_cell: u32 => "u32",
        /// The grid's cells per unit length.
        grid_cells_per_unit: [f32; 3] => "vec3<f32>",
        /// Unused: fills the row.
        padding_a: u32 => "u32",
        /// The normal `sample_guide` samples a volume leaf about.
        sample_normal: [f32; 3] => "vec3<f32>",
        /// Unused: fills the row.
        padding_b: u32 => "u32",
        /// The tree: the word of `index_table` its leaves start at.
        tree_leaves_at: u32 => "u32",
        /// The tree: the word of `index_table` its quadtree nodes' children start at.
        tree_quad_at: u32 => "u32",
        /// The tree: TREE_FLAG_* (a spatial tree per axis, folding, the cosine product).
        tree_flags: u32 => "u32",
        /// The tree: records the pass's record buffer holds.
        record_capacity: u32 => "u32",
    }
}

impl Params {
    /// The guide `kind` (GUIDE_*) and its grid of cells: cells per axis, low corner and
    /// cells per unit length.
    pub(super) fn set_cell_grid(&mut self, kind: u32, cells: [u32; 3], (low, inverse_cell_size): (Vec3, Vec3)) {
        self.guide_kind = kind;
        self.grid_cells = cells;
        self.grid_low = low.to_array();
        self.grid_cells_per_unit = inverse_cell_size.to_array();
    }

    /// The learning rate's code and the exponential rate's α.
    pub(super) fn set_learning_rate(&mut self, rate: LearningRate) {
        (self.learning_rate, self.learning_rate_alpha) = match rate {
            LearningRate::Exponential { alpha } => (LEARNING_RATE_EXPONENTIAL, alpha),
            // The shader keeps no epoch count: the global schedule learns as the simple
            // average does.
            LearningRate::SimpleAverage | LearningRate::Global { .. } => (LEARNING_RATE_ENTRY_VISITS, 0.0),
            LearningRate::RegionVisits => (LEARNING_RATE_REGION_VISITS, 0.0),
            other => unreachable!("{other:?} has no shader code yet"),
        };
    }
}

/// `Params::learning_rate`: α constant, 1/(1 + the entry's visits), or 1/(1 + the
/// region's visits) (the shader's LEARNING_RATE_*).
pub(super) const LEARNING_RATE_EXPONENTIAL: u32 = 0;
pub(super) const LEARNING_RATE_ENTRY_VISITS: u32 = 1;
pub(super) const LEARNING_RATE_REGION_VISITS: u32 = 2;

pub(super) fn method_code(method: Method) -> u32 {
    match method {
        Method::Pt => 0,
        Method::Nee => 1,
        Method::Guided => 2,
        Method::GuidedNee => 3,
        // Refused before the GPU is reached (`Session::render`).
        Method::Light | Method::LightGuided | Method::Bdpt | Method::BdptGuided | Method::Vpl | Method::VplGuided => {
            unreachable!("the GPU tracer has no light subpaths")
        }
    }
}
