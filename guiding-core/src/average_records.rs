//! [`AverageRecords`]: one thread's learning of a table of running averages during a
//! pass, in tables of its own, added to the shared table between passes. The light and
//! environment guides learn this way instead of a locked read-modify-write per shadow
//! ray on lines that every thread writes.

use alloc::vec::Vec;
use core::sync::atomic::AtomicU32;

use crate::atomic_f32;

/// What one record teaches its entry.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Learned {
    /// A target for the running average.
    Target(f32),
    /// One more update without a value (a count, such as a visible shadow ray).
    Count,
    /// Only that the record was made (an event the entry counts apart).
    Nothing,
}

/// Per entry of a guide's table: Σ of the targets, the updates and the records made since
/// the last splat. Made once per thread and kept from pass to pass (16 bytes an entry; the
/// tables stop growing after the first pass).
#[derive(Clone, Debug, Default)]
pub(crate) struct AverageRecords {
    sums: Vec<f64>,
    updates: Vec<u32>,
    events: Vec<u32>,
    /// The entries with a record since the last splat, each once.
    touched: Vec<u32>,
}

impl AverageRecords {
    /// Whether nothing is held.
    pub(crate) fn is_empty(&self) -> bool {
        self.touched.is_empty()
    }

    /// Records `learned` at `entry` of a table of `entries` entries.
    #[inline]
    pub(crate) fn add(&mut self, entries: usize, entry: usize, learned: Learned) {
        if self.events.len() != entries {
            // A first record, or another guide's: the tables fit this one.
            self.sums = alloc::vec![0.0; entries];
            self.updates = alloc::vec![0; entries];
            self.events = alloc::vec![0; entries];
            self.touched.clear();
        }
        if self.events[entry] == 0 {
            self.touched.push(entry as u32);
        }
        self.events[entry] = self.events[entry].saturating_add(1);
        match learned {
            Learned::Target(target) => {
                self.sums[entry] += target as f64;
                self.updates[entry] = self.updates[entry].saturating_add(1);
            }
            Learned::Count => self.updates[entry] = self.updates[entry].saturating_add(1),
            Learned::Nothing => {}
        }
    }

    /// Adds the records to a table of running averages and empties them: per entry the
    /// value becomes the mean over its targets and these, (v·n + Σ)/(n + m), in one step
    /// (left alone unless `averages`: a table of counts), the update counts add, and
    /// `events(entry, records made)` sees every touched entry. Records made for a table of
    /// another size are dropped.
    pub(crate) fn splat(
        &mut self,
        values: &mut [AtomicU32],
        updates: &mut [AtomicU32],
        averages: bool,
        mut events: impl FnMut(usize, u32),
    ) {
        let fits = self.events.len() == values.len() && values.len() == updates.len();
        for &entry in &self.touched {
            let i = entry as usize;
            let (m, sum) = (self.updates[i], self.sums[i]);
            if fits {
                events(i, self.events[i]);
                if m > 0 {
                    let n = *updates[i].get_mut();
                    if averages {
                        let value = atomic_f32::load(&values[i]) as f64;
                        let mean = (value * n as f64 + sum) / (n as f64 + m as f64);
                        *values[i].get_mut() = (mean.min(f32::MAX as f64) as f32).to_bits();
                    }
                    *updates[i].get_mut() = n.saturating_add(m);
                }
            }
            // Emptied whether added or dropped: an entry left non-zero would never be
            // touched again, and would hold its stale records for good.
            self.sums[i] = 0.0;
            self.updates[i] = 0;
            self.events[i] = 0;
        }
        self.touched.clear();
    }
}
