//! [`CoarseGrid`]: a regular grid of cubic cells over a box, a given number along its
//! longest side; the spatial index of the learned shares and the learned roulette.

use glam::Vec3;

use crate::error::Error;

/// Cubic cells over a box, `resolution` along the longest side and the other sides in
/// proportion (at least one each); points outside use the nearest cell.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CoarseGrid {
    cells: [u32; 3],
    low: Vec3,
    /// Cells per unit length: a multiply per lookup instead of three divides.
    cells_per_unit: f32,
}

impl CoarseGrid {
    /// The grid over `low..high` (finite, high ≥ low), `resolution` (≥ 1, its owner's
    /// setting, checked there) cells along the longest side.
    pub(crate) fn new(low: Vec3, high: Vec3, resolution: u32) -> Result<Self, Error> {
        let resolution = resolution.max(1);
        if !(low.is_finite() && high.is_finite() && high.cmpge(low).all()) {
            return Err(Error::InvalidSetting {
                name: "bounds",
                value: f64::NAN,
                requirement: "finite, with high ≥ low on every axis",
            });
        }
        let extent = (high - low).max(Vec3::splat(1e-6));
        let cell_size = extent.max_element() / resolution as f32;
        let counts = (extent / cell_size).ceil().max(Vec3::ONE);
        Ok(Self { cells: [counts.x as u32, counts.y as u32, counts.z as u32], low, cells_per_unit: 1.0 / cell_size })
    }

    /// Cells in the grid.
    #[inline]
    pub(crate) fn len(&self) -> usize {
        self.cells.iter().product::<u32>() as usize
    }

    /// The cell holding `point` (clamped into the grid); `None` for a non-finite point.
    #[inline]
    pub(crate) fn cell(&self, point: Vec3) -> Option<usize> {
        if !point.is_finite() {
            return None;
        }
        let local = ((point - self.low) * self.cells_per_unit).max(Vec3::ZERO);
        let [nx, ny, nz] = self.cells;
        let (x, y, z) = ((local.x as u32).min(nx - 1), (local.y as u32).min(ny - 1), (local.z as u32).min(nz - 1));
        Some((x + nx * (y + ny * z)) as usize)
    }

    /// The cell holding `point` (clamped into the grid) numbered with the coordinate along
    /// world axis `axis` (0, 1 or 2) varying slowest: the cells of one layer across that
    /// axis (a wall facing along it) are then consecutive. Each axis numbers all cells
    /// once, from 0 to [`len`](Self::len); `None` for a non-finite point.
    #[inline]
    pub(crate) fn cell_in_layers(&self, point: Vec3, axis: u32) -> Option<usize> {
        if !point.is_finite() {
            return None;
        }
        let local = ((point - self.low) * self.cells_per_unit).max(Vec3::ZERO);
        let [nx, ny, nz] = self.cells;
        let (x, y, z) = ((local.x as u32).min(nx - 1), (local.y as u32).min(ny - 1), (local.z as u32).min(nz - 1));
        Some(match axis {
            0 => y + ny * (z + nz * x),
            1 => x + nx * (z + nz * y),
            _ => x + nx * (y + ny * z),
        } as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_follow_the_longest_side_and_clamp_points_outside() {
        let grid = CoarseGrid::new(Vec3::ZERO, Vec3::new(4.0, 2.0, 1.0), 4).unwrap();
        assert_eq!(grid.len(), 4 * 2);
        assert_eq!(grid.cell(Vec3::new(0.5, 0.5, 0.5)), Some(0));
        assert_eq!(grid.cell(Vec3::new(3.5, 1.5, 0.5)), Some(7));
        assert_eq!(grid.cell(Vec3::new(-9.0, 9.0, 0.5)), Some(4));
        assert_eq!(grid.cell(Vec3::NAN), None);
        // Numbered in layers across each axis: every cell once, and a layer consecutive.
        for axis in 0..3 {
            let mut seen = [false; 8];
            for (x, y, z) in [(0.5, 0.5, 0.5), (1.5, 0.5, 0.5), (2.5, 0.5, 0.5), (3.5, 0.5, 0.5)]
                .into_iter()
                .flat_map(|(x, y, z)| [(x, y, z), (x, y + 1.0, z)])
            {
                let cell = grid.cell_in_layers(Vec3::new(x, y, z), axis).unwrap();
                assert!(!seen[cell], "cell {cell} numbered twice along axis {axis}");
                seen[cell] = true;
            }
        }
        let wall: alloc::vec::Vec<usize> =
            (0..2).map(|y| grid.cell_in_layers(Vec3::new(2.5, y as f32 + 0.5, 0.5), 0).unwrap()).collect();
        assert_eq!(wall, [4, 5], "the layer x = 2 is cells 4 and 5");
        assert_eq!(grid.cell_in_layers(Vec3::NAN, 1), None);
        let err = CoarseGrid::new(Vec3::ONE, Vec3::ZERO, 4).unwrap_err();
        assert!(alloc::format!("{err}").contains("bounds"));
    }
}
