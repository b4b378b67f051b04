//! A directional guide on the GPU: a [`HemisphereGrid`]'s or an [`IrradianceVolume`]'s
//! flat arrays uploaded as they are (f32 positions and normals, Q as f32 bits, visit
//! counts, CDF, Lambertian sums or spherical-harmonic coefficients, the hash grid's
//! bucket table or the octree's nodes), a [`GaussianMixture`]'s lobe table and batch
//! words, or a [`SpatialDirectionalTree`]'s flat arrays and a buffer the shader appends
//! its records to (`tree_upload.rs`); updated in place by the shader (the tree by the
//! host, from the records), and read back into the same structure. What differs between
//! the structures on the GPU's host side lives here: their shape in the pass parameters,
//! the host's copy of a guide it refits between passes ([`HostGuide`]), and the download.

use std::sync::atomic::{AtomicU32, Ordering};

use guiding_core::{
    GaussianMixture, Guide, HemisphereGrid, HemisphereMapping, IrradianceVolume, LearningRate, SpatialDirectionalTree,
};
use wgpu::util::DeviceExt;

use super::params::Params;
use super::tree_upload::{self, TreeOnHost};
use super::GpuContext;
use crate::directional_guide::DirectionalGuide;

/// `Params::guide_kind`: which structure guides (the shader's GUIDE_*).
const GUIDE_HEMISPHERE: u32 = 0;
const GUIDE_VOLUME: u32 = 1;
const GUIDE_MIXTURE: u32 = 2;
pub(super) const GUIDE_TREE: u32 = 3;

/// A structure on the GPU: the name of its code in the shader (`Params::guide_kind`),
/// the code, and its own shader file, which defines the hooks the shader's guide
/// dispatch calls by the code (`PREFIX_locate`, `_pdf`, `_sample`, `_learn`,
/// `_integral`, `_rebuild`: see `shader/guide.wgsl` and `shader.rs`).
pub(super) struct GuideShader {
    pub(super) constant: &'static str,
    pub(super) code: u32,
    pub(super) prefix: &'static str,
    pub(super) source: &'static str,
}

/// Every structure the GPU guides with; the first is what the dispatch falls back on.
pub(super) const GUIDE_SHADERS: [GuideShader; 4] = [
    GuideShader {
        constant: "GUIDE_HEMISPHERE",
        code: GUIDE_HEMISPHERE,
        prefix: "hemisphere",
        source: include_str!("shader/guide_hemisphere.wgsl"),
    },
    GuideShader {
        constant: "GUIDE_VOLUME",
        code: GUIDE_VOLUME,
        prefix: "volume",
        source: include_str!("shader/guide_volume.wgsl"),
    },
    GuideShader {
        constant: "GUIDE_MIXTURE",
        code: GUIDE_MIXTURE,
        prefix: "mixture",
        source: include_str!("shader/guide_mixture.wgsl"),
    },
    GuideShader {
        constant: "GUIDE_TREE",
        code: GUIDE_TREE,
        prefix: "tree",
        source: include_str!("shader/guide_tree.wgsl"),
    },
];

/// The structure the GPU guides with.
#[derive(Clone, Copy)]
pub enum GpuGuide<'a> {
    /// Probes with hemispheres of patches.
    Hemisphere(&'a HemisphereGrid),
    /// Octree leaves with full-sphere tables (splitting runs on the host between passes).
    Volume(&'a IrradianceVolume),
    /// Grid regions with vMF mixtures (the M-step runs on the host between passes).
    Mixture(&'a GaussianMixture),
    /// The spatial × directional tree (records splatted and the tree refitted on the
    /// host between passes).
    Tree(&'a SpatialDirectionalTree),
}

impl<'a> GpuGuide<'a> {
    /// The GPU's view of `guide`.
    pub fn of(guide: &'a DirectionalGuide) -> Result<Self, String> {
        match guide {
            DirectionalGuide::Hemisphere(grid) => Ok(GpuGuide::Hemisphere(grid)),
            DirectionalGuide::Volume(volume) => Ok(GpuGuide::Volume(volume)),
            DirectionalGuide::Mixture(mixture) => Ok(GpuGuide::Mixture(mixture)),
            DirectionalGuide::Tree(tree) => Ok(GpuGuide::Tree(tree)),
        }
    }
}

impl<'a> From<&'a GaussianMixture> for GpuGuide<'a> {
    fn from(mixture: &'a GaussianMixture) -> Self {
        GpuGuide::Mixture(mixture)
    }
}

impl<'a> From<&'a SpatialDirectionalTree> for GpuGuide<'a> {
    fn from(tree: &'a SpatialDirectionalTree) -> Self {
        GpuGuide::Tree(tree)
    }
}

impl<'a> From<&'a HemisphereGrid> for GpuGuide<'a> {
    fn from(grid: &'a HemisphereGrid) -> Self {
        GpuGuide::Hemisphere(grid)
    }
}

impl<'a> From<&'a IrradianceVolume> for GpuGuide<'a> {
    fn from(volume: &'a IrradianceVolume) -> Self {
        GpuGuide::Volume(volume)
    }
}

impl GpuGuide<'_> {
    /// Writes what the shader needs to know of the guide's shape and settings into
    /// `params`: its kind, region and patch counts, the lookup of its regions, its
    /// learning rate and sampling mix.
    pub(super) fn write_params(self, params: &mut Params) {
        match self {
            GpuGuide::Hemisphere(grid) => {
                let s = grid.settings();
                let lookup = grid.lookup();
                params.guide_kind = GUIDE_HEMISPHERE;
                params.guide_regions = grid.probe_count() as u32;
                params.guide_patches = grid.patch_count() as u32;
                [params.patch_rows, params.patch_columns] = s.layout.resolution;
                params.lookup_buckets = (lookup.bucket_starts().len() - 1) as u32;
                params.search_rings = lookup.max_rings();
                params.lookup_origin = lookup.origin().to_array();
                params.lookup_cell_size = lookup.cell_size();
                params.q_floor = s.q_floor;
                params.max_normal_cos = s.max_normal_angle_deg.to_radians().cos();
                params.set_learning_rate(s.update_rule.learning_rate);
                params.uniform_mix = s.uniform_mix;
            }
            GpuGuide::Volume(volume) => {
                let s = volume.settings();
                params.guide_regions = volume.leaf_count() as u32;
                params.guide_patches = volume.patch_count() as u32;
                [params.patch_rows, params.patch_columns] = s.layout.resolution;
                params.q_floor = s.q_floor;
                params.set_learning_rate(s.update_rule.learning_rate);
                params.set_cell_grid(GUIDE_VOLUME, volume.resolution(), volume.grid_transform());
                params.uniform_mix = s.uniform_mix;
            }
            GpuGuide::Mixture(mixture) => {
                let s = mixture.settings();
                params.guide_regions = mixture.region_count() as u32;
                params.guide_patches = s.lobes as u32;
                params.regions_per_cell = s.regions_per_cell() as u32;
                params.set_cell_grid(GUIDE_MIXTURE, mixture.resolution(), mixture.grid_transform());
                params.uniform_mix = s.uniform_mix;
            }
            GpuGuide::Tree(tree) => tree_upload::write_params(tree, params),
        }
    }

    /// The host's copy of the guide where the host refits it between passes (a volume
    /// splits its leaves, a mixture takes its M-step); `None` for the grid, whose CDFs
    /// the GPU rebuilds.
    pub(super) fn host_copy(self) -> Option<HostGuide> {
        match self {
            GpuGuide::Hemisphere(_) => None,
            GpuGuide::Volume(volume) => Some(HostGuide::Volume(volume.clone())),
            GpuGuide::Mixture(mixture) => Some(HostGuide::Mixture(mixture.clone())),
            GpuGuide::Tree(tree) => Some(HostGuide::Tree(TreeOnHost::new(tree.clone()))),
        }
    }
}

/// The host's copy of an uploaded guide that it refits between learning passes, and
/// downloads from.
pub enum HostGuide {
    /// Leaves split on the host, the grown tree uploaded.
    Volume(IrradianceVolume),
    /// guiding-core's M-step on the host, the refitted lobes uploaded.
    Mixture(GaussianMixture),
    /// The pass's records splatted and the tree refitted on the host, the refitted tree
    /// uploaded.
    Tree(TreeOnHost),
}

impl HostGuide {
    /// Whether the GPU's rebuild kernel builds this guide's CDFs after a learning pass
    /// (the mixture's sampling is refitted by the host alone).
    pub(super) fn rebuilt_on_gpu(&self) -> bool {
        matches!(self, HostGuide::Volume(_))
    }

    /// The buffer the host reads after every learning pass: a volume's leaf visit
    /// counts, a mixture's batch words, the tree's records.
    pub(super) fn pass_readback<'b>(&self, buffers: &'b GuideBuffers) -> &'b wgpu::Buffer {
        match self {
            HostGuide::Volume(_) => &buffers.region_visits,
            HostGuide::Mixture(_) | HostGuide::Tree(_) => &buffers.q,
        }
    }

    /// Between passes, from the pass's `words` ([`pass_readback`](Self::pass_readback)):
    /// a volume takes its leaf visit counts and, where its rule says leaves split, its
    /// tables too, splits on the host and uploads the grown tree, tables and CDFs; a
    /// mixture takes its batch sums, fits, and uploads its lobes and an empty batch; the
    /// tree takes the pass's records, refits (as the CPU's online schedule does after
    /// every pass), and uploads itself and an empty record buffer.
    pub(super) fn refit(
        &mut self,
        words: &[u32],
        context: &GpuContext,
        buffers: &GuideBuffers,
        params: &mut Params,
    ) -> Result<(), String> {
        match self {
            HostGuide::Volume(volume) => {
                let leaves = volume.leaf_count();
                store(volume.leaf_visit_counts(), &words[..leaves]);
                if !volume.splits_pending() {
                    return Ok(());
                }
                buffers.read_volume_tables(context, volume, &words[..leaves])?;
                buffers.write_volume(&context.queue, volume);
                params.guide_regions = volume.leaf_count() as u32;
            }
            HostGuide::Mixture(mixture) => {
                store(mixture.batch_words(), words);
                mixture.rebuild_sampling();
                buffers.write_mixture(&context.queue, mixture);
            }
            HostGuide::Tree(host) => host.learn_pass(words, &context.queue, buffers, params)?,
        }
        Ok(())
    }
}

/// What the GPU guide cannot do with `guide`'s settings, if anything.
pub fn unsupported(guide: GpuGuide<'_>) -> Option<String> {
    let rate = match guide {
        GpuGuide::Hemisphere(grid) => {
            let settings = grid.settings();
            if settings.layout.mapping != HemisphereMapping::Cylindrical {
                return Some("the concentric patch layout (use --mapping cylindrical)".into());
            }
            if settings.sampling_exponent != 1.0 {
                return Some("a sampling exponent other than 1".into());
            }
            if settings.cosine_product {
                return Some("the cosine product (use --cosine-product off)".into());
            }
            settings.update_rule.learning_rate
        }
        GpuGuide::Volume(volume) => volume.settings().update_rule.learning_rate,
        // The host takes the M-step, or refits the tree, with guiding-core's own rule.
        GpuGuide::Mixture(_) | GpuGuide::Tree(_) => return None,
    };
    if matches!(rate, LearningRate::Global { .. }) {
        return Some("the global learning rate".into());
    }
    None
}

/// The guide's buffers on a device. Bindings cannot be zero-sized, so an empty array
/// (or no guide) uploads one element; a volume's arrays have room for every leaf and
/// node its budget allows.
pub struct GuideBuffers {
    /// The grid's probe positions, or the tree's cell probabilities.
    pub positions: wgpu::Buffer,
    /// The grid's probe normals, or the tree's cell probabilities under the cosine product.
    pub normals: wgpu::Buffer,
    /// The grid's bucket starts, the volume's nodes, or the tree's nodes and leaves.
    pub index_table: wgpu::Buffer,
    pub q: wgpu::Buffer,
    pub patch_visits: wgpu::Buffer,
    /// Per probe or leaf.
    pub region_visits: wgpu::Buffer,
    pub cdf: wgpu::Buffer,
    /// The grid's Lambertian sums, or the volume's nine coefficients per leaf.
    pub integral_terms: wgpu::Buffer,
    /// The grid's per-patch ∫cos, or the volume's nine ∫Y_lm per patch.
    pub patch_weights: wgpu::Buffer,
    pub built_visits: wgpu::Buffer,
}

fn bits(words: &[AtomicU32]) -> Vec<u32> {
    words.iter().map(|w| w.load(Ordering::Relaxed)).collect()
}

/// `values` zero-padded to `length` (at least one element).
pub(super) fn padded<T: Default + Clone>(values: &[T], length: usize) -> Vec<T> {
    let mut padded = values.to_vec();
    padded.resize(length.max(values.len()).max(1), T::default());
    padded
}

const READ_WRITE: wgpu::BufferUsages =
    wgpu::BufferUsages::STORAGE.union(wgpu::BufferUsages::COPY_SRC).union(wgpu::BufferUsages::COPY_DST);

/// The arrays of one structure, as uploaded.
struct Arrays {
    positions: Vec<f32>,
    normals: Vec<f32>,
    index_table: Vec<u32>,
    q: Vec<u32>,
    patch_visits: Vec<u32>,
    region_visits: Vec<u32>,
    cdf: Vec<f32>,
    integral_terms: Vec<u32>,
    patch_weights: Vec<f32>,
}

impl Arrays {
    fn of_grid(g: &HemisphereGrid) -> Self {
        let floats = |values: &[glam::Vec3]| values.iter().flat_map(|v| v.to_array()).collect::<Vec<f32>>();
        Self {
            positions: floats(g.probe_positions()),
            normals: floats(g.probe_normals()),
            index_table: g.lookup().bucket_starts().to_vec(),
            q: bits(g.q_values()),
            patch_visits: bits(g.visit_counts()),
            region_visits: bits(g.probe_visit_counts()),
            cdf: g.cdf().to_vec(),
            integral_terms: bits(g.lambertian_sums()),
            patch_weights: g.patch_cos_integrals().to_vec(),
        }
    }

    /// A volume's arrays, padded to its capacity.
    fn of_volume(v: &IrradianceVolume) -> Self {
        let (leaves, nodes) = v.capacity();
        let patches = v.patch_count();
        let flat = |values: &[[f32; 9]]| values.iter().flatten().map(|c| c.to_bits()).collect::<Vec<u32>>();
        Self {
            positions: vec![0.0],
            normals: vec![0.0],
            index_table: padded(v.nodes(), nodes),
            q: padded(&bits(v.q_values()), leaves * patches),
            patch_visits: padded(&bits(v.patch_visit_counts()), leaves * patches),
            region_visits: padded(&bits(v.leaf_visit_counts()), leaves),
            cdf: padded(v.cdf(), leaves * patches),
            integral_terms: padded(&flat(v.irradiance_coefficients()), leaves * 9),
            patch_weights: v.patch_basis_integrals().iter().flatten().copied().collect(),
        }
    }

    /// A tree's tables ([`tree_upload::tables`]) in the `positions`, `normals`,
    /// `index_table` and `q` slots.
    fn of_tree(tree: &SpatialDirectionalTree, record_capacity: u32) -> Result<Self, String> {
        let t = tree_upload::tables(tree, record_capacity)?;
        let (positions, normals, index_table) = (t.probabilities, t.cosine_probabilities, t.index_table);
        Ok(Self { positions, normals, index_table, q: t.records, ..Self::empty() })
    }

    /// A mixture's lobe table (in the `cdf` slot) and batch words (in the `q` slot).
    fn of_mixture(m: &GaussianMixture) -> Self {
        Self { cdf: m.lobe_table(), q: bits(m.batch_words()), ..Self::empty() }
    }

    fn empty() -> Self {
        Self {
            positions: vec![0.0],
            normals: vec![0.0],
            index_table: vec![0, 0],
            q: vec![0],
            patch_visits: vec![0],
            region_visits: vec![0],
            cdf: vec![0.0],
            integral_terms: vec![0],
            patch_weights: vec![0.0],
        }
    }
}

impl GuideBuffers {
    /// Uploads `guide` (its shape written into `params`), or one-element placeholders
    /// for unguided renders.
    pub fn new(device: &wgpu::Device, guide: Option<GpuGuide<'_>>, params: &Params) -> Result<Self, String> {
        let arrays = match guide {
            Some(GpuGuide::Hemisphere(grid)) => Arrays::of_grid(grid),
            Some(GpuGuide::Volume(volume)) => Arrays::of_volume(volume),
            Some(GpuGuide::Mixture(mixture)) => Arrays::of_mixture(mixture),
            Some(GpuGuide::Tree(tree)) => Arrays::of_tree(tree, params.record_capacity)?,
            None => Arrays::empty(),
        };
        let buffer = |label: &str, bytes: &[u8], usage: wgpu::BufferUsages| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents: bytes, usage })
        };
        let read = wgpu::BufferUsages::STORAGE;
        // The volume's tree grows when leaves split: the host rewrites it.
        let index_usage = read | wgpu::BufferUsages::COPY_DST;
        let a = &arrays;
        let one = |values: &[u32]| padded(values, 1);
        // The tree's arrays are rewritten whole at every refit.
        let refitted =
            if matches!(guide, Some(GpuGuide::Tree(_))) { read | wgpu::BufferUsages::COPY_DST } else { read };
        Ok(Self {
            positions: buffer("probe positions", bytemuck::cast_slice(&padded(&a.positions, 1)), refitted),
            normals: buffer("probe normals", bytemuck::cast_slice(&padded(&a.normals, 1)), refitted),
            index_table: buffer("index table", bytemuck::cast_slice(&one(&a.index_table)), index_usage),
            q: buffer("q", bytemuck::cast_slice(&one(&a.q)), READ_WRITE),
            patch_visits: buffer("patch visits", bytemuck::cast_slice(&one(&a.patch_visits)), READ_WRITE),
            region_visits: buffer("region visits", bytemuck::cast_slice(&one(&a.region_visits)), READ_WRITE),
            cdf: buffer("cdf", bytemuck::cast_slice(&padded(&a.cdf, 1)), READ_WRITE),
            integral_terms: buffer("integral terms", bytemuck::cast_slice(&one(&a.integral_terms)), READ_WRITE),
            patch_weights: buffer("patch weights", bytemuck::cast_slice(&padded(&a.patch_weights, 1)), read),
            // The CDFs uploaded are current: rebuild only what the first pass changes.
            built_visits: buffer("built visits", bytemuck::cast_slice(&one(&a.region_visits)), READ_WRITE),
        })
    }

    /// Rewrites every array of `volume` (after the host split leaves), its CDFs
    /// current; the buffers were sized for its capacity.
    pub fn write_volume(&self, queue: &wgpu::Queue, volume: &IrradianceVolume) {
        let a = Arrays::of_volume(volume);
        queue.write_buffer(&self.index_table, 0, bytemuck::cast_slice(&a.index_table));
        queue.write_buffer(&self.q, 0, bytemuck::cast_slice(&a.q));
        queue.write_buffer(&self.patch_visits, 0, bytemuck::cast_slice(&a.patch_visits));
        queue.write_buffer(&self.region_visits, 0, bytemuck::cast_slice(&a.region_visits));
        queue.write_buffer(&self.cdf, 0, bytemuck::cast_slice(&a.cdf));
        queue.write_buffer(&self.integral_terms, 0, bytemuck::cast_slice(&a.integral_terms));
        queue.write_buffer(&self.built_visits, 0, bytemuck::cast_slice(&a.region_visits));
    }

    /// Rewrites a mixture's lobe table and batch words (after the host's M-step).
    pub fn write_mixture(&self, queue: &wgpu::Queue, mixture: &GaussianMixture) {
        let a = Arrays::of_mixture(mixture);
        queue.write_buffer(&self.cdf, 0, bytemuck::cast_slice(&a.cdf));
        queue.write_buffer(&self.q, 0, bytemuck::cast_slice(&a.q));
    }

    /// Reads the volume's learned Q and patch visits back into `volume` (whose leaves are
    /// those on the GPU), with its `leaf_visits`, and rebuilds its sampling.
    fn read_volume_tables(
        &self,
        context: &GpuContext,
        volume: &mut IrradianceVolume,
        leaf_visits: &[u32],
    ) -> Result<(), String> {
        let entries = volume.leaf_count() * volume.patch_count();
        let q = context.copy_to_host(&self.q)?;
        let patch_visits = context.copy_to_host(&self.patch_visits)?;
        store_volume_tables(volume, &q[..entries], &patch_visits[..entries], leaf_visits);
        volume.rebuild_sampling();
        Ok(())
    }

    /// Reads what `guide` (the guide uploaded, with `host` its host copy and `params`
    /// the pass parameters) learned back into it: a grid takes the learned Q and visit
    /// counts ([`store_learned`]); a volume becomes the host's copy as it learned and
    /// split, with the tables read back; a mixture becomes the host's copy (every pass's
    /// batch already absorbed).
    pub(super) fn download(
        &self,
        context: &GpuContext,
        host: Option<&HostGuide>,
        params: &Params,
        guide: &mut DirectionalGuide,
    ) -> Result<(), String> {
        match (guide, host) {
            (DirectionalGuide::Hemisphere(grid), None) => {
                if params.guide_regions as usize != grid.probe_count()
                    || params.guide_patches as usize != grid.patch_count()
                {
                    return Err("the grid does not match the one uploaded".into());
                }
                let q = context.copy_to_host(&self.q)?;
                let patch_visits = context.copy_to_host(&self.patch_visits)?;
                let probe_visits = context.copy_to_host(&self.region_visits)?;
                store_learned(grid, &q, &patch_visits, &probe_visits);
            }
            (DirectionalGuide::Volume(volume), Some(HostGuide::Volume(learned))) => {
                let mut learned = learned.clone();
                let leaf_visits = context.copy_to_host(&self.region_visits)?;
                let leaves = learned.leaf_count();
                self.read_volume_tables(context, &mut learned, &leaf_visits[..leaves])?;
                *volume = learned;
            }
            (DirectionalGuide::Mixture(mixture), Some(HostGuide::Mixture(learned))) => mixture.clone_from(learned),
            (DirectionalGuide::Tree(tree), Some(HostGuide::Tree(learned))) => *tree = learned.tree.clone(),
            (guide, _) => return Err(format!("the {} guide is not the one uploaded", guide.structure().name())),
        }
        Ok(())
    }
}

/// Stores words read back from the GPU into `slots` (as many as both hold).
pub fn store(slots: &[AtomicU32], words: &[u32]) {
    for (slot, &word) in slots.iter().zip(words) {
        slot.store(word, Ordering::Relaxed);
    }
}

/// Stores learned Q and visit counts (read back from the GPU) into `grid`, then
/// rebuilds its sampling: the grid then holds exactly the GPU's learned state.
pub fn store_learned(grid: &mut HemisphereGrid, q: &[u32], patch_visits: &[u32], probe_visits: &[u32]) {
    store(grid.q_values(), q);
    store(grid.visit_counts(), patch_visits);
    store(grid.probe_visit_counts(), probe_visits);
    grid.rebuild_sampling();
}

/// Stores learned Q and visit counts (read back from the GPU, its leaves in the same
/// tree) into `volume`, without rebuilding.
pub fn store_volume_tables(volume: &IrradianceVolume, q: &[u32], patch_visits: &[u32], leaf_visits: &[u32]) {
    store(volume.q_values(), q);
    store(volume.patch_visit_counts(), patch_visits);
    store(volume.leaf_visit_counts(), leaf_visits);
}
