//! [`CandidateTable`]: per small cell of space, the probes that can be nearest to a
//! point in it, so that most nearest-probe queries test a handful of probes and no ring
//! of hash buckets.
//!
//! A cell's list holds every probe within `reach` of the cell's box. For a query in the
//! cell, every probe within `reach` of the query is then in the list: if the nearest
//! admitted probe of the list lies within `reach`, it is the nearest admitted probe of
//! all, exactly. Otherwise (and in cells the table does not hold) the caller searches as
//! before. Keys are the cells' integer coordinates in an open-addressed table whose size
//! follows from the probe count alone, so the bytes are known before the probes are:
//! cells that do not fit are left to the search.

use alloc::vec;
use alloc::vec::Vec;
use glam::{IVec3, Vec3};

/// Slots of the key table per probe (rounded up to a power of two): a surface puts
/// about 2.5 cells of one spacing within a reach of 0.75 spacings of each probe.
const SLOTS_PER_PROBE: usize = 4;

/// Candidate entries per probe: each probe lies in the lists of about sixteen cells.
const CANDIDATES_PER_PROBE: usize = 20;

/// Coordinates take 21 bits each in a key.
const COORDINATE_LIMIT: i32 = 1 << 21;

/// A slot's list is `start | count << COUNT_SHIFT`: lists of up to 63 probes starting
/// below 2²⁶ (larger ones are left to the search).
const COUNT_SHIFT: u32 = 26;

/// An empty slot's key (no cell packs to it: the top bit stays clear).
const EMPTY: u64 = u64::MAX;

/// See the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct CandidateTable {
    origin: Vec3,
    inverse_cell_size: f32,
    reach_squared: f32,
    keys: Vec<u64>,
    /// Per slot, its list packed as `start | count << COUNT_SHIFT`.
    ranges: Vec<u32>,
    candidates: Vec<u32>,
}

impl CandidateTable {
    /// Slots of the key table for `probes` probes.
    fn slot_count(probes: usize) -> usize {
        (probes.max(1) * SLOTS_PER_PROBE).next_power_of_two()
    }

    /// Bytes the table holds for `probes` probes, wherever they are.
    pub(crate) fn bytes_for(probes: usize) -> usize {
        let slots = Self::slot_count(probes);
        slots * (8 + 4) + probes.saturating_mul(CANDIDATES_PER_PROBE) * 4
    }

    /// Bytes held.
    pub(crate) fn memory_bytes(&self) -> usize {
        self.keys.capacity() * 8 + self.ranges.capacity() * 4 + self.candidates.capacity() * 4
    }

    /// The table over `positions` (in the order the caller indexes them) with cells of
    /// `cell_size` from `origin` and lists of every probe within `reach` of a cell.
    pub(crate) fn build(positions: &[Vec3], origin: Vec3, cell_size: f32, reach: f32) -> Self {
        let slots = Self::slot_count(positions.len());
        let mut table = Self {
            origin,
            inverse_cell_size: 1.0 / cell_size,
            reach_squared: reach * reach,
            keys: vec![EMPTY; slots],
            ranges: vec![0; slots],
            candidates: Vec::with_capacity(positions.len() * CANDIDATES_PER_PROBE),
        };
        // A reach of many cells would make every probe's neighbourhood a large block.
        let cells_per_reach = reach * table.inverse_cell_size;
        if !(table.inverse_cell_size.is_finite() && cells_per_reach > 0.0 && cells_per_reach <= 8.0) {
            return table;
        }
        // Every (cell, probe) pair with the probe within reach of the cell's box.
        let mut pairs: Vec<(u64, u32)> = Vec::new();
        for (probe, &p) in positions.iter().enumerate() {
            let (low, high) = (table.coordinates(p - Vec3::splat(reach)), table.coordinates(p + Vec3::splat(reach)));
            let (low, high) = (low.max(Vec3::ZERO), high.min(Vec3::splat((COORDINATE_LIMIT - 1) as f32)));
            if !(low.cmple(high).all()) {
                continue;
            }
            let (low, high) = (low.as_ivec3(), high.as_ivec3());
            for z in low.z..=high.z {
                for y in low.y..=high.y {
                    for x in low.x..=high.x {
                        let cell = IVec3::new(x, y, z);
                        let box_low = origin + cell.as_vec3() * cell_size;
                        let nearest = p.clamp(box_low, box_low + Vec3::splat(cell_size));
                        if nearest.distance_squared(p) <= table.reach_squared {
                            pairs.push((pack(cell), probe as u32));
                        }
                    }
                }
            }
        }
        pairs.sort_unstable();
        // Cells in key order while the table stays at most three quarters full and the
        // entries last; the rest are left to the search.
        let mut filled = 0;
        let mut start = 0;
        while start < pairs.len() && 4 * (filled + 1) <= 3 * slots {
            let key = pairs[start].0;
            let end = start + pairs[start..].iter().take_while(|pair| pair.0 == key).count();
            let (first, count) = (table.candidates.len(), end - start);
            if first + count <= table.candidates.capacity() && first < 1 << COUNT_SHIFT && count < 64 {
                let slot = table.free_slot(key);
                table.candidates.extend(pairs[start..end].iter().map(|pair| pair.1));
                table.keys[slot] = key;
                table.ranges[slot] = first as u32 | (count as u32) << COUNT_SHIFT;
                filled += 1;
            }
            start = end;
        }
        table
    }

    /// Squared reach: a list holds every probe this close to its cell.
    pub(crate) fn reach_squared(&self) -> f32 {
        self.reach_squared
    }

    /// The probes that can be nearest to `query` (sorted by index), if the table holds
    /// its cell.
    #[inline]
    pub(crate) fn candidates(&self, query: Vec3) -> Option<&[u32]> {
        let key = pack(self.cell_of(query)?);
        let mask = self.keys.len() - 1;
        let mut slot = slot_of(key, mask);
        loop {
            let stored = self.keys[slot];
            if stored == key {
                let range = self.ranges[slot];
                let start = (range & ((1 << COUNT_SHIFT) - 1)) as usize;
                return Some(&self.candidates[start..start + (range >> COUNT_SHIFT) as usize]);
            }
            if stored == EMPTY {
                return None;
            }
            slot = (slot + 1) & mask;
        }
    }

    /// The slot a new `key` goes to (linear probing; the table is never full).
    fn free_slot(&self, key: u64) -> usize {
        let mask = self.keys.len() - 1;
        let mut slot = slot_of(key, mask);
        while self.keys[slot] != EMPTY {
            slot = (slot + 1) & mask;
        }
        slot
    }

    /// A point in cell units from the origin.
    #[inline]
    fn coordinates(&self, p: Vec3) -> Vec3 {
        (p - self.origin) * self.inverse_cell_size
    }

    /// A point's cell, `None` outside the coordinates a key holds (or for NaN).
    #[inline]
    fn cell_of(&self, p: Vec3) -> Option<IVec3> {
        let c = self.coordinates(p);
        // Compared as floats first: NaN and far points fail here, before any cast.
        let inside = c.cmpge(Vec3::ZERO).all() && c.cmplt(Vec3::splat(COORDINATE_LIMIT as f32)).all();
        inside.then(|| c.as_ivec3())
    }
}

fn pack(cell: IVec3) -> u64 {
    cell.x as u64 | (cell.y as u64) << 21 | (cell.z as u64) << 42
}

/// Fibonacci hashing onto the table's power-of-two size.
#[inline]
fn slot_of(key: u64, mask: usize) -> usize {
    let hashed = key.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    (hashed >> 32) as usize & mask
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::low_discrepancy::Pcg32;

    #[test]
    fn every_probe_within_reach_of_a_query_is_a_candidate() {
        let mut rng = Pcg32::new(5, 0);
        let positions: Vec<Vec3> =
            (0..500).map(|_| Vec3::new(rng.next_f32(), rng.next_f32(), 0.05 * rng.next_f32()) * 4.0).collect();
        let spacing = 4.0 / libm::sqrtf(500.0);
        let table = CandidateTable::build(&positions, Vec3::splat(-0.1), spacing, 0.75 * spacing);
        assert!(table.memory_bytes() <= CandidateTable::bytes_for(positions.len()));
        let mut held = 0;
        for _ in 0..2000 {
            let query = Vec3::new(rng.next_f32(), rng.next_f32(), 0.05 * rng.next_f32()) * 4.0;
            let Some(list) = table.candidates(query) else { continue };
            held += 1;
            assert!(list.windows(2).all(|w| w[0] < w[1]));
            for (probe, p) in positions.iter().enumerate() {
                if p.distance_squared(query) <= table.reach_squared() {
                    assert!(list.contains(&(probe as u32)), "probe {probe} within reach of {query} is missing");
                }
            }
        }
        // On a surface nearly every query finds its cell in the table.
        assert!(held > 1900, "{held} of 2000 queries had a list");
    }

    #[test]
    fn far_or_nan_queries_have_no_list() {
        let table = CandidateTable::build(&[Vec3::ZERO, Vec3::ONE], Vec3::splat(-0.25), 0.5, 0.1);
        assert!(table.candidates(Vec3::splat(0.05)).is_some());
        for query in [Vec3::NAN, Vec3::splat(-1e30), Vec3::splat(1e30), Vec3::splat(100.0)] {
            assert_eq!(table.candidates(query), None);
        }
    }

    #[test]
    fn a_full_table_leaves_cells_to_the_search_and_keeps_its_bytes() {
        // Coincident probes: one cell's list would need every probe; lists that do not
        // fit are dropped, never truncated.
        let positions = vec![Vec3::splat(0.2); 64];
        let table = CandidateTable::build(&positions, Vec3::ZERO, 0.5, 2.0);
        assert!(table.memory_bytes() <= CandidateTable::bytes_for(64));
        if let Some(list) = table.candidates(Vec3::splat(0.2)) {
            assert_eq!(list.len(), 64);
        }
    }
}
