//! [`EnvironmentTiles`]: a lat-long map's texels grouped into rectangular tiles, each
//! with the CDF that picks a texel inside it by luminance × sin θ (its share of the
//! tile's power), and each tile's power.

use core::f32::consts::PI;

use alloc::vec;
use alloc::vec::Vec;
use glam::{Vec2, Vec3};

use crate::cdf::{build_cdf, build_cdf_guide, cdf_probability, sample_cdf_guided};
use crate::error::{require, Error};

use super::lat_long::{direction_of_uv, sin_theta, texel_density, texel_of_direction};

/// Most texels a map may have (a 16k × 8k map).
pub const MAX_TEXELS: usize = 1 << 27;

/// Guide-table entries per tile ([`build_cdf_guide`]): a tile of a 2k × 1k map cut
/// 32 × 16 holds 4096 texels, whose CDF a whole binary search crossed in 12 dependent
/// loads, most of them cache misses (a quarter of nee's time on the living room); 64
/// entries (256 bytes a tile) leave a search among a few dozen.
const GUIDE_ENTRIES: usize = 64;

/// The tiles of a `width × height` lat-long map and the texel distribution inside each.
///
/// Sampling tile t then a texel inside it (then a point uniform in (u, v) within the
/// texel) has density P(texel | t)·W·H/(2π² sin θ) per steradian given t; with tiles
/// chosen in proportion to [`power`](Self::power) this is exactly plain luminance
/// importance sampling of the map.
///
/// ```
/// use guiding_core::environment::EnvironmentTiles;
/// use glam::Vec2;
/// // A 4 × 2 map, bright in one texel, cut into 2 × 1 tiles.
/// let luminance = [0.0, 0.0, 9.0, 0.0, 1.0, 1.0, 1.0, 1.0];
/// let tiles = EnvironmentTiles::new(4, 2, &luminance, [2, 1])?;
/// assert_eq!(tiles.tile_count(), 2);
/// let (d, pdf) = tiles.sample_in_tile(1, Vec2::new(0.5, 0.5));
/// assert_eq!(tiles.tile_of(d), 1);
/// assert!(pdf > 0.0 && pdf == tiles.pdf_in_tile(1, d));
/// # Ok::<(), guiding_core::Error>(())
/// ```
#[derive(Clone, Debug)]
pub struct EnvironmentTiles {
    width: usize,
    height: usize,
    /// Tiles across (u) and down (v).
    tiles: [usize; 2],
    /// Per tile, in tile order: the CDF over its texels, row by row.
    texel_cdf: Vec<f32>,
    /// Start of each tile's texels in `texel_cdf` (one more entry than tiles).
    tile_start: Vec<usize>,
    /// Per tile, [`GUIDE_ENTRIES`] entries of its CDF's guide table.
    texel_guide: Vec<u32>,
    /// Per tile: Σ luminance × texel solid angle (luminance × steradians).
    power: Vec<f32>,
}

impl EnvironmentTiles {
    /// Tiles of a `width × height` map with per-texel `luminance` (row-major, top row
    /// first; finite, ≥ 0), cut into `tiles = [across, down]` (each clamped to the map's
    /// size). Errors name the offending size or texel.
    pub fn new(width: usize, height: usize, luminance: &[f32], tiles: [u32; 2]) -> Result<Self, Error> {
        let texels = width.saturating_mul(height);
        require(texels > 0 && texels <= MAX_TEXELS, "map texels", texels as f64, "in 1..=2^27")?;
        require(luminance.len() == texels, "luminance length", luminance.len() as f64, "width × height")?;
        if let Some(&bad) = luminance.iter().find(|l| !(l.is_finite() && **l >= 0.0)) {
            require(false, "texel luminance", bad as f64, "finite and ≥ 0")?;
        }
        require(tiles[0] >= 1 && tiles[1] >= 1, "tiles", tiles[0].min(tiles[1]) as f64, "at least 1 per axis")?;
        let tiles = [(tiles[0] as usize).min(width), (tiles[1] as usize).min(height)];
        let texel_solid_angle = 2.0 * PI * PI / texels as f32;
        let row_sin_theta = |row: usize| libm::sinf(PI * (row as f32 + 0.5) / height as f32);
        let mut texel_cdf = vec![0.0; texels];
        let mut tile_start = Vec::with_capacity(tiles[0] * tiles[1] + 1);
        let mut power = Vec::with_capacity(tiles[0] * tiles[1]);
        let mut texel_guide = Vec::with_capacity(tiles[0] * tiles[1] * GUIDE_ENTRIES);
        let mut start = 0;
        for tile_row in 0..tiles[1] {
            let rows = span(tile_row, tiles[1], height);
            for tile_column in 0..tiles[0] {
                let columns = span(tile_column, tiles[0], width);
                let tile_width = columns.len();
                let weight = |k: usize| {
                    let (row, column) = (rows.start + k / tile_width, columns.start + k % tile_width);
                    luminance[row * width + column] * row_sin_theta(row)
                };
                let count = rows.len() * tile_width;
                build_cdf(&mut texel_cdf[start..start + count], 0.0, weight);
                let guide = texel_guide.len();
                texel_guide.resize(guide + GUIDE_ENTRIES, 0);
                build_cdf_guide(&texel_cdf[start..start + count], &mut texel_guide[guide..]);
                let total: f64 = (0..count).map(|k| weight(k) as f64).sum();
                power.push((total * texel_solid_angle as f64) as f32);
                tile_start.push(start);
                start += count;
            }
        }
        tile_start.push(start);
        Ok(Self { width, height, tiles, texel_cdf, tile_start, texel_guide, power })
    }

    /// Number of tiles.
    pub fn tile_count(&self) -> usize {
        self.power.len()
    }

    /// Tiles across (u) and down (v).
    pub fn tiles(&self) -> [usize; 2] {
        self.tiles
    }

    /// Power of tile `t`: Σ luminance × texel solid angle (luminance × steradians).
    pub fn power(&self, t: usize) -> f32 {
        self.power[t]
    }

    /// The map's size in texels, (width, height).
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Bytes held.
    pub fn memory_bytes(&self) -> usize {
        (self.texel_cdf.len() + self.power.len() + self.texel_guide.len()) * 4
            + self.tile_start.len() * core::mem::size_of::<usize>()
    }

    /// The tile that direction `d` (unit) falls in, and the index of its texel within it.
    #[inline]
    fn locate(&self, d: Vec3) -> (usize, usize, usize) {
        let (column, row) = texel_of_direction(d, self.width, self.height);
        // Tile index by inverting `span`: the last tile whose start is ≤ the texel.
        let tile_column = ((column + 1) * self.tiles[0] - 1) / self.width;
        let tile_row = ((row + 1) * self.tiles[1] - 1) / self.height;
        let columns = span(tile_column, self.tiles[0], self.width);
        let rows = span(tile_row, self.tiles[1], self.height);
        let tile = tile_row * self.tiles[0] + tile_column;
        (tile, (row - rows.start) * columns.len() + (column - columns.start), row)
    }

    /// The tile that direction `d` (unit) falls in.
    #[inline]
    pub fn tile_of(&self, d: Vec3) -> usize {
        self.locate(d).0
    }

    /// A direction in tile `t`: a texel by its CDF from `u.x`, then uniform in (u, v)
    /// inside it from the rest of `u.x` and `u.y`. Returns the direction and its density
    /// given the tile, per steradian (what [`pdf_in_tile`](Self::pdf_in_tile) reports for
    /// it, unless rounding put it across a texel border).
    #[inline]
    pub fn sample_in_tile(&self, t: usize, u: Vec2) -> (Vec3, f32) {
        let [tx, ty] = self.tiles;
        let (columns, rows) = (span(t % tx, tx, self.width), span(t / tx, ty, self.height));
        let cdf = &self.texel_cdf[self.tile_start[t]..self.tile_start[t + 1]];
        let (k, u_column) = sample_cdf_guided(cdf, &self.texel_guide[t * GUIDE_ENTRIES..(t + 1) * GUIDE_ENTRIES], u.x);
        let column = columns.start + k % columns.len();
        let row = rows.start + k / columns.len();
        // Kept off the poles, where dω = 2π² sin θ du dv has no density: a direction there
        // would come with pdf 0 (found by the capi_calls fuzzer at u.y = 0).
        let v = ((row as f32 + u.y) / self.height as f32).clamp(POLE_MARGIN, 1.0 - POLE_MARGIN);
        let uv = Vec2::new((column as f32 + u_column) / self.width as f32, v);
        let direction = direction_of_uv(uv);
        (direction, self.texel_pdf(t, k, direction))
    }

    /// Density per steradian of [`sample_in_tile`](Self::sample_in_tile)`(t, ·)` at
    /// direction `d` (unit): 0 outside tile t and within about 10⁻⁶ rad of the poles,
    /// where nothing is sampled.
    #[inline]
    pub fn pdf_in_tile(&self, t: usize, d: Vec3) -> f32 {
        let (tile, k, _) = self.locate(d);
        if tile != t {
            return 0.0;
        }
        self.texel_pdf(tile, k, d)
    }

    /// The tile of `d` and the density of `d` given that tile.
    #[inline]
    pub fn tile_and_pdf(&self, d: Vec3) -> (usize, f32) {
        let (tile, k, _) = self.locate(d);
        (tile, self.texel_pdf(tile, k, d))
    }

    #[inline]
    fn texel_pdf(&self, tile: usize, k: usize, d: Vec3) -> f32 {
        let sin_theta = sin_theta(d);
        // Nothing is sampled this close to a pole (POLE_MARGIN), and 1/sin θ would reach ∞
        // (and ∞·0 = NaN) there.
        if sin_theta < MIN_SAMPLED_SIN_THETA {
            return 0.0;
        }
        let p = cdf_probability(&self.texel_cdf[self.tile_start[tile]..self.tile_start[tile + 1]], k);
        p * texel_density(self.width, self.height, sin_theta)
    }
}

/// How far in v a sampled direction stays from either pole: sin θ ≈ 3·10⁻⁶, so its
/// density stays finite and positive in f32.
const POLE_MARGIN: f32 = 1e-6;

/// Half the least sin θ a sampled direction has (sin(π·POLE_MARGIN) ≈ 3.1·10⁻⁶): closer
/// to a pole the density is 0.
const MIN_SAMPLED_SIN_THETA: f32 = 1.5e-6;

/// The texels `[i·n/parts, (i+1)·n/parts)` of part `i` of `n` texels cut in `parts`.
#[inline]
fn span(i: usize, parts: usize, n: usize) -> core::ops::Range<usize> {
    i * n / parts..(i + 1) * n / parts
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::low_discrepancy::Pcg32;

    fn test_map(width: usize, height: usize) -> Vec<f32> {
        (0..width * height).map(|i| if i % 7 == 3 { 50.0 } else { (i % 5) as f32 * 0.3 }).collect()
    }

    #[test]
    fn every_texel_belongs_to_exactly_one_tile() {
        for (w, h, tiles) in [(16, 8, [4, 2]), (17, 9, [5, 4]), (3, 2, [8, 8]), (1, 1, [1, 1]), (64, 32, [7, 3])] {
            let t = EnvironmentTiles::new(w, h, &test_map(w, h), tiles).unwrap();
            let mut seen = vec![false; w * h];
            for row in 0..h {
                for column in 0..w {
                    let uv = Vec2::new((column as f32 + 0.5) / w as f32, (row as f32 + 0.5) / h as f32);
                    let (tile, k, _) = t.locate(direction_of_uv(uv));
                    let index = t.tile_start[tile] + k;
                    assert!(
                        index < t.tile_start[tile + 1] && !seen[index],
                        "{w}×{h} {tiles:?}: texel ({column}, {row})"
                    );
                    seen[index] = true;
                }
            }
            assert!(seen.iter().all(|&s| s));
        }
    }

    #[test]
    fn tile_powers_add_up_to_the_maps_integral() {
        let (w, h) = (64, 32);
        let luminance = test_map(w, h);
        let t = EnvironmentTiles::new(w, h, &luminance, [8, 4]).unwrap();
        let total: f64 = (0..t.tile_count()).map(|i| t.power(i) as f64).sum();
        // ∫ L dω by a fine quadrature over the sphere.
        let mut quadrature = 0.0f64;
        let steps = 1024;
        for i in 0..steps {
            for j in 0..steps {
                let uv = Vec2::new((j as f32 + 0.5) / steps as f32, (i as f32 + 0.5) / steps as f32);
                let (column, row) = texel_of_direction(direction_of_uv(uv), w, h);
                let sin_theta = libm::sin(core::f64::consts::PI * uv.y as f64);
                quadrature += luminance[row * w + column] as f64 * sin_theta;
            }
        }
        quadrature *= 2.0 * core::f64::consts::PI * core::f64::consts::PI / (steps * steps) as f64;
        assert!((total - quadrature).abs() < 2e-3 * quadrature, "{total} vs {quadrature}");
    }

    #[test]
    fn samples_in_a_tile_stay_there_and_match_their_pdf() {
        let (w, h) = (40, 20);
        let t = EnvironmentTiles::new(w, h, &test_map(w, h), [5, 3]).unwrap();
        let mut rng = Pcg32::new(9, 9);
        for tile in 0..t.tile_count() {
            for _ in 0..2000 {
                let (d, sampled_pdf) = t.sample_in_tile(tile, rng.next_vec2());
                assert!((d.length() - 1.0).abs() < 1e-5);
                let (found, pdf) = t.tile_and_pdf(d);
                assert_eq!(found, tile);
                assert!(pdf > 0.0 && pdf == t.pdf_in_tile(tile, d) && pdf == sampled_pdf);
            }
        }
    }

    #[test]
    fn samples_at_the_edges_of_the_unit_square_keep_a_positive_pdf() {
        let (w, h) = (4, 2);
        let t = EnvironmentTiles::new(w, h, &[1.0; 8], [2, 2]).unwrap();
        for tile in 0..t.tile_count() {
            for u in [Vec2::ZERO, Vec2::ONE, Vec2::new(0.0, 1.0), Vec2::new(1.0, 0.0)] {
                let (d, pdf) = t.sample_in_tile(tile, u);
                // (u = 1 lies on the tile's far border, which rounding may put across.)
                assert!(pdf.is_finite() && pdf > 0.0, "tile {tile}, u {u}: {d} with pdf {pdf}");
                assert_eq!(t.tile_and_pdf(d).1, pdf);
            }
        }
    }

    #[test]
    fn directions_at_and_near_the_poles_have_a_finite_pdf() {
        let t = EnvironmentTiles::new(4, 2, &[1.0; 8], [2, 2]).unwrap();
        for d in [Vec3::Y, Vec3::NEG_Y, Vec3::new(1e-40, 1.0, 0.0), Vec3::new(0.0, -1.0, 1e-7)] {
            let (_, pdf) = t.tile_and_pdf(d);
            assert!(pdf.is_finite() && pdf >= 0.0, "{d}: {pdf}");
        }
    }

    #[test]
    fn bad_maps_are_rejected_by_name() {
        let name = |r: Result<EnvironmentTiles, Error>| match r {
            Err(Error::InvalidSetting { name, .. }) => name,
            _ => "",
        };
        assert_eq!(name(EnvironmentTiles::new(0, 4, &[], [1, 1])), "map texels");
        assert_eq!(name(EnvironmentTiles::new(2, 2, &[1.0; 3], [1, 1])), "luminance length");
        assert_eq!(name(EnvironmentTiles::new(2, 1, &[1.0, f32::NAN], [1, 1])), "texel luminance");
        assert_eq!(name(EnvironmentTiles::new(2, 1, &[1.0, -1.0], [1, 1])), "texel luminance");
        assert_eq!(name(EnvironmentTiles::new(2, 1, &[1.0, 1.0], [0, 1])), "tiles");
    }
}
