//! [`CellGrid`]: a regular grid of near-cubic cells over a box, sized from a byte budget;
//! the spatial index of the light and environment guides.

use glam::{IVec3, Vec3};

use crate::error::{require, Error};

/// Most cells a grid holds (the index is a u32 and tables stay addressable).
const MAX_CELLS: usize = 1 << 24;

/// A regular grid over `low..high`; points outside use the nearest cell.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CellGrid {
    low: Vec3,
    inverse_cell_size: Vec3,
    /// Cells per axis (i32: glam's unsigned vectors are not built here).
    resolution: IVec3,
}

impl CellGrid {
    /// A grid over `low..high` with `resolution` cells per axis if given, else as many
    /// near-cubic cells as `budget_bytes` holds at `bytes_per_cell` each. Errors name the
    /// bounds or the budget.
    pub(crate) fn new(
        low: Vec3,
        high: Vec3,
        resolution: Option<[u32; 3]>,
        budget_bytes: usize,
        bytes_per_cell: usize,
    ) -> Result<Self, Error> {
        if !(low.is_finite() && high.is_finite() && low.cmple(high).all()) {
            let value = (high - low).min_element() as f64;
            return Err(Error::InvalidSetting { name: "bounds", value, requirement: "finite with low ≤ high" });
        }
        let resolution = match resolution {
            Some(r) => IVec3::new(r[0] as i32, r[1] as i32, r[2] as i32),
            None => {
                let cells = budget_bytes / bytes_per_cell.max(1);
                if cells == 0 {
                    return Err(Error::BudgetTooSmall { budget_bytes, needed_bytes: bytes_per_cell });
                }
                resolution_for(high - low, cells.min(MAX_CELLS))
            }
        };
        let cells = (resolution.x as usize) * (resolution.y as usize) * (resolution.z as usize);
        let needed_bytes = cells.saturating_mul(bytes_per_cell);
        if needed_bytes > budget_bytes {
            return Err(Error::OverBudget { regions: cells, needed_bytes, budget_bytes });
        }
        // Degenerate (flat) extents get cells of the largest extent's size.
        let extent = (high - low).max(Vec3::splat((high - low).max_element().max(f32::MIN_POSITIVE) * 1e-6));
        Ok(Self { low, inverse_cell_size: resolution.as_vec3() / extent, resolution })
    }

    /// The index of the cell holding `position` (nearest cell outside the box); `None`
    /// for a non-finite position.
    #[inline]
    #[cfg_attr(not(any(feature = "lights", feature = "env", feature = "mixture")), allow(dead_code))]
    pub(crate) fn cell(&self, position: Vec3) -> Option<u32> {
        self.cell_and_offset(position).map(|(cell, _)| cell)
    }

    /// [`cell`](Self::cell), with `position`'s place inside the cell in [0, 1]³.
    #[inline]
    pub(crate) fn cell_and_offset(&self, position: Vec3) -> Option<(u32, Vec3)> {
        if !position.is_finite() {
            return None;
        }
        let scaled = ((position - self.low) * self.inverse_cell_size).max(Vec3::ZERO);
        let c = scaled.as_ivec3().min(self.resolution - 1);
        let offset = (scaled - c.as_vec3()).clamp(Vec3::ZERO, Vec3::ONE);
        Some((((c.z * self.resolution.y + c.y) * self.resolution.x + c.x) as u32, offset))
    }

    /// Cells along x, y and z.
    pub(crate) fn resolution(&self) -> [u32; 3] {
        self.resolution.to_array().map(|n| n as u32)
    }

    /// The box's low corner and the cells per unit length along each axis: cell
    /// coordinates are `(position - low) * inverse_cell_size`.
    #[cfg_attr(not(any(feature = "volume", feature = "mixture")), allow(dead_code))]
    pub(crate) fn transform(&self) -> (Vec3, Vec3) {
        (self.low, self.inverse_cell_size)
    }

    /// Number of cells.
    pub(crate) fn cell_count(&self) -> usize {
        (self.resolution.x * self.resolution.y * self.resolution.z) as usize
    }
}

/// Checks a grid resolution given by hand: 1..=1024 cells per axis.
pub(crate) fn validate_resolution(resolution: Option<[u32; 3]>) -> Result<(), Error> {
    for (axis, &n) in resolution.iter().flatten().enumerate() {
        let name = ["resolution.x", "resolution.y", "resolution.z"][axis];
        require((1..=1024).contains(&n), name, n as f64, "in 1..=1024")?;
    }
    Ok(())
}

/// Near-cubic cells: as many as `cells` allows over `extent`, at least one per axis.
fn resolution_for(extent: Vec3, cells: usize) -> IVec3 {
    let largest = extent.max_element();
    if largest.is_nan() || largest <= 0.0 {
        return IVec3::ONE;
    }
    // Relative to the largest side, in f64: a tiny box's products would underflow to 0
    // (and 0/0 cells per axis) in f32.
    let relative = |e: f32| (e as f64 / largest as f64).max(1e-3);
    let extent = [relative(extent.x), relative(extent.y), relative(extent.z)];
    let mut side = libm::cbrt(extent[0] * extent[1] * extent[2] / cells as f64);
    loop {
        let [x, y, z] = extent.map(|e| libm::floor(e / side).clamp(1.0, 1024.0) as i32);
        let r = IVec3::new(x, y, z);
        if (r.x as usize) * (r.y as usize) * (r.z as usize) <= cells {
            return r;
        }
        side *= 1.05;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_follow_the_budget_and_clamp_outside_points() {
        let grid = CellGrid::new(Vec3::ZERO, Vec3::new(4.0, 2.0, 1.0), None, 1 << 10, 8).unwrap();
        let [x, y, z] = grid.resolution();
        assert!(x >= y && y >= z && grid.cell_count() <= 128 && grid.cell_count() >= 64, "{x}×{y}×{z}");
        assert_eq!(grid.cell(Vec3::splat(-1e30)), Some(0));
        assert_eq!(grid.cell(Vec3::splat(1e30)), Some(grid.cell_count() as u32 - 1));
        assert_eq!(grid.cell(Vec3::NAN), None);
        // A flat box still has cells.
        let flat = CellGrid::new(Vec3::ZERO, Vec3::new(1.0, 0.0, 1.0), None, 1 << 10, 8).unwrap();
        assert!(flat.cell_count() > 1);
        // A box of denormal size has cells on every axis (found by the capi_calls fuzzer:
        // its f32 volume underflowed and an axis got none).
        let tiny = CellGrid::new(Vec3::ZERO, Vec3::new(0.0, 0.0, 1.65e-43), None, 1 << 16, 8).unwrap();
        assert!(tiny.resolution().iter().all(|&n| n >= 1), "{:?}", tiny.resolution());
        assert!(tiny.cell(Vec3::new(0.0, 0.0, 1.5784e-41)).unwrap() < tiny.cell_count() as u32);
        assert!(matches!(CellGrid::new(Vec3::ONE, Vec3::ZERO, None, 64, 8), Err(Error::InvalidSetting { .. })));
        assert!(matches!(CellGrid::new(Vec3::ZERO, Vec3::ONE, None, 4, 8), Err(Error::BudgetTooSmall { .. })));
        assert!(matches!(CellGrid::new(Vec3::ZERO, Vec3::ONE, Some([4, 4, 4]), 64, 8), Err(Error::OverBudget { .. })));
    }
}
