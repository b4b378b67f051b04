//! Each spatial leaf builds its directional square around one world axis: the one most of
//! its records' normals lie along, so that such a normal's hemisphere is exactly half of
//! the square. Here: the epoch's counts that choose it, and turning a leaf's quadtree
//! to a new axis.

use alloc::vec::Vec;
use core::sync::atomic::{AtomicU32, Ordering};

use glam::{Vec2, Vec3};

use super::distribution::ALIGNED_COS;
use super::quadtree::{self, QuadNode};
use super::square::{axis_square, from_axis_frame, square_to_direction};

/// Cells per side of the quadtree a leaf gets when its axis changes (depth 4: 85 nodes),
/// read from its old tree; the next refit splits and merges it as usual.
pub(crate) const ROTATED_SIDE: usize = 16;
/// Nodes of that tree.
pub(crate) const ROTATED_NODES: usize = 85;

/// A leaf's records of the current epoch, per half of the leaf along the axis it would
/// split next: how many had a normal along world x, y and z (either sign, within
/// [`ALIGNED_COS`]) and how many along none, so that a record is one increment. The
/// halves let a split's two new leaves each pick their axis.
#[derive(Debug, Default)]
pub(crate) struct LeafCounts([AtomicU32; 8]);

/// Counts stop this far below `u32::MAX`: an increment is a load and an add, not a
/// compare-exchange loop, and concurrent adders cannot wrap a count past the gap.
const COUNT_CEILING: u32 = u32::MAX - (1 << 20);

impl LeafCounts {
    /// Counts from their stored values (per half: the records, then the x, y and z votes);
    /// `None` where a half's votes add up to more than its records.
    pub(crate) fn from_values(values: [u32; 8]) -> Option<Self> {
        let mut counts = [0u32; 8];
        for half in 0..2 {
            let [records, x, y, z] = [0, 1, 2, 3].map(|i| values[4 * half + i]);
            let none = (records as u64).checked_sub(x as u64 + y as u64 + z as u64)?;
            counts[4 * half..4 * half + 4].copy_from_slice(&[x, y, z, none as u32]);
        }
        Some(Self(counts.map(AtomicU32::new)))
    }

    /// The counts as stored (per half: the records, then the x, y and z votes).
    pub(crate) fn values(&self) -> [u32; 8] {
        let c = self.0.each_ref().map(|c| c.load(Ordering::Relaxed));
        let mut values = [0u32; 8];
        for half in 0..2 {
            let counts = &c[4 * half..4 * half + 4];
            let records = counts.iter().map(|&n| n as u64).sum::<u64>().min(u32::MAX as u64) as u32;
            values[4 * half..4 * half + 4].copy_from_slice(&[records, counts[0], counts[1], counts[2]]);
        }
        values
    }

    /// Records in both halves.
    pub(crate) fn records(&self) -> u32 {
        let v = self.values();
        v[0].saturating_add(v[4])
    }

    /// Counts one record in `half` (0 or 1) whose surface had `normal`.
    #[inline]
    pub(crate) fn add(&self, half: usize, normal: Vec3) {
        let count = &self.0[Self::slot(half, normal)];
        if count.load(Ordering::Relaxed) < COUNT_CEILING {
            count.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Where [`add`](Self::add) counts a record in `half` whose surface had `normal`: 0..8.
    #[inline]
    pub(crate) fn slot(half: usize, normal: Vec3) -> usize {
        4 * (half & 1) + aligned_axis(normal).unwrap_or(3) as usize
    }

    /// [`add`](Self::add) by its [`slot`](Self::slot), with the counts held alone.
    #[inline]
    pub(crate) fn add_to_slot(&mut self, slot: usize) {
        let count = self.0[slot & 7].get_mut();
        if *count < COUNT_CEILING {
            *count += 1;
        }
    }

    /// Whether the leaf holds at least `least` records and neither one world axis nor
    /// the off-axis normals together have `share` of them.
    pub(crate) fn mixed(&self, share: f64, least: u32) -> bool {
        let v = self.values();
        let records = v[0] as u64 + v[4] as u64;
        if records < least as u64 {
            return false;
        }
        let along: [u64; 3] = core::array::from_fn(|a| v[1 + a] as u64 + v[5 + a] as u64);
        // Normals along no axis (a slope, a curve) are a class of their own: splitting
        // cannot align them, only part them from the aligned ones.
        let along_none = records.saturating_sub(along.iter().sum::<u64>());
        let best = along.into_iter().max().unwrap_or(0).max(along_none);
        (best as f64) < share * records as f64
    }

    /// The axis that more than half of the records in `halves` lie along, if any.
    pub(crate) fn majority_axis(&self, halves: &[usize]) -> Option<u32> {
        let v = self.values();
        let (mut records, mut votes) = (0u64, [0u64; 3]);
        for &h in halves {
            records += v[4 * h] as u64;
            for (axis, vote) in votes.iter_mut().enumerate() {
                *vote += v[4 * h + 1 + axis] as u64;
            }
        }
        let best = (0..3).max_by_key(|&a| votes[a])?;
        (votes[best] * 2 > records).then_some(best as u32)
    }
}

impl Clone for LeafCounts {
    fn clone(&self) -> Self {
        Self(self.0.each_ref().map(|c| AtomicU32::new(c.load(Ordering::Relaxed))))
    }
}

/// The world axis `normal` lies along (within [`ALIGNED_COS`], either sign), if any.
#[inline]
fn aligned_axis(normal: Vec3) -> Option<u32> {
    let a = normal.abs();
    let axis = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    (a[axis] >= ALIGNED_COS).then_some(axis as u32)
}

/// The cells (row-major, u fastest) of a [`ROTATED_SIDE`]-wide quadtree over the square
/// of polar axis `axis`, each holding the density of the tree at `root` of `nodes` (polar
/// axis `old_axis`) averaged over 4×4 points: the same distribution, turned to `axis`
/// (for [`quadtree::full_tree`]).
pub(crate) fn rotated_cells(nodes: &[QuadNode], root: u32, old_axis: u32, axis: u32) -> Vec<f64> {
    const POINTS: usize = 4;
    let side = ROTATED_SIDE;
    (0..side * side)
        .map(|i| {
            let (x, y) = (i % side, i / side);
            let mut sum = 0.0f64;
            for j in 0..POINTS * POINTS {
                let offset = Vec2::new((j % POINTS) as f32 + 0.5, (j / POINTS) as f32 + 0.5) / POINTS as f32;
                let p = (Vec2::new(x as f32, y as f32) + offset) / side as f32;
                let world = from_axis_frame(square_to_direction(p), axis);
                let old = axis_square(world, old_axis);
                sum += quadtree::square_density(nodes, root, old) as f64;
            }
            sum
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn leaf_counts_count_one_slot_per_record_and_keep_their_stored_form() {
        let counts = LeafCounts::default();
        counts.add(0, Vec3::Y);
        counts.add(0, Vec3::new(0.6, 0.8, 0.0));
        counts.add(1, -Vec3::Z);
        assert_eq!(counts.values(), [2, 0, 1, 0, 1, 0, 0, 1]);
        assert_eq!(counts.records(), 3);
        let stored = [10, 3, 4, 2, 5, 0, 0, 5];
        assert_eq!(LeafCounts::from_values(stored).map(|c| c.values()), Some(stored));
        assert!(LeafCounts::from_values([2, 3, 0, 0, 0, 0, 0, 0]).is_none(), "more votes than records");
    }
}
