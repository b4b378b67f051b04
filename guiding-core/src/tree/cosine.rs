//! The cosine product of a leaf's quadtree: for a surface whose normal lies along the
//! leaf's axis, the scattering integrand is Q·fs·cos θ, and cos θ to that axis is
//! |2u − 1| on the equal-area square (u = (z + 1)/2). Each node's four cells get a
//! second set of probabilities, of the tree's density times that cosine (piecewise
//! constant per leaf cell, as the tree is), which the normal's half of the square is
//! sampled by: the guide then sends no more samples near the horizon than cos θ lets
//! count. Computed once per refit from the tree; never stored in a tree's bytes.

use alloc::vec::Vec;

use super::quadtree::QuadNode;

/// Per node of `nodes` (indexed alike), its cells' probabilities under the tree's
/// density times |2u − 1|, for the trees at `roots`; nodes no root reaches get a
/// uniform node's.
pub(crate) fn cosine_probabilities(nodes: &[QuadNode], roots: impl Iterator<Item = u32>) -> Vec<[f32; 4]> {
    let mut out = alloc::vec![[0.25f32; 4]; nodes.len()];
    // Each node of a sound arena is visited once; a damaged one (a cycle, a shared
    // child) stops when the visits run out instead of recursing without end.
    let mut visits = nodes.len();
    for root in roots {
        if (root as usize) < nodes.len() && visits > 0 {
            visits -= 1;
            mean_cosine(nodes, root as usize, 0.0, 1.0, &mut out, &mut visits);
        }
    }
    out
}

/// The mean of |2u − 1| under the distribution of the node at `node`, whose cells span
/// u ∈ [`low`, `low + size`); fills `out` for it and every node below.
fn mean_cosine(nodes: &[QuadNode], node: usize, low: f32, size: f32, out: &mut [[f32; 4]], visits: &mut usize) -> f64 {
    let half = size * 0.5;
    let mut masses = [0.0f64; 4];
    for (cell, mass) in masses.iter_mut().enumerate() {
        let cell_low = low + (cell & 1) as f32 * half;
        let probability = nodes[node].probability[cell] as f64;
        let child = nodes[node].child[cell] as usize;
        let mean = if child == 0 || child >= nodes.len() || *visits == 0 {
            mean_over(cell_low as f64, (cell_low + half) as f64)
        } else {
            *visits -= 1;
            mean_cosine(nodes, child, cell_low, half, out, visits)
        };
        *mass = probability * mean;
    }
    let total: f64 = masses.iter().sum();
    if total > 0.0 && total.is_finite() {
        out[node] = masses.map(|m| (m / total) as f32);
    }
    if total.is_finite() {
        total
    } else {
        0.0
    }
}

/// The mean of |2u − 1| over u ∈ [a, b].
fn mean_over(a: f64, b: f64) -> f64 {
    // t|t|/4 with t = 2u − 1 is an antiderivative of |2u − 1|.
    let antiderivative = |u: f64| {
        let t = 2.0 * u - 1.0;
        t * t.abs() * 0.25
    };
    if b > a {
        (antiderivative(b) - antiderivative(a)) / (b - a)
    } else {
        (2.0 * a - 1.0).abs()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tree::quadtree::{half_mass, sample_square_by, square_density_by};
    use glam::Vec2;

    #[test]
    fn a_uniform_tree_samples_the_cosine_within_its_cells() {
        // A root split once more at each cell: 16 cells of u width 1/4.
        let mut nodes = alloc::vec![QuadNode { probability: [0.25; 4], child: [1, 2, 3, 4] }];
        nodes.extend([QuadNode::UNIFORM; 4]);
        let cosine = cosine_probabilities(&nodes, [0u32].into_iter());
        // Mean |2u − 1| over the u quarters: 3/4, 1/4, 1/4, 3/4.
        let density = |u: f32| square_density_by(&nodes, cosine.as_slice(), 0, Vec2::new(u, 0.3));
        // The density relative to uniform is the cell's mean cosine over the square's (1/2).
        for (u, mean) in [(0.1, 0.75), (0.3, 0.25), (0.6, 0.25), (0.9, 0.75)] {
            assert!((density(u) - mean / 0.5).abs() < 1e-5, "at u {u}: {}", density(u));
        }
        assert!((half_mass(cosine.as_slice(), 0, true) - 0.5).abs() < 1e-6);
        // Sampling reads the same probabilities: each draw's density is the pdf there.
        let mut rng = crate::low_discrepancy::Pcg32::new(2, 3);
        for _ in 0..1000 {
            let (p, d) = sample_square_by(&nodes, cosine.as_slice(), 0, rng.next_vec2(), Some(true));
            assert!(p.x >= 0.5);
            assert_eq!(square_density_by(&nodes, cosine.as_slice(), 0, p), d);
        }
    }

    #[test]
    fn means_of_the_cosine_over_intervals() {
        assert!((mean_over(0.0, 1.0) - 0.5).abs() < 1e-12);
        assert!((mean_over(0.5, 1.0) - 0.5).abs() < 1e-12);
        assert!((mean_over(0.75, 1.0) - 0.75).abs() < 1e-12);
        assert!((mean_over(0.25, 0.75) - 0.25).abs() < 1e-12);
    }
}
