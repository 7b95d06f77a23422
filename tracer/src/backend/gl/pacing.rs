//! The GL runtime's band pacing: bands of rows on the GPU, each behind a fence, queued ahead
//! ([`BandsInFlight`]), their times fed to the [`BandPolicy`] (the policy and why:
//! `backend/frame_split.rs`).

use glow::HasContext;

use super::GlRenderer;
use crate::backend::frame_split::{BandPolicy, BandsInFlight, Step};
use crate::backend::{RenderError, Renderer};

/// Rows of the blocks bands cover: fragments are shaded in 2x2 quads, so a band of an odd
/// number of rows shades a quad row it does not keep (`BandPolicy::aligned_to`).
pub const QUAD_ROWS: u32 = 2;

/// Submits bands of rows, each behind a fence, and feeds the measured times to a
/// [`BandPolicy`]. Call [`step`](Self::step) from the frame loop (the browser's
/// `requestAnimationFrame`) with a clock in milliseconds; call [`forget`](Self::forget) before
/// the renderer goes (the fences are objects of its context).
pub struct Pacer {
    policy: BandPolicy,
    in_flight: BandsInFlight<glow::Fence>,
}

impl Pacer {
    pub fn new(height: u32, budget_ms: Option<f64>) -> Self {
        let policy = BandPolicy::new(height, budget_ms).aligned_to(QUAD_ROWS);
        Pacer { in_flight: BandsInFlight::for_policy(&policy), policy }
    }

    pub fn policy(&self) -> &BandPolicy {
        &self.policy
    }

    /// Whether work is on the GPU (submitted, its fence not yet seen signalled).
    pub fn busy(&self) -> bool {
        !self.in_flight.is_empty()
    }

    /// Checks, without blocking, which work in flight is done; records the bands' times.
    /// True when nothing is in flight (any more).
    pub fn poll(&mut self, gl: &glow::Context, now_ms: f64) -> bool {
        self.in_flight.poll(
            now_ms,
            &mut self.policy,
            // SAFETY: the fences were created on this context and are deleted once, on release.
            |&fence| match unsafe { gl.client_wait_sync(fence, 0, 0) } {
                glow::TIMEOUT_EXPIRED => Some(false),
                glow::ALREADY_SIGNALED | glow::CONDITION_SATISFIED => Some(true),
                // WAIT_FAILED (e.g. a lost context): no time to record, and nothing to wait for.
                _ => None,
            },
            // SAFETY: as above.
            |fence| unsafe { gl.delete_sync(fence) },
        )
    }

    /// Tops the GPU's queue up with bands of `renderer`'s frame, as many as the queue admits
    /// (a frame's first band once the last frame's are done): `Waiting` if none, else whether
    /// the last completed the frame. `then` (given the renderer and whether the band completed
    /// the frame) queues what belongs to each band's submission, e.g. a display pass; the fence
    /// and the time include it.
    pub fn step(
        &mut self,
        renderer: &mut GlRenderer,
        now_ms: f64,
        mut then: impl FnMut(&GlRenderer, bool),
    ) -> Result<Step, RenderError> {
        self.poll(renderer.gl(), now_ms);
        let mut step = Step::Waiting;
        let height = renderer.packed().scene.height;
        while self.in_flight.admits(now_ms, renderer.rows_left() == height, self.policy.band_ms()) {
            let rows = self.policy.rows().min(renderer.rows_left());
            let frame_done = renderer.render_band(rows)?;
            then(renderer, frame_done);
            // Without a fence (no sync objects) the band is simply not measured, nor queued behind.
            let Some(fence) = fence_and_flush(renderer.gl()) else { return Ok(Step::Submitted { frame_done }) };
            self.in_flight.push(fence, now_ms, rows, self.policy.band_ms());
            step = Step::Submitted { frame_done };
        }
        Ok(step)
    }

    /// Puts a fence behind work the caller just submitted that is no band (a preview), so that
    /// the next band waits for it as for a band in flight; its time is not measured. Call it
    /// when [`poll`](Self::poll) said nothing is in flight.
    pub fn track(&mut self, gl: &glow::Context, now_ms: f64) {
        self.forget(gl);
        if let Some(fence) = fence_and_flush(gl) {
            self.in_flight.push(fence, now_ms, 0, None);
        }
    }

    /// Drops the work in flight without measuring it (before the renderer's context goes, or
    /// when something else submits work that a band's time would wrongly include).
    pub fn forget(&mut self, gl: &glow::Context) {
        // SAFETY: the fences belong to `gl`'s context and are deleted once.
        self.in_flight.clear(|fence| unsafe { gl.delete_sync(fence) });
    }
}

/// A fence behind everything submitted on `gl`'s current context so far, flushed so that the
/// GPU gets it.
fn fence_and_flush(gl: &glow::Context) -> Option<glow::Fence> {
    // SAFETY: a fence and a flush on the current context.
    unsafe {
        let fence = gl.fence_sync(glow::SYNC_GPU_COMMANDS_COMPLETE, 0);
        gl.flush();
        fence.ok()
    }
}
