//! `?schedule=auto` on WebGPU, measured (`crate::schedule_choice`): once the scene's first frame
//! has shown on the megakernel, the page's loop (`measureSchedule` in `web/www/main.js`) asks
//! for the wavefront beside it on the same device (`beginScheduleMeasurement`), then runs the
//! turns `scheduleTurn` names, whole frames through `measureFrame`, each turn timed the way
//! `renderFrames` times frames (until the device's queue is done) and handed back with
//! `recordScheduleTurn`; after the last the faster schedule is kept (restarting the
//! accumulation if that is the wavefront) and the other renderer dropped. The megakernel's
//! timed frames are the page's frames (the image goes on converging); the wavefront's are drawn
//! nowhere. A restart, a rebuild, a new scene, frames from the test hook or a lost device give
//! the measurement up (the megakernel stays); a wavefront that fails keeps the megakernel with
//! a notice.

use js_sys::Object;
use tracer::backend::Schedule;
use wasm_bindgen::prelude::*;

use super::Viewer;
use crate::js::set;
use crate::runtime::webgpu::{Candidate, GpuRuntime};
use crate::runtime::Runtime;
use crate::schedule_choice::{decide, Choice, Measurement};

/// `measureFrame`'s answers.
const FRAME_PENDING: u32 = 0;
const FRAME_DONE: u32 = 1;
const MEASUREMENT_OVER: u32 = 2;

#[wasm_bindgen]
impl Viewer {
    /// Whether `auto`'s measurement should start now: the schedule is auto, the scene runs on
    /// WebGPU, its first frame has shown and it was not measured since it was loaded. A scene
    /// whose animation plays is not measured while it plays (each pose restarts the
    /// accumulation: recorded as skipped, the megakernel runs); paused, it is measured once the
    /// view has stayed put, as after an interruption. (It was skipped for good: LittlestTokyo
    /// kept the megakernel where the wavefront took 0.89x its frame time.)
    #[wasm_bindgen(js_name = scheduleMeasurementDue)]
    pub fn schedule_measurement_due(&mut self) -> bool {
        let waiting = matches!(self.choice, Choice::Pending | Choice::Interrupted { .. } | Choice::Skipped(_));
        if self.schedule.is_some() || !waiting || self.halted() {
            return false;
        }
        let Some(Runtime::WebGpu(_)) = &self.running else { return false };
        if self.playback.as_ref().is_some_and(|p| p.playing()) {
            self.choice = Choice::Skipped("the scene moves (paused, it is measured)".into());
            return false;
        }
        self.choice.due_at(self.spp())
    }

    /// Starts the measurement: the wavefront for the running scene on the same device. Returns
    /// its id for the calls that follow, or 0 when it did not start (building the wavefront
    /// failed: `sceneInfo().notice` says why, the megakernel runs).
    #[wasm_bindgen(js_name = beginScheduleMeasurement)]
    pub fn begin_schedule_measurement(&mut self) -> u32 {
        if !self.schedule_measurement_due() {
            return 0;
        }
        let (Some(gpu), Some(running)) = (self.gpu.clone(), &self.running) else { return 0 };
        let packed = running.packed().clone();
        match GpuRuntime::prepare(&gpu, &packed, self.seed, &self.wgpu_options, Schedule::Wavefront) {
            Ok(prepared) => {
                self.measurements += 1;
                self.measurement_tries += 1;
                self.candidate = Some(Candidate::new(prepared));
                self.choice = Choice::Measuring(Measurement::new(self.measurements));
                self.measurements
            }
            Err(e) => {
                self.fail_measurement(format!("building it failed: {e}"));
                0
            }
        }
    }

    /// Whether a measurement is in progress (the frame loop and the denoiser wait meanwhile).
    #[wasm_bindgen(js_name = measuringSchedule)]
    pub fn measuring_schedule(&self) -> bool {
        matches!(self.choice, Choice::Measuring(_))
    }

    /// The turn measurement `id` runs now: `{ schedule, frames, warmUp }`, or null when it is
    /// over (done, failed or given up).
    #[wasm_bindgen(js_name = scheduleTurn)]
    pub fn schedule_turn(&self, id: u32) -> JsValue {
        let Choice::Measuring(m) = &self.choice else { return JsValue::NULL };
        let Some(turn) = m.turn().filter(|_| m.id == id) else { return JsValue::NULL };
        let o = Object::new();
        set(&o, "schedule", turn.schedule.name());
        set(&o, "frames", turn.frames);
        set(&o, "warmUp", turn.warm_up);
        o.into()
    }

    /// One whole frame of the current turn's schedule (the rest of it, in one submission):
    /// 0 when it is not done yet (the wavefront's: call again after `sync()`), 1 when it is,
    /// 2 when measurement `id` is over (failed or given up: stop). The megakernel's frame is
    /// drawn (the page's image converges meanwhile); the wavefront's is not.
    #[wasm_bindgen(js_name = measureFrame)]
    pub fn measure_frame(&mut self, id: u32) -> Result<u32, JsError> {
        let turn = match &self.choice {
            Choice::Measuring(m) if m.id == id => m.turn(),
            _ => None,
        };
        let Some(turn) = turn else { return Ok(MEASUREMENT_OVER) };
        if self.halted() {
            self.abandon_measurement("the WebGPU device was lost");
            return Ok(MEASUREMENT_OVER);
        }
        match turn.schedule {
            Schedule::Megakernel => {
                let Some(running) = &mut self.running else { return Ok(MEASUREMENT_OVER) };
                match running.frame(&self.display) {
                    Ok(done) => {
                        if done {
                            self.show_denoised();
                        }
                        Ok(if done { FRAME_DONE } else { FRAME_PENDING })
                    }
                    Err(e) => {
                        self.abandon_measurement("the megakernel reported an error");
                        self.recover(e)?;
                        Ok(MEASUREMENT_OVER)
                    }
                }
            }
            Schedule::Wavefront => {
                let Some(candidate) = &mut self.candidate else { return Ok(MEASUREMENT_OVER) };
                match candidate.frame() {
                    Ok(done) => Ok(if done { FRAME_DONE } else { FRAME_PENDING }),
                    Err(e) => {
                        self.fail_measurement(format!("it failed while rendering: {e}"));
                        Ok(MEASUREMENT_OVER)
                    }
                }
            }
        }
    }

    /// Records the current turn of measurement `id`: `ms_per_frame`, its time (submission of its
    /// first frame until the queue was done after its last) over its frames. After the last turn
    /// the schedule is chosen: the wavefront takes the running renderer's place (the
    /// accumulation restarts) if its median frame time is lower than the megakernel's by more
    /// than 5 %, else the megakernel stays; the other renderer is dropped.
    #[wasm_bindgen(js_name = recordScheduleTurn)]
    pub fn record_schedule_turn(&mut self, id: u32, ms_per_frame: f64) {
        let Choice::Measuring(m) = &mut self.choice else { return };
        if m.id != id || !m.record(ms_per_frame) {
            return;
        }
        let measured = m.clone();
        let (verdict, injected) = match self.injected_times {
            Some((megakernel, wavefront)) => (decide(megakernel, wavefront), true),
            None => (measured.verdict(), false),
        };
        if verdict.chosen == Schedule::Wavefront {
            let adopted = match (&mut self.running, self.candidate.take()) {
                (Some(Runtime::WebGpu(gpu)), Some(candidate)) => gpu.adopt(candidate),
                _ => Err("the WebGPU renderer is gone".into()),
            };
            if let Err(e) = adopted {
                self.fail_measurement(format!("switching to it failed: {e}"));
                return;
            }
            self.denoiser.new_runtime();
        } else {
            self.candidate = None;
            self.watch_uncaptured();
        }
        self.choice = Choice::Measured { verdict, measured, injected };
    }

    /// Gives measurement `id` up (the page's loop failed): the megakernel stays.
    #[wasm_bindgen(js_name = abandonScheduleMeasurement)]
    pub fn abandon_schedule_measurement(&mut self, id: u32, why: &str) {
        if matches!(&self.choice, Choice::Measuring(m) if m.id == id) {
            self.abandon_measurement(why);
        }
    }

    /// Test hook (`?autoScheduleTimes=MK,WF`): `auto` decides on these milliseconds per frame
    /// of the megakernel and the wavefront instead of the measured medians (the measurement
    /// still runs, and `sceneInfo().scheduleChoice` keeps what it measured beside them).
    #[wasm_bindgen(js_name = setScheduleTimesForTest)]
    pub fn set_schedule_times_for_test(&mut self, megakernel_ms: f64, wavefront_ms: f64) {
        self.injected_times = Some((megakernel_ms, wavefront_ms));
    }
}

impl Viewer {
    /// A measurement in progress is given up, `why`; the megakernel stays.
    pub(super) fn abandon_measurement(&mut self, why: &str) {
        if self.choice.abandon(why) {
            self.candidate = None;
            self.watch_uncaptured();
        }
    }

    /// The view or a setting changed during a measurement: it starts again once the view
    /// stays put, longer after each interruption (`Choice::interrupt`).
    pub(super) fn interrupt_measurement(&mut self, why: &str) {
        if self.choice.interrupt(why, self.measurement_tries) {
            self.candidate = None;
            self.watch_uncaptured();
        }
    }

    /// The wavefront failed while measured: the megakernel stays, with a notice.
    fn fail_measurement(&mut self, error: String) {
        self.candidate = None;
        self.watch_uncaptured();
        self.notice =
            Some(format!("auto measured the wavefront against the megakernel, but {error}; the megakernel runs"));
        self.choice = Choice::Failed(error);
    }

    /// The running renderer watches the device's uncaptured errors again.
    fn watch_uncaptured(&mut self) {
        if let Some(Runtime::WebGpu(gpu)) = &mut self.running {
            gpu.watch_uncaptured();
        }
    }

    /// `sceneInfo().scheduleChoice`: `auto`'s measurement (null unless the schedule is auto and
    /// the scene runs on WebGPU): `{ state: pending | measuring | measured | failed | abandoned |
    /// interrupted | skipped, chosen, reason (the read-out's words), megakernelMs, wavefrontMs (the medians
    /// decided on), ratio (wavefront / megakernel), injected (a test's times decided),
    /// measuredMegakernelMs, measuredWavefrontMs (the measured medians), megakernelTurnsMs,
    /// wavefrontTurnsMs (ms per frame of each counted turn), warmUpMs: { megakernel,
    /// wavefront }, rounds, framesPerTurn, tries (measurements begun for this scene: an
    /// interrupted one, state `interrupted`, starts again once the view stays put), error }`.
    pub(super) fn describe_schedule_choice(&self) -> JsValue {
        if self.schedule.is_some() || !matches!(self.running, Some(Runtime::WebGpu(_))) {
            return JsValue::NULL;
        }
        let o = Object::new();
        let choice = &self.choice;
        set(&o, "state", choice.state());
        set(&o, "chosen", choice.schedule().name());
        set(&o, "reason", choice.reason().map_or(JsValue::NULL, JsValue::from));
        set(&o, "rounds", crate::schedule_choice::ROUNDS as u32);
        set(&o, "framesPerTurn", crate::schedule_choice::FRAMES_PER_TURN);
        set(&o, "tries", self.measurement_tries);
        let measurement = match choice {
            Choice::Measuring(m) => Some(m),
            Choice::Measured { verdict, measured, injected } => {
                set(&o, "megakernelMs", verdict.megakernel_ms);
                set(&o, "wavefrontMs", verdict.wavefront_ms);
                set(&o, "ratio", verdict.ratio());
                set(&o, "injected", *injected);
                Some(measured)
            }
            Choice::Failed(e) => {
                set(&o, "error", e.as_str());
                None
            }
            _ => None,
        };
        if let Some(m) = measurement {
            let list = |v: &[f64]| v.iter().copied().map(JsValue::from).collect::<js_sys::Array>();
            let verdict = m.verdict();
            set(&o, "measuredMegakernelMs", verdict.megakernel_ms);
            set(&o, "measuredWavefrontMs", verdict.wavefront_ms);
            set(&o, "megakernelTurnsMs", list(&m.megakernel_ms));
            set(&o, "wavefrontTurnsMs", list(&m.wavefront_ms));
            let warm = Object::new();
            let ms = |v: Option<f64>| v.map_or(JsValue::NULL, JsValue::from);
            set(&warm, "megakernel", ms(m.warm_up_ms[0]));
            set(&warm, "wavefront", ms(m.warm_up_ms[1]));
            set(&o, "warmUpMs", warm);
        }
        o.into()
    }
}
