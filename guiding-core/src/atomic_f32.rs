//! f32 values stored in `AtomicU32`, updated lock-free by compare-exchange.

use core::sync::atomic::{AtomicU32, Ordering};

/// An `AtomicU32` holding the bits of `value`.
#[cfg_attr(not(any(feature = "hemisphere", feature = "lights", feature = "env", feature = "volume")), allow(dead_code))]
pub(crate) fn new(value: f32) -> AtomicU32 {
    AtomicU32::new(value.to_bits())
}

/// The current value; relaxed, since Q values carry no ordering with other memory.
pub(crate) fn load(cell: &AtomicU32) -> f32 {
    f32::from_bits(cell.load(Ordering::Relaxed))
}

/// Replaces the value by `next(current)` atomically, retrying when another thread
/// changed it in between, so no update is lost and no value is ever torn.
/// Returns the value replaced and the value stored.
pub(crate) fn update(cell: &AtomicU32, next: impl Fn(f32) -> f32) -> (f32, f32) {
    let mut current = cell.load(Ordering::Relaxed);
    loop {
        let replacement = next(f32::from_bits(current)).to_bits();
        match cell.compare_exchange_weak(current, replacement, Ordering::Relaxed, Ordering::Relaxed) {
            Ok(_) => return (f32::from_bits(current), f32::from_bits(replacement)),
            Err(actual) => current = actual,
        }
    }
}

/// Adds one to a counter, saturating at `u32::MAX` instead of wrapping (a wrapped visit
/// count would reset α = 1/(1+visits) to 1). Returns the count before the increment.
pub(crate) fn increment_saturating(counter: &AtomicU32) -> u32 {
    match counter.fetch_update(Ordering::Relaxed, Ordering::Relaxed, |v| v.checked_add(1)) {
        Ok(previous) | Err(previous) => previous,
    }
}

/// One step of a running average: counts the sample in `count` and blends `target` into
/// `value` with α = 1/(1+n), n the count before, so `value` is the mean of all targets.
#[cfg(any(feature = "lights", feature = "env"))]
pub(crate) fn running_average(value: &AtomicU32, count: &AtomicU32, target: f32) {
    let n = increment_saturating(count);
    let alpha = (1.0 / (1.0 + n as f64)) as f32;
    update(value, |v| crate::update_rule::blend(v, target, alpha, 0.0));
}

/// Adds what other running averages learned to these, entry by entry: each merged value
/// is the mean over both sets of targets, (v·n + v'·n') / (n + n'), and the counts add
/// (saturating). Exact: a running average is a sum and a count.
#[cfg(any(feature = "lights", feature = "env"))]
pub(crate) fn merge_running_averages(
    values: &[AtomicU32],
    counts: &[AtomicU32],
    other_values: &[AtomicU32],
    other_counts: &[AtomicU32],
) {
    let entries = values.iter().zip(counts).zip(other_values.iter().zip(other_counts));
    for ((value, count), (other_value, other_count)) in entries {
        let (n, m) = (count.load(Ordering::Relaxed) as f64, other_count.load(Ordering::Relaxed) as f64);
        if m > 0.0 {
            let merged = (load(value) as f64 * n + load(other_value) as f64 * m) / (n + m);
            value.store((merged as f32).to_bits(), Ordering::Relaxed);
            count.store((n + m).min(u32::MAX as f64) as u32, Ordering::Relaxed);
        }
    }
}
