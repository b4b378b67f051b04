//! A spatial hash grid over probe positions: nearest probe with a similar normal.
//!
//! Layout (flat, GPU-readable): probes are stored sorted by hash bucket, and
//! `bucket_starts[b]..bucket_starts[b+1]` is the range of probes in bucket `b`. A cell
//! (integer coordinates of `floor((p - origin) / cell_size)`) hashes to one of
//! `bucket_starts.len() - 1` buckets, a power of two between 2 and 4 times the probe count.

use alloc::vec;
use alloc::vec::Vec;
use glam::{IVec3, Vec3};

use super::candidate_table::CandidateTable;

/// Coordinates are clamped to ±2²⁰ cells so neighbour offsets never overflow.
const MAX_CELL_COORDINATE: i32 = 1 << 20;

/// Cell edge in probe spacings. A query first searches the 2×2×2 block of cells around
/// it, which holds every probe within half a cell: 0.75 spacings covers the nearest
/// probe of most queries on a surface, so the shell search is rarely needed.
const CELL_SIZE_IN_SPACINGS: f32 = 1.5;

/// ⌊x⌋ as an integer without a software `floor` (this crate has no std): `as` truncates
/// towards zero and saturates, maps NaN to 0; one step down fixes negative non-integers
/// (saturating, for values below i32::MIN; found by the capi_calls fuzz target).
fn floor_to_i32(x: f32) -> i32 {
    let truncated = x as i32;
    if (truncated as f32) > x {
        truncated.saturating_sub(1)
    } else {
        truncated
    }
}

/// The hash grid. See the module documentation for its layout.
#[derive(Clone, Debug, PartialEq)]
pub struct ProbeLookup {
    origin: Vec3,
    cell_size: f32,
    inverse_cell_size: f32,
    max_rings: u32,
    bucket_starts: Vec<u32>,
    /// Cells of one probe spacing, each listing the probes within 0.75 spacings of it:
    /// most queries end there.
    candidates: CandidateTable,
}

impl ProbeLookup {
    /// Number of buckets for `probe_count` probes.
    pub fn bucket_count(probe_count: usize) -> usize {
        (probe_count.max(1) * 2).next_power_of_two()
    }

    /// Builds the grid over `positions` with cells of 1.5 `spacing` (clamped to a usable size)
    /// and returns it with the order to store the probes in: `order[i]` is the index in
    /// `positions` of the probe that goes to slot `i`. The sort is stable, so building
    /// again over already sorted positions returns the identity.
    pub fn build(positions: &[Vec3], spacing: f32, max_rings: u32) -> (Self, Vec<u32>) {
        let origin = positions.iter().fold(Vec3::splat(f32::INFINITY), |lo, &p| lo.min(p));
        let origin = if origin.is_finite() { origin } else { Vec3::ZERO };
        let extent = positions.iter().fold(0.0f32, |e, &p| e.max((p - origin).max_element()));
        // Cells no smaller than 2⁻²⁰ of the extent (coordinates stay in range) and never
        // zero or non-finite.
        let mut cell_size = (spacing * CELL_SIZE_IN_SPACINGS).max(extent / MAX_CELL_COORDINATE as f32);
        if !(cell_size.is_finite() && cell_size > 0.0) {
            cell_size = if extent > 0.0 && extent.is_finite() { extent } else { 1.0 };
        }
        // Shift the grid by half a cell: scenes put walls on their bounding box, and a wall
        // on a cell face would make every query start next to a face, defeating the
        // own-cell fast path of `nearest`.
        let origin = origin - Vec3::splat(0.5 * cell_size);
        let mut lookup = Self {
            origin,
            cell_size,
            inverse_cell_size: 1.0 / cell_size,
            max_rings,
            bucket_starts: vec![0; Self::bucket_count(positions.len()) + 1],
            candidates: CandidateTable::build(&[], origin, 1.0, 0.0),
        };
        let buckets: Vec<u32> = positions.iter().map(|&p| lookup.bucket(lookup.cell_of(p))).collect();
        for &b in &buckets {
            lookup.bucket_starts[b as usize + 1] += 1;
        }
        for b in 1..lookup.bucket_starts.len() {
            lookup.bucket_starts[b] += lookup.bucket_starts[b - 1];
        }
        let mut next = lookup.bucket_starts.clone();
        let mut order = vec![0u32; positions.len()];
        for (probe, &b) in buckets.iter().enumerate() {
            order[next[b as usize] as usize] = probe as u32;
            next[b as usize] += 1;
        }
        let sorted: Vec<Vec3> = order.iter().map(|&i| positions[i as usize]).collect();
        let spacing = cell_size / CELL_SIZE_IN_SPACINGS;
        lookup.candidates = CandidateTable::build(&sorted, origin, spacing, 0.75 * spacing);
        (lookup, order)
    }

    /// Edge length of a grid cell, scene units.
    pub fn cell_size(&self) -> f32 {
        self.cell_size
    }

    /// The corner of cell (0, 0, 0): a position's cell is ⌊(p − origin) / cell_size⌋.
    pub fn origin(&self) -> Vec3 {
        self.origin
    }

    /// How many shells of cells around a query's cell `nearest` searches.
    pub fn max_rings(&self) -> u32 {
        self.max_rings
    }

    /// The bucket table: probes of bucket `b` are `bucket_starts[b]..bucket_starts[b+1]`.
    pub fn bucket_starts(&self) -> &[u32] {
        &self.bucket_starts
    }

    /// Bytes held by the table.
    pub fn memory_bytes(&self) -> usize {
        self.bucket_starts.capacity() * core::mem::size_of::<u32>() + self.candidates.memory_bytes()
    }

    /// Bytes a lookup over `probe_count` probes holds, wherever they are.
    pub fn bytes_for(probe_count: usize) -> usize {
        (Self::bucket_count(probe_count) + 1) * core::mem::size_of::<u32>() + CandidateTable::bytes_for(probe_count)
    }

    fn cell_of(&self, p: Vec3) -> IVec3 {
        let c = (p - self.origin) * self.inverse_cell_size;
        IVec3::new(floor_to_i32(c.x), floor_to_i32(c.y), floor_to_i32(c.z))
            .clamp(IVec3::splat(-MAX_CELL_COORDINATE), IVec3::splat(MAX_CELL_COORDINATE))
    }

    fn bucket(&self, cell: IVec3) -> u32 {
        let hash = (cell.x as u32).wrapping_mul(73_856_093)
            ^ (cell.y as u32).wrapping_mul(19_349_663)
            ^ (cell.z as u32).wrapping_mul(83_492_791);
        hash & (self.bucket_starts.len() as u32 - 2)
    }

    /// The probe nearest to `query` among those `accept` admits, if one lies within
    /// `max_rings · cell_size`. Searches shells of cells around the query's cell: after
    /// shell r every unvisited probe is at least r·cell_size away, so the search stops
    /// as soon as the best distance is within that, and the result is the exact nearest.
    pub fn nearest(&self, query: Vec3, positions: &[Vec3], accept: impl Fn(usize) -> bool) -> Option<usize> {
        self.nearest_candidate(query, positions, &accept).or_else(|| self.search(query, positions, accept))
    }

    /// The nearest admitted probe of the query's small cell's list, when it lies within
    /// the reach inside which the list is complete (then it is the nearest of all).
    #[inline]
    fn nearest_candidate(&self, query: Vec3, positions: &[Vec3], accept: &impl Fn(usize) -> bool) -> Option<usize> {
        let list = self.candidates.candidates(query)?;
        let mut best: Option<(usize, f32)> = None;
        for &probe in list {
            let probe = probe as usize;
            let d2 = positions[probe].distance_squared(query);
            if best.is_none_or(|(_, best_d2)| d2 < best_d2) && accept(probe) {
                best = Some((probe, d2));
            }
        }
        best.filter(|&(_, d2)| d2 <= self.candidates.reach_squared()).map(|(probe, _)| probe)
    }

    /// [`nearest`](Self::nearest) by the shells of hash cells alone.
    fn search(&self, query: Vec3, positions: &[Vec3], accept: impl Fn(usize) -> bool) -> Option<usize> {
        let mut best: Option<(usize, f32)> = None;
        let visit = |cell: IVec3, best: &mut Option<(usize, f32)>| {
            let b = self.bucket(cell) as usize;
            let (start, end) = (self.bucket_starts[b] as usize, self.bucket_starts[b + 1] as usize);
            for (offset, position) in positions[start..end].iter().enumerate() {
                let probe = start + offset;
                let d2 = position.distance_squared(query);
                if best.is_none_or(|(_, best_d2)| d2 < best_d2) && accept(probe) {
                    *best = Some((probe, d2));
                }
            }
        };
        // The query's own cell holds every probe closer than its nearest cell face.
        let scaled = (query - self.origin) * self.inverse_cell_size;
        let center = self.cell_of(query);
        let fraction = (scaled - center.as_vec3()).clamp(Vec3::ZERO, Vec3::ONE);
        visit(center, &mut best);
        if let Some((probe, d2)) = best {
            let margin = fraction.min(Vec3::ONE - fraction).min_element() * self.cell_size;
            if d2 <= margin * margin {
                return Some(probe);
            }
        }
        // The 2×2×2 block towards the nearest faces holds every probe within half a cell.
        let toward = fraction.cmplt(Vec3::splat(0.5));
        let step = IVec3::new(
            if toward.test(0) { -1 } else { 1 },
            if toward.test(1) { -1 } else { 1 },
            if toward.test(2) { -1 } else { 1 },
        );
        for corner in 1..8 {
            let offset = IVec3::new(corner & 1, (corner >> 1) & 1, corner >> 2) * step;
            visit(center + offset, &mut best);
        }
        if let Some((probe, d2)) = best {
            let half = 0.5 * self.cell_size;
            if d2 <= half * half {
                return Some(probe);
            }
        }
        for ring in 1..=self.max_rings as i32 {
            self.for_each_shell_cell(center, ring, |cell| visit(cell, &mut best));
            if let Some((probe, d2)) = best {
                let reach = ring as f32 * self.cell_size;
                if d2 <= reach * reach {
                    return Some(probe);
                }
            }
        }
        None
    }

    /// Visits the cells at Chebyshev distance exactly `ring` from `center`.
    fn for_each_shell_cell(&self, center: IVec3, ring: i32, mut visit: impl FnMut(IVec3)) {
        for dz in -ring..=ring {
            for dy in -ring..=ring {
                let on_face = dz.abs() == ring || dy.abs() == ring;
                if on_face {
                    for dx in -ring..=ring {
                        visit(center + IVec3::new(dx, dy, dz));
                    }
                } else {
                    visit(center + IVec3::new(-ring, dy, dz));
                    if ring != 0 {
                        visit(center + IVec3::new(ring, dy, dz));
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hemisphere::probes::ProbeSet;
    use crate::low_discrepancy::Pcg32;

    #[test]
    fn floor_saturates_at_the_extremes() {
        assert_eq!(floor_to_i32(-2.5), -3);
        assert_eq!(floor_to_i32(2.5), 2);
        assert_eq!(floor_to_i32(-1e30), i32::MIN);
        assert_eq!(floor_to_i32(f32::NEG_INFINITY), i32::MIN);
        assert_eq!(floor_to_i32(1e30), i32::MAX);
        assert_eq!(floor_to_i32(f32::NAN), 0);
    }

    #[test]
    fn queries_far_outside_the_grid_find_nothing_and_do_not_overflow() {
        let positions = [Vec3::ZERO, Vec3::X];
        let (lookup, _) = ProbeLookup::build(&positions, 0.5, 2);
        for query in [Vec3::splat(-1e30), Vec3::splat(1e30), Vec3::new(-3e38, 0.0, 3e38)] {
            assert_eq!(lookup.nearest(query, &positions, |_| true), None);
        }
    }

    fn random_points(rng: &mut Pcg32, count: usize, scale: f32, offset: Vec3) -> Vec<Vec3> {
        (0..count).map(|_| offset + Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32() * 0.1) * scale).collect()
    }

    fn brute_force(query: Vec3, positions: &[Vec3], accept: impl Fn(usize) -> bool) -> Option<f32> {
        positions
            .iter()
            .enumerate()
            .filter(|&(i, _)| accept(i))
            .map(|(_, p)| p.distance_squared(query))
            .min_by(f32::total_cmp)
    }

    #[test]
    fn floor_matches_the_mathematical_floor() {
        for x in [0.0f32, 0.5, 1.0, -0.5, -1.0, -1.5, 2.999, -2.999, 1e9, -1e9, f32::NAN] {
            let expected = if x.is_nan() { 0 } else { libm::floorf(x) as i32 };
            assert_eq!(floor_to_i32(x), expected, "{x}");
        }
    }

    #[test]
    fn shells_visit_each_cell_once() {
        let (lookup, _) = ProbeLookup::build(&[Vec3::ZERO], 1.0, 3);
        for ring in 0..4 {
            let mut cells = Vec::new();
            lookup.for_each_shell_cell(IVec3::ZERO, ring, |c| cells.push(c));
            let expected = if ring == 0 { 1 } else { (2 * ring + 1).pow(3) - (2 * ring - 1).pow(3) };
            assert_eq!(cells.len(), expected as usize);
            cells.sort_by_key(|c| (c.x, c.y, c.z));
            cells.dedup();
            assert_eq!(cells.len(), expected as usize);
            assert!(cells.iter().all(|c| c.abs().max_element() == ring));
        }
    }

    #[test]
    fn nearest_matches_brute_force() {
        let mut rng = Pcg32::new(11, 0);
        for (scale, offset) in [(1.0, Vec3::ZERO), (1e-3, Vec3::splat(1e3)), (1e4, Vec3::splat(-5e3))] {
            let points = random_points(&mut rng, 2000, scale, offset);
            let spacing = scale / libm::sqrtf(2000.0);
            let (lookup, order) = ProbeLookup::build(&points, spacing, 64);
            let sorted: Vec<Vec3> = order.iter().map(|&i| points[i as usize]).collect();
            for _ in 0..500 {
                let query = offset + Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32() * 0.2) * scale;
                // Admit only a third of the probes, as a normal test would.
                let accept = |i: usize| order[i] % 3 == 0;
                let found = lookup.nearest(query, &sorted, accept).unwrap();
                let expected = brute_force(query, &sorted, accept).unwrap();
                assert_eq!(sorted[found].distance_squared(query), expected);
            }
        }
    }

    /// The inside of a 2 × 1 × 3 box: twelve triangles facing in.
    fn box_faces() -> Vec<crate::Triangle> {
        let corner = |i: usize| Vec3::new((i & 1) as f32 * 2.0, ((i >> 1) & 1) as f32, (i >> 2) as f32 * 3.0);
        let quads = [[0, 2, 6, 4], [1, 5, 7, 3], [0, 4, 5, 1], [2, 3, 7, 6], [0, 1, 3, 2], [4, 6, 7, 5]];
        let mut triangles = Vec::new();
        for q in quads {
            let [a, b, c, d] = q.map(corner);
            triangles.push(crate::Triangle::new(a, b, c));
            triangles.push(crate::Triangle::new(a, c, d));
        }
        triangles
    }

    #[test]
    fn most_queries_on_surfaces_end_in_their_cells_list_with_the_searched_probe() {
        let faces = box_faces();
        let probes = ProbeSet::place_on_triangles(&faces, 2000, false).unwrap();
        let (lookup, order) = ProbeLookup::build(&probes.positions, probes.spacing, 8);
        let sorted: Vec<Vec3> = order.iter().map(|&i| probes.positions[i as usize]).collect();
        let normals: Vec<Vec3> = order.iter().map(|&i| probes.normals[i as usize]).collect();
        // Queries uniform on the faces, admitting probes within 45° of their normal.
        let mut rng = Pcg32::new(14, 0);
        let (mut from_list, mut count) = (0, 0);
        for _ in 0..4000 {
            let face = &faces[(rng.next_f32() * faces.len() as f32) as usize % faces.len()];
            let (mut u, mut v) = (rng.next_f32(), rng.next_f32());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            let [v0, v1, v2] = face.vertices;
            let query = v0 + (v1 - v0) * u + (v2 - v0) * v;
            let normal = face.normal().unwrap();
            let accept = |i: usize| normals[i].dot(normal) >= 0.7;
            let searched = lookup.search(query, &sorted, accept);
            if let Some(found) = lookup.nearest_candidate(query, &sorted, &accept) {
                from_list += 1;
                assert_eq!(Some(found), searched);
            }
            assert_eq!(lookup.nearest(query, &sorted, accept), searched);
            count += 1;
        }
        assert!(from_list * 10 > count * 9, "{from_list} of {count} from the lists");
    }

    #[test]
    fn nothing_admitted_or_far_away_gives_none() {
        let mut rng = Pcg32::new(12, 0);
        let points = random_points(&mut rng, 100, 1.0, Vec3::ZERO);
        let (lookup, order) = ProbeLookup::build(&points, 0.1, 2);
        let sorted: Vec<Vec3> = order.iter().map(|&i| points[i as usize]).collect();
        assert_eq!(lookup.nearest(Vec3::splat(0.5), &sorted, |_| false), None);
        assert_eq!(lookup.nearest(Vec3::splat(100.0), &sorted, |_| true), None);
        assert_eq!(lookup.nearest(Vec3::NAN, &sorted, |_| true), None);
    }

    #[test]
    fn sorting_is_stable_and_buckets_cover_all_probes() {
        let mut rng = Pcg32::new(13, 0);
        let points = random_points(&mut rng, 300, 2.0, Vec3::ZERO);
        let (lookup, order) = ProbeLookup::build(&points, 0.2, 2);
        assert_eq!(*lookup.bucket_starts().last().unwrap(), 300);
        let sorted: Vec<Vec3> = order.iter().map(|&i| points[i as usize]).collect();
        let (again, identity) = ProbeLookup::build(&sorted, 0.2, 2);
        assert_eq!(again, lookup);
        assert!(identity.iter().enumerate().all(|(i, &j)| i as u32 == j));
    }

    #[test]
    fn a_single_probe_or_coincident_probes_work() {
        let (lookup, order) = ProbeLookup::build(&[Vec3::splat(3.0)], 0.0, 2);
        assert_eq!(order, [0]);
        assert_eq!(lookup.nearest(Vec3::splat(3.0), &[Vec3::splat(3.0)], |_| true), Some(0));
        let same = [Vec3::ONE; 5];
        let (lookup, _) = ProbeLookup::build(&same, 0.0, 1);
        assert!(lookup.nearest(Vec3::ONE * 1.5, &same, |_| true).is_some());
        assert!(lookup.nearest(Vec3::ONE, &same, |_| true).is_some());
    }
}
