//! Frames split into bands of rows, so that no single GPU submission exceeds a time budget.
//!
//! On a slow GPU one full frame of the kernel takes seconds (SwiftShader at 640x480: ~3 s; the
//! thesis measured 0.37 fps on phones). Submitted as one draw, it keeps the GPU (and, in a
//! browser, the compositor and everything queued behind it: the restarted accumulation after a
//! camera move) busy for that long. [`GlRenderer::render_band`](crate::backend::gl::GlRenderer::render_band) draws the same fragment pass
//! over a scissor rectangle of rows instead; the accumulation's frame index only advances when
//! the last band of a frame is drawn, so a split frame is the unsplit one (same pixels, same
//! per-pixel random sequence), as `tests/cli/web.rs` checks.
//!
//! [`BandPolicy`] (pure logic) chooses the band height from measured band times: bands aim at
//! [`TARGET_FRACTION`] of the budget ([`DEFAULT_BUDGET_MS`], 50 ms), start small
//! ([`FIRST_ROWS`]), at most double per band, and shrink at once when a band was slow.
//! Where even a band of one row takes more than [`FIXED_COST_BUDGETS`] budgets (the fastest of
//! [`THIN_SAMPLES`] such bands: a band's measured time only errs upwards), the cost is the
//! band's, not its rows' (a driver's work per draw, a fence's round trip): no split keeps
//! submissions short, and one-row bands would only multiply that cost by the height. Bands are
//! then sized so that it is at most half of each (written for LittlestTokyo posed by its
//! animation, WebGL2 on SwiftShader at 320x240: ~250 ms per band whatever its height, which
//! turned out to be the page's own read-outs hashing every texel each animation frame; a
//! driver's cost per draw would look the same).
//! The GL runtime's `Pacer` (`backend/gl/pacing.rs`) measures: it puts a fence (`glFenceSync`, core in WebGL2 and OpenGL ES 3.0) behind
//! each band and polls it without blocking (`glClientWaitSync` with a zero timeout, the only
//! timeout WebGL allows); a band's time lies between the last poll that saw it pending and the
//! poll that sees it signalled ([`polled_bounds`]), so it is known to the caller's polling
//! interval (an animation frame in the browser). No timer-query extension is needed (WebGL2 has none on SwiftShader and
//! many phones), nothing blocks the thread, and nothing is read back. The pacer submits nothing
//! while a band is in flight: at most one band is queued, so new work (a restart) waits for at
//! most one band.

/// The longest a single GPU submission should take (milliseconds), by default.
pub const DEFAULT_BUDGET_MS: f64 = 50.0;
/// Bands aim at this fraction of the budget: headroom for the variation between bands (rows
/// that see the sky cost less than rows inside a room) and for the measurement's rounding.
pub const TARGET_FRACTION: f64 = 0.7;
/// Rows of the first band, before anything is measured (the first draw also pays the driver's
/// shader compilation, so it is small whatever the device).
pub const FIRST_ROWS: u32 = 8;
/// A band is at most this many times the rows of the band measured before it.
pub const MAX_GROWTH: u32 = 2;
/// One-row bands slower than this many budgets (the fastest of [`THIN_SAMPLES`]) mean a cost
/// per band that splitting cannot avoid.
pub const FIXED_COST_BUDGETS: f64 = 2.0;
/// One-row bands measured before their fastest is believed as the cost of any band.
pub const THIN_SAMPLES: usize = 6;
/// Rows of the band that measures the cost per row once a fixed cost is known.
const PROBE_ROWS: u32 = FIRST_ROWS;

/// What a band polled once per tick is known to have taken (ms): at least until the last poll
/// that found it pending (`pending_at_ms`; never: 0), at most until `now_ms`, the poll that
/// found it done. For [`BandPolicy::record_between`]; the GL pacer and the WebGPU page's loop
/// both measure this way.
pub fn polled_bounds(submitted_ms: f64, pending_at_ms: Option<f64>, now_ms: f64) -> (f64, f64) {
    let at_most = now_ms - submitted_ms;
    (pending_at_ms.map_or(0.0, |t| t - submitted_ms), at_most)
}

/// How many rows each band of a frame covers, adapted from measured band times.
#[derive(Clone, Debug, PartialEq)]
pub struct BandPolicy {
    height: u32,
    /// `None`: frames are not split (one submission per frame).
    budget_ms: Option<f64>,
    rows: u32,
    /// Milliseconds per row of the last band measured.
    ms_per_row: Option<f64>,
    /// The last one-row bands' times.
    thin: ThinBands,
    /// Where a band's own cost rules ([`FIXED_COST_BUDGETS`]), the cost per row beyond the
    /// first, once a thicker band measured it.
    per_row: Option<f64>,
}

/// The times of the last [`THIN_SAMPLES`] one-row bands.
#[derive(Clone, Debug, Default, PartialEq)]
struct ThinBands {
    times: [f64; THIN_SAMPLES],
    count: usize,
}

impl ThinBands {
    fn push(&mut self, ms: f64) {
        self.times[self.count % THIN_SAMPLES] = ms;
        self.count += 1;
    }

    /// The fastest, once [`THIN_SAMPLES`] were measured.
    fn fastest(&self) -> Option<f64> {
        (self.count >= THIN_SAMPLES).then(|| self.times.iter().copied().fold(f64::INFINITY, f64::min))
    }
}

impl BandPolicy {
    /// A policy for images of `height` rows; `budget_ms` `None` (or not a positive number)
    /// never splits.
    pub fn new(height: u32, budget_ms: Option<f64>) -> Self {
        let height = height.max(1);
        let budget_ms = budget_ms.filter(|b| b.is_finite() && *b > 0.0);
        let rows = if budget_ms.is_some() { FIRST_ROWS.min(height) } else { height };
        BandPolicy { height, budget_ms, rows, ms_per_row: None, thin: ThinBands::default(), per_row: None }
    }

    /// Rows of the next band (the last band of a frame may cover fewer: those left).
    pub fn rows(&self) -> u32 {
        self.rows
    }

    /// Bands per frame at the current band height.
    pub fn bands(&self) -> u32 {
        self.height.div_ceil(self.rows)
    }

    pub fn budget_ms(&self) -> Option<f64> {
        self.budget_ms
    }

    /// Whether a whole frame is estimated to take longer than the budget (frames are split
    /// because they must be, not merely because nothing was measured yet); false unsplit.
    pub fn frames_exceed_budget(&self) -> bool {
        match (self.budget_ms, self.ms_per_row) {
            (Some(budget), Some(per_row)) => per_row * self.height as f64 > budget,
            _ => false,
        }
    }

    /// The estimated time of one band at the current height, once a band was measured.
    pub fn band_ms(&self) -> Option<f64> {
        self.ms_per_row.map(|m| m * self.rows as f64)
    }

    /// Records that a band of `rows` rows took `ms` and chooses the next band's height. Times
    /// that are not finite or negative are ignored.
    pub fn record(&mut self, rows: u32, ms: f64) {
        self.record_between(rows, ms, ms);
    }

    /// Records a band whose time is only known to lie between `at_least` and `at_most` ms (a
    /// fence polled once per animation frame: not yet signalled at one poll, signalled at the
    /// next; `at_least` 0 when it was already signalled at the first poll). A band that may
    /// have exceeded the budget is taken at its upper bound; one that fit at its lower bound,
    /// but no lower than half its upper bound (the middle of what it may have taken, where
    /// nothing bounds it from below), else the polling interval (and, in a browser, the frame
    /// the fence's status takes to arrive) would keep bands far smaller than the budget allows:
    /// a band done by the first poll of a page ticking every 33 ms measured 33 ms whatever its
    /// rows, which at a 35 ms target kept bands of one row (LittlestTokyo, 320x240: 0.7 frames/s).
    pub fn record_between(&mut self, rows: u32, at_least: f64, at_most: f64) {
        let Some(budget) = self.budget_ms else { return };
        let valid = |ms: f64| ms.is_finite() && ms >= 0.0;
        if rows == 0 || !valid(at_least) || !valid(at_most) {
            return;
        }
        let ms = if at_most > budget { at_most } else { at_least.max(at_most / 2.0).min(at_most) };
        if rows == 1 {
            self.thin.push(ms);
        }
        if let Some(one_row) = self.thin.fastest().filter(|t| *t > FIXED_COST_BUDGETS * budget) {
            if self.amortise(one_row, rows, ms, budget) {
                return;
            }
        }
        // The latest band is believed: a slow one shrinks the next at once (it must fit), and a
        // fast one (a lucky band, or one after the slow first draw) grows it at most MAX_GROWTH
        // times, so one outlier neither overshoots the budget far nor keeps bands tiny.
        let estimate = ms / rows as f64;
        self.ms_per_row = Some(estimate);
        let target = budget * TARGET_FRACTION;
        let wanted = if estimate > 0.0 { (target / estimate).floor().min(u32::MAX as f64) as u32 } else { u32::MAX };
        self.rows = wanted.min(rows.saturating_mul(MAX_GROWTH)).clamp(1, self.height);
    }

    /// Band heights where a band costs `one_row` ms or more whatever its rows: a band of `rows`
    /// took `ms`. The first one-row band is followed by a thicker probe; a thicker band gives
    /// the cost per row beyond the first, and bands grow to the height at which the band's own
    /// cost is half of each (at most [`MAX_GROWTH`]² times the last, so that one outlier does
    /// not make whole frames). A thicker band within the budget shows that the cost was not the
    /// band's: the one-row times are forgotten and the budget rules again (false).
    fn amortise(&mut self, one_row: f64, rows: u32, ms: f64, budget: f64) -> bool {
        if rows > 1 && ms <= budget {
            self.thin = ThinBands::default();
            self.per_row = None;
            return false;
        }
        if rows > 1 {
            self.per_row = Some(((ms - one_row) / (rows - 1) as f64).max(0.0));
        }
        let Some(per_row) = self.per_row else {
            self.rows = PROBE_ROWS.clamp(1, self.height);
            self.ms_per_row = Some(one_row);
            return true;
        };
        let fixed = one_row - per_row;
        let limit = rows.saturating_mul(MAX_GROWTH * MAX_GROWTH);
        let wanted = if per_row > 0.0 { (fixed / per_row).ceil().min(u32::MAX as f64) as u32 } else { limit };
        self.rows = wanted.min(limit).clamp(1, self.height);
        self.ms_per_row = Some((fixed + per_row * self.rows as f64) / self.rows as f64);
        true
    }
}

/// What a pacer's step did (the GL runtime's `Pacer::step`, the WebGPU page's loop).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// The previous band is still on the GPU: nothing was submitted.
    Waiting,
    /// A band was submitted; `frame_done`: it was the frame's last (a sample per pixel was added).
    Submitted { frame_done: bool },
    /// A preview was submitted and shown (the web runtimes' first step after a scene loads:
    /// `backend::preview`), no band of the frame.
    Preview,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Feeds `policy` bands of a device taking `ms_per_row` per row; returns the band heights.
    fn run(policy: &mut BandPolicy, ms_per_row: f64, bands: usize) -> Vec<u32> {
        (0..bands)
            .map(|_| {
                let rows = policy.rows();
                policy.record(rows, rows as f64 * ms_per_row);
                rows
            })
            .collect()
    }

    #[test]
    fn unsplit_without_a_budget() {
        for budget in [None, Some(0.0), Some(-5.0), Some(f64::NAN), Some(f64::INFINITY)] {
            let mut p = BandPolicy::new(480, budget);
            assert_eq!((p.rows(), p.bands()), (480, 1), "{budget:?}");
            p.record(480, 3000.0);
            assert_eq!(p.rows(), 480, "{budget:?}");
        }
    }

    #[test]
    fn a_slow_device_settles_on_bands_within_the_budget() {
        // SwiftShader, Cornell box, 640x480: ~3.4 s per frame, ~7 ms per row.
        let mut p = BandPolicy::new(480, Some(DEFAULT_BUDGET_MS));
        assert_eq!(p.rows(), FIRST_ROWS);
        run(&mut p, 7.0, 20);
        assert_eq!(p.rows(), 5, "floor(35 ms / 7 ms)");
        assert_eq!(p.bands(), 96);
        assert!(p.band_ms().unwrap() <= DEFAULT_BUDGET_MS * TARGET_FRACTION + 1e-9);
    }

    #[test]
    fn a_fast_device_grows_to_whole_frames_at_most_doubling() {
        let mut p = BandPolicy::new(480, Some(DEFAULT_BUDGET_MS));
        let rows = run(&mut p, 0.001, 12);
        assert_eq!(&rows[..7], &[8, 16, 32, 64, 128, 256, 480]);
        assert!(rows[7..].iter().all(|&r| r == 480));
        assert_eq!(p.bands(), 1);
        // A zero time (a coarse clock) grows too, without dividing by zero.
        let mut p = BandPolicy::new(100, Some(50.0));
        p.record(8, 0.0);
        assert_eq!(p.rows(), 16);
    }

    #[test]
    fn a_slow_band_shrinks_the_next_at_once() {
        let mut p = BandPolicy::new(480, Some(50.0));
        run(&mut p, 1.0, 10);
        assert_eq!(p.rows(), 35);
        // The device slows down 10x (another tab, thermal throttling): the next band fits again.
        p.record(35, 350.0);
        assert_eq!(p.rows(), 3);
        // The first draw pays the shader compilation: seconds for a few rows, then it recovers.
        let mut p = BandPolicy::new(480, Some(50.0));
        p.record(8, 4000.0);
        assert_eq!(p.rows(), 1);
        let rows = run(&mut p, 1.0, 8);
        assert_eq!(rows, [1, 2, 4, 8, 16, 32, 35, 35]);
    }

    #[test]
    fn a_band_known_to_fit_is_taken_at_its_lower_bound() {
        // Fences seen once per animation frame (16.7 ms), and a frame late: a 1-row band of
        // 7 ms was pending at the first poll and seen done at the second.
        let mut p = BandPolicy::new(480, Some(50.0));
        p.record_between(1, 16.7, 33.4);
        assert_eq!(p.rows(), 2, "grows (35 / 16.7 allows 2), where its upper bound would keep 1 row");
        // Never seen pending: no lower bound but zero, growth at most doubles.
        p.record_between(2, 0.0, 16.7);
        assert_eq!(p.rows(), 4);
        // It may have exceeded the budget: its upper bound shrinks the next band.
        p.record_between(4, 40.0, 60.0);
        assert_eq!(p.rows(), 2, "floor(35 / 15)");
        p.record_between(2, f64::NAN, 10.0);
        assert_eq!(p.rows(), 2, "ignored");
    }

    /// A frame loop polling each band's fence once per tick of `tick_ms` (the browser's
    /// animation frames, which do not wait for the GPU here) over a device taking `ms_per_row`:
    /// a band is seen done at the first poll after it ends, and pending at the polls before.
    /// Returns each band's rows and the ticks each frame of `height` rows took.
    fn run_polled(
        policy: &mut BandPolicy,
        height: u32,
        ms_per_row: f64,
        tick_ms: f64,
        frames: usize,
    ) -> (Vec<u32>, Vec<u32>) {
        let (mut rows_seen, mut ticks_per_frame) = (Vec::new(), Vec::new());
        for _ in 0..frames {
            let (mut left, mut ticks) = (height, 0);
            while left > 0 {
                let rows = policy.rows().min(left);
                let polls = (rows as f64 * ms_per_row / tick_ms).floor() as u32 + 1;
                let pending_at = (polls > 1).then(|| (polls - 1) as f64 * tick_ms);
                let (at_least, at_most) = polled_bounds(0.0, pending_at, polls as f64 * tick_ms);
                policy.record_between(rows, at_least, at_most);
                rows_seen.push(rows);
                (left, ticks) = (left - rows, ticks + polls);
            }
            ticks_per_frame.push(ticks);
        }
        (rows_seen, ticks_per_frame)
    }

    #[test]
    fn bands_done_by_the_first_poll_grow_past_the_polling_interval() {
        // LittlestTokyo paused, WebGL2 on SwiftShader, 320x240: ~3 ms per row, a page ticking
        // every 17-33 ms. Each band was seen done at the first poll, so it measured one tick
        // whatever its rows: at 33 ms a tick, bands of 1 row, a frame 240 ticks (8 s, 0.7 s of
        // GPU time). Taken at the middle of what it may have taken, a band grows until it
        // outlasts a tick.
        for tick in [16.7, 33.3] {
            let mut p = BandPolicy::new(240, Some(DEFAULT_BUDGET_MS));
            p.record_between(1, 0.0, tick);
            let (rows, ticks) = run_polled(&mut p, 240, 3.0, tick, 12);
            let gpu_ms = 240.0 * 3.0;
            let frame_ms = *ticks.last().unwrap() as f64 * tick;
            assert!(
                frame_ms <= 2.0 * gpu_ms,
                "tick {tick}: a frame takes {frame_ms} ms for {gpu_ms} of GPU time: {:?}",
                &rows[..24]
            );
            // No band over twice the budget: growth at most doubles a band that fit.
            assert!(rows.iter().all(|&r| r as f64 * 3.0 <= 2.0 * DEFAULT_BUDGET_MS), "tick {tick}: {rows:?}");
        }
    }

    #[test]
    fn where_animation_frames_wait_for_the_gpu_bands_stay_near_the_budget() {
        // Each band is seen done at the first poll, which comes when it ends (a browser whose
        // animation frames wait for a busy GPU): taken at half, the band after one at the
        // target doubles, and the one after that shrinks again. No band past 1.5 budgets, and
        // on average within the budget.
        let mut p = BandPolicy::new(480, Some(DEFAULT_BUDGET_MS));
        let ms = |rows: u32| rows as f64 * 3.0;
        let mut times = Vec::new();
        for _ in 0..60 {
            let rows = p.rows();
            let (at_least, at_most) = polled_bounds(0.0, None, ms(rows));
            p.record_between(rows, at_least, at_most);
            times.push(ms(rows));
        }
        let settled = &times[10..];
        let mean = settled.iter().sum::<f64>() / settled.len() as f64;
        assert!(settled.iter().all(|&t| t <= 1.5 * DEFAULT_BUDGET_MS), "{settled:?}");
        assert!(mean <= DEFAULT_BUDGET_MS, "mean {mean} ms: {settled:?}");
    }

    #[test]
    fn frames_exceed_the_budget_only_once_measured_to() {
        let mut p = BandPolicy::new(480, Some(DEFAULT_BUDGET_MS));
        assert!(!p.frames_exceed_budget(), "nothing measured: split only to measure");
        p.record(8, 8.0 * 0.01);
        assert!(!p.frames_exceed_budget(), "4.8 ms a frame");
        p.record(16, 16.0 * 7.0);
        assert!(p.frames_exceed_budget(), "3.4 s a frame");
        let mut unsplit = BandPolicy::new(480, None);
        unsplit.record(480, 5000.0);
        assert!(!unsplit.frames_exceed_budget());
    }

    /// Feeds `policy` bands of a device taking `fixed + per_row * rows` ms; returns the heights.
    fn run_affine(policy: &mut BandPolicy, fixed: f64, per_row: f64, bands: usize) -> Vec<u32> {
        (0..bands)
            .map(|_| {
                let rows = policy.rows();
                policy.record(rows, fixed + rows as f64 * per_row);
                rows
            })
            .collect()
    }

    #[test]
    fn a_cost_per_band_past_the_budget_is_amortised_not_split_finer() {
        // LittlestTokyo posed, WebGL2 on SwiftShader, 320x240: ~250 ms per band whatever its
        // height, ~5 ms per row. One-row bands made a frame 240 x 255 ms = 61 s.
        let mut p = BandPolicy::new(240, Some(DEFAULT_BUDGET_MS));
        let rows = run_affine(&mut p, 250.0, 5.0, 12);
        assert_eq!(&rows[..9], &[8, 1, 1, 1, 1, 1, 1, 8, 32], "six one-row bands, a probe, then growth");
        assert_eq!(p.rows(), 50, "ceil(250 / 5): the band's own cost half of each band");
        let frame_ms = p.bands() as f64 * (250.0 + 5.0 * p.rows() as f64);
        assert!(frame_ms <= 2.0 * (250.0 + 240.0 * 5.0), "{frame_ms} ms per frame split, 1450 unsplit");
        assert!((p.band_ms().unwrap() - 500.0).abs() < 1e-6, "{:?}", p.band_ms());
        // A cost per band alone (no cost per row measurable): whole frames, growing 4x a band.
        let mut p = BandPolicy::new(240, Some(DEFAULT_BUDGET_MS));
        let rows = run_affine(&mut p, 250.0, 0.0, 11);
        assert_eq!(&rows[7..], &[8, 32, 128, 240]);
    }

    #[test]
    fn slow_rows_or_a_slow_moment_are_not_a_cost_per_band() {
        // A device slow per row (one row 120 ms, eight 960): rows, not bands, cost; one probe,
        // then one-row bands.
        let mut p = BandPolicy::new(240, Some(DEFAULT_BUDGET_MS));
        let rows = run_affine(&mut p, 0.0, 120.0, 20);
        assert_eq!(&rows[6..9], &[1, 8, 1]);
        assert!(rows[9..].iter().all(|&r| r == 1), "{rows:?}");
        // One-row bands of 20 ms but for a moment (a busy machine, a late poll) of 200: the
        // fastest of the last six is believed, so bands stay within the budget.
        let mut p = BandPolicy::new(480, Some(DEFAULT_BUDGET_MS));
        p.record(8, 4000.0);
        for ms in [200.0, 20.0, 200.0, 200.0, 200.0, 200.0, 200.0] {
            p.record(1, ms);
        }
        assert_eq!(p.rows(), 1, "35 ms at 200 ms per row");
        // A thicker band within the budget after a fixed cost was believed: the budget rules.
        let mut p = BandPolicy::new(480, Some(DEFAULT_BUDGET_MS));
        for _ in 0..6 {
            p.record(1, 150.0);
        }
        assert_eq!(p.rows(), PROBE_ROWS);
        p.record(PROBE_ROWS, 16.0);
        assert_eq!(p.rows(), 16, "floor(35 / 2) = 17, at most 2 x 8");
    }

    #[test]
    fn bad_measurements_are_ignored_and_rows_stay_in_range() {
        let mut p = BandPolicy::new(3, Some(50.0));
        assert_eq!(p.rows(), 3, "never more rows than the image has");
        p.record(3, f64::NAN);
        p.record(3, -1.0);
        p.record(0, 10.0);
        assert_eq!((p.rows(), p.band_ms()), (3, None));
        p.record(1, 1e9);
        assert_eq!(p.rows(), 1, "at least one row");
        assert_eq!(BandPolicy::new(0, Some(50.0)).rows(), 1);
    }
}
