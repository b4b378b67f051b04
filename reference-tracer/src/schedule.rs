//! When a guided render learns: all the time (`online`, the seed's way), or in
//! iterations of 1, 2, 4, … passes whose images are discarded, the guide refitted at each
//! boundary, and then a final image rendered with the guide frozen (`iterative`,
//! Müller et al. 2017, §5).

/// When to stop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    /// After this many samples per pixel.
    SamplesPerPixel(u32),
    /// After the first pass that ends at or past this many seconds of rendering.
    Seconds(f64),
}

impl Budget {
    /// Whether a render that has done `passes` passes in `seconds` stops.
    pub fn reached(&self, passes: u32, seconds: f64) -> bool {
        match *self {
            Budget::SamplesPerPixel(spp) => passes >= spp,
            Budget::Seconds(limit) => seconds >= limit,
        }
    }
}

/// The most of a seconds budget the iterative schedule trains for by default. 0.15
/// measured best: guided-nee at 60 s, seed 41, relMSE against the doubling rule alone
/// (which trains up to half the budget): glossy 128² 0.98×, door 160×120 0.97×, cornell
/// 128² 0.97×, Veach Ajar 0.95×, living room 0.82×; 0.3 gave 0.99×, 0.99× and 0.97× on the
/// first three. Training passes record and learn, so they run at 0.74–0.95× the frozen
/// passes' speed, and the guide gains little from the longest iterations.
pub const DEFAULT_TRAINING_SHARE: f64 = 0.15;

/// Training passes before which an iteration may end within twice the share: the
/// second and third iterations (to 3 and 7 passes). Where a pass is long, the share alone
/// stopped training after 3 passes: Veach Ajar 1280×720 at 60 s (about 1.3 s a pass)
/// then rendered guided-nee ÷ nee 0.531, 0.533, 0.511 and 0.552 (seeds 41, 42, 41, 42),
/// and after 7 passes (`--train-share 0.2`, or the share at the third iteration's end
/// on a faster day) 0.480, 0.519, 0.492 and 0.494.
const EARLY_PASSES: u32 = 7;

/// The training schedule of a guided render.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Schedule {
    /// Learn during every pass, rebuild the guide's sampling after each, keep every pass.
    Online,
    /// Train in iterations of doubling length (discarded), refit between them, then
    /// render the rest of the budget frozen: no records, no integral estimates.
    Iterative,
}

impl Schedule {
    /// Every schedule, in the order the command line lists them.
    pub const ALL: [Schedule; 2] = [Schedule::Online, Schedule::Iterative];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Schedule::Online => "online",
            Schedule::Iterative => "iterative",
        }
    }

    /// Parses a command-line name.
    pub fn from_name(name: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|s| s.name() == name)
            .ok_or_else(|| format!("unknown schedule `{name}` (online, iterative)"))
    }
}

/// What the render loop does after a pass of the iterative schedule.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// A training pass inside an iteration: discard it, keep learning, no refit yet.
    Train,
    /// The pass ended an iteration: discard it and refit the guide; `last` when training
    /// stops here and the rest of the budget renders frozen.
    Refit {
        /// Whether this was the last training iteration.
        last: bool,
    },
    /// A pass of the frozen final image: keep it.
    Render,
}

/// The iterative schedule's progress through a render.
#[derive(Clone, Copy, Debug)]
pub struct Training {
    /// Passes in the current iteration (1, 2, 4, …).
    iteration_passes: u32,
    /// Passes done in it.
    done: u32,
    /// When it started, seconds into the render.
    started: f64,
    /// Training passes so far.
    total: u32,
    /// Whether training goes on.
    active: bool,
    /// The most of a seconds budget training may take, in (0, 1].
    share: f64,
}

impl Training {
    /// A schedule that trains first when `active` (else every pass renders), for at most
    /// `share` of a seconds budget.
    pub fn new(active: bool, share: f64) -> Self {
        Self { iteration_passes: 1, done: 0, started: 0.0, total: 0, active, share }
    }

    /// Whether the next pass trains (records and learns).
    pub fn learning(&self) -> bool {
        self.active
    }

    /// Training passes so far.
    pub fn passes(&self) -> u32 {
        self.total
    }

    /// Stops training: every pass from the next one on renders frozen.
    pub fn stop(&mut self) {
        self.active = false;
    }

    /// Accounts for a pass that ended `seconds` into the render.
    ///
    /// An iteration that took d seconds is followed by one of ≈ 2d. Training goes on
    /// while the time left after that next iteration is still at least twice its length,
    /// so the frozen image gets at least half the time even in the worst case, and while
    /// that next iteration would end within `share` of the budget; the second and third
    /// iterations (the first learned with a refitted guide) may end within twice the
    /// share (up to 7 passes). Without that, where a pass is long the count of training
    /// passes was a coin flip: the living room 1280×720 at 60 s trained 3 passes in some
    /// runs and 1 in others (a first pass of 3.09 s puts the next two past 9 s), relMSE
    /// 0.169 and 0.251. Ending training at the boundary nearest the share instead gave
    /// door 160×120 twice the training and 1.08× the relMSE. Under a sample budget of N,
    /// training goes on while its passes stay within N/2.
    pub fn after_pass(&mut self, seconds: f64, budget: Budget) -> Step {
        if !self.active {
            return Step::Render;
        }
        self.done += 1;
        self.total += 1;
        if self.done < self.iteration_passes {
            return Step::Train;
        }
        let next = 2 * self.iteration_passes;
        let goes_on = match budget {
            Budget::Seconds(limit) => {
                let next_seconds = 2.0 * (seconds - self.started);
                let share = if self.total < EARLY_PASSES { 2.0 * self.share } else { self.share };
                limit - seconds - next_seconds >= 2.0 * next_seconds && seconds + next_seconds <= share * limit
            }
            Budget::SamplesPerPixel(spp) => 2 * (self.total as u64 + next as u64) <= spp as u64,
        };
        self.iteration_passes = next;
        self.done = 0;
        self.started = seconds;
        self.active = goes_on;
        Step::Refit { last: !goes_on }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iterations_double_and_training_stops_in_time() {
        let mut training = Training::new(true, 1.0);
        let mut steps = Vec::new();
        // One second per pass, a 60 s budget: iterations of 1, 2, 4, 8 passes end at 1,
        // 3, 7, 15 s; after 8 the next (16 s) would leave 60 - 15 - 16 = 29 < 32.
        let mut t = 0.0;
        while training.learning() {
            t += 1.0;
            steps.push(training.after_pass(t, Budget::Seconds(60.0)));
        }
        let refits: Vec<usize> =
            steps.iter().enumerate().filter(|(_, s)| matches!(s, Step::Refit { .. })).map(|(i, _)| i + 1).collect();
        assert_eq!(refits, [1, 3, 7, 15]);
        assert_eq!(steps.last(), Some(&Step::Refit { last: true }));
        assert_eq!(training.after_pass(t + 1.0, Budget::Seconds(60.0)), Step::Render);
    }

    #[test]
    fn training_stays_within_its_share_of_the_budget() {
        // One second per pass, 60 s, share 0.15 (9 s): iterations end at 1 and 3 s; the
        // next (4 passes, to 7 s) fits, the one after (8 passes, to 15 s) would not.
        let mut training = Training::new(true, 0.15);
        let mut t = 0.0;
        while training.learning() {
            t += 1.0;
            training.after_pass(t, Budget::Seconds(60.0));
        }
        assert_eq!((training.passes(), t), (7, 7.0));
    }

    #[test]
    fn the_second_and_third_iterations_may_take_up_to_twice_the_share() {
        let passes_at = |pass_seconds: f64| {
            let mut training = Training::new(true, 0.15);
            let mut t = 0.0;
            while training.learning() {
                t += pass_seconds;
                training.after_pass(t, Budget::Seconds(60.0));
            }
            training.passes()
        };
        // 9 s of 60: passes of 2.9 s and of 3.09 s alike end the second iteration within
        // 18 s (at 8.7 and 9.27 s); the third, of 4 passes, would end past 20 s.
        assert_eq!(passes_at(2.9), 3);
        assert_eq!(passes_at(3.09), 3);
        // Passes of 6.5 s: the second iteration would end at 19.5 s, past 18 s.
        assert_eq!(passes_at(6.5), 1);
        // Passes of 1.3 s (Veach Ajar's): the third iteration ends at 9.1 s, past the
        // share's 9 s but within twice it; the fourth would end at 19.5 s, past 9 s.
        assert_eq!(passes_at(1.3), 7);
        // Passes of 2.6 s: the third would end at 18.2 s, past 18 s.
        assert_eq!(passes_at(2.6), 3);
        // Short passes: the share alone decides (iterations end at 2.55, 5.11 s; the next
        // would end at 10.23 s).
        assert_eq!(passes_at(0.01), 511);
    }

    #[test]
    fn a_stopped_schedule_renders_from_the_next_pass_on() {
        let mut training = Training::new(true, 1.0);
        assert_eq!(training.after_pass(1.0, Budget::Seconds(60.0)), Step::Refit { last: false });
        assert_eq!(training.after_pass(2.0, Budget::Seconds(60.0)), Step::Train);
        assert_eq!(training.passes(), 2);
        training.stop();
        assert!(!training.learning());
        assert_eq!(training.after_pass(3.0, Budget::Seconds(60.0)), Step::Render);
        assert_eq!(training.passes(), 2);
    }

    #[test]
    fn a_sample_budget_trains_at_most_half_as_many_passes() {
        let mut training = Training::new(true, 1.0);
        let mut passes = 0;
        while training.learning() {
            passes += 1;
            training.after_pass(passes as f64, Budget::SamplesPerPixel(64));
        }
        assert_eq!(passes, 31, "iterations 1 + 2 + 4 + 8 + 16 ≤ 32");
        assert_eq!(Training::new(false, 1.0).after_pass(1.0, Budget::SamplesPerPixel(4)), Step::Render);
    }
}
