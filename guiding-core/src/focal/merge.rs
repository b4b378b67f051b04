//! Merging the focal leaves into fewer, longer boxes: a door's gap is a sheet a
//! centimetre thick and metres long, which cubic leaves cover only as a row of many
//! small boxes, each one more slab test per direction. Neighbours that share a face
//! exactly and hold similar densities become one box with their summed mass.

use alloc::vec::Vec;

use glam::Vec3;

/// A box with the mass it holds (before the masses become sampling densities).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct MassBox {
    pub low: Vec3,
    pub high: Vec3,
    pub mass: f64,
}

impl MassBox {
    pub fn volume(&self) -> f64 {
        let extent = self.high - self.low;
        extent.x as f64 * extent.y as f64 * extent.z as f64
    }

    fn density(&self) -> f64 {
        self.mass / self.volume()
    }
}

/// Whether `a` and `b` touch along one axis with the same extent on the other two
/// (within a rounding tolerance `epsilon`, metres), and their densities differ by at
/// most `ratio`: then their union is a box.
fn mergeable(a: &MassBox, b: &MassBox, ratio: f64, epsilon: f32) -> bool {
    let same = |x: f32, y: f32| (x - y).abs() <= epsilon;
    let (da, db) = (a.density(), b.density());
    // Written so that a NaN density (an empty box) never merges.
    let alike = da.max(db) <= ratio * da.min(db);
    if !alike {
        return false;
    }
    (0..3).any(|axis| {
        let touching = same(a.high[axis], b.low[axis]) || same(b.high[axis], a.low[axis]);
        let others = (0..3).filter(|&o| o != axis);
        touching && others.clone().all(|o| same(a.low[o], b.low[o]) && same(a.high[o], b.high[o]))
    })
}

/// Merges pairs of `boxes` until none is left that [`mergeable`] allows. `epsilon` is
/// the tolerance for faces that should coincide (leaf corners are sums of halvings, so
/// two routes to one plane may differ by an ulp). Quadratic per merge: it runs between
/// passes on a few hundred boxes.
pub(crate) fn merge_boxes(boxes: &mut Vec<MassBox>, ratio: f64, epsilon: f32) {
    let mut merged = true;
    while merged {
        merged = false;
        let mut i = 0;
        while i < boxes.len() {
            let mut j = i + 1;
            while j < boxes.len() {
                if mergeable(&boxes[i], &boxes[j], ratio, epsilon) {
                    let other = boxes.swap_remove(j);
                    let into = &mut boxes[i];
                    *into = MassBox {
                        low: into.low.min(other.low),
                        high: into.high.max(other.high),
                        mass: into.mass + other.mass,
                    };
                    merged = true;
                } else {
                    j += 1;
                }
            }
            i += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::vec;

    fn cube(low: Vec3, size: f32, mass: f64) -> MassBox {
        MassBox { low, high: low + Vec3::splat(size), mass }
    }

    #[test]
    fn a_column_of_like_cubes_becomes_one_box_and_unlike_ones_stay_apart() {
        // Five cubes stacked in y (one off by an ulp), a sixth beside them in x at a
        // tenth of their density, a seventh diagonal to the column.
        let mut boxes: Vec<MassBox> = (0..5).map(|k| cube(Vec3::new(0.0, 0.1 * k as f32, 0.0), 0.1, 1.0)).collect();
        boxes[2].low.y = f32::from_bits(boxes[2].low.y.to_bits() + 1);
        boxes.push(cube(Vec3::new(0.1, 0.0, 0.0), 0.1, 0.1));
        boxes.push(cube(Vec3::new(0.1, 0.5, 0.1), 0.1, 1.0));
        let total: f64 = boxes.iter().map(|b| b.mass).sum();
        merge_boxes(&mut boxes, 2.0, 1e-6);
        assert_eq!(boxes.len(), 3, "{boxes:?}");
        let column = boxes.iter().find(|b| b.mass == 5.0).expect("the column merged");
        assert!((column.high.y - 0.5).abs() < 1e-6 && (column.high.x - 0.1).abs() < 1e-6, "{column:?}");
        assert!((boxes.iter().map(|b| b.mass).sum::<f64>() - total).abs() < 1e-12, "mass is kept");
        // Ratio 1 merges only equal densities: the two equal cubes side by side do.
        let mut pair = vec![cube(Vec3::ZERO, 1.0, 2.0), cube(Vec3::X, 1.0, 2.0), cube(Vec3::Y, 1.0, 3.0)];
        merge_boxes(&mut pair, 1.0, 1e-6);
        assert_eq!(pair.len(), 2, "{pair:?}");
    }
}
