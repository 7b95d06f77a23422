//! The page's `?schedule=auto` on WebGPU: which schedule runs is measured on the device and
//! scene at hand (`docs/wavefront.md`, "auto in the page"). After the scene's first frame shows
//! on the megakernel, the page builds the wavefront for the same scene on the same device and
//! times whole frames of each, alternated ([`plan`]: a warm-up frame of each, not counted, then
//! [`ROUNDS`] rounds of [`FRAMES_PER_TURN`] frames of the megakernel, then as many of the
//! wavefront); [`decide`] keeps the wavefront if the median of its turns is lower than the
//! megakernel's by more than [`MARGIN`], else the megakernel.
//!
//! Plain Rust (no browser), unit-tested natively; the viewer (`viewer/measure.rs`) drives it.

use tracer::backend::Schedule;

/// Rounds of alternated turns (megakernel, then wavefront), after the warm-up.
pub const ROUNDS: usize = 3;
/// Whole frames per turn (the time of a turn is divided by them).
pub const FRAMES_PER_TURN: u32 = 2;
/// The wavefront must take less than `1 - MARGIN` times the megakernel's frame time to run.
pub const MARGIN: f64 = 0.05;

/// One turn of the measurement: `frames` whole frames of `schedule`, timed together.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Turn {
    pub schedule: Schedule,
    pub frames: u32,
    /// A warm-up turn (the wavefront's first frame waits for its pipelines; the megakernel's
    /// completes a frame the frame loop may have begun in bands): timed, not counted.
    pub warm_up: bool,
}

/// The turns of one measurement, in order: a warm-up frame of each, then [`ROUNDS`] times
/// the megakernel's turn and the wavefront's.
pub fn plan() -> Vec<Turn> {
    let mut turns = Vec::with_capacity(2 + 2 * ROUNDS);
    for schedule in Schedule::ALL {
        turns.push(Turn { schedule, frames: 1, warm_up: true });
    }
    for _ in 0..ROUNDS {
        for schedule in Schedule::ALL {
            turns.push(Turn { schedule, frames: FRAMES_PER_TURN, warm_up: false });
        }
    }
    turns
}

/// The median (the mean of the middle two for an even count); NaN for none.
pub fn median(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    match sorted.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => sorted[n / 2],
        n => (sorted[n / 2 - 1] + sorted[n / 2]) / 2.0,
    }
}

/// What a measurement chose, from the milliseconds per frame the schedules' medians took.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Verdict {
    pub chosen: Schedule,
    pub megakernel_ms: f64,
    pub wavefront_ms: f64,
}

impl Verdict {
    /// The wavefront's frame time over the megakernel's.
    pub fn ratio(&self) -> f64 {
        self.wavefront_ms / self.megakernel_ms
    }

    /// Why it runs, for the read-out ("auto: 0.62x the megakernel's frame time, measured").
    pub fn reason(&self) -> String {
        let ratio = self.ratio();
        match self.chosen {
            Schedule::Wavefront => format!("auto: {ratio:.2}x the megakernel's frame time, measured"),
            Schedule::Megakernel if ratio < 1.0 => format!(
                "auto: the wavefront took {ratio:.2}x its frame time, not {:.0} % less, measured",
                MARGIN * 100.0
            ),
            Schedule::Megakernel => format!("auto: the wavefront took {ratio:.2}x its frame time, measured"),
        }
    }
}

/// The rule: the wavefront when its frame time is lower than the megakernel's by more than
/// [`MARGIN`], else the megakernel (also for times that are not positive and finite).
pub fn decide(megakernel_ms: f64, wavefront_ms: f64) -> Verdict {
    let valid = |ms: f64| ms.is_finite() && ms > 0.0;
    let faster = valid(megakernel_ms) && valid(wavefront_ms) && wavefront_ms < (1.0 - MARGIN) * megakernel_ms;
    let chosen = if faster { Schedule::Wavefront } else { Schedule::Megakernel };
    Verdict { chosen, megakernel_ms, wavefront_ms }
}

/// A measurement in progress: the turns done and the times they took.
#[derive(Clone, Debug)]
pub struct Measurement {
    /// Tells its turns from an older measurement's (the page's loop passes it back).
    pub id: u32,
    turns: Vec<Turn>,
    done: usize,
    /// Milliseconds per frame of each counted turn.
    pub megakernel_ms: Vec<f64>,
    pub wavefront_ms: Vec<f64>,
    /// Milliseconds per frame of the warm-up turns (megakernel, wavefront).
    pub warm_up_ms: [Option<f64>; 2],
}

impl Measurement {
    pub fn new(id: u32) -> Self {
        Measurement {
            id,
            turns: plan(),
            done: 0,
            megakernel_ms: Vec::new(),
            wavefront_ms: Vec::new(),
            warm_up_ms: [None; 2],
        }
    }

    /// The turn to run now; `None` once every turn is recorded.
    pub fn turn(&self) -> Option<Turn> {
        self.turns.get(self.done).copied()
    }

    /// Records the current turn's milliseconds per frame; whether that was the last turn.
    pub fn record(&mut self, ms_per_frame: f64) -> bool {
        let Some(turn) = self.turn() else { return true };
        let slot = match turn.schedule {
            Schedule::Megakernel => 0,
            Schedule::Wavefront => 1,
        };
        match (turn.warm_up, turn.schedule) {
            (true, _) => self.warm_up_ms[slot] = Some(ms_per_frame),
            (false, Schedule::Megakernel) => self.megakernel_ms.push(ms_per_frame),
            (false, Schedule::Wavefront) => self.wavefront_ms.push(ms_per_frame),
        }
        self.done += 1;
        self.turn().is_none()
    }

    /// The verdict on the medians of the counted turns.
    pub fn verdict(&self) -> Verdict {
        decide(median(&self.megakernel_ms), median(&self.wavefront_ms))
    }
}

/// Where the loaded scene's `auto` stands (reset by each scene load).
#[derive(Clone, Debug, Default)]
pub enum Choice {
    /// Not measured yet: it starts once the first frame has shown on the megakernel.
    #[default]
    Pending,
    Measuring(Measurement),
    /// Measured: the verdict on `measured`'s medians, or on times a test injected instead.
    Measured {
        verdict: Verdict,
        measured: Measurement,
        injected: bool,
    },
    /// Building or running the wavefront failed: the megakernel runs.
    Failed(String),
    /// Given up on (the device was lost, frames rendered outside it...): the megakernel runs.
    Abandoned(String),
    /// Interrupted by a change of the view or a setting (`why`), after `tries` measurements
    /// begun for this scene: the megakernel runs, and the measurement starts again once the
    /// view has stayed put for [`settle_frames`]`(tries)` frames, longer after each
    /// interruption. It is never given up for it: a view that kept changing while a person
    /// looked around (or resized the window) is measured once it rests.
    Interrupted {
        why: String,
        tries: u32,
    },
    /// Not measured for now, and why (a scene whose animation plays: each pose restarts the
    /// accumulation): the megakernel runs, and the measurement starts once the animation is
    /// paused and the view has stayed put for [`SETTLED_FRAMES`] frames.
    Skipped(String),
}

impl Choice {
    /// The schedule it makes the page run.
    pub fn schedule(&self) -> Schedule {
        match self {
            Choice::Measured { verdict, .. } => verdict.chosen,
            _ => Schedule::auto(),
        }
    }

    /// "pending", "measuring", "measured", "failed", "abandoned" or "skipped".
    pub fn state(&self) -> &'static str {
        match self {
            Choice::Pending => "pending",
            Choice::Measuring(_) => "measuring",
            Choice::Measured { .. } => "measured",
            Choice::Failed(_) => "failed",
            Choice::Abandoned(_) => "abandoned",
            Choice::Interrupted { .. } => "interrupted",
            Choice::Skipped(_) => "skipped",
        }
    }

    /// Why the schedule runs, for the read-out; `None` while nothing is measured yet.
    pub fn reason(&self) -> Option<String> {
        match self {
            Choice::Pending => None,
            Choice::Measuring(_) => Some("auto: measuring the wavefront against it".into()),
            Choice::Measured { verdict, .. } => Some(verdict.reason()),
            Choice::Failed(_) => Some("auto: the wavefront failed while measured".into()),
            Choice::Abandoned(why) | Choice::Skipped(why) => Some(format!("auto: not measured, {why}")),
            Choice::Interrupted { why, .. } => Some(format!("auto: measuring again once the view stays put ({why})")),
        }
    }

    /// Ends a measurement in progress (a restart, a rebuild, a new device...): `why` it was
    /// given up. Anything else stays.
    pub fn abandon(&mut self, why: &str) -> bool {
        if matches!(self, Choice::Measuring(_)) {
            *self = Choice::Abandoned(why.to_string());
            return true;
        }
        false
    }

    /// Ends a measurement in progress because the view or a setting changed (`why`), after
    /// `tries` measurements begun for this scene: measured again once the view has stayed put
    /// for [`settle_frames`]`(tries)` frames. Anything else stays.
    pub fn interrupt(&mut self, why: &str, tries: u32) -> bool {
        if !matches!(self, Choice::Measuring(_)) {
            return false;
        }
        *self = Choice::Interrupted { why: why.to_string(), tries };
        true
    }

    /// Whether a measurement is due once the accumulation holds `spp` samples: a scene's
    /// first after its first frame, a retry after an interruption once the view has stayed
    /// put for [`settle_frames`] frames (each change restarts the accumulation), a moving
    /// scene's first once it is paused and the view has stayed put for [`SETTLED_FRAMES`].
    pub fn due_at(&self, spp: u32) -> bool {
        match self {
            Choice::Pending => spp >= 1,
            Choice::Interrupted { tries, .. } => spp >= settle_frames(*tries),
            Choice::Skipped(_) => spp >= SETTLED_FRAMES,
            _ => false,
        }
    }
}

/// Frames the view must stay put before a measurement interrupted once starts again.
pub const SETTLED_FRAMES: u32 = 4;

/// Doublings of that wait after further interruptions: a view that keeps changing is measured
/// less and less often (each measurement's wavefront turns pause the image's convergence),
/// at worst after 64 frames at rest.
pub const MAX_DOUBLINGS: u32 = 4;

/// Frames the view must stay put before a measurement interrupted after `tries` measurements
/// starts again: [`SETTLED_FRAMES`], doubled per interruption after the first, up to
/// [`MAX_DOUBLINGS`] times.
pub fn settle_frames(tries: u32) -> u32 {
    SETTLED_FRAMES << tries.saturating_sub(1).min(MAX_DOUBLINGS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_plan_alternates_after_a_warm_up_of_each() {
        let turns = plan();
        assert_eq!(turns.len(), 2 + 2 * ROUNDS);
        assert!(turns[..2].iter().all(|t| t.warm_up && t.frames == 1));
        const { assert!(ROUNDS >= 2) };
        for (i, turn) in turns[2..].iter().enumerate() {
            let want = if i % 2 == 0 { Schedule::Megakernel } else { Schedule::Wavefront };
            assert_eq!((turn.schedule, turn.frames, turn.warm_up), (want, FRAMES_PER_TURN, false));
        }
    }

    #[test]
    fn the_wavefront_runs_only_when_more_than_5_percent_faster() {
        assert_eq!(decide(100.0, 62.0).chosen, Schedule::Wavefront);
        assert_eq!(decide(100.0, 94.9).chosen, Schedule::Wavefront);
        assert_eq!(decide(100.0, 95.0).chosen, Schedule::Megakernel);
        assert_eq!(decide(100.0, 97.0).chosen, Schedule::Megakernel);
        assert_eq!(decide(100.0, 160.0).chosen, Schedule::Megakernel);
        for bad in [f64::NAN, 0.0, -1.0, f64::INFINITY] {
            assert_eq!(decide(bad, 50.0).chosen, Schedule::Megakernel);
            assert_eq!(decide(100.0, bad).chosen, Schedule::Megakernel);
        }
        assert_eq!(decide(100.0, 62.0).reason(), "auto: 0.62x the megakernel's frame time, measured");
        assert_eq!(
            decide(100.0, 97.0).reason(),
            "auto: the wavefront took 0.97x its frame time, not 5 % less, measured"
        );
        assert_eq!(decide(100.0, 160.0).reason(), "auto: the wavefront took 1.60x its frame time, measured");
    }

    #[test]
    fn medians_of_the_counted_turns_decide() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
        assert!(median(&[]).is_nan());
        let mut m = Measurement::new(7);
        // Warm-ups (slow: compiling) do not count; one outlier per schedule does not decide.
        let times = [500.0, 9000.0, 100.0, 60.0, 400.0, 61.0, 101.0, 900.0];
        for (i, ms) in times.iter().enumerate() {
            assert_eq!(m.record(*ms), i == times.len() - 1);
        }
        assert_eq!(m.turn(), None);
        assert_eq!(m.warm_up_ms, [Some(500.0), Some(9000.0)]);
        assert_eq!(
            (m.megakernel_ms.clone(), m.wavefront_ms.clone()),
            (vec![100.0, 400.0, 101.0], vec![60.0, 61.0, 900.0])
        );
        let v = m.verdict();
        assert_eq!((v.chosen, v.megakernel_ms, v.wavefront_ms), (Schedule::Wavefront, 101.0, 61.0));
    }

    #[test]
    fn only_a_measurement_in_progress_is_abandoned() {
        let mut c = Choice::Measuring(Measurement::new(1));
        assert!(c.abandon("the view changed"));
        assert_eq!((c.state(), c.schedule()), ("abandoned", Schedule::Megakernel));
        assert_eq!(c.reason().as_deref(), Some("auto: not measured, the view changed"));
        let mut measured =
            Choice::Measured { verdict: decide(100.0, 50.0), measured: Measurement::new(2), injected: false };
        assert!(!measured.abandon("the view changed"));
        assert_eq!(measured.schedule(), Schedule::Wavefront);
        assert_eq!(Choice::Pending.reason(), None);
    }

    #[test]
    fn an_interrupted_measurement_starts_again_once_the_view_stays_put_ever_later() {
        let mut choice = Choice::Pending;
        assert!(!choice.due_at(0) && choice.due_at(1));
        let mut waits = Vec::new();
        for tries in 1..=8 {
            choice = Choice::Measuring(Measurement::new(tries));
            assert!(!choice.due_at(1000), "no second measurement while one runs");
            assert!(choice.interrupt("the view or a setting changed", tries));
            assert_eq!(choice.state(), "interrupted", "never given up for an interruption");
            assert!(choice.reason().unwrap().contains("measuring again"), "{:?}", choice.reason());
            let wait = settle_frames(tries);
            assert!(!choice.due_at(wait - 1) && choice.due_at(wait));
            waits.push(wait);
        }
        assert_eq!(waits, [4, 8, 16, 32, 64, 64, 64, 64]);
        let mut skipped = Choice::Skipped("the scene moves".into());
        assert!(!skipped.interrupt("the view changed", 1) && skipped.state() == "skipped");
        // A moving scene, paused: measured once the view has stayed put.
        assert!(!skipped.due_at(SETTLED_FRAMES - 1) && skipped.due_at(SETTLED_FRAMES));
    }
}
