//! A thread's records of one pass for the [`SpatialDirectionalTree`]: appended during the
//! pass with no write another thread reads, learned between passes by
//! [`splat`](crate::Guide::splat) with plain adds (Müller et al. 2017 splat their records
//! the same way; learning in place costs a compare-exchange on a line both threads write).

use alloc::vec::Vec;

use glam::Vec3;

use super::axis::LeafCounts;
use super::guide::{SpatialDirectionalTree, TreeRegion};
use super::quadtree;
use super::square::{axis_square, axis_squares};

/// Bits of a record's word that name its leaf; the three above hold its count slot.
const LEAF_BITS: u32 = 29;

/// One record: 20 bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
struct TreeRecord {
    /// The direction (unit, world space) as pushed; once mapped
    /// ([`TreeRecords::mapped`]), the point it falls at in its leaf's square, in x and y.
    /// One field for both keeps a record at 20 bytes: a pass holds millions.
    point: Vec3,
    /// What it adds to its cell: target/pdf (target²/pdf under the second moment).
    weight: f32,
    /// The leaf (low [`LEAF_BITS`] bits) and the slot its leaf counts it in (above).
    leaf_and_slot: u32,
}

impl TreeRecord {
    fn leaf(&self) -> usize {
        (self.leaf_and_slot & ((1 << LEAF_BITS) - 1)) as usize
    }
}

/// A thread's records of one pass for a [`SpatialDirectionalTree`]
/// ([`Guide::record`](crate::Guide::record) appends, [`Guide::splat`](crate::Guide::splat)
/// learns and empties them). Kept from pass to pass, its room stops growing after the
/// first.
///
/// A push only checks and appends. The map from direction to square, two thirds of a
/// record's cost when done at the push, waits for
/// [`Guide::prepare_splat`](crate::Guide::prepare_splat), which maps four at a time on
/// the thread that made the records, or for the splat.
///
/// ```
/// use guiding_core::{glam::Vec3, Guide, SpatialDirectionalTree, SpatialDirectionalTreeSettings, TreeRecords};
/// let settings = SpatialDirectionalTreeSettings::default();
/// let mut tree = SpatialDirectionalTree::new(Vec3::splat(-1.0), Vec3::ONE, settings).unwrap();
/// let region = tree.locate(Vec3::ZERO, Vec3::Y).unwrap();
/// let mut records = TreeRecords::default();
/// tree.record(&mut records, region, Vec3::Y, 2.0, 0.5);
/// assert_eq!(records.len(), 1);
/// assert_eq!(tree.stats().accepted_updates, 0, "nothing learned before the splat");
/// tree.prepare_splat(&mut records); // on the thread that made them: optional, parallel
/// assert_eq!(tree.splat(&mut records), 0);
/// assert!(records.is_empty());
/// assert_eq!(tree.stats().accepted_updates, 1);
/// ```
#[derive(Clone, Debug, Default)]
pub struct TreeRecords {
    records: Vec<TreeRecord>,
    /// How many records, from the first, hold their square point rather than their
    /// direction.
    mapped: usize,
    /// The tree's epoch when the first of them was made: a tree refitted since has
    /// another shape.
    epoch: u32,
}

impl TreeRecords {
    /// Records held.
    pub fn len(&self) -> usize {
        self.records.len()
    }

    /// Whether none is held.
    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// Whether a record can name `leaf`.
    pub(super) fn can_name(leaf: u32) -> bool {
        leaf < 1 << LEAF_BITS
    }

    /// Appends the record of `weight` for unit `direction` in `region`'s leaf (which
    /// [`can_name`](Self::can_name)), made by a tree at `epoch`.
    #[inline]
    pub(super) fn push(&mut self, epoch: u32, region: TreeRegion, direction: Vec3, weight: f32) {
        if self.records.is_empty() {
            self.epoch = epoch;
        }
        let slot = LeafCounts::slot(region.upper_half as usize, region.normal) as u32;
        self.records.push(TreeRecord { point: direction, weight, leaf_and_slot: region.leaf | slot << LEAF_BITS });
    }
}

impl SpatialDirectionalTree {
    /// [`Guide::prepare_splat`](crate::Guide::prepare_splat): maps the directions of the
    /// records not yet mapped to their leaves' squares, four at a time. Records of
    /// another epoch are left as they are (the splat leaves them out).
    pub(super) fn map_records(&self, records: &mut TreeRecords) {
        if records.epoch != self.epoch {
            return;
        }
        // A leaf the tree lacks (never pushed: the push checks) maps as axis z; the splat
        // leaves its record out.
        let axis = |record: &TreeRecord| self.leaves.get(record.leaf()).map_or(2, |leaf| leaf.axis);
        let pending = &mut records.records[records.mapped..];
        let mut fours = pending.chunks_exact_mut(4);
        for four in &mut fours {
            let squares = axis_squares(
                [four[0].point, four[1].point, four[2].point, four[3].point],
                [axis(&four[0]), axis(&four[1]), axis(&four[2]), axis(&four[3])],
            );
            for (record, square) in four.iter_mut().zip(squares) {
                record.point = square.extend(0.0);
            }
        }
        for record in fours.into_remainder() {
            record.point = axis_square(record.point, axis(record)).extend(0.0);
        }
        records.mapped = records.records.len();
    }

    /// [`Guide::splat`](crate::Guide::splat): adds every record to its cell's building sum
    /// and its leaf's counts, then empties `records`; returns how many were left out
    /// (made before the last refit, or naming a leaf this tree lacks).
    pub(super) fn splat_records(&mut self, records: &mut TreeRecords) -> usize {
        let mut left_out = 0;
        if records.epoch != self.epoch {
            left_out = records.records.len();
        } else {
            self.map_records(records);
            for record in &records.records {
                let leaf = record.leaf();
                let Some(root) = self.leaves.get(leaf).map(|l| l.root) else {
                    left_out += 1;
                    continue;
                };
                let cell = quadtree::leaf_cell(&self.quad, root, record.point.truncate());
                let sum = self.sums[cell].get_mut();
                *sum = (f32::from_bits(*sum) + record.weight).min(f32::MAX).to_bits();
                self.leaf_counts[leaf].add_to_slot((record.leaf_and_slot >> LEAF_BITS) as usize);
            }
        }
        records.records.clear();
        records.mapped = 0;
        left_out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::update_rule::UpdateOutcome;
    use crate::{Guide, Pcg32, SpatialDirectionalTreeSettings};
    use glam::Vec3;

    fn tree() -> SpatialDirectionalTree {
        let settings = SpatialDirectionalTreeSettings { min_split_records: 1, ..Default::default() };
        SpatialDirectionalTree::new(Vec3::splat(-1.0), Vec3::ONE, settings).unwrap()
    }

    /// Records of a light in one corner, seen from points all over the box.
    fn teach(
        tree: &SpatialDirectionalTree,
        mut learn: impl FnMut(&SpatialDirectionalTree, TreeRegion, Vec3, f32, f32),
    ) {
        let mut rng = Pcg32::new(7, 3);
        let light = Vec3::new(0.6, 0.8, 0.0);
        for _ in 0..3000 {
            let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
            let normal = if rng.next_f32() < 0.5 { Vec3::Y } else { Vec3::new(0.0, 0.6, 0.8) };
            let region = tree.locate(p, normal).unwrap();
            let s = tree.sample(region, rng.next_vec2());
            let target = if s.direction.dot(light) > 0.9 { 20.0 } else { 0.2 };
            learn(tree, region, s.direction, target, s.pdf);
        }
    }

    #[test]
    fn splatted_records_teach_exactly_what_updates_in_place_teach() {
        let (mut in_place, mut splatted) = (tree(), tree());
        let mut records = TreeRecords::default();
        for epoch in 0..6 {
            // Twice per epoch, the records mapped before the splat in some epochs, in
            // part (the first half) in others, and by the splat alone in the rest.
            for half in 0..2 {
                teach(&in_place, |tree, region, direction, target, pdf| {
                    tree.update_sampled(region, direction, target, pdf);
                });
                teach(&splatted, |tree, region, direction, target, pdf| {
                    tree.record(&mut records, region, direction, target, pdf);
                });
                if (epoch + half) % 3 == 0 {
                    splatted.prepare_splat(&mut records);
                }
            }
            assert_eq!(records.len(), 6000);
            assert_eq!(splatted.splat(&mut records), 0);
            assert!(records.is_empty());
            assert_eq!(in_place.stats(), splatted.stats());
            in_place.rebuild_sampling();
            splatted.rebuild_sampling();
        }
        assert!(splatted.leaf_count() > 1, "the records split space");
        assert_eq!(in_place.to_bytes(), splatted.to_bytes(), "same records in the same order: the same tree");
    }

    #[test]
    fn bad_records_are_counted_and_stale_ones_left_out() {
        let mut tree = tree();
        let region = tree.locate(Vec3::ZERO, Vec3::Y).unwrap();
        let mut records = TreeRecords::default();
        assert_eq!(tree.record(&mut records, region, Vec3::Y, f32::NAN, 1.0), UpdateOutcome::RejectedNonFinite);
        assert_eq!(tree.record(&mut records, region, Vec3::Y, -1.0, 1.0), UpdateOutcome::RejectedNegative);
        assert_eq!(tree.record(&mut records, region, Vec3::Y, 1.0, 0.0), UpdateOutcome::OutsideDomain);
        for direction in [Vec3::new(f32::NAN, 0.0, 1.0), Vec3::new(0.0, f32::INFINITY, 0.0), Vec3::new(0.6, 0.0, 0.6)] {
            assert_eq!(tree.record(&mut records, region, direction, 1.0, 1.0), UpdateOutcome::OutsideDomain);
        }
        let elsewhere = TreeRegion { leaf: 5, ..region };
        assert_eq!(tree.record(&mut records, elsewhere, Vec3::Y, 1.0, 1.0), UpdateOutcome::OutsideDomain);
        assert!(records.is_empty());
        let stats = tree.stats();
        assert_eq!((stats.rejected_non_finite, stats.rejected_negative), (1, 1));
        // Records made before a refit point into the old shape: left out, and said so.
        assert_eq!(tree.record(&mut records, region, Vec3::Y, 1.0, 1.0), UpdateOutcome::Accepted);
        tree.rebuild_sampling();
        assert_eq!(tree.splat(&mut records), 1);
        assert!(records.is_empty());
        assert_eq!(tree.stats().accepted_updates, 0);
    }
}
