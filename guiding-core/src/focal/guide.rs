//! [`FocalGuide`]: learns an octree of where light-carrying segments pass, and samples
//! directions towards its densest leaves.

use alloc::vec::Vec;

use glam::Vec3;

use super::box_cells::{carry_multiplier, probabilities, BoxCells};
use super::known_boxes::{KnownBox, KnownBoxes};
use super::lanes::{crossed_runs, morton, ray_box, BoxLanes, LANES};
use super::merge::{merge_boxes, MassBox};
use super::octree::{FocalOctree, Leaf};
use super::settings::FocalGuideSettings;
use crate::atomic_f32;
use crate::distribution::DirectionSample;
use crate::error::Error;
use crate::strategy_share::{StrategyArrival, StrategyShares};
use crate::update_rule::{classify_target, UpdateOutcome};

/// One path segment that carried light, as the focal guide learns from it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FocalRecord {
    /// Where the segment starts (a path vertex), world space, metres.
    pub origin: Vec3,
    /// Its unit direction.
    pub direction: Vec3,
    /// Its length to the next vertex, metres (infinite for an escaped ray: it is clipped
    /// to the scene's cube).
    pub length: f32,
    /// What it brought to the image: the camera-side throughput times the radiance that
    /// arrived along it (luminance). Zero teaches nothing.
    pub weight: f32,
}

/// One box the sampler aims at: a focal leaf of the octree, or neighbouring ones merged.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FocalBox {
    /// Lower corner, world space, metres.
    pub low: Vec3,
    /// Upper corner.
    pub high: Vec3,
    /// Probability of a sampled point per m³ inside the box (its share ÷ its volume).
    pub density: f32,
}

/// A guide that aims at the points where light squeezes through (a gap, a keyhole, a
/// focus), the same points from every vertex: see the [module docs](super).
///
/// A sampled direction points from the vertex towards a point drawn uniformly in one of
/// the focal boxes (chosen by learned mass); its density per steradian is
/// `Σ_k density_k · ∫ t² dt` over the part of the ray inside box k, exact, so the
/// guide mixes with a BSDF by one-sample MIS like any directional distribution.
///
/// ```
/// use glam::Vec3;
/// use guiding_core::focal::{FocalGuide, FocalGuideSettings, FocalRecord};
///
/// let mut guide = FocalGuide::new(Vec3::splat(-1.0), Vec3::splat(1.0), FocalGuideSettings::default()).unwrap();
/// // Light reaches every vertex through the point (0.5, 0.5, 0.5). The first rebuild
/// // refines the octree where mass landed; the second finds the dense leaves in it.
/// for _ in 0..2 {
///     for i in 0..2000 {
///         let origin = Vec3::new(-0.9, (i % 40) as f32 / 25.0 - 0.8, (i / 40) as f32 / 30.0 - 0.8);
///         let direction = (Vec3::splat(0.5) - origin).normalize();
///         let record = FocalRecord { origin, direction, length: 3.0, weight: 1.0 };
///         guide.record(&record, (i as f32 * 0.618).fract());
///     }
///     guide.rebuild_sampling();
/// }
/// assert!(!guide.boxes().is_empty());
/// let from = Vec3::new(-0.9, -0.5, 0.0);
/// let sample = guide.sample(from, 0.3, Vec3::splat(0.5)).unwrap();
/// assert!((sample.direction - (Vec3::splat(0.5) - from).normalize()).length() < 0.1);
/// assert!((guide.pdf(from, sample.direction) - sample.pdf).abs() <= 1e-3 * sample.pdf);
/// ```
pub struct FocalGuide {
    octree: FocalOctree,
    settings: FocalGuideSettings,
    boxes: Vec<FocalBox>,
    /// The bounds (low, high) of every box; the boxes in runs of [`LANES`] (in Morton
    /// order of their centres, so a run is a compact cluster); and the bounds of the runs,
    /// [`LANES`] runs to an entry: a ray that misses a run's bounds skips its boxes.
    bounds: (Vec3, Vec3),
    box_lanes: Vec<BoxLanes>,
    run_lanes: Vec<BoxLanes>,
    /// Cumulative probabilities of `boxes`, the last 1.
    cdf: Vec<f32>,
    /// The probability of aiming at the boxes, learned per cell of a coarse grid.
    selection: StrategyShares,
    /// The boxes' probabilities learned per cell of the same grid (`boxes_per_cell`).
    cells: BoxCells,
    /// Boxes the caller told it of, which join the learned ones at every rebuild.
    known: KnownBoxes,
}

/// The probabilities of aiming at the boxes that each selection cell weighs.
pub const CANDIDATES: [f32; 7] = crate::strategy_share::CANDIDATES;

/// One direction a path scattered into, as the selection learns from it: what arrived
/// and every density that drew it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FocalArrival {
    /// The vertex, world space.
    pub point: Vec3,
    /// The direction drawn (unit).
    pub direction: Vec3,
    /// fs·cos θ × the radiance that arrived along the direction (luminance): the
    /// integrand of the vertex's scattering integral at that direction.
    pub integrand: f32,
    /// The pdf the direction was drawn with (the whole mixture's), per steradian.
    pub pdf: f32,
    /// The focal boxes' pdf of the direction.
    pub focal_pdf: f32,
    /// The BSDF's own pdf of it.
    pub bsdf_pdf: f32,
    /// The probability of aiming at the boxes the mixture used; the rest of the mixture
    /// (the BSDF's share) changes with it, any other component stays.
    pub selection: f32,
}

impl FocalGuide {
    /// A guide over the box `low`..`high` (the scene's bounds) that has learned nothing
    /// and samples nothing yet.
    pub fn new(low: Vec3, high: Vec3, settings: FocalGuideSettings) -> Result<Self, Error> {
        settings.validate()?;
        if !(low.is_finite() && high.is_finite() && high.cmpge(low).all()) {
            return Err(Error::InvalidSetting {
                name: "bounds",
                value: f64::NAN,
                requirement: "finite, with high ≥ low on every axis",
            });
        }
        let selection = StrategyShares::new(low, high, settings.share_resolution)?.with_cost(settings.share_cost)?;
        Ok(Self {
            octree: FocalOctree::new(low, high),
            settings,
            boxes: Vec::new(),
            bounds: (Vec3::ZERO, Vec3::ZERO),
            box_lanes: Vec::new(),
            run_lanes: Vec::new(),
            cdf: Vec::new(),
            selection,
            cells: BoxCells::default(),
            known: KnownBoxes::default(),
        })
    }

    /// Tells the guide of boxes light is known to seem to come from (a light's mirror
    /// image, say; see [`KnownBox`]): they join the learned boxes at once (a
    /// [`rebuild_sampling`](Self::rebuild_sampling), so call it between passes) and at
    /// every rebuild, together holding `share` times the learned boxes' mass (all of it
    /// while none was learned), split by their weights. The first pass can then already
    /// learn where aiming at them pays. Replaces any told before; an empty slice removes
    /// them. A bad box or share is refused and changes nothing.
    pub fn set_known_boxes(&mut self, boxes: &[KnownBox], share: f32) -> Result<(), Error> {
        self.known = KnownBoxes::new(boxes, share)?;
        self.rebuild_sampling();
        Ok(())
    }

    /// Whether boxes were told with [`set_known_boxes`](Self::set_known_boxes).
    pub fn has_known_boxes(&self) -> bool {
        !self.known.is_empty()
    }

    /// The selection grid: its cells that aim at the boxes (a share above 0) and all of
    /// them.
    pub fn selection_cells(&self) -> (usize, usize) {
        (self.selection.cells_in_use(), self.selection.cell_count())
    }

    /// The probability with which a vertex at `point` should aim at the boxes: of the
    /// [`CANDIDATES`], the one whose one-sample estimator had the least variance (times
    /// `1 + share_cost` above 0) over the arrivals learned around `point` (0 before
    /// enough were).
    #[inline]
    pub fn selection_probability(&self, point: Vec3) -> f32 {
        self.selection.share(point)
    }

    /// Whether some region aims at the boxes at all (some cell's probability above 0,
    /// and boxes to aim at): where none does, a renderer that is not learning can leave
    /// the focal guide out of its vertices.
    #[inline]
    pub fn aims(&self) -> bool {
        !self.boxes.is_empty() && self.selection.any()
    }

    /// Learns how well aiming at the boxes would have served the vertex of `arrival`:
    /// for each candidate probability c, the second moment ∫ F²/p_c of the estimator
    /// with that mixture is estimated from the direction drawn with p:
    /// F²/(p·p_c), where p_c = p + (c − selection)·(focal_pdf − bsdf_pdf).
    ///
    /// With `boxes_per_cell`, the arrival also teaches its cell which boxes its light came
    /// through: integrand / pdf, shared among the boxes the direction crosses by their
    /// part of the focal density along it.
    pub fn record_arrival(&self, arrival: &FocalArrival) -> UpdateOutcome {
        if self.cells.enabled() {
            self.learn_boxes(arrival);
        }
        self.selection.record(&StrategyArrival {
            point: arrival.point,
            integrand: arrival.integrand,
            pdf: arrival.pdf,
            strategy_pdf: arrival.focal_pdf,
            bsdf_pdf: arrival.bsdf_pdf,
            selection: arrival.selection,
        })
    }

    fn learn_boxes(&self, arrival: &FocalArrival) {
        let Some(cell) = self.selection.cell(arrival.point) else { return };
        self.cells.count(cell);
        let amount = arrival.integrand / arrival.pdf;
        if !(amount > 0.0 && amount.is_finite() && arrival.direction.is_finite()) {
            return;
        }
        let inverse = arrival.direction.recip();
        let scales = self.cells.scales(cell);
        // Each crossed box's part of the cell's focal density along the direction: once
        // to add them up, once to share the amount out (no allocation per arrival).
        let each_term = |visit: &mut dyn FnMut(usize, f32)| {
            crossed_runs(&self.run_lanes, arrival.point, inverse, |run| {
                let terms = self.box_lanes[run].span_terms(arrival.point, inverse);
                for (lane, &term) in terms.iter().enumerate() {
                    let index = run * LANES + lane;
                    let term = term * scales.map_or(1.0, |s| s[index]);
                    if term > 0.0 {
                        visit(index, term);
                    }
                }
            });
        };
        let mut total = 0.0f32;
        each_term(&mut |_, term| total += term);
        if total > 0.0 && total.is_finite() {
            each_term(&mut |index, term| self.cells.add(cell, index, amount * term / total));
        }
    }

    /// The settings it was built with.
    pub fn settings(&self) -> &FocalGuideSettings {
        &self.settings
    }

    /// The boxes sampled now (empty before anything focal was learned).
    pub fn boxes(&self) -> &[FocalBox] {
        &self.boxes
    }

    /// Octree nodes.
    pub fn node_count(&self) -> usize {
        self.octree.children.len()
    }

    /// Bytes held: octree nodes, sampling boxes and the selection grid.
    pub fn memory_bytes(&self) -> usize {
        self.octree.children.len() * 8
            + self.boxes.len() * (core::mem::size_of::<FocalBox>() + 4)
            + (self.box_lanes.len() + self.run_lanes.len()) * core::mem::size_of::<BoxLanes>()
            + self.selection.memory_bytes()
            + self.cells.memory_bytes()
    }

    /// Learns one segment: its weight × length is spread over the leaves it crosses,
    /// exactly (each leaf gets weight × the length inside it) or, where
    /// `deposits_per_segment` is above 0, at that many points stratified along it (`u` in
    /// [0, 1) places them).
    /// Lock-free; safe from many threads during a pass.
    pub fn record(&self, record: &FocalRecord, u: f32) -> UpdateOutcome {
        let weight = match classify_target(record.weight) {
            Ok(w) => w,
            Err(outcome) => return outcome,
        };
        let direction = record.direction;
        if !(record.origin.is_finite() && direction.is_finite() && (direction.length_squared() - 1.0).abs() < 1e-3)
            || record.length.is_nan()
            || record.length < 0.0
        {
            return UpdateOutcome::OutsideDomain;
        }
        if weight == 0.0 {
            return UpdateOutcome::Accepted;
        }
        let cube_high = self.octree.low + Vec3::splat(self.octree.size);
        let (t0, t1) = ray_box(record.origin, direction.recip(), self.octree.low, cube_high);
        let (t0, t1) = (t0.max(0.0), t1.min(record.length));
        if t1.is_nan() || t0.is_nan() || t1 <= t0 {
            return UpdateOutcome::OutsideDomain;
        }
        let count = self.settings.deposits_per_segment;
        if count == 0 {
            self.octree.deposit_along(record.origin, direction, (t0, t1), weight);
            return UpdateOutcome::Accepted;
        }
        let step = (t1 - t0) / count as f32;
        let amount = weight * step;
        let u = if (0.0..1.0).contains(&u) { u } else { 0.5 };
        for k in 0..count {
            let t = t0 + (k as f32 + u) * step;
            self.octree.deposit(record.origin + direction * t, amount);
        }
        UpdateOutcome::Accepted
    }

    /// Refines the octree where mass gathered and rebuilds the boxes sampled: the leaves
    /// whose density is at least `focal_ratio` times the mean over occupied leaves, merged
    /// where neighbours are alike (`merge_ratio`), the heaviest `max_boxes` of them, each
    /// chosen by its mass.
    pub fn rebuild_sampling(&mut self) {
        self.selection.rebuild_sampling();
        // What each cell learned of the old boxes, carried to the new ones below.
        let old_boxes = core::mem::take(&mut self.boxes);
        let old_global = probabilities(&self.cdf);
        let multipliers = if self.cells.enabled() { self.cells.multipliers(&old_global) } else { Vec::new() };
        self.rebuild_boxes();
        if self.settings.boxes_per_cell && !self.boxes.is_empty() {
            let carried: Vec<Option<Vec<f32>>> = multipliers
                .iter()
                .map(|m| {
                    let m = m.as_ref()?;
                    Some(self.boxes.iter().map(|b| carry_multiplier(&old_boxes, m, 0.5 * (b.low + b.high))).collect())
                })
                .collect();
            let global = probabilities(&self.cdf);
            let cells = self.selection.cell_count();
            self.cells.restart(cells, self.box_lanes.len() * LANES, &global, &carried);
        } else {
            self.cells = BoxCells::default();
        }
    }

    /// The boxes, their cdf and lanes from the octree (refined first where mass gathered)
    /// and the known boxes, which stand alone before anything is learned.
    fn rebuild_boxes(&mut self) {
        self.boxes.clear();
        self.cdf.clear();
        self.box_lanes.clear();
        self.run_lanes.clear();
        // Only leaves gather mass: the node array's sum is the leaves' without a walk.
        let total: f64 = self.octree.mass.iter().map(|m| atomic_f32::load(m) as f64).sum();
        let learned = total > 0.0 && total.is_finite();
        let mut chosen = if learned { self.learned_boxes(total) } else { Vec::new() };
        self.known.add_to(&mut chosen, if learned { total } else { 1.0 });
        self.install_boxes(chosen);
    }

    /// The octree's focal leaves, merged into at most `max_boxes` boxes, heaviest first;
    /// `total` is the octree's mass.
    fn learned_boxes(&mut self, total: f64) -> Vec<MassBox> {
        let s = self.settings;
        self.octree.split_heavy_leaves((s.split_share as f64 * total) as f32, s.max_nodes, s.max_depth);
        let leaves = self.octree.leaves();
        let volume = |l: &Leaf| (l.size as f64) * (l.size as f64) * (l.size as f64);
        let (mass, occupied) = leaves
            .iter()
            .filter(|l| l.mass > 0.0)
            .fold((0.0f64, 0.0f64), |(m, v), l| (m + l.mass as f64, v + volume(l)));
        let threshold = s.focal_ratio as f64 * mass / occupied;
        let mut focal: Vec<(f64, &Leaf)> = leaves
            .iter()
            .map(|l| (l.mass as f64 / volume(l), l))
            .filter(|(density, l)| l.mass > 0.0 && *density >= threshold)
            .collect();
        focal.sort_by(|a, b| b.0.total_cmp(&a.0));
        let as_box = |l: &Leaf| MassBox { low: l.low, high: l.low + Vec3::splat(l.size), mass: l.mass as f64 };
        let mut chosen: Vec<MassBox> = if s.merge_ratio > 0.0 {
            focal.truncate(4 * s.max_boxes as usize);
            let mut merged: Vec<MassBox> = focal.iter().map(|(_, l)| as_box(l)).collect();
            merge_boxes(&mut merged, s.merge_ratio as f64, 1e-6 * self.octree.size);
            merged.sort_by(|a, b| b.mass.total_cmp(&a.mass));
            merged
        } else {
            focal.iter().map(|(_, l)| as_box(l)).collect()
        };
        chosen.truncate(s.max_boxes as usize);
        chosen
    }

    /// Makes `chosen` the boxes: their cdf by mass, Morton-ordered lanes and runs.
    fn install_boxes(&mut self, mut chosen: Vec<MassBox>) {
        let mass: f64 = chosen.iter().map(|b| b.mass).sum();
        if mass.is_nan() || mass <= 0.0 {
            return;
        }
        let union = |boxes: &[MassBox]| {
            boxes.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(low, high), b| (low.min(b.low), high.max(b.high)))
        };
        let (low, high) = union(&chosen);
        let scale = (high - low).max(Vec3::splat(1e-12)).recip();
        chosen.sort_by_key(|b| morton((0.5 * (b.low + b.high) - low) * scale));
        self.bounds = (low, high);
        let mut running = 0.0f64;
        for b in &chosen {
            let share = b.mass / mass;
            running += share;
            self.boxes.push(FocalBox { low: b.low, high: b.high, density: (share / b.volume()) as f32 });
            self.cdf.push(running as f32);
        }
        if let Some(last) = self.cdf.last_mut() {
            *last = 1.0;
        }
        let runs: Vec<(Vec3, Vec3, f32)> = self
            .boxes
            .chunks(LANES)
            .map(|run| {
                let lanes: Vec<(Vec3, Vec3, f32)> = run.iter().map(|b| (b.low, b.high, b.density)).collect();
                self.box_lanes.push(BoxLanes::new(&lanes));
                let (low, high) = run
                    .iter()
                    .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(low, high), b| (low.min(b.low), high.max(b.high)));
                (low, high, 1.0)
            })
            .collect();
        self.run_lanes = runs.chunks(LANES).map(BoxLanes::new).collect();
    }

    /// A direction from `point` towards a point drawn in the boxes: `u_box` picks the box
    /// (by mass), `u` the point inside it. `None` when there are no boxes or the point
    /// drawn is `point` itself.
    pub fn sample(&self, point: Vec3, u_box: f32, u: Vec3) -> Option<DirectionSample> {
        let cdf = self.cell_of(point).and_then(|cell| self.cells.cdf(cell)).unwrap_or(&self.cdf);
        let index = cdf.partition_point(|&c| c <= u_box).min(self.boxes.len().checked_sub(1)?);
        let chosen = &self.boxes[index];
        let target = chosen.low + (chosen.high - chosen.low) * u.clamp(Vec3::ZERO, Vec3::ONE);
        let offset = target - point;
        let distance = offset.length();
        if !(distance > 0.0 && distance.is_finite()) {
            return None;
        }
        let direction = offset / distance;
        let pdf = self.pdf(point, direction);
        (pdf > 0.0 && pdf.is_finite()).then_some(DirectionSample { direction, pdf })
    }

    /// Density per steradian with which [`sample`](Self::sample) draws `direction` from
    /// `point`: Σ_k density_k · (t1³ − t0³)/3 over the ray's span [t0, t1] in box k.
    pub fn pdf(&self, point: Vec3, direction: Vec3) -> f32 {
        let inverse = direction.recip();
        let (t0, t1) = ray_box(point, inverse, self.bounds.0, self.bounds.1);
        // A NaN span (a degenerate direction) skips the boxes too.
        let crosses = t1 > t0.max(0.0);
        if self.boxes.is_empty() || !crosses {
            return 0.0;
        }
        let scales = self.cell_of(point).and_then(|cell| self.cells.scales(cell));
        let mut pdf = 0.0f32;
        // Most directions that cross the bounds still miss most runs.
        crossed_runs(&self.run_lanes, point, inverse, |run| {
            let lanes = &self.box_lanes[run];
            let scale = scales.and_then(|s| <&[f32; LANES]>::try_from(s.get(run * LANES..(run + 1) * LANES)?).ok());
            pdf += match scale {
                Some(scale) => lanes.span_integral_scaled(point, inverse, scale),
                None => lanes.span_integral(point, inverse),
            };
        });
        pdf
    }

    /// The selection cell of `point` where cells learn their own box probabilities.
    #[inline]
    fn cell_of(&self, point: Vec3) -> Option<usize> {
        if self.cells.enabled() {
            self.selection.cell(point)
        } else {
            None
        }
    }
}

#[cfg(test)]
pub(super) mod tests;
