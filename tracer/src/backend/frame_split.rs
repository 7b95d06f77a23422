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
//! [`TARGET_FRACTION`] of the budget ([`DEFAULT_BUDGET_MS`], 100 ms), start small
//! ([`FIRST_ROWS`]), at most double per band, and shrink at once when a band was slow.
//! Where even the thinnest band (one row, or one block of rows: below) takes more than [`FIXED_COST_BUDGETS`] budgets (the fastest of
//! [`THIN_SAMPLES`] such bands: a band's measured time only errs upwards), the cost is the
//! band's, not its rows' (a driver's work per draw, a fence's round trip): no split keeps
//! submissions short, and the thinnest bands would only multiply that cost by the height. Bands are
//! then sized so that it is at most half of each (written for LittlestTokyo posed by its
//! animation, WebGL2 on SwiftShader at 320x240: ~250 ms per band whatever its height, which
//! turned out to be the page's own read-outs hashing every texel each animation frame; a
//! driver's cost per draw would look the same).
//! The GL runtime's `Pacer` (`backend/gl/pacing.rs`) measures: it puts a fence (`glFenceSync`, core in WebGL2 and OpenGL ES 3.0) behind
//! each band and polls it without blocking (`glClientWaitSync` with a zero timeout, the only
//! timeout WebGL allows); a band's time lies between the last poll that saw it pending and the
//! poll that sees it signalled ([`polled_bounds`]), so it is known to the caller's polling
//! interval (an animation frame in the browser). No timer-query extension is needed (WebGL2 has none on SwiftShader and
//! many phones), nothing blocks the thread, and nothing is read back.
//!
//! Bands can cover whole blocks of rows ([`BandPolicy::aligned_to`]): a GPU shades fragments in 2x2
//! quads and a compute megakernel runs 8x8 workgroups, so a band of 1 row costs what 2 (GL) or
//! 8 (WebGPU) rows do, and a band that starts mid-block pays for the block's other rows twice.
//! Measured in the page (`tests/web/bench.mjs --band-rows`: the Cornell box at 640x480, a frame
//! in bands of N rows submitted back to back against the whole frame, SwiftShader): WebGL2 1
//! row 1.95x, 3 rows 1.29x, while 2, 4, 6, 8 and 16 rows took 0.98-1.04x; WebGPU 1 row 1.60x, 2
//! rows 1.25x, 3 rows 1.13x, 4 rows 1.05x, 8 rows 0.99x. The frame loop's bands (4-7 rows of any
//! parity, starting anywhere) had cost it up to 1.6x a whole frame on WebGL2 (docs/web.md).
//! GL's `Pacer` aligns to its quads, the WebGPU page to its workgroups (`policy_for` in
//! `web/src/runtime/webgpu.rs`).
//!
//! Bands are queued ahead ([`BandsInFlight`]): each tick of the frame loop tops the GPU's queue up
//! to [`AHEAD_BUDGETS`] budgets of estimated work. The news that a band is done reaches the page
//! a tick or more after the GPU finished it (a browser updates a fence's status, and resolves
//! `onSubmittedWorkDone`, between tasks): with one band in flight the GPU idled that long after
//! every band, and the delay, counted as the band's time, kept bands at a few rows. A band
//! queued behind another is timed from that one's news to its own, in which the delay cancels.
//! A frame's first band waits until the last frame's are seen done (a pose, a denoise or a
//! restart's preview come between frames), so new work waits for at most the queued bands.

/// The longest a single GPU submission should take (milliseconds), by default. 50 until
/// 2026-12-07: in headless Chromium on SwiftShader the WebGL2 frame loop paid ~8 ms per band
/// beyond its rows (cause not found; not where bands are submitted back to back), 1.3x a frame
/// in one submission with 50 ms bands, 1.1x with 100 (docs/web.md, "Fewer, larger bands").
pub const DEFAULT_BUDGET_MS: f64 = 100.0;
/// Bands aim at this fraction of the budget: headroom for the variation between bands (rows
/// that see the sky cost less than rows inside a room) and for the measurement's rounding.
pub const TARGET_FRACTION: f64 = 0.7;
/// Rows of the first band, before anything is measured (the first draw also pays the driver's
/// shader compilation, so it is small whatever the device).
pub const FIRST_ROWS: u32 = 8;
/// A band is at most this many times the rows of the band measured before it.
pub const MAX_GROWTH: u32 = 2;
/// Thinnest bands (one block of rows) slower than this many budgets (the fastest of [`THIN_SAMPLES`]) mean a cost
/// per band that splitting cannot avoid.
pub const FIXED_COST_BUDGETS: f64 = 2.0;
/// Thinnest bands measured before their fastest is believed as the cost of any band.
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

/// The estimated GPU work a frame loop queues ahead, in budgets ([`BandsInFlight`]). Headless
/// Chromium on SwiftShader learnt of a finished band 2-3 animation frames late: with one band
/// in flight the Cornell box at 640x480 took 6.0 s a frame in bands of 4 rows (WebGL2), against
/// 1.8 s in one submission. Queued work must outlast a tick and the news' delay, or the GPU
/// idles, the idle time is timed as the bands', and bands shrink further.
///
/// 1.5 budgets of 100 ms: the 150 ms that 3 budgets of 50 were, which a restart waits for.
pub const AHEAD_BUDGETS: f64 = 1.5;
/// Submissions in flight, at most (fences are objects of the context).
pub const MAX_IN_FLIGHT: usize = 16;
/// Work not yet seen done (estimated) is at most this many times the queue's aim: the queue
/// aims at the work its model says is still to run (news may come late, or in bursts), and
/// this bounds what the model could hide if bands ran slower than estimated.
pub const UNSEEN_AHEAD: f64 = 2.0;
/// Bands timed together when they ran back to back ([`BandsInFlight`]): a band seen done one
/// tick late or early is then a tick in this many bands' time, not in one's.
pub const STREAK: usize = 4;
/// The span (ms, from submission to news) over which bands queued back to back bound their
/// rate from above ([`BandsInFlight`]): long against the news' delay and the wait in the queue.
pub const WINDOW_MS: f64 = 1000.0;

/// The work a frame loop submitted and has not yet seen done, oldest first, each behind its
/// `F` (a GL fence, a WebGPU done flag): bands of a frame and other work (a preview: waited
/// for, not timed). Bands seen done are timed into a [`BandPolicy`]. A band queued behind
/// another ran from when that one was done: it is timed from that one's news to its own, in
/// which the delay of the news cancels; such bands in a row (up to [`STREAK`]) are timed
/// together, as the rate of their rows, so that one seen a tick late does not halve or double
/// the next band. A band submitted to an idle GPU is timed from its submission, the news'
/// delay included, between bounds ([`polled_bounds`]).
///
/// News to news assumes the news comes equally late. Under contention (a second browser on
/// two cores) it came in bursts: held, then a band per poll, so bands that ran for 150 ms
/// were seen done milliseconds apart and timed at a tenth of that. The bands since the queue
/// was last idle, over at least [`WINDOW_MS`] of submissions, bound the rate from above
/// whatever the news does (they cannot have run before they were submitted nor after they
/// were seen done), and news to news is believed down to half that bound (as a band with no
/// lower bound is: [`BandPolicy::record_between`]).
#[derive(Debug)]
pub struct BandsInFlight<F> {
    queued: std::collections::VecDeque<InFlight<F>>,
    /// The estimated GPU work that may be queued (ms); 0: one submission at a time.
    ahead_ms: f64,
    /// When the last work was seen done.
    last_done_ms: Option<f64>,
    /// When the queued bands end if each takes its estimate, from when the GPU was last
    /// idle (`None`: work of no estimate is queued): see [`admits`](Self::admits).
    end_ms: Option<f64>,
    /// The bands seen done since the queue was last idle (the latest last; trimmed to the last
    /// [`WINDOW_MS`] of submissions, but at least [`STREAK`] + 1), each poll's bands together.
    busy: std::collections::VecDeque<Seen>,
}

/// Bands seen done at one poll.
#[derive(Clone, Copy, Debug)]
struct Seen {
    rows: u32,
    /// When the first of them was submitted.
    submitted_ms: f64,
    seen_ms: f64,
}

#[derive(Debug)]
struct InFlight<F> {
    marker: F,
    submitted_ms: f64,
    /// The last poll that found it not done.
    pending_at_ms: Option<f64>,
    /// Its rows; 0: other work (waited for, not timed).
    rows: u32,
    /// Its estimated GPU time, if known.
    estimate_ms: Option<f64>,
}

impl<F> BandsInFlight<F> {
    /// A queue of up to `ahead_ms` of estimated GPU work (0: one submission at a time).
    pub fn new(ahead_ms: f64) -> Self {
        BandsInFlight {
            queued: Default::default(),
            ahead_ms: if ahead_ms.is_finite() { ahead_ms.max(0.0) } else { 0.0 },
            last_done_ms: None,
            end_ms: None,
            busy: Default::default(),
        }
    }

    /// A queue for bands sized by `policy`: [`AHEAD_BUDGETS`] of its budget (unsplit frames:
    /// one at a time).
    pub fn for_policy(policy: &BandPolicy) -> Self {
        Self::new(policy.budget_ms().map_or(0.0, |budget| budget * AHEAD_BUDGETS))
    }

    /// Whether nothing is in flight.
    pub fn is_empty(&self) -> bool {
        self.queued.is_empty()
    }

    /// Whether a band estimated at `next_ms` may be submitted at `now_ms`: anything to an
    /// idle GPU; a frame's first band (`starts_frame`) only then; another while the work still
    /// to run with it stays within the queue's aim, and all work not seen done within
    /// [`UNSEEN_AHEAD`] times that.
    ///
    /// The work still to run is a model's: the queued bands run back to back from when the GPU
    /// was last idle, each for its estimate, and none ends after it was seen done. Counting
    /// every band not yet *seen* done instead, the queue held the news' delay less work than
    /// its aim, and where the news came a few ticks late the GPU ran dry after every band
    /// (simulated in the unit tests; in headless Chromium on SwiftShader the frame loop's
    /// remaining cost was not this: docs/web.md, "Fewer, larger bands").
    pub fn admits(&self, now_ms: f64, starts_frame: bool, next_ms: Option<f64>) -> bool {
        if self.queued.is_empty() {
            return true;
        }
        if starts_frame || self.queued.len() >= MAX_IN_FLIGHT {
            return false;
        }
        let unseen: Option<f64> = self.queued.iter().map(|band| band.estimate_ms).sum();
        let (Some(unseen), Some(end), Some(next)) = (unseen, self.end_ms, next_ms) else { return false };
        let to_run = (end - now_ms).clamp(0.0, unseen);
        to_run + next <= self.ahead_ms && unseen + next <= UNSEEN_AHEAD * self.ahead_ms
    }

    /// Records work submitted at `submitted_ms` behind `marker`: a band of `rows` rows
    /// estimated at `estimate_ms`, or other work (`rows` 0) that is waited for and not timed.
    pub fn push(&mut self, marker: F, submitted_ms: f64, rows: u32, estimate_ms: Option<f64>) {
        let idle = self.queued.is_empty();
        self.end_ms = match (estimate_ms, self.end_ms) {
            (Some(estimate), _) if idle => Some(submitted_ms + estimate),
            (Some(estimate), Some(end)) => Some(end.max(submitted_ms) + estimate),
            _ => None,
        };
        self.queued.push_back(InFlight { marker, submitted_ms, pending_at_ms: None, rows, estimate_ms });
    }

    /// Asks `done` about the work in flight, oldest first, until some is not done (`done`:
    /// `Some(true)` done, `Some(false)` not yet, `None` never: a lost context; dropped
    /// untimed); hands each finished marker to `release` and times the bands among them into
    /// `policy`. True when nothing is in flight (any more).
    pub fn poll(
        &mut self,
        now_ms: f64,
        policy: &mut BandPolicy,
        mut done: impl FnMut(&F) -> Option<bool>,
        mut release: impl FnMut(F),
    ) -> bool {
        let (mut first, mut pending, mut rows, mut timed) = (None, None, 0u32, true);
        while let Some(oldest) = self.queued.front_mut() {
            let finished = done(&oldest.marker);
            if finished == Some(false) {
                oldest.pending_at_ms = Some(now_ms);
                break;
            }
            let band = self.queued.pop_front().expect("the front is there");
            first.get_or_insert(band.submitted_ms);
            pending = band.pending_at_ms;
            rows = rows.saturating_add(band.rows);
            timed &= band.rows > 0 && finished.is_some();
            release(band.marker);
        }
        let Some(submitted_ms) = first else { return self.queued.is_empty() };
        // The bands still queued ran after those seen done now.
        let left: Option<f64> = self.queued.iter().map(|band| band.estimate_ms).sum();
        self.end_ms = self.end_ms.zip(left).map(|(end, left)| end.min(now_ms + left));
        // Queued behind work seen done since (at a later poll than its submission): it ran
        // from that work's end.
        let behind = self.last_done_ms.filter(|&t| t > submitted_ms);
        self.last_done_ms = Some(now_ms);
        let seen = Seen { rows, submitted_ms, seen_ms: now_ms };
        match behind {
            Some(previous) if timed => {
                let (news_to_news, bound) = self.busy_rate(seen, previous);
                policy.record(rows, news_to_news.max(bound / 2.0) * rows as f64);
            }
            _ => {
                self.busy.clear();
                if timed {
                    self.busy.push_back(seen);
                    let (at_least, at_most) = polled_bounds(submitted_ms, pending, now_ms);
                    policy.record_between(rows, at_least, at_most);
                }
            }
        }
        self.queued.is_empty()
    }

    /// Drops what is in flight untimed, handing each marker to `release` (before the context
    /// goes, or when other work would be counted in a band's time).
    pub fn clear(&mut self, release: impl FnMut(F)) {
        self.queued.drain(..).map(|band| band.marker).for_each(release);
        self.last_done_ms = None;
        self.end_ms = None;
        self.busy.clear();
    }

    /// Adds `seen` (queued behind work seen done at `previous`) to the busy queue's bands:
    /// their rate (ms per row) news to news over the last [`STREAK`], and its upper bound
    /// from submission to news over the last [`WINDOW_MS`].
    fn busy_rate(&mut self, seen: Seen, previous: f64) -> (f64, f64) {
        self.busy.push_back(seen);
        let now = seen.seen_ms;
        while self.busy.len() > STREAK + 1 && now - self.busy[1].submitted_ms >= WINDOW_MS {
            self.busy.pop_front();
        }
        let rows_since = |i: usize| self.busy.range(i..).map(|band| band.rows).sum::<u32>().max(1) as f64;
        // The last STREAK bands (those after the first, which was timed from its submission),
        // from the news before them.
        let n = self.busy.len();
        let streak = STREAK.min(n - 1).max(1);
        let streak_from = if n > streak { self.busy[n - streak - 1].seen_ms } else { previous };
        let news_to_news = (now - streak_from).max(0.0) / rows_since(n - streak);
        // From the latest band submitted WINDOW_MS or more ago (the oldest if none was).
        let first = (0..n).rev().find(|&i| now - self.busy[i].submitted_ms >= WINDOW_MS).unwrap_or(0);
        let bound = (now - self.busy[first].submitted_ms).max(0.0) / rows_since(first);
        (news_to_news, bound)
    }
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
    /// The last thinnest bands' times.
    thin: ThinBands,
    /// Where a band's own cost rules ([`FIXED_COST_BUDGETS`]), the cost per row beyond the
    /// thinnest band's, once a thicker band measured it.
    per_row: Option<f64>,
    /// Bands are whole multiples of this many rows ([`aligned_to`](Self::aligned_to)), but for
    /// a frame's last band (the rows left).
    multiple: u32,
}

/// The times of the last [`THIN_SAMPLES`] thinnest bands.
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
        BandPolicy { height, budget_ms, rows, ms_per_row: None, thin: ThinBands::default(), per_row: None, multiple: 1 }
    }

    /// The policy with bands of whole multiples of `rows` rows (the device's block of rows: 2
    /// for GL's 2x2 fragment quads, the workgroup's height for a compute kernel; see the
    /// module's comment for what a band across blocks costs), so that every band also starts
    /// on a block. A frame's last band covers the rows left; `rows` 0 counts as 1.
    pub fn aligned_to(mut self, rows: u32) -> Self {
        self.multiple = rows.max(1);
        self.rows = self.aligned(self.rows);
        self
    }

    /// `rows` rounded down to a multiple of the block, at least one block, at most the height.
    fn aligned(&self, rows: u32) -> u32 {
        let whole = rows.clamp(1, self.height) / self.multiple * self.multiple;
        whole.max(self.thinnest())
    }

    /// The thinnest band: one block of rows (the whole frame if shorter).
    fn thinnest(&self) -> u32 {
        self.multiple.min(self.height)
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
        if rows == self.thinnest() {
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
        self.rows = self.aligned(wanted.min(rows.saturating_mul(MAX_GROWTH)));
    }

    /// Band heights where a band costs `one_row` ms (the thinnest band's time) or more whatever
    /// its rows: a band of `rows` took `ms`. The first thinnest band is followed by a thicker
    /// probe; a thicker band gives the cost per row beyond the thinnest's, and bands grow to the height at which the band's own
    /// cost is half of each (at most [`MAX_GROWTH`]² times the last, so that one outlier does
    /// not make whole frames). A thicker band within the budget shows that the cost was not the
    /// band's: the thinnest bands' times are forgotten and the budget rules again (false).
    fn amortise(&mut self, one_row: f64, rows: u32, ms: f64, budget: f64) -> bool {
        let thinnest = self.thinnest();
        if rows > thinnest && ms <= budget {
            self.thin = ThinBands::default();
            self.per_row = None;
            return false;
        }
        if rows > thinnest {
            self.per_row = Some(((ms - one_row) / (rows - thinnest) as f64).max(0.0));
        }
        let Some(per_row) = self.per_row else {
            self.rows = self.aligned(PROBE_ROWS.max(2 * thinnest));
            self.ms_per_row = Some(one_row / thinnest as f64);
            return true;
        };
        let fixed = (one_row - per_row * thinnest as f64).max(0.0);
        let limit = rows.saturating_mul(MAX_GROWTH * MAX_GROWTH);
        let wanted = if per_row > 0.0 { (fixed / per_row).ceil().min(u32::MAX as f64) as u32 } else { limit };
        self.rows = self.aligned(wanted.min(limit));
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
mod tests;
