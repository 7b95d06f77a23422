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
//! The GL runtime's `Pacer` (`backend/gl/pacing.rs`) measures: it puts a fence (`glFenceSync`, core in WebGL2 and OpenGL ES 3.0) behind
//! each band and polls it without blocking (`glClientWaitSync` with a zero timeout, the only
//! timeout WebGL allows); a band's time is from its submission to the poll that sees the fence
//! signalled, so it is an upper bound, rounded up to the caller's polling interval (an animation
//! frame in the browser). No timer-query extension is needed (WebGL2 has none on SwiftShader and
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

/// How many rows each band of a frame covers, adapted from measured band times.
#[derive(Clone, Debug, PartialEq)]
pub struct BandPolicy {
    height: u32,
    /// `None`: frames are not split (one submission per frame).
    budget_ms: Option<f64>,
    rows: u32,
    /// Milliseconds per row of the last band measured.
    ms_per_row: Option<f64>,
}

impl BandPolicy {
    /// A policy for images of `height` rows; `budget_ms` `None` (or not a positive number)
    /// never splits.
    pub fn new(height: u32, budget_ms: Option<f64>) -> Self {
        let height = height.max(1);
        let budget_ms = budget_ms.filter(|b| b.is_finite() && *b > 0.0);
        let rows = if budget_ms.is_some() { FIRST_ROWS.min(height) } else { height };
        BandPolicy { height, budget_ms, rows, ms_per_row: None }
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
    /// next). A band that may have exceeded the budget is taken at its upper bound; one that
    /// fit at its lower bound, else the polling interval (and, in a browser, the frame the
    /// fence's status takes to arrive) would keep bands far smaller than the budget allows.
    pub fn record_between(&mut self, rows: u32, at_least: f64, at_most: f64) {
        let Some(budget) = self.budget_ms else { return };
        let valid = |ms: f64| ms.is_finite() && ms >= 0.0;
        if rows == 0 || !valid(at_least) || !valid(at_most) {
            return;
        }
        let ms = if at_most > budget { at_most } else { at_least.min(at_most) };
        // The latest band is believed: a slow one shrinks the next at once (it must fit), and a
        // fast one (a lucky band, or one after the slow first draw) grows it at most MAX_GROWTH
        // times, so one outlier neither overshoots the budget far nor keeps bands tiny.
        let estimate = ms / rows as f64;
        self.ms_per_row = Some(estimate);
        let target = budget * TARGET_FRACTION;
        let wanted = if estimate > 0.0 { (target / estimate).floor().min(u32::MAX as f64) as u32 } else { u32::MAX };
        self.rows = wanted.min(rows.saturating_mul(MAX_GROWTH)).clamp(1, self.height);
    }
}

/// What a pacer's step did (the GL runtime's `Pacer::step`, the WebGPU page's loop).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// The previous band is still on the GPU: nothing was submitted.
    Waiting,
    /// A band was submitted; `frame_done`: it was the frame's last (a sample per pixel was added).
    Submitted { frame_done: bool },
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
