//! Directional quadtrees over the equal-area square ([`super::square`]), kept in one
//! arena per tree: sampling and the pdf by one descent each, records added at the cell
//! a direction falls in, and the refit between epochs that splits cells holding much of
//! the flux and merges those holding little (Müller et al. 2017, §3).

use alloc::vec::Vec;
use core::sync::atomic::AtomicU32;

use glam::{Vec2, Vec4};

use super::square::{ONE_BELOW, SQUARE_TO_SOLID_ANGLE};
use crate::atomic_f32;

/// One node of a directional quadtree: four cells, in the order (u low, v low),
/// (u high, v low), (u low, v high), (u high, v high).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct QuadNode {
    /// The probability of each cell within this node; they sum to one.
    pub(crate) probability: [f32; 4],
    /// The arena index of each cell's node, or 0 where the cell is a leaf (index 0 is
    /// always a root, never a child).
    pub(crate) child: [u32; 4],
}

impl QuadNode {
    /// A node of four leaf cells of equal probability.
    pub(crate) const UNIFORM: QuadNode = QuadNode { probability: [0.25; 4], child: [0; 4] };
}

/// Bytes a node costs: the node, its four building sums and its cells' probabilities
/// under the cosine product ([`super::cosine`]; counted whether or not the settings use
/// it, so the budget does not depend on that switch).
pub(crate) const NODE_BYTES: usize =
    core::mem::size_of::<QuadNode>() + 4 * core::mem::size_of::<AtomicU32>() + core::mem::size_of::<[f32; 4]>();

/// The probabilities of a node's four cells that a descent reads: the tree's own
/// ([`QuadNode::probability`]), or another set over the same nodes, indexed alike (the
/// cosine product's).
pub(crate) trait CellProbabilities {
    /// The four cells' probabilities at arena index `node`, in place: a descent reads
    /// one of them by the cell it picked, a load from the node rather than from a copy.
    fn cells(&self, node: usize) -> &[f32; 4];
}

impl CellProbabilities for [QuadNode] {
    #[inline]
    fn cells(&self, node: usize) -> &[f32; 4] {
        &self[node].probability
    }
}

impl CellProbabilities for [[f32; 4]] {
    #[inline]
    fn cells(&self, node: usize) -> &[f32; 4] {
        &self[node]
    }
}

/// The cell of `p` within a node, and `p` in that cell's own unit square.
#[inline]
fn descend(p: Vec2) -> (usize, Vec2) {
    let (ix, iy) = (p.x >= 0.5, p.y >= 0.5);
    let cell = ix as usize + 2 * iy as usize;
    // Doubling and subtracting one are exact in floating point.
    let q = Vec2::new(if ix { p.x * 2.0 - 1.0 } else { p.x * 2.0 }, if iy { p.y * 2.0 - 1.0 } else { p.y * 2.0 });
    (cell, q)
}

/// Picks between two masses `a` and `b` with `u` ∈ [0, 1) and rescales `u` to [0, 1)
/// within the one picked: `false` for `a`. Selects rather than branches: the pick is a
/// coin flip the branch predictor cannot learn, taken twice per level of every descent.
#[inline]
fn choose(u: &mut f32, a: f32, b: f32) -> bool {
    let total = a + b;
    if total.is_nan() || total <= 0.0 {
        // Both empty, or damaged data: split evenly.
        let high = *u >= 0.5;
        *u = if high { *u * 2.0 - 1.0 } else { *u * 2.0 };
        return high;
    }
    let scaled = *u * total;
    // `b > 0` keeps an empty high side from being picked when u·total rounds up to a.
    let high = (scaled >= a) & (b > 0.0);
    let (offset, width) = (if high { a } else { 0.0 }, if high { b } else { a });
    *u = ((scaled - offset) / width).clamp(0.0, ONE_BELOW);
    high
}

/// Picks one of a node's four cells by their probabilities `p` with `u` ∈ [0, 1) and
/// rescales `u` to [0, 1) within the cell picked. One number picks among all four, so a
/// level's pick waits on one comparison, not two (the second number's pick waited on the
/// first's rescale); the division that rescales `u` is needed only two levels on.
///
/// Branch-free: the four lower edges are compared at once and the cell is the count of
/// those at or below `u`·total. A coin flip per level is what a branch predictor cannot
/// learn, and the descent's levels wait on each other.
#[inline(always)]
fn pick_cell(u: &mut f32, p: &[f32; 4]) -> usize {
    let low_pair = p[0] + p[1];
    // The lower edges (0, p₀, p₀+p₁, p₀+p₁+p₂), and the total added pairwise beside them.
    let edges = Vec4::new(0.0, p[0], low_pair, low_pair + p[2]);
    let total = low_pair + (p[2] + p[3]);
    if total.is_nan() || total <= 0.0 {
        // All empty, or damaged data: four equal cells.
        let cell = ((*u * 4.0) as usize).min(3);
        *u = (*u * 4.0 - cell as f32).clamp(0.0, ONE_BELOW);
        return cell;
    }
    let scaled = *u * total;
    // An edge counts where u·total reaches it and mass lies above it: the cells above
    // the last one holding mass share its upper edge, the total, so u·total rounding up
    // onto it picks no empty cell.
    let reached = Vec4::splat(scaled).cmpge(edges) & edges.cmplt(Vec4::splat(total));
    // The edges reached are a prefix (they ascend), the first always among them.
    let cell = (reached.bitmask() | 1).ilog2() as usize;
    let low = Vec4::select(reached, edges, Vec4::ZERO).max_element();
    *u = ((scaled - low) / p[cell]).clamp(0.0, ONE_BELOW);
    cell
}

/// One level of a descent: the cell `cell` of `node` picked, with probability
/// `probability`; moves the cell's corner and size on and multiplies the density by the
/// cell's. Returns the child node, or `None` where the cell is a leaf.
#[inline(always)]
fn step_into(nodes: &[QuadNode], node: usize, cell: usize, probability: f32, walk: &mut Walk) -> Option<usize> {
    walk.density *= 4.0 * probability;
    walk.size *= 0.5;
    walk.origin += Vec2::new((cell & 1) as f32, (cell >> 1) as f32) * walk.size;
    match nodes[node].child[cell] {
        0 => None,
        child => Some(child as usize),
    }
}

/// Where a sampling descent stands: the current cell's corner and side in the square,
/// and the density of the cells picked so far relative to uniform.
struct Walk {
    origin: Vec2,
    size: f32,
    density: f32,
}

impl Walk {
    /// The point of the leaf cell reached at `u` within it, kept inside the cell
    /// (origin + u·size can round up onto its far edge), and its density.
    #[inline(always)]
    fn finish(&self, u: Vec2) -> (Vec2, f32) {
        let end = self.origin + Vec2::splat(self.size);
        let below = Vec2::new(f32::from_bits(end.x.to_bits() - 1), f32::from_bits(end.y.to_bits() - 1));
        ((self.origin + u * self.size).min(below), self.density)
    }
}

/// A point of the square drawn with the tree's density from `u` ∈ [0, 1)², and the
/// density there relative to the uniform one: one descent, the uniform numbers rescaled
/// at each level (no further random numbers). `half` restricts the draw to the half
/// u ≥ 1/2 (`Some(true)`: polar z ≥ 0) or u < 1/2 (`Some(false)`); the density returned
/// is the whole tree's, so the restricted density is it over [`half_mass`].
pub(crate) fn sample_square(nodes: &[QuadNode], root: u32, u: Vec2, half: Option<bool>) -> (Vec2, f32) {
    sample_square_by(nodes, nodes, root, u, half)
}

/// [`sample_square`] by the cell probabilities `probabilities` over `nodes`.
///
/// The levels take turns with the two numbers: each level picks one of four cells with
/// one of them ([`pick_cell`]) while the other's rescale from the level before is still
/// in flight. What is left of both places the point in the leaf cell reached.
#[inline]
pub(crate) fn sample_square_by<P: CellProbabilities + ?Sized>(
    nodes: &[QuadNode],
    probabilities: &P,
    root: u32,
    u: Vec2,
    half: Option<bool>,
) -> (Vec2, f32) {
    let mut walk = Walk { origin: Vec2::ZERO, size: 1.0, density: 1.0 };
    let (mut ux, mut uy) = (u.x, u.y);
    let mut node = root as usize;
    if let Some(high) = half {
        // The half's side is given: v picks between its two cells, and u takes the
        // next level.
        let p = probabilities.cells(node);
        let ix = high as usize;
        let cell = ix + 2 * choose(&mut uy, p[ix], p[ix + 2]) as usize;
        match step_into(nodes, node, cell, p[cell], &mut walk) {
            Some(child) => node = child,
            None => return walk.finish(Vec2::new(ux, uy)),
        }
    }
    // Two levels per turn, u's then v's: each number stays in its own register.
    loop {
        let p = probabilities.cells(node);
        let cell = pick_cell(&mut ux, p);
        match step_into(nodes, node, cell, p[cell], &mut walk) {
            Some(child) => node = child,
            None => return walk.finish(Vec2::new(ux, uy)),
        }
        let p = probabilities.cells(node);
        let cell = pick_cell(&mut uy, p);
        match step_into(nodes, node, cell, p[cell], &mut walk) {
            Some(child) => node = child,
            None => return walk.finish(Vec2::new(ux, uy)),
        }
    }
}

/// The share of the tree's mass in the half u ≥ 1/2 (`high`) or u < 1/2 of the square.
#[inline]
pub(crate) fn half_mass<P: CellProbabilities + ?Sized>(probabilities: &P, root: u32, high: bool) -> f32 {
    let [p0, p1, p2, p3] = *probabilities.cells(root as usize);
    if high {
        p1 + p3
    } else {
        p0 + p2
    }
}

/// The tree's density at square point `p` ∈ [0, 1)², relative to the uniform density
/// (so it integrates to one over the square).
#[inline]
pub(crate) fn square_density(nodes: &[QuadNode], root: u32, p: Vec2) -> f32 {
    square_density_by(nodes, nodes, root, p)
}

/// [`square_density`] by the cell probabilities `probabilities` over `nodes`.
#[inline]
pub(crate) fn square_density_by<P: CellProbabilities + ?Sized>(
    nodes: &[QuadNode],
    probabilities: &P,
    root: u32,
    mut p: Vec2,
) -> f32 {
    let (mut density, mut node) = (1.0f32, root as usize);
    loop {
        let (cell, q) = descend(p);
        density *= 4.0 * probabilities.cells(node)[cell];
        match nodes[node].child[cell] {
            0 => return density,
            child => (node, p) = (child as usize, q),
        }
    }
}

/// The index (node · 4 + cell) of the leaf cell holding square point `p`.
#[inline]
pub(crate) fn leaf_cell(nodes: &[QuadNode], root: u32, mut p: Vec2) -> usize {
    let mut node = root as usize;
    loop {
        let (cell, q) = descend(p);
        match nodes[node].child[cell] {
            0 => return node * 4 + cell,
            child => (node, p) = (child as usize, q),
        }
    }
}

/// Adds `weight` (a record's target / pdf) to the building sum of a leaf cell.
#[inline]
pub(crate) fn add_record(sums: &[AtomicU32], cell: usize, weight: f32) {
    atomic_f32::update(&sums[cell], |s| (s + weight).min(f32::MAX));
}

/// Appends a copy of the tree at `root` of `nodes` to `out`, whose first node will sit
/// at arena index `base`; returns the copy's root (an arena index).
pub(crate) fn copy_tree(nodes: &[QuadNode], root: u32, base: usize, out: &mut Vec<QuadNode>) -> u32 {
    let local = out.len();
    out.push(nodes[root as usize]);
    for cell in 0..4 {
        let child = nodes[root as usize].child[cell];
        if child != 0 {
            let copied = copy_tree(nodes, child, base, out);
            out[local].child[cell] = copied;
        }
    }
    (base + local) as u32
}

/// Appends a full quadtree over the `size`×`size` block of `cells` at (`x`, `y`) (a
/// `side`-wide grid); returns the node's index (or 0 and the block's sum for a single
/// cell) and the block's flux.
pub(crate) fn full_tree(
    cells: &[f64],
    side: usize,
    x: usize,
    y: usize,
    size: usize,
    out: &mut Vec<QuadNode>,
) -> (u32, f64) {
    if size == 1 {
        return (0, cells[y * side + x]);
    }
    let index = out.len();
    out.push(QuadNode::UNIFORM);
    let half = size / 2;
    let mut flux = [0.0f64; 4];
    for (cell, f) in flux.iter_mut().enumerate() {
        let (cx, cy) = (x + (cell & 1) * half, y + (cell >> 1) * half);
        let (child, total) = full_tree(cells, side, cx, cy, half, out);
        out[index].child[cell] = child;
        *f = total;
    }
    let sum: f64 = flux.iter().sum();
    if sum > 0.0 {
        out[index].probability = flux.map(|f| (f / sum) as f32);
    }
    (index as u32, sum)
}

/// Nodes in the tree at `root`.
pub(crate) fn node_count(nodes: &[QuadNode], root: u32) -> usize {
    1 + nodes[root as usize].child.iter().filter(|&&c| c != 0).map(|&c| node_count(nodes, c)).sum::<usize>()
}

/// How a refit splits and merges.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RefitRule {
    /// ρ: cells above this share of the leaf's flux split, inner cells below it merge.
    pub(crate) flux_fraction: f64,
    /// Deepest cell level.
    pub(crate) max_depth: u32,
    /// The arena may not grow past this many nodes (the byte budget).
    pub(crate) node_cap: usize,
}

/// What one leaf's tree learned in an epoch, and how much it counts.
#[derive(Clone, Copy, Debug)]
pub(crate) struct EpochBlend {
    /// The flux the tree stood for before the epoch (∫ L dω over the sphere).
    pub(crate) previous_flux: f64,
    /// Converts building sums (Σ target/pdf) into flux: one over the epoch's records.
    pub(crate) sum_scale: f64,
    /// The weight of the epoch's estimate against the previous one, in [0, 1].
    pub(crate) alpha: f64,
    /// The sums are of target²/pdf, estimating ∫ L² dω over each cell: a cell's flux is
    /// then its solid angle times the root mean square radiance there,
    /// √(Ω · ∫ L² dω) (the settings' `second_moment`).
    pub(crate) second_moment: bool,
}

/// Rebuilds one leaf's tree from its sampling probabilities and building sums, blended
/// by `blend`, into `out`; returns the new root and the new flux. `scratch` is reused
/// across leaves.
pub(crate) fn refit(
    nodes: &[QuadNode],
    sums: &[AtomicU32],
    root: u32,
    blend: EpochBlend,
    rule: RefitRule,
    scratch: &mut Vec<[f64; 4]>,
    out: &mut Vec<QuadNode>,
) -> (u32, f64) {
    scratch.resize(nodes.len(), [0.0; 4]);
    let total = blend_cells(nodes, sums, root, 1.0, 1.0, &blend, scratch);
    let mut builder = Builder { old: nodes, blended: scratch, out, total, rule };
    let new_root = builder.build(Some(root), scratch[root as usize], 0);
    (new_root, total)
}

/// Fills `blended[node]` with each cell's blended flux, below `node` first; `mass` is
/// the node's share of the previous distribution, `area` its share of the square.
/// Returns the node's total.
fn blend_cells(
    nodes: &[QuadNode],
    sums: &[AtomicU32],
    node: u32,
    mass: f64,
    area: f64,
    blend: &EpochBlend,
    blended: &mut [[f64; 4]],
) -> f64 {
    let mut cells = [0.0f64; 4];
    let cell_area = 0.25 * area;
    for (cell, value) in cells.iter_mut().enumerate() {
        let share = mass * nodes[node as usize].probability[cell] as f64;
        *value = match nodes[node as usize].child[cell] {
            0 => {
                let sum = atomic_f32::load(&sums[node as usize * 4 + cell]) as f64 * blend.sum_scale;
                let learned =
                    if blend.second_moment { libm::sqrt(SQUARE_TO_SOLID_ANGLE as f64 * cell_area * sum) } else { sum };
                let previous = blend.previous_flux * share;
                let mixed = (1.0 - blend.alpha) * previous + blend.alpha * learned;
                if mixed.is_finite() && mixed > 0.0 {
                    mixed
                } else {
                    0.0
                }
            }
            child => blend_cells(nodes, sums, child, share, cell_area, blend, blended),
        };
    }
    blended[node as usize] = cells;
    cells.iter().sum()
}

struct Builder<'a> {
    old: &'a [QuadNode],
    blended: &'a [[f64; 4]],
    out: &'a mut Vec<QuadNode>,
    total: f64,
    rule: RefitRule,
}

impl Builder<'_> {
    /// Appends the node for `flux` (the four cells' flux) at `depth`, built from `old`
    /// where the previous tree had a node there; returns its index.
    fn build(&mut self, old: Option<u32>, flux: [f64; 4], depth: u32) -> u32 {
        let index = self.out.len();
        let sum: f64 = flux.iter().sum();
        let probability = if sum > 0.0 { flux.map(|f| (f / sum) as f32) } else { [0.25; 4] };
        self.out.push(QuadNode { probability, child: [0; 4] });
        for (cell, &cell_flux) in flux.iter().enumerate() {
            let splits = self.total > 0.0
                && cell_flux > self.rule.flux_fraction * self.total
                && depth + 2 <= self.rule.max_depth
                && self.out.len() < self.rule.node_cap;
            if !splits {
                continue;
            }
            let previous = old.map_or(0, |node| self.old[node as usize].child[cell]);
            let (child_old, child_flux) = match previous {
                0 => (None, [cell_flux * 0.25; 4]),
                node => (Some(node), self.blended[node as usize]),
            };
            let child = self.build(child_old, child_flux, depth + 1);
            self.out[index].child[cell] = child;
        }
        index as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::low_discrepancy::Pcg32;

    fn sums(count: usize) -> Vec<AtomicU32> {
        (0..count * 4).map(|_| atomic_f32::new(0.0)).collect()
    }

    /// A tree learned from a point-like source at square point `light`.
    fn learned(light: Vec2) -> (Vec<QuadNode>, u32) {
        let mut nodes = alloc::vec![QuadNode::UNIFORM];
        let mut root = 0;
        let rule = RefitRule { flux_fraction: 0.01, max_depth: 20, node_cap: 100_000 };
        let mut rng = Pcg32::new(1, 2);
        for _ in 0..12 {
            let building = sums(nodes.len());
            for _ in 0..20_000 {
                // Drawn from the tree itself, half the time, as a guided renderer would.
                let (p, pdf) = if rng.next_f32() < 0.5 {
                    let p = sample_square(&nodes, root, rng.next_vec2(), None).0;
                    (p, 0.5 * square_density(&nodes, root, p) + 0.5)
                } else {
                    let p = rng.next_vec2();
                    (p, 0.5 * square_density(&nodes, root, p) + 0.5)
                };
                let target = if (p - light).abs().max_element() < 1e-3 { 1e4 } else { 0.01 };
                add_record(&building, leaf_cell(&nodes, root, p), target / pdf);
            }
            let blend = EpochBlend { previous_flux: 0.0, sum_scale: 1.0 / 20_000.0, alpha: 1.0, second_moment: false };
            let (mut out, mut scratch) = (Vec::new(), Vec::new());
            root = refit(&nodes, &building, root, blend, rule, &mut scratch, &mut out).0;
            nodes = out;
        }
        (nodes, root)
    }

    #[test]
    fn density_integrates_to_one_and_sampling_follows_it() {
        let light = Vec2::new(0.3217, 0.7431);
        let (nodes, root) = learned(light);
        assert!(nodes.len() > 20, "the tree refined: {} nodes", nodes.len());
        // Σ density × area over every leaf cell, the density read by descending to the
        // cell's midpoint: checks that the descent agrees with the structure.
        fn integrate(nodes: &[QuadNode], root: u32, node: u32, origin: Vec2, size: f32) -> f64 {
            (0..4)
                .map(|cell| {
                    let half = size * 0.5;
                    let corner = origin + Vec2::new((cell & 1) as f32, (cell >> 1) as f32) * half;
                    match nodes[node as usize].child[cell] {
                        0 => {
                            square_density(nodes, root, corner + Vec2::splat(half * 0.5)) as f64 * (half * half) as f64
                        }
                        child => integrate(nodes, root, child, corner, half),
                    }
                })
                .sum()
        }
        let total = integrate(&nodes, root, root, Vec2::ZERO, 1.0);
        assert!((total - 1.0).abs() < 1e-3, "∫ density = {total}");
        // Samples near the light: the share they take matches the density's mass there.
        let mut rng = Pcg32::new(7, 7);
        let near = (0..100_000)
            .filter(|_| (sample_square(&nodes, root, rng.next_vec2(), None).0 - light).abs().max_element() < 4e-3)
            .count();
        assert!(near > 30_000, "{near} of 100000 samples near the light");
    }

    #[test]
    fn sampled_points_fall_in_the_cell_whose_density_they_were_drawn_with() {
        let (nodes, root) = learned(Vec2::new(0.61, 0.12));
        let mut rng = Pcg32::new(9, 1);
        for _ in 0..100_000 {
            let (p, density) = sample_square(&nodes, root, rng.next_vec2(), None);
            assert!(p.x >= 0.0 && p.x < 1.0 && p.y >= 0.0 && p.y < 1.0);
            assert_eq!(square_density(&nodes, root, p), density);
            for high in [false, true] {
                let (q, density) = sample_square(&nodes, root, rng.next_vec2(), Some(high));
                assert_eq!(q.x >= 0.5, high, "{q} outside its half");
                assert_eq!(square_density(&nodes, root, q), density);
            }
        }
    }

    #[test]
    fn a_pick_never_lands_in_an_empty_cell_and_keeps_its_number_in_range() {
        let cases: [([f32; 4], f32, usize); 7] = [
            ([0.5, 0.5, 0.0, 0.0], ONE_BELOW, 1),
            ([0.0, 0.0, 0.0, 1.0], 0.0, 3),
            ([0.0, 1.0, 0.0, 0.0], 0.999, 1),
            ([0.25, 0.0, 0.75, 0.0], 0.25, 2),
            ([0.25, 0.0, 0.75, 0.0], 0.2499, 0),
            ([0.0; 4], 0.6, 2),
            ([f32::NAN, 0.5, 0.5, 0.0], 0.1, 0),
        ];
        for (p, u, expected) in cases {
            let mut rescaled = u;
            let cell = pick_cell(&mut rescaled, &p);
            assert_eq!(cell, expected, "{p:?} at {u}");
            assert!((0.0..1.0).contains(&rescaled), "{p:?} at {u} rescaled to {rescaled}");
        }
        // Across a node, the picks follow the probabilities and the rescaled numbers
        // stay uniform within each cell.
        let p = [0.1, 0.2, 0.3, 0.4];
        let (mut counts, mut means) = ([0u32; 4], [0.0f64; 4]);
        let n = 100_000;
        for i in 0..n {
            let mut u = (i as f32 + 0.5) / n as f32;
            let cell = pick_cell(&mut u, &p);
            counts[cell] += 1;
            means[cell] += u as f64;
        }
        for cell in 0..4 {
            assert!((counts[cell] as f32 / n as f32 - p[cell]).abs() < 1e-3, "{counts:?}");
            assert!((means[cell] / counts[cell] as f64 - 0.5).abs() < 1e-3, "{means:?}");
        }
    }

    #[test]
    fn an_empty_epoch_keeps_the_tree_and_nothing_learned_stays_uniform() {
        let nodes = alloc::vec![QuadNode::UNIFORM];
        let rule = RefitRule { flux_fraction: 0.01, max_depth: 20, node_cap: 1000 };
        let blend = EpochBlend { previous_flux: 0.0, sum_scale: 0.0, alpha: 1.0, second_moment: false };
        let (mut out, mut scratch) = (Vec::new(), Vec::new());
        let (root, flux) = refit(&nodes, &sums(1), 0, blend, rule, &mut scratch, &mut out);
        assert_eq!((out.len(), flux), (1, 0.0));
        assert_eq!(out[root as usize], QuadNode::UNIFORM);
    }

    #[test]
    fn the_node_cap_bounds_the_arena() {
        let nodes = alloc::vec![QuadNode::UNIFORM];
        let building = sums(1);
        add_record(&building, 0, 1.0);
        let rule = RefitRule { flux_fraction: 1e-6, max_depth: 20, node_cap: 7 };
        let blend = EpochBlend { previous_flux: 0.0, sum_scale: 1.0, alpha: 1.0, second_moment: false };
        let (mut out, mut scratch) = (Vec::new(), Vec::new());
        refit(&nodes, &building, 0, blend, rule, &mut scratch, &mut out);
        assert!(out.len() <= 7, "{} nodes", out.len());
    }
}
