//! The GL runtime's band pacing: one band of rows on the GPU at a time, each behind a fence,
//! its time fed to the [`BandPolicy`] (the policy and why: `backend/frame_split.rs`).

use glow::HasContext;

use super::GlRenderer;
use crate::backend::frame_split::{polled_bounds, BandPolicy, Step};
use crate::backend::{RenderError, Renderer};

struct InFlight {
    fence: glow::Fence,
    submitted_ms: f64,
    /// The last poll that found the fence unsignalled.
    pending_at_ms: Option<f64>,
    /// The band's rows; 0: other work, waited for but not measured ([`track`](Pacer::track)).
    rows: u32,
}

/// Submits one band at a time, each behind a fence, and feeds the measured times to a
/// [`BandPolicy`]. Call [`step`](Self::step) from the frame loop (the browser's
/// `requestAnimationFrame`) with a clock in milliseconds; call [`forget`](Self::forget) before
/// the renderer goes (the fence is an object of its context).
pub struct Pacer {
    policy: BandPolicy,
    in_flight: Option<InFlight>,
}

impl Pacer {
    pub fn new(height: u32, budget_ms: Option<f64>) -> Self {
        Pacer { policy: BandPolicy::new(height, budget_ms), in_flight: None }
    }

    pub fn policy(&self) -> &BandPolicy {
        &self.policy
    }

    /// Whether a band is on the GPU (submitted, its fence not yet seen signalled).
    pub fn busy(&self) -> bool {
        self.in_flight.is_some()
    }

    /// Checks, without blocking, whether the band in flight is done; records its time if so.
    /// True when no band is in flight (any more).
    pub fn poll(&mut self, gl: &glow::Context, now_ms: f64) -> bool {
        let Some(band) = &mut self.in_flight else { return true };
        // SAFETY: the fence was created on this context and is deleted once, here or in forget.
        let status = unsafe { gl.client_wait_sync(band.fence, 0, 0) };
        match status {
            glow::TIMEOUT_EXPIRED => {
                band.pending_at_ms = Some(now_ms);
                return false;
            }
            glow::ALREADY_SIGNALED | glow::CONDITION_SATISFIED => {
                let (at_least, at_most) = polled_bounds(band.submitted_ms, band.pending_at_ms, now_ms);
                if band.rows > 0 {
                    self.policy.record_between(band.rows, at_least, at_most);
                }
            }
            // WAIT_FAILED (e.g. a lost context): no time to record, and nothing to wait for.
            _ => {}
        }
        // SAFETY: as above.
        unsafe { gl.delete_sync(band.fence) };
        self.in_flight = None;
        true
    }

    /// Submits the next band of `renderer`'s frame unless the previous one is still running.
    /// `then` (given the renderer and whether the band completed the frame) queues what belongs
    /// to the band's submission, e.g. a display pass; the fence and the time include it.
    pub fn step(
        &mut self,
        renderer: &mut GlRenderer,
        now_ms: f64,
        then: impl FnOnce(&GlRenderer, bool),
    ) -> Result<Step, RenderError> {
        if !self.poll(renderer.gl(), now_ms) {
            return Ok(Step::Waiting);
        }
        let rows = self.policy.rows().min(renderer.rows_left());
        let frame_done = renderer.render_band(rows)?;
        then(renderer, frame_done);
        let gl = renderer.gl();
        // SAFETY: a fence and a flush on the renderer's context, which render_band made current.
        let fence = unsafe {
            let fence = gl.fence_sync(glow::SYNC_GPU_COMMANDS_COMPLETE, 0);
            gl.flush();
            fence
        };
        // Without a fence (no sync objects) the band is simply not measured.
        if let Ok(fence) = fence {
            self.in_flight = Some(InFlight { fence, submitted_ms: now_ms, pending_at_ms: None, rows });
        }
        Ok(Step::Submitted { frame_done })
    }

    /// Puts a fence behind work the caller just submitted that is no band (a preview), so that
    /// the next band waits for it as for a band in flight; its time is not measured. Call it
    /// when [`poll`](Self::poll) said nothing is in flight.
    pub fn track(&mut self, gl: &glow::Context, now_ms: f64) {
        self.forget(gl);
        // SAFETY: a fence and a flush on the caller's current context.
        let fence = unsafe {
            let fence = gl.fence_sync(glow::SYNC_GPU_COMMANDS_COMPLETE, 0);
            gl.flush();
            fence
        };
        if let Ok(fence) = fence {
            self.in_flight = Some(InFlight { fence, submitted_ms: now_ms, pending_at_ms: None, rows: 0 });
        }
    }

    /// Drops the band in flight without measuring it (before the renderer's context goes, or
    /// when something else submits work that the band's time would wrongly include).
    pub fn forget(&mut self, gl: &glow::Context) {
        if let Some(band) = self.in_flight.take() {
            // SAFETY: the fence belongs to `gl`'s context and is deleted once.
            unsafe { gl.delete_sync(band.fence) };
        }
    }
}
