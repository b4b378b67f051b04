//! Checks that a table structure (the hemisphere grid, the irradiance volume) makes of
//! its Q values and CDF rows when it validates, after decoding or merging.

use core::sync::atomic::AtomicU32;

use crate::atomic_f32;
use crate::bytes::invalid_field;
use crate::cdf::PROBABILITY_QUANTUM;
use crate::error::Error;

/// Every Q finite and at least `floor` (radiance); the first one that is not is named.
pub(crate) fn check_q(q: &[AtomicU32], floor: f32) -> Result<(), Error> {
    match q.iter().map(atomic_f32::load).position(|q| !(q.is_finite() && q >= floor)) {
        Some(i) => Err(invalid_field("q", i, "finite and at least q_floor")),
        None => Ok(()),
    }
}

/// Every row of `entries` CDF values non-decreasing multiples of 2⁻²⁴ in [0, 1], ending
/// at 1; the first value that is not is named.
pub(crate) fn check_cdf_rows(cdf: &[f32], entries: usize) -> Result<(), Error> {
    for (row_index, row) in cdf.chunks_exact(entries).enumerate() {
        let mut previous = 0.0;
        for (k, &c) in row.iter().enumerate() {
            if !(c >= previous && c <= 1.0) || c != libm::roundf(c / PROBABILITY_QUANTUM) * PROBABILITY_QUANTUM {
                return Err(invalid_field(
                    "cdf",
                    row_index * entries + k,
                    "non-decreasing multiples of 2^-24 in [0, 1]",
                ));
            }
            previous = c;
        }
        if previous != 1.0 {
            return Err(invalid_field("cdf", row_index * entries + entries - 1, "ending at 1"));
        }
    }
    Ok(())
}
