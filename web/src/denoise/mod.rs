//! The denoiser in the page (`Viewer::setDenoise`, the page's Denoise control, `?denoise=0|1`):
//! `tracer::denoise` over the accumulation with the guide the path tracer accumulated beside
//! it, the à-trous passes on the runtime that renders (`GlFilter`'s fragment passes on WebGL2,
//! queued behind a fence the frame loop polls; `WgpuFilter`'s compute passes on WebGPU, run as
//! promises), neither blocking the page, the remodulation by `tracer::denoise::denoise_on`
//! itself over the passes' output ([`gpu::Replay`]), and the denoised image drawn through the
//! same display transform as the raw one ([`show`]).
//!
//! **When it denoises.** The passes cost about 800 ms at 640x480 on SwiftShader (a few ms on a
//! real GPU); while they run the GPU renders nothing else (on WebGL2 no band is submitted
//! until their fence is signalled). So the page denoises when the accumulation has reached
//! [`FIRST_SPP`] samples per pixel and then whenever the sample count has doubled since the
//! image shown was denoised (4, 8, 16, ... spp: the filter's share of the time falls as the
//! image converges), and never sooner than [`SPACING`] times the last denoise's time after it
//! ended (at most about a third of the time goes to the filter); the first waits until the
//! accumulation has run [`SETTLE_MS`] without a restart (the camera has stopped). In between,
//! the latest denoised image stays on the canvas while the raw accumulation goes on. A restart
//! (camera move, strategy, depth, size, seed, API) shows the raw image until the next denoise
//! of the new accumulation; a denoise of an older accumulation that finishes late is dropped.
//! One denoise is in flight at a time: a due one waits for it.
//!
//! **On request** ([`PageDenoiser::request`], `Viewer::denoiseNow`): a denoise of the
//! accumulation as it is now, whatever the rule says (after the one in flight, if any); with
//! the schedule off ([`PageDenoiser::set_schedule`], `Viewer::setDenoiseSchedule`) only
//! requested denoises run, so that `lightport chart --denoise` times a render to N samples per
//! pixel denoised once (`tests/web/run.mjs chart`).
//!
//! **The guide** comes from one function, [`page_guide`]: the sums the path tracer accumulates
//! beside the colour (`Features::denoise_guide`: the renderer is created with it while the
//! denoiser is on), read back with the accumulation at the same sample count.

pub mod gpu;
pub mod show;

use std::cell::RefCell;
use std::rc::Rc;

use glam::Vec4;
use js_sys::Object;
use tracer::backend::{mean_image, Image, Renderer};
use tracer::denoise::{denoise_on, filter_input, Guide};
use wasm_bindgen::JsValue;

use self::gpu::{GpuFilter, Replay, Slot, StagedRead};
use crate::js::{now_ms, set};
use crate::runtime::Runtime;

/// The first denoise of an accumulation waits for this many samples per pixel (below, the
/// variance says little and the filter spreads light: see the README's "Where it is weak").
pub const FIRST_SPP: u32 = 4;
/// A denoise starts no sooner than this many times the last one's time after the last ended.
pub const SPACING: f64 = 2.0;
/// The first denoise of an accumulation also waits until it has run this long without a
/// restart: while the camera moves (restarts every few frames on a fast GPU), the read-backs
/// and the filter would only compete with the frames that follow the input.
pub const SETTLE_MS: f64 = 300.0;

/// The denoised image on show.
struct Shown {
    /// The accumulation it was denoised from (see [`PageDenoiser::generation`]).
    generation: u64,
    spp: u32,
    image: Image,
    /// Names this image for the display passes (uploaded once).
    id: u64,
}

/// What a denoise in flight waits for.
enum Stage {
    /// The accumulation and the guide being read back ([`page_guide`]).
    Reading(PageRead),
    /// The passes on the GPU. WebGPU: where the output arrives; WebGL2: `None`, the runtime
    /// holds the queued passes.
    Filtering { image: Image, guide: Guide, output: Option<Slot<Vec<Vec4>>> },
}

/// A denoise in flight.
struct Job {
    generation: u64,
    spp: u32,
    stage: Stage,
    started_ms: f64,
    /// Milliseconds from the start to the guide and accumulation read back.
    read_ms: f64,
}

/// The accumulation and the guide being read back at one sample count ([`page_guide`]).
struct PageRead {
    sums: Sums,
    guide: Slot<Guide>,
}

/// The accumulation's read: done (WebGL2 reads synchronously) or a staging copy (WebGPU).
enum Sums {
    Now(Option<Result<Vec<Vec4>, String>>),
    Staged(StagedRead),
}

impl PageRead {
    /// Both reads, once both arrived.
    fn take(&mut self) -> Option<Result<(Vec<Vec4>, Guide), String>> {
        self.guide.borrow().as_ref()?;
        let sums = match &mut self.sums {
            Sums::Now(sums) => sums.take()?,
            Sums::Staged(read) => read.take()?,
        };
        let guide = self.guide.borrow_mut().take()?;
        Some(sums.and_then(|sums| guide.map(|guide| (sums, guide))))
    }
}

/// THE source of the page's guide (the only one): the guide `running`'s path tracer
/// accumulated beside the image, read back with the accumulation, both at the current sample
/// count (between frames). WebGL2 reads synchronously; on WebGPU both are promises (the
/// accumulation through a staging buffer of the page's own).
fn page_guide(running: &Runtime) -> PageRead {
    let spp = running.frames();
    let sums = match running {
        Runtime::WebGl2(r) => {
            Sums::Now(Some(r.renderer().accumulation().map_err(|e| format!("reading the accumulation failed: {e}"))))
        }
        Runtime::WebGpu(r) => Sums::Staged(StagedRead::queue(r.renderer())),
    };
    let read = running.renderer().read_guide_sums();
    let guide: Slot<Guide> = Rc::new(RefCell::new(None));
    let filled = guide.clone();
    wasm_bindgen_futures::spawn_local(async move {
        let sums = read.await.map_err(|e| format!("reading the denoiser's guide failed: {e}"));
        *filled.borrow_mut() = Some(sums.map(|s| Guide::from_sums(spp, &s)));
    });
    PageRead { sums, guide }
}

/// The page's denoiser state: whether it is on, the denoise in flight and the image on show.
pub struct PageDenoiser {
    enabled: bool,
    /// Whether the rule above starts denoises (else only [`request`](Self::request)s do).
    schedule: bool,
    /// A denoise of the current accumulation at this many samples per pixel was asked for
    /// ([`request`](Self::request)) and has not started yet.
    requested: Option<(u64, u32)>,
    /// Bumped at every restart of the accumulation (and new renderer): older results are dropped.
    generation: u64,
    /// WebGPU: the filter pass on the current renderer's device.
    gpu_filter: Option<GpuFilter>,
    job: Option<Job>,
    shown: Option<Shown>,
    next_id: u64,
    /// The last denoise: when it ended, its whole time (read-backs, demodulation, passes,
    /// remodulation) and the read-backs' share, in milliseconds.
    last_end_ms: Option<f64>,
    filter_ms: Option<f64>,
    guide_ms: Option<f64>,
    /// Why the current accumulation is not denoised (cleared at the next restart).
    error: Option<String>,
    /// When the current accumulation began (`performance.now()`).
    restarted_ms: f64,
}

impl PageDenoiser {
    pub fn new(enabled: bool) -> Self {
        PageDenoiser {
            enabled,
            schedule: true,
            requested: None,
            generation: 0,
            gpu_filter: None,
            job: None,
            shown: None,
            next_id: 0,
            last_end_ms: None,
            filter_ms: None,
            guide_ms: None,
            error: None,
            restarted_ms: now_ms(),
        }
    }

    pub fn enabled(&self) -> bool {
        self.enabled
    }

    /// Switches the denoiser on or off. Off: the raw image shows. (The renderer needs the
    /// guide while it is on: the viewer recreates it when it lacks it.)
    pub fn set_enabled(&mut self, on: bool) {
        self.enabled = on;
        self.shown = None;
    }

    /// Whether the page's rule (see the module) starts denoises; off, only requested ones run.
    pub fn set_schedule(&mut self, on: bool) {
        self.schedule = on;
    }

    /// Asks for a denoise of `running`'s accumulation as it is now, whatever the rule says: it
    /// starts at the next poll (after the denoise in flight, if any). Nothing to do when the
    /// image shown already is this accumulation denoised at its sample count. An error when the
    /// denoiser is off, failed on this accumulation, or the renderer lacks the guide, or
    /// nothing is rendered yet.
    pub fn request(&mut self, running: &Runtime) -> Result<(), String> {
        if !self.enabled {
            return Err("the denoiser is off (setDenoise(true) first)".into());
        }
        if !running.packed().features.denoise_guide {
            return Err("the renderer does not accumulate the denoiser's guide".into());
        }
        if let Some(e) = &self.error {
            return Err(format!("the denoiser failed on this accumulation: {e}"));
        }
        let spp = running.frames();
        if spp == 0 {
            return Err("nothing is rendered yet (0 samples per pixel)".into());
        }
        let shown = self.shown.as_ref().filter(|s| s.generation == self.generation).map(|s| s.spp);
        if shown != Some(spp) && self.pending() != Some(spp) {
            self.requested = Some((self.generation, spp));
        }
        Ok(())
    }

    /// The image on show for the current accumulation, its sample count and the time its
    /// denoise took (milliseconds), if there is one.
    pub fn shown(&self) -> Option<(u32, &Image, f64)> {
        let shown = self.shown.as_ref().filter(|s| self.enabled && s.generation == self.generation)?;
        Some((shown.spp, &shown.image, self.filter_ms.unwrap_or(f64::NAN)))
    }

    /// The accumulation restarted: the raw image shows until the next denoise.
    pub fn restart(&mut self) {
        self.requested = None;
        self.generation += 1;
        self.shown = None;
        self.error = None;
        self.restarted_ms = now_ms();
    }

    /// A new renderer (size, seed, API, guide, context or device): as a restart, and the
    /// WebGPU filter pass is compiled again on the new device.
    pub fn new_runtime(&mut self) {
        self.restart();
        self.gpu_filter = None;
        self.job = None;
    }

    /// The denoised image to show instead of the raw one, and its id, if the current
    /// accumulation has one.
    pub fn current(&self) -> Option<(&Image, u64)> {
        let shown = self.shown.as_ref().filter(|s| self.enabled && s.generation == self.generation)?;
        Some((&shown.image, shown.id))
    }

    fn pending(&self) -> Option<u32> {
        self.job.as_ref().filter(|j| j.generation == self.generation).map(|j| j.spp)
    }

    pub fn fail(&mut self, error: String) {
        web_sys::console::error_1(&format!("the denoiser: {error}").into());
        self.error = Some(error);
    }

    /// Advances the denoise in flight (read-backs arrived: queue the passes; passes done:
    /// remodulate and show), then starts a denoise if one is due. Call it after each frame
    /// and from the frame loop also while no frame is rendered. Returns whether a new denoised
    /// image is ready to show.
    pub fn poll(&mut self, running: &mut Runtime) -> bool {
        if !self.enabled {
            return false;
        }
        let ready = self.advance(running);
        if self.due(running, now_ms()) {
            self.start(running);
        }
        ready
    }

    /// Whether the accumulation should be denoised now (see the module's rule).
    fn due(&self, running: &Runtime, now: f64) -> bool {
        let spp = running.frames();
        let requested = self.requested == Some((self.generation, spp));
        let scene = &running.packed().scene;
        let between_frames = running.renderer().rows_left() == scene.height;
        let shown = self.shown.as_ref().filter(|s| s.generation == self.generation).map_or(0, |s| s.spp);
        let spaced = match (self.last_end_ms, self.filter_ms) {
            (Some(end), Some(ms)) => now - end >= SPACING * ms,
            _ => true,
        } && (shown > 0 || now - self.restarted_ms >= SETTLE_MS);
        let has_guide = running.packed().features.denoise_guide;
        let by_rule = self.schedule && spp >= FIRST_SPP.max(2 * shown) && spaced;
        self.job.is_none() && self.error.is_none() && has_guide && between_frames && (requested || by_rule)
    }

    /// Starts a denoise of the accumulation as it is: its read-back and the guide's
    /// ([`page_guide`]); later polls queue the passes and show the result. On WebGPU the filter
    /// pass is compiled first (a promise; a later poll starts the denoise).
    fn start(&mut self, running: &mut Runtime) {
        if let Runtime::WebGpu(r) = running {
            let device = r.renderer().device();
            match self.gpu_filter.get_or_insert_with(|| GpuFilter::compile(device)).ready() {
                Ok(Some(_)) => {}
                Ok(None) => return,
                Err(e) => return self.fail(e),
            }
        }
        self.requested = None;
        let stage = Stage::Reading(page_guide(running));
        self.job =
            Some(Job { generation: self.generation, spp: running.frames(), stage, started_ms: now_ms(), read_ms: 0.0 });
    }

    /// Moves the job in flight on; true when it finished with an image to show.
    fn advance(&mut self, running: &mut Runtime) -> bool {
        let Some(job) = &mut self.job else { return false };
        let result = match &mut job.stage {
            Stage::Reading(reading) => {
                let Some(read) = reading.take() else { return false };
                job.read_ms = now_ms() - job.started_ms;
                read.and_then(|(sums, guide)| {
                    let scene = &running.packed().scene;
                    let image = mean_image(scene.width, scene.height, job.spp, &sums);
                    let input = filter_input(&image, &guide).map_err(|e| e.to_string())?;
                    let output = match &mut *running {
                        Runtime::WebGl2(r) => r.queue_filter(&input).map(|()| None)?,
                        Runtime::WebGpu(r) => {
                            let filter = match self.gpu_filter.as_mut().map(GpuFilter::ready) {
                                Some(Ok(Some(f))) => f,
                                _ => return Err("the WebGPU filter pass is not ready".to_string()),
                            };
                            Some(gpu::run_filter(&filter, r.renderer().device(), &input)?)
                        }
                    };
                    job.stage = Stage::Filtering { image, guide, output };
                    Ok(None)
                })
            }
            Stage::Filtering { image, guide, output } => {
                let done = match (output, &mut *running) {
                    (Some(slot), _) => slot.borrow_mut().take(),
                    (None, Runtime::WebGl2(r)) => r.filter_output(),
                    (None, Runtime::WebGpu(_)) => Some(Err("the filter's output was lost".to_string())),
                };
                let Some(done) = done else { return false };
                let mut replay = Replay { packed: running.packed(), output: None };
                done.and_then(|filtered| {
                    replay.output = Some(filtered);
                    let d = denoise_on(&mut replay, image, guide).map_err(|e| e.to_string())?;
                    Ok(Some(d.image))
                })
            }
        };
        let (generation, spp, started, read_ms) = (job.generation, job.spp, job.started_ms, job.read_ms);
        let current = generation == self.generation;
        match result {
            Ok(None) => false,
            Ok(Some(image)) => {
                self.job = None;
                if current {
                    self.show(spp, image, now_ms() - started, read_ms);
                }
                current
            }
            Err(e) => {
                self.job = None;
                if current {
                    self.fail(e);
                }
                false
            }
        }
    }

    fn show(&mut self, spp: u32, image: Image, filter_ms: f64, guide_ms: f64) {
        self.next_id += 1;
        self.shown = Some(Shown { generation: self.generation, spp, image, id: self.next_id });
        self.last_end_ms = Some(now_ms());
        self.filter_ms = Some(filter_ms);
        self.guide_ms = Some(guide_ms);
    }

    /// What the read-out says of the image on the canvas; `running`: the runtime that renders,
    /// or why none does.
    pub fn readout(&self, running: Result<&Runtime, &str>) -> String {
        if !self.enabled {
            return "raw (denoise off)".into();
        }
        let running = match running {
            Ok(r) => r,
            Err(why) => return format!("raw ({why})"),
        };
        let pending = self.pending();
        let mut text = match (self.current(), &self.shown) {
            (Some(_), Some(shown)) => format!("denoised at {} spp", shown.spp),
            _ if self.error.is_some() => "raw".to_string(),
            _ if pending.is_none() && running.frames() < FIRST_SPP => format!("raw (denoised from {FIRST_SPP} spp)"),
            _ => "raw".to_string(),
        };
        if let Some(spp) = pending {
            text.push_str(&format!(", denoising {spp} spp…"));
        }
        if let Some(e) = &self.error {
            text.push_str(&format!(": the denoiser failed: {e}"));
        }
        text
    }

    /// The read-outs of `sceneInfo().denoise`.
    pub fn describe(&self, running: Result<&Runtime, &str>) -> Object {
        let o = Object::new();
        set(&o, "enabled", self.enabled);
        let shown = self.current().and(self.shown.as_ref()).map(|s| s.spp);
        set(&o, "shownSpp", shown.map_or(JsValue::NULL, JsValue::from));
        let pending = self.pending();
        set(&o, "pendingSpp", pending.map_or(JsValue::NULL, JsValue::from));
        set(&o, "filterMs", self.filter_ms.map_or(JsValue::NULL, JsValue::from));
        set(&o, "guideMs", self.guide_ms.map_or(JsValue::NULL, JsValue::from));
        set(&o, "error", self.error.as_deref().map_or(JsValue::NULL, JsValue::from));
        set(&o, "readout", self.readout(running));
        o
    }
}
