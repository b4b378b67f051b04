//! Turning a finished path into the targets of Eq. (1): the renderer records each
//! scattering vertex as it traces, tells the recorder what arrived along the last
//! direction, and at the end hands every target to a [`Guide`].
//!
//! The target of a vertex x that scattered towards y is what arrives at x from y:
//! `Le(y) + ∫ Q(y, ωi) fs cos θi dωi` (Eq. 1). With next-event estimation the light y's
//! own light sample brings back counts as arriving too, and y's emission arrives with the
//! MIS weight it got as a scattering hit, so that Q learns the light that scattering has
//! to find and not the light next-event estimation already brings. The integral is
//! either estimated at y ([`Onward::Integral`], e.g. by [`Guide::estimate_integral`]) or,
//! where y has no estimate of its own (a delta surface, a point outside the guide, or a
//! renderer that learns from the path's own continuation), carried back from y's target
//! scaled by y's sampled factor fs·cos/pdf and, past Russian roulette, 1/survival: the
//! one-sample estimate the path itself made ([`Onward::Carry`]).
//!
//! The recorder allocates only while its buffer grows to the longest path; `clear`
//! keeps the buffer.
//!
//! ```
//! use glam::Vec3;
//! use guiding_core::{Onward, PathRecorder};
//!
//! // A camera path: x0 scatters to a mirror x1 (delta: no estimate of its own), which
//! // reflects (factor 0.9) to a diffuse x2, whose light sample brings back 0.5 and whose
//! // scattered direction (factor 0.6, carried: this renderer learns from the path's
//! // continuation) escapes into a sky of radiance 2.
//! let mut path: PathRecorder<u32> = PathRecorder::new();
//! path.scattered(Some(7), Vec3::ZERO, Vec3::Y, 0.3, 1.0, ());
//! path.reached(1.0); // x1, the mirror
//! path.carry(0.9);
//! path.scattered(None, Vec3::Y, Vec3::X, 1.0, 0.9, ());
//! path.reached(2.0); // x2
//! path.arrive(0.5); // x2's light sample, as indirect light for x1
//! path.carry(0.6);
//! path.scattered(Some(3), Vec3::new(2.0, 1.0, 0.0), Vec3::Y, 0.2, 0.54, ());
//! path.arrive(2.0); // the sky, seen from x2
//! let targets: Vec<f32> = path.targets().map(|(_, target)| target).collect();
//! assert_eq!(targets, [2.0, 0.5 + 0.6 * 2.0, 0.9 * (0.5 + 0.6 * 2.0)]); // last vertex first
//! ```

use alloc::vec::Vec;

use glam::Vec3;

use crate::guide::Guide;
use crate::update_rule::UpdateOutcome;

/// What a vertex learns about the light beyond its next vertex y (beyond what arrived
/// directly: y's emission and y's own light sample).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Onward {
    /// An estimate of ∫ Q(y, ωi) fs cos θi dωi at y (radiance, luminance).
    Integral(f32),
    /// y has no estimate: y's own target, times this factor (y's fs·cos/pdf, and
    /// 1/survival where Russian roulette ran at y).
    Carry(f32),
    /// Nothing: the path ended at y or escaped.
    End,
}

/// One scattering vertex as recorded, with what arrived along its direction.
#[derive(Clone, Copy, Debug)]
pub struct RecordedVertex<R, E> {
    /// The guide's region at the vertex (`None` outside the guide: it learns nothing,
    /// and passes its target on where its predecessor carries).
    pub region: Option<R>,
    /// Where the direction leaves from.
    pub origin: Vec3,
    /// The sampled direction (unit).
    pub direction: Vec3,
    /// The density the direction was drawn with, per steradian.
    pub pdf: f32,
    /// How far the direction went (infinite until it reached a surface).
    pub length: f32,
    /// The path's throughput (luminance) for what arrives along `direction`.
    pub throughput: f32,
    /// Radiance (luminance) that arrived along the direction: the next vertex's emission
    /// times its MIS weight, plus the light its own light sample reflected back.
    pub arriving: f32,
    /// Radiance (luminance) that arrived along the direction which this vertex learns
    /// but does not pass back to its predecessor ([`PathRecorder::arrive_learned_only`]).
    pub learned_only: f32,
    /// What the vertex learns beyond that.
    pub onward: Onward,
    /// What the renderer keeps beside each vertex for its own learners.
    pub extra: E,
}

impl<R: Copy, E> RecordedVertex<R, E> {
    /// Teaches `guide` this vertex's `target` (from [`PathRecorder::targets`]) where it
    /// has a region: by [`Guide::update_sampled`] (weighed by the density the direction
    /// was drawn with) when `density_weighted`, else by [`Guide::update`]. `None` without
    /// a region.
    pub fn teach<G: Guide<Region = R>>(&self, guide: &G, target: f32, density_weighted: bool) -> Option<UpdateOutcome> {
        let region = self.region?;
        Some(if density_weighted {
            guide.update_sampled(region, self.direction, target, self.pdf)
        } else {
            guide.update(region, self.direction, target)
        })
    }

    /// [`teach`](Self::teach) through a thread's own `records` ([`Guide::record`]) when
    /// `density_weighted`; the guide learns them at [`Guide::splat`] after the pass.
    pub fn teach_into<G: Guide<Region = R>>(
        &self,
        guide: &G,
        records: &mut G::Records,
        target: f32,
        density_weighted: bool,
    ) -> Option<UpdateOutcome> {
        let region = self.region?;
        Some(if density_weighted {
            guide.record(records, region, self.direction, target, self.pdf)
        } else {
            guide.update(region, self.direction, target)
        })
    }
}

/// The vertices of the path being traced. `R` is the guide's region, `E` whatever else
/// the renderer keeps per vertex (`()` for nothing).
#[derive(Clone, Debug)]
pub struct PathRecorder<R, E = ()> {
    vertices: Vec<RecordedVertex<R, E>>,
}

impl<R, E> Default for PathRecorder<R, E> {
    fn default() -> Self {
        Self { vertices: Vec::new() }
    }
}

impl<R: Copy, E: Copy> PathRecorder<R, E> {
    /// An empty recorder.
    pub fn new() -> Self {
        Self::default()
    }

    /// Forgets the path, keeping the buffer: call before each path.
    pub fn clear(&mut self) {
        self.vertices.clear();
    }

    /// The vertices recorded, first first.
    pub fn vertices(&self) -> &[RecordedVertex<R, E>] {
        &self.vertices
    }

    /// Whether no vertex has scattered yet.
    pub fn is_empty(&self) -> bool {
        self.vertices.is_empty()
    }

    /// Records a vertex at `origin` that scattered along `direction`, drawn with `pdf`
    /// (per steradian); `throughput` is the path's (luminance) for what arrives along it.
    pub fn scattered(&mut self, region: Option<R>, origin: Vec3, direction: Vec3, pdf: f32, throughput: f32, extra: E) {
        self.vertices.push(RecordedVertex {
            region,
            origin,
            direction,
            pdf,
            length: f32::INFINITY,
            throughput,
            arriving: 0.0,
            learned_only: 0.0,
            onward: Onward::End,
            extra,
        });
    }

    /// The last direction reached a surface `distance` away.
    pub fn reached(&mut self, distance: f32) {
        if let Some(last) = self.vertices.last_mut() {
            last.length = distance;
        }
    }

    /// Radiance (luminance) arrived along the last direction: emission seen there (with
    /// its MIS weight) or the light its own light sample reflects back.
    pub fn arrive(&mut self, radiance: f32) {
        if let Some(last) = self.vertices.last_mut() {
            last.arriving += radiance;
        }
    }

    /// Radiance (luminance) arrived along the last direction that this vertex learns
    /// but its predecessor must not: with next-event estimation the predecessor's target
    /// already holds the emission a direction finds only by its MIS weight, the light
    /// sample bringing the rest, while a guide that learns the full incident radiance
    /// (weighing the light samples in by the densities of both strategies) needs the
    /// emission whole here.
    pub fn arrive_learned_only(&mut self, radiance: f32) {
        if let Some(last) = self.vertices.last_mut() {
            last.learned_only += radiance;
        }
    }

    /// Adds `pdf` (per steradian) to the density the last direction counts as drawn with:
    /// a second strategy that could have drawn it (a light sample, for an emitter found
    /// by scattering) makes it a sample of their deterministic mixture.
    pub fn add_density(&mut self, pdf: f32) {
        if let Some(last) = self.vertices.last_mut() {
            last.pdf += pdf;
        }
    }

    /// The vertex the last direction reached estimates Eq. (1)'s integral there.
    pub fn estimate(&mut self, integral: f32) {
        if let Some(last) = self.vertices.last_mut() {
            last.onward = Onward::Integral(integral);
        }
    }

    /// The vertex the last direction reached has no estimate: it passes its own target
    /// back, times `factor` (its fs·cos/pdf, and 1/survival past Russian roulette).
    pub fn carry(&mut self, factor: f32) {
        if let Some(last) = self.vertices.last_mut() {
            last.onward = Onward::Carry(factor);
        }
    }

    /// Whether the last direction's vertex learns from an estimate of Eq. (1)'s integral
    /// at the vertex it reached ([`estimate`](Self::estimate)), which then holds all the
    /// light leaving there: light that vertex's own light sample found must not also
    /// arrive where the estimate already counts it.
    pub fn last_is_estimated(&self) -> bool {
        self.vertices.last().is_some_and(|v| matches!(v.onward, Onward::Integral(_)))
    }

    /// The last vertex recorded, to amend what the renderer keeps beside it.
    pub fn last_mut(&mut self) -> Option<&mut RecordedVertex<R, E>> {
        self.vertices.last_mut()
    }

    /// Every vertex with its target of Eq. (1), last vertex first (each target needs the
    /// next one's).
    pub fn targets(&self) -> Targets<'_, R, E> {
        Targets { vertices: self.vertices.iter().rev(), next_target: 0.0 }
    }

    /// Teaches `guide` every target at the vertices it has a region for
    /// ([`RecordedVertex::teach`]). Returns how many updates the guide accepted.
    pub fn learn<G: Guide<Region = R>>(&self, guide: &G, density_weighted: bool) -> usize {
        self.targets()
            .filter(|(vertex, target)| vertex.teach(guide, *target, density_weighted) == Some(UpdateOutcome::Accepted))
            .count()
    }
}

/// The vertices of a path with their targets, last first ([`PathRecorder::targets`]).
pub struct Targets<'a, R, E> {
    vertices: core::iter::Rev<core::slice::Iter<'a, RecordedVertex<R, E>>>,
    next_target: f32,
}

impl<'a, R, E> Iterator for Targets<'a, R, E> {
    type Item = (&'a RecordedVertex<R, E>, f32);

    fn next(&mut self) -> Option<Self::Item> {
        let vertex = self.vertices.next()?;
        let onward = match vertex.onward {
            Onward::Integral(estimate) => estimate,
            Onward::Carry(factor) => factor * self.next_target,
            Onward::End => 0.0,
        };
        let target = vertex.arriving + onward;
        self.next_target = target;
        Some((vertex, target + vertex.learned_only))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::vec;

    fn targets<R: Copy, E: Copy>(path: &PathRecorder<R, E>) -> Vec<f32> {
        path.targets().map(|(_, t)| t).collect()
    }

    #[test]
    fn an_estimate_stops_what_is_carried_from_further_on() {
        let mut path: PathRecorder<u8> = PathRecorder::new();
        path.scattered(Some(0), Vec3::ZERO, Vec3::Z, 1.0, 1.0, ());
        path.reached(1.0);
        path.arrive(0.25);
        assert!(!path.last_is_estimated());
        path.estimate(0.5);
        assert!(path.last_is_estimated());
        path.scattered(Some(1), Vec3::Z, Vec3::X, 1.0, 1.0, ());
        path.arrive(100.0);
        // The first vertex learns its own estimate, not what the second one saw.
        assert_eq!(targets(&path), [100.0, 0.75]);
    }

    #[test]
    fn what_is_learned_only_stays_at_its_vertex() {
        let mut path: PathRecorder<u8> = PathRecorder::new();
        path.scattered(Some(0), Vec3::ZERO, Vec3::Z, 1.0, 1.0, ());
        path.carry(0.5);
        path.scattered(Some(1), Vec3::Z, Vec3::X, 2.0, 1.0, ());
        path.arrive(1.0);
        path.arrive_learned_only(3.0);
        path.add_density(0.5);
        assert_eq!(path.vertices()[1].pdf, 2.5);
        // The second vertex learns 1 + 3, the first half of the 1 alone.
        assert_eq!(targets(&path), [4.0, 0.5]);
    }

    #[test]
    fn russian_roulette_survival_is_carried_with_the_factor() {
        // Bug 1 of the guiding issue: a vertex past Russian roulette without an estimate
        // must carry 1/survival, as the throughput does. The renderer hands the recorder
        // fs·cos/pdf / survival; the recorder must apply exactly that.
        let (factor, survival) = (0.8f32, 0.4f32);
        let mut path: PathRecorder<u8> = PathRecorder::new();
        path.scattered(Some(0), Vec3::ZERO, Vec3::Z, 1.0, 1.0, ());
        path.carry(factor / survival);
        path.scattered(None, Vec3::Z, Vec3::X, 1.0, factor / survival, ());
        path.arrive(1.0);
        // Averaged over the roulette (surviving with probability 0.4) the carried
        // target is the unbiased factor × arriving.
        let carried = targets(&path)[1];
        assert!((survival * carried - factor).abs() < 1e-6);
    }

    #[test]
    fn clearing_keeps_the_buffer() {
        let mut path: PathRecorder<u8> = PathRecorder::new();
        for _ in 0..32 {
            path.scattered(None, Vec3::ZERO, Vec3::Z, 1.0, 1.0, ());
        }
        let capacity = path.vertices.capacity();
        path.clear();
        assert!(path.is_empty());
        for _ in 0..32 {
            path.scattered(None, Vec3::ZERO, Vec3::Z, 1.0, 1.0, ());
        }
        assert_eq!(path.vertices.capacity(), capacity, "no allocation once the buffer has grown");
    }

    #[test]
    fn calls_before_any_vertex_change_nothing() {
        let mut path: PathRecorder<u8, u32> = PathRecorder::new();
        path.reached(1.0);
        path.arrive(1.0);
        path.estimate(1.0);
        path.carry(1.0);
        assert!(path.is_empty() && path.last_mut().is_none());
        assert_eq!(targets(&path), vec![]);
    }
}
