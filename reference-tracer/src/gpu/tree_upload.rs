//! The host's side of the spatial × directional tree on the GPU: its [`FlatTree`] laid
//! out as `shader/guide_tree.wgsl` reads it, with room for all its budget allows; the
//! record buffer the shader appends to; and, after each learning pass, the records read
//! back, splatted into the host's copy, the refit, and the upload of what changed.

use glam::Vec3;
use guiding_core::{FlatTree, Guide, SpatialDirectionalTree, TreeRecords, TreeRegion};

use super::guide_buffers::{padded, GuideBuffers, GUIDE_TREE};
use super::params::Params;

/// `Params::tree_flags`: a spatial tree per world axis, picked by the normal.
pub(super) const TREE_FLAG_PER_AXIS: u32 = 1;
/// `Params::tree_flags`: regions keep to the normal's hemisphere.
pub(super) const TREE_FLAG_FOLD: u32 = 2;
/// `Params::tree_flags`: an aligned normal's half is sampled by the cosine product.
pub(super) const TREE_FLAG_COSINE: u32 = 4;

/// Words per record the shader appends (leaf and half, normal, direction, target, pdf).
const RECORD_WORDS: usize = 9;

/// The record buffer holds at most this many records per pass (36 MiB): at 1280×720 a
/// pass makes more, and the rest go unlearned (counted in [`TreeOnHost::lost_records`]).
const MAX_RECORDS: u32 = 1 << 20;

/// Records per pixel the record buffer has room for, within [`MAX_RECORDS`].
const RECORDS_PER_PIXEL: u32 = 16;

/// The record buffer's room for an image of `pixels`.
fn record_capacity(pixels: u32) -> u32 {
    pixels.saturating_mul(RECORDS_PER_PIXEL).clamp(1, MAX_RECORDS)
}

/// Words of `index_table` before the spatial nodes: the roots of up to three trees.
const ROOT_WORDS: usize = 3;

/// Writes the tree's shape and settings into `params`: the box, where its leaves and
/// quadtree nodes start in `index_table` (fixed by its budget), its flags, its uniform
/// share, and the record buffer's room (none where the guide does not learn; `params`
/// says whether it does).
pub(super) fn write_params(tree: &SpatialDirectionalTree, params: &mut Params) {
    let flat = tree.flat();
    let (leaves, _) = tree.capacity();
    params.set_cell_grid(GUIDE_TREE, [1; 3], (flat.low, flat.inverse_extent));
    params.tree_leaves_at = (ROOT_WORDS + 3 * leaves) as u32;
    params.tree_quad_at = (ROOT_WORDS + 7 * leaves) as u32;
    params.tree_flags = (flat.trees_per_axis as u32 * TREE_FLAG_PER_AXIS)
        | (flat.fold_to_hemisphere as u32 * TREE_FLAG_FOLD)
        | (!flat.cosine_probabilities.is_empty() as u32 * TREE_FLAG_COSINE);
    params.uniform_mix = flat.uniform_mix;
    let learns = params.guide_learns != 0;
    params.record_capacity = if learns { record_capacity(params.width.saturating_mul(params.height)) } else { 0 };
    set_shape(params, tree);
}

/// The tree's regions (its leaves) in `params` (they change at every refit); it has no
/// fixed entries per region, so `guide_patches` stays unused.
fn set_shape(params: &mut Params, tree: &SpatialDirectionalTree) {
    params.guide_regions = tree.leaf_count() as u32;
}

/// The tree's flat arrays and the leaves and nodes its budget holds (which its buffers
/// are sized for); an error for a tree larger than that, or with a number of spatial
/// trees the shader does not know.
fn flat_within_budget(tree: &SpatialDirectionalTree) -> Result<(FlatTree, usize, usize), String> {
    let flat = tree.flat();
    let (leaves, nodes) = tree.capacity();
    let roots = flat.roots.len();
    if flat.leaves.len() > 4 * leaves || flat.quad_children.len() > 4 * nodes || !(1..=ROOT_WORDS).contains(&roots) {
        return Err(format!(
            "the tree ({} leaves, {} directional nodes, {roots} spatial trees) is larger than its budget allows",
            tree.leaf_count(),
            tree.directional_node_count(),
        ));
    }
    Ok((flat, leaves, nodes))
}

/// The three root words (a tree per axis, or the one tree's root thrice).
fn root_words(flat: &FlatTree) -> [u32; ROOT_WORDS] {
    core::array::from_fn(|k| flat.roots[k % flat.roots.len()])
}

/// The tree's arrays as first uploaded, padded to its budget.
pub(super) struct Tables {
    /// Four cell probabilities per quadtree node.
    pub(super) probabilities: Vec<f32>,
    /// Four per node under the cosine product (zeros where the settings leave it off).
    pub(super) cosine_probabilities: Vec<f32>,
    /// The roots, the spatial nodes, the leaves and the quadtree's children, at the
    /// offsets [`write_params`] gives.
    pub(super) index_table: Vec<u32>,
    /// The record buffer: the count, then room for the records.
    pub(super) records: Vec<u32>,
}

/// The tree's [`Tables`], with room for `records` records a pass.
pub(super) fn tables(tree: &SpatialDirectionalTree, records: u32) -> Result<Tables, String> {
    let (flat, leaves, nodes) = flat_within_budget(tree)?;
    let mut index_table = root_words(&flat).to_vec();
    index_table.extend(padded(&flat.spatial, 3 * leaves));
    index_table.extend(padded(&flat.leaves, 4 * leaves));
    index_table.extend(padded(&flat.quad_children, 4 * nodes));
    Ok(Tables {
        probabilities: padded(&flat.quad_probabilities, 4 * nodes),
        cosine_probabilities: padded(&flat.cosine_probabilities, 4 * nodes),
        index_table,
        records: vec![0; 1 + RECORD_WORDS * records as usize],
    })
}

/// Rewrites the tree's arrays (after a refit; `params` has their offsets) and empties
/// the record buffer. Only what the tree holds is written: no descent reaches past it.
fn write(
    buffers: &GuideBuffers,
    queue: &wgpu::Queue,
    tree: &SpatialDirectionalTree,
    params: &Params,
) -> Result<(), String> {
    let (flat, _, _) = flat_within_budget(tree)?;
    let words = |offset: usize, values: &[u32]| {
        if !values.is_empty() {
            queue.write_buffer(&buffers.index_table, 4 * offset as u64, bytemuck::cast_slice(values));
        }
    };
    words(0, &root_words(&flat));
    words(ROOT_WORDS, &flat.spatial);
    words(params.tree_leaves_at as usize, &flat.leaves);
    words(params.tree_quad_at as usize, &flat.quad_children);
    queue.write_buffer(&buffers.positions, 0, bytemuck::cast_slice(&flat.quad_probabilities));
    if !flat.cosine_probabilities.is_empty() {
        queue.write_buffer(&buffers.normals, 0, bytemuck::cast_slice(&flat.cosine_probabilities));
    }
    queue.write_buffer(&buffers.q, 0, bytemuck::bytes_of(&0u32));
    Ok(())
}

/// The host's copy of a tree guiding on the GPU.
pub struct TreeOnHost {
    /// The tree, refitted after every learning pass.
    pub tree: SpatialDirectionalTree,
    /// Records read back from a pass, before the splat (kept for their room).
    records: TreeRecords,
    /// Records the shader made past the record buffer's room, over all passes.
    pub lost_records: u64,
}

impl TreeOnHost {
    /// The host's copy of `tree`, as uploaded.
    pub(super) fn new(tree: SpatialDirectionalTree) -> Self {
        Self { tree, records: TreeRecords::default(), lost_records: 0 }
    }

    /// After a learning pass, from the record buffer's `words`: learns the records (a
    /// bad one is counted by the tree and left out, as on the CPU), refits (as the
    /// CPU's online schedule does after every pass), and uploads the refitted tree and
    /// an empty record buffer.
    pub(super) fn learn_pass(
        &mut self,
        words: &[u32],
        queue: &wgpu::Queue,
        buffers: &GuideBuffers,
        params: &mut Params,
    ) -> Result<(), String> {
        let made = words.first().copied().unwrap_or(0);
        let kept = made.min(params.record_capacity);
        self.lost_records += (made - kept) as u64;
        let upper = 1 << 31;
        for record in words.get(1..).unwrap_or_default().chunks_exact(RECORD_WORDS).take(kept as usize) {
            let float = |k: usize| f32::from_bits(record[k]);
            let region = TreeRegion {
                leaf: record[0] & !upper,
                normal: Vec3::new(float(1), float(2), float(3)),
                upper_half: record[0] & upper != 0,
            };
            let direction = Vec3::new(float(4), float(5), float(6));
            self.tree.record(&mut self.records, region, direction, float(7), float(8));
        }
        self.tree.splat(&mut self.records);
        self.tree.rebuild_sampling();
        write(buffers, queue, &self.tree, params)?;
        set_shape(params, &self.tree);
        Ok(())
    }
}
