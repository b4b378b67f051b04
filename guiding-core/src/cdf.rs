//! Discrete distributions stored as cumulative distribution functions (CDFs) and
//! sampled by inversion.
//!
//! A CDF here is a slice `cdf` of length N with `cdf[k] = P(index ≤ k)` and
//! `cdf[N-1] = 1`. Every value is a multiple of 2⁻²⁴, the resolution of a 24-bit uniform
//! number: the probability that [`sample_cdf`] returns `k` for a uniform `u` is then
//! exactly `cdf[k] - cdf[k-1]`, which is what [`cdf_probability`] reports, so a sampler
//! and its pdf never disagree. Sums are taken in f64, so entries far smaller than the
//! total are not lost to rounding while the CDF is accumulated; an entry below 2⁻²⁵
//! of the total can still round to probability 0, and then it is never sampled either.

/// The quantum of every stored probability: 2⁻²⁴.
pub const PROBABILITY_QUANTUM: f32 = 1.0 / (1u32 << 24) as f32;

const QUANTA: f64 = (1u32 << 24) as f64;

/// Fills `cdf` with the CDF of `p_k = (1 - uniform_mix)·w_k/W + uniform_mix/N`, where
/// `w_k = weight(k)` and `W = Σ w_k`.
///
/// Weights must be finite and non-negative (callers clamp them); if they sum to zero the
/// distribution is uniform. `uniform_mix` in [0, 1] is a defensive share spread evenly
/// over all entries, which keeps every probability at least `uniform_mix/N`.
pub fn build_cdf(cdf: &mut [f32], uniform_mix: f32, weight: impl Fn(usize) -> f32) {
    let count = cdf.len();
    if count == 0 {
        return;
    }
    let total: f64 = (0..count).map(|k| weight(k) as f64).sum();
    let mix = if total > 0.0 { uniform_mix.clamp(0.0, 1.0) as f64 } else { 1.0 };
    // Accumulate directly in quanta (2⁻²⁴ units): every stored value is then an integer
    // count of quanta, converted exactly to f32.
    let scale = if total > 0.0 { (1.0 - mix) / total * QUANTA } else { 0.0 };
    let uniform = mix / count as f64 * QUANTA;
    let mut cumulative = 0.0f64;
    for (k, slot) in cdf.iter_mut().enumerate() {
        cumulative += weight(k) as f64 * scale + uniform;
        // Round to the nearest quantum: the value is non-negative, so adding ½ and
        // truncating rounds (and is far cheaper than a software `round`).
        let quanta = ((cumulative + 0.5) as u64).min(1 << 24);
        *slot = quanta as f32 * PROBABILITY_QUANTUM;
    }
    cdf[count - 1] = 1.0;
}

/// Inverts the CDF at `u` in [0, 1): returns the index `k` with
/// `cdf[k-1] ≤ u < cdf[k]` and `u` rescaled to [0, 1) inside that interval, so the
/// caller can reuse it as a fresh uniform number.
pub fn sample_cdf(cdf: &[f32], u: f32) -> (usize, f32) {
    let last = cdf.len() - 1;
    let index = cdf.partition_point(|&c| c <= u).min(last);
    (index, remap(cdf, index, u))
}

/// `u` rescaled to [0, 1) inside entry `index`'s interval of `cdf`.
#[inline]
fn remap(cdf: &[f32], index: usize, u: f32) -> f32 {
    let low = if index == 0 { 0.0 } else { cdf[index - 1] };
    let width = cdf[index] - low;
    let remapped = if width > 0.0 { (u - low) / width } else { 0.0 };
    remapped.clamp(0.0, 1.0 - f32::EPSILON / 2.0)
}

/// Fills `guide` (its length a power of two, G) with the guide table of `cdf`: entry j
/// is the first index whose CDF value exceeds j/G. [`sample_cdf_guided`] then searches
/// only between two entries, a few values of a long CDF instead of all of it (the
/// texels of an environment map's tile, where the whole search missed the cache at
/// every level). `cdf` must not be empty.
pub fn build_cdf_guide(cdf: &[f32], guide: &mut [u32]) {
    debug_assert!(guide.len().is_power_of_two());
    let buckets = guide.len() as f32;
    let last = cdf.len().saturating_sub(1);
    for (j, entry) in guide.iter_mut().enumerate() {
        // j/G is exact in f32 for a power-of-two G, as is u·G in the sampler.
        let threshold = j as f32 / buckets;
        *entry = cdf.partition_point(|&c| c <= threshold).min(last) as u32;
    }
}

/// [`sample_cdf`] through the guide table [`build_cdf_guide`] made for `cdf`: the same
/// index and rescaled number for every `u`, found by a search between two guide entries.
pub fn sample_cdf_guided(cdf: &[f32], guide: &[u32], u: f32) -> (usize, f32) {
    let last = cdf.len() - 1;
    let buckets = guide.len();
    // The index k sought has cdf[k - 1] ≤ u < cdf[k]; with j/G ≤ u < (j + 1)/G it lies
    // at or after guide[j] (cdf[guide[j] - 1] ≤ j/G) and at or before guide[j + 1]
    // (cdf[guide[j + 1]] > (j + 1)/G), or the last index.
    let j = ((u * buckets as f32) as usize).min(buckets - 1);
    let low = (guide[j] as usize).min(last);
    let high = guide.get(j + 1).map_or(last, |&g| (g as usize).min(last)).max(low);
    let index = low + cdf[low..=high].partition_point(|&c| c <= u).min(high - low);
    (index, remap(cdf, index, u))
}

/// The probability of index `k`: `cdf[k] - cdf[k-1]` (exact, a multiple of 2⁻²⁴).
pub fn cdf_probability(cdf: &[f32], index: usize) -> f32 {
    let low = if index == 0 { 0.0 } else { cdf[index - 1] };
    cdf[index] - low
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::low_discrepancy::Pcg32;
    use alloc::vec;
    use alloc::vec::Vec;

    #[test]
    fn the_guided_search_finds_what_the_whole_search_finds() {
        let mut rng = Pcg32::new(21, 4);
        for (count, buckets) in [(1usize, 4usize), (3, 64), (100, 8), (4096, 64), (5000, 1)] {
            // Long runs of empty entries and a few spikes, as a map's tile has.
            let weights: Vec<f32> = (0..count)
                .map(|_| {
                    let r = rng.next_f32();
                    if r < 0.5 {
                        0.0
                    } else if r < 0.52 {
                        1e4
                    } else {
                        r
                    }
                })
                .collect();
            let mut cdf = vec![0.0; count];
            build_cdf(&mut cdf, 0.0, |k| weights[k]);
            let mut guide = vec![0u32; buckets];
            build_cdf_guide(&cdf, &mut guide);
            let edges = (0..buckets).flat_map(|j| {
                let edge = j as f32 / buckets as f32;
                [edge, f32::from_bits(edge.to_bits().saturating_sub(1)).max(0.0)]
            });
            let values: Vec<f32> = edges.chain(cdf.iter().copied().filter(|&c| c < 1.0)).collect();
            for u in values.into_iter().chain((0..20_000).map(|_| rng.next_f32())) {
                assert_eq!(sample_cdf_guided(&cdf, &guide, u), sample_cdf(&cdf, u), "u {u}, {count} entries");
            }
        }
    }

    #[test]
    fn probabilities_follow_the_weights() {
        let weights = [1.0f32, 0.0, 3.0, 4.0];
        let mut cdf = [0.0; 4];
        build_cdf(&mut cdf, 0.0, |k| weights[k]);
        let p: Vec<f32> = (0..4).map(|k| cdf_probability(&cdf, k)).collect();
        assert_eq!(p, [0.125, 0.0, 0.375, 0.5]);
        assert_eq!(cdf[3], 1.0);
    }

    #[test]
    fn uniform_mix_keeps_every_entry_positive() {
        let mut cdf = [0.0; 4];
        build_cdf(&mut cdf, 0.2, |k| if k == 0 { 1.0 } else { 0.0 });
        assert!((cdf_probability(&cdf, 0) - 0.85).abs() < 1e-6);
        for k in 1..4 {
            assert!((cdf_probability(&cdf, k) - 0.05).abs() < 1e-6);
        }
    }

    #[test]
    fn zero_weights_give_a_uniform_distribution() {
        let mut cdf = [0.0; 8];
        build_cdf(&mut cdf, 0.0, |_| 0.0);
        for k in 0..8 {
            assert_eq!(cdf_probability(&cdf, k), 0.125);
        }
    }

    #[test]
    fn zero_probability_entries_are_never_sampled() {
        let weights = [0.0f32, 2.0, 0.0, 0.0, 1.0, 0.0];
        let mut cdf = [0.0; 6];
        build_cdf(&mut cdf, 0.0, |k| weights[k]);
        let mut rng = Pcg32::new(1, 1);
        for _ in 0..10_000 {
            let (k, rest) = sample_cdf(&cdf, rng.next_f32());
            assert!(k == 1 || k == 4);
            assert!((0.0..1.0).contains(&rest));
        }
        assert_eq!(sample_cdf(&cdf, 0.0).0, 1);
        assert_eq!(sample_cdf(&cdf, 1.0 - PROBABILITY_QUANTUM).0, 4);
    }

    /// One huge weight ahead of many small ones, and weights spanning 1e-30…1e30: every
    /// stored probability is within one quantum (2⁻²⁴) of its exact share, so no entry
    /// that a 24-bit uniform number can reach is lost while the CDF is accumulated.
    #[test]
    fn small_entries_after_a_huge_one_are_not_lost() {
        let mut weights = vec![1.0f32; 1024];
        weights[0] = (1u32 << 14) as f32;
        let mut cdf = vec![0.0; weights.len()];
        build_cdf(&mut cdf, 0.0, |k| weights[k]);
        let total: f64 = weights.iter().map(|&w| w as f64).sum();
        for (k, &w) in weights.iter().enumerate() {
            let exact = w as f64 / total;
            let stored = cdf_probability(&cdf, k) as f64;
            assert!((stored - exact).abs() <= PROBABILITY_QUANTUM as f64, "{k}: {stored} vs {exact}");
            assert!(stored > 0.0);
        }
        let extreme: Vec<f32> = (0..61).map(|i| libm::powf(10.0, (i - 30) as f32)).collect();
        let mut cdf = vec![0.0; extreme.len()];
        build_cdf(&mut cdf, 0.0, |k| extreme[k]);
        let total: f64 = extreme.iter().map(|&w| w as f64).sum();
        for (k, &w) in extreme.iter().enumerate() {
            let exact = w as f64 / total;
            let stored = cdf_probability(&cdf, k) as f64;
            assert!((stored - exact).abs() <= PROBABILITY_QUANTUM as f64, "{k}: {stored} vs {exact}");
        }
        // With a defensive share every entry stays reachable, however small its weight.
        build_cdf(&mut cdf, 0.01, |k| extreme[k]);
        assert!((0..extreme.len()).all(|k| cdf_probability(&cdf, k) > 0.0));
    }
}
