//! What paths count: rays, vertices, paths that brought light, time in the guide.

/// Counters of one or many paths.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PathCounters {
    /// Paths traced.
    pub paths: u64,
    /// Paths whose contribution is non-zero.
    pub nonzero_paths: u64,
    /// Closest-hit and shadow rays cast.
    pub rays: u64,
    /// Surface vertices (hits) over all paths.
    pub vertices: u64,
    /// Nanoseconds spent in guide calls on the timed paths (1 in [`TIMED_PATH_STRIDE`]).
    pub timed_guide_nanos: u64,
    /// Paths whose guide calls were timed.
    pub timed_paths: u64,
}

/// One path in this many has its guide calls timed: timing every call would cost more
/// than many of the calls themselves.
pub const TIMED_PATH_STRIDE: u64 = 64;

/// The next-event gate counts the shadow rays of one path in this many: its counters are
/// shared by every thread, and a quarter of the rays judge a cell as well (cornell 128²,
/// every path counting: training passes ≈ 15 % slower than ungated).
pub(super) const GATE_PATH_STRIDE: u64 = 4;

impl PathCounters {
    /// Estimated seconds spent in guide calls over all paths, extrapolated from the
    /// timed ones.
    pub fn estimated_guide_seconds(&self) -> f64 {
        if self.timed_paths == 0 {
            return 0.0;
        }
        self.timed_guide_nanos as f64 * 1e-9 * self.paths as f64 / self.timed_paths as f64
    }
}

impl std::ops::Add for PathCounters {
    type Output = PathCounters;
    fn add(self, o: PathCounters) -> PathCounters {
        PathCounters {
            paths: self.paths + o.paths,
            nonzero_paths: self.nonzero_paths + o.nonzero_paths,
            rays: self.rays + o.rays,
            vertices: self.vertices + o.vertices,
            timed_guide_nanos: self.timed_guide_nanos + o.timed_guide_nanos,
            timed_paths: self.timed_paths + o.timed_paths,
        }
    }
}
