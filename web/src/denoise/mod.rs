//! The denoiser in the page (`Viewer::setDenoise`, the page's Denoise control, `?denoise=0|1`):
//! `tracer::denoise` over the accumulation, the à-trous passes on the runtime that renders
//! (`GlFilter`'s fragment passes on WebGL2, queued behind a fence the frame loop polls;
//! `WgpuFilter`'s compute passes on WebGPU, run as promises), neither blocking the page, the
//! remodulation by `tracer::denoise::denoise_on` itself over the passes' output
//! ([`gpu::Replay`]), and the denoised image drawn through the same display transform as the
//! raw one ([`show`]).
//!
//! **When it denoises.** The passes cost about 800 ms at 640x480 on SwiftShader (a few ms on a
//! real GPU); while they run the GPU renders nothing else (on WebGL2 no band is submitted
//! until their fence is signalled). So the page denoises when the
//! accumulation has reached [`FIRST_SPP`] samples per pixel and then whenever the sample count
//! has doubled since the image shown was denoised (4, 8, 16, ... spp: the filter's share of the
//! time falls as the image converges), and never sooner than [`SPACING`] times the last filter
//! time after the last one ended (at most about a third of the time goes to the filter); the
//! first waits until the accumulation has run [`SETTLE_MS`] without a restart (the camera has
//! stopped: the guide's AOVs are traced on the CPU once per view). In
//! between, the latest denoised image stays on the canvas while the raw accumulation goes on.
//! A restart (camera move, strategy, depth, size, seed, API) shows the raw image until the next
//! denoise of the new accumulation; a denoise of an older accumulation that finishes late is
//! dropped. On WebGPU one denoise is in flight at a time: a due one waits for it.
//!
//! **The guide** comes from one function, [`page_guide`]: until the path tracer accumulates
//! the guide itself, the first hits' AOVs (`tracer::denoise::first_hit_aovs`, on the CPU, once
//! per view) and each pixel's variance from `SampleMoments`, fed by a read-back of the
//! accumulation after every frame (synchronous on WebGL2; on WebGPU one staging copy per frame,
//! mapped later and fed in order). Frames it missed (denoise switched on after the
//! accumulation began, read-backs piling up) make the variance unknown (infinite) until the
//! next restart, as `SampleMoments` reports below two frames.

pub mod gpu;
pub mod show;

use std::collections::VecDeque;
use std::rc::Rc;

use glam::Vec4;
use js_sys::Object;
use tracer::backend::{mean_image, Image, Renderer};
use tracer::denoise::{denoise_on, filter_input, first_hit_aovs, SampleMoments};
use tracer::kernel::denoise::Aov;
use tracer::kernel::scene_data::Scene;
use wasm_bindgen::JsValue;

use self::gpu::{GpuFilter, Replay, Slot, StagedRead};
use crate::js::{now_ms, set};
use crate::runtime::Runtime;

/// The first denoise of an accumulation waits for this many samples per pixel (below, the
/// variance says little and the filter spreads light: see the README's "Where it is weak").
pub const FIRST_SPP: u32 = 4;
/// A denoise starts no sooner than this many times the last filter time after the last ended.
pub const SPACING: f64 = 2.0;
/// The first denoise of an accumulation also waits until it has run this long without a
/// restart: while the camera moves (restarts every few frames on a fast GPU), the guide's
/// AOVs, traced on the CPU, would stall the input.
pub const SETTLE_MS: f64 = 300.0;
/// WebGPU accumulation reads queued and not yet mapped beyond which the oldest are dropped
/// (and the variance becomes unknown until the next restart).
const MAX_PENDING_READS: usize = 32;

/// The denoised image on show.
struct Shown {
    /// The accumulation it was denoised from (see [`PageDenoiser::generation`]).
    generation: u64,
    spp: u32,
    image: Image,
    /// Names this image for the display passes (uploaded once).
    id: u64,
}

/// A WebGPU denoise in flight.
struct Job {
    generation: u64,
    spp: u32,
    image: Image,
    variance: Vec<f32>,
    aovs: Rc<Vec<Aov>>,
    /// WebGPU: where the output arrives; WebGL2: `None`, the runtime holds the queued passes.
    output: Option<Slot<Vec<Vec4>>>,
    started_ms: f64,
    guide_ms: f64,
}

/// The guide the filter is given: per pixel the first hit's AOVs and the variance of the mean
/// luminance.
pub struct PageGuide {
    pub aovs: Rc<Vec<Aov>>,
    pub variance: Vec<f32>,
}

/// THE source of the page's guide (the only one: swap this for the path tracer's accumulated
/// guide when it lands). Now: `first_hit_aovs` of `scene` (kept in `aovs` while the view
/// stays) and `SampleMoments`' variance when the moments hold every one of the `spp` frames,
/// else an unknown (infinite) variance.
fn page_guide(scene: &Scene, aovs: &mut Option<Rc<Vec<Aov>>>, moments: Option<&SampleMoments>, spp: u32) -> PageGuide {
    let pixels = scene.width as usize * scene.height as usize;
    let cached = aovs.as_ref().filter(|a| a.len() == pixels).cloned();
    let aovs = cached.unwrap_or_else(|| {
        let fresh = Rc::new(first_hit_aovs(scene));
        *aovs = Some(fresh.clone());
        fresh
    });
    let variance = match moments {
        Some(m) if spp >= 1 => m.variance_of_mean(),
        _ => vec![f32::INFINITY; pixels],
    };
    PageGuide { aovs, variance }
}

/// The page's denoiser state: whether it is on, what it has read of the accumulation, the
/// denoise in flight and the image on show.
pub struct PageDenoiser {
    enabled: bool,
    /// Bumped at every restart of the accumulation (and new renderer): older results are dropped.
    generation: u64,
    /// The first hits' AOVs of the current view (`None` after the view changed).
    aovs: Option<Rc<Vec<Aov>>>,
    /// Luminance moments of every frame since the restart (`None`: one was missed).
    moments: Option<SampleMoments>,
    /// Frames fed to the moments (the spp of the last accumulation read).
    frames_seen: u32,
    /// The last accumulation read: its spp and running sums.
    latest: Option<(u32, Vec<Vec4>)>,
    /// WebGPU: reads queued after each frame, oldest first.
    reads: VecDeque<StagedRead>,
    /// WebGPU: the filter pass on the current renderer's device.
    gpu_filter: Option<GpuFilter>,
    job: Option<Job>,
    shown: Option<Shown>,
    next_id: u64,
    /// The last denoise: when it ended, the filter's time (demodulation, passes, read-back,
    /// remodulation) and the guide's, in milliseconds.
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
            generation: 0,
            aovs: None,
            moments: None,
            frames_seen: 0,
            latest: None,
            reads: VecDeque::new(),
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

    /// Switches the denoiser on or off. Off: the raw image shows (what was read is dropped).
    /// On while an accumulation of `frames` > 0 samples runs: its earlier frames were not read,
    /// so its variance is unknown until the next restart.
    pub fn set_enabled(&mut self, on: bool, frames: u32, pixels: usize) {
        if on == self.enabled {
            return;
        }
        self.enabled = on;
        self.shown = None;
        self.job = None;
        self.reads.clear();
        self.latest = None;
        self.frames_seen = frames;
        self.moments = (on && frames == 0).then(|| SampleMoments::new(pixels));
    }

    /// The accumulation restarted (`pixels` per image): the raw image shows until the next
    /// denoise. `view_changed`: the camera moved, the guide's AOVs are stale.
    pub fn restart(&mut self, pixels: usize, view_changed: bool) {
        self.generation += 1;
        self.shown = None;
        self.reads.clear();
        self.latest = None;
        self.frames_seen = 0;
        self.error = None;
        self.restarted_ms = now_ms();
        self.moments = self.enabled.then(|| SampleMoments::new(pixels));
        if view_changed {
            self.aovs = None;
        }
    }

    /// A new renderer (size, seed, API, context or device): as a restart with a new view, and
    /// the WebGPU filter pass is compiled again on the new device.
    pub fn new_runtime(&mut self, pixels: usize) {
        self.restart(pixels, true);
        self.gpu_filter = None;
        self.job = None;
    }

    /// The denoised image to show instead of the raw one, and its id, if the current
    /// accumulation has one.
    pub fn current(&self) -> Option<(&Image, u64)> {
        let shown = self.shown.as_ref().filter(|s| self.enabled && s.generation == self.generation)?;
        Some((&shown.image, shown.id))
    }

    /// A frame completed on `running` (now `running.frames()` samples): reads the accumulation
    /// for the moments, then denoises if due (see [`poll`](Self::poll)). Returns whether a new
    /// denoised image is ready to show.
    pub fn after_frame(&mut self, running: &mut Runtime) -> bool {
        if !self.enabled {
            return false;
        }
        let spp = running.frames();
        match running {
            Runtime::WebGl2(r) => match r.renderer().accumulation() {
                Ok(sums) => self.feed(spp, sums),
                Err(e) => self.fail(format!("reading the accumulation failed: {e}")),
            },
            Runtime::WebGpu(r) => {
                if self.reads.len() >= MAX_PENDING_READS {
                    self.reads.pop_front();
                }
                self.reads.push_back(StagedRead::queue(r.renderer(), spp));
            }
        }
        self.poll(running)
    }

    fn feed(&mut self, spp: u32, sums: Vec<Vec4>) {
        if spp == 0 || spp < self.frames_seen {
            return;
        }
        match &mut self.moments {
            Some(m) if spp == self.frames_seen + 1 => m.add_frame(&sums),
            _ => self.moments = None,
        }
        self.frames_seen = spp;
        self.latest = Some((spp, sums));
    }

    pub fn fail(&mut self, error: String) {
        web_sys::console::error_1(&format!("the denoiser: {error}").into());
        self.error = Some(error);
    }

    /// Collects what the GPU finished (WebGPU's mapped reads; the filter's output), then starts a denoise
    /// if one is due. Call it from the frame loop also while no frame is rendered. Returns
    /// whether a new denoised image is ready to show.
    pub fn poll(&mut self, running: &mut Runtime) -> bool {
        if !self.enabled {
            return false;
        }
        while let Some(read) = self.reads.front() {
            let Some(result) = read.take() else { break };
            let spp = read.spp;
            self.reads.pop_front();
            match result {
                Ok(sums) => self.feed(spp, sums),
                Err(e) => {
                    self.moments = None;
                    self.fail(e);
                }
            }
        }
        let ready = self.finish_job(running);
        if self.due(now_ms()) {
            self.start(running);
        }
        ready
    }

    /// Whether the latest read accumulation should be denoised now (see the module's rule).
    fn due(&self, now: f64) -> bool {
        let Some((spp, _)) = &self.latest else { return false };
        let shown = self.shown.as_ref().filter(|s| s.generation == self.generation).map_or(0, |s| s.spp);
        let spaced = match (self.last_end_ms, self.filter_ms) {
            (Some(end), Some(ms)) => now - end >= SPACING * ms,
            _ => true,
        } && (shown > 0 || now - self.restarted_ms >= SETTLE_MS);
        self.job.is_none() && self.error.is_none() && *spp >= FIRST_SPP.max(2 * shown) && spaced
    }

    /// Starts denoising the latest accumulation read: the passes are queued (WebGL2: behind a
    /// fence the runtime polls; WebGPU: as promises) and finished by a later [`poll`](Self::poll).
    fn start(&mut self, running: &mut Runtime) {
        // WebGPU: the filter pass compiles first (a promise; the next polls see it done).
        let gpu_filter = match running {
            Runtime::WebGl2(_) => None,
            Runtime::WebGpu(r) => {
                let device = r.renderer().device();
                match self.gpu_filter.get_or_insert_with(|| GpuFilter::compile(device)).ready() {
                    Ok(Some(f)) => Some(f),
                    Ok(None) => return,
                    Err(e) => {
                        self.fail(e);
                        return;
                    }
                }
            }
        };
        let Some((spp, sums)) = &self.latest else { return };
        let spp = *spp;
        let (image, guide, guide_ms) = {
            let scene = &running.packed().scene;
            let image = mean_image(scene.width, scene.height, spp, sums);
            let started = now_ms();
            let moments = self.moments.as_ref().filter(|_| self.frames_seen == spp);
            let guide = page_guide(scene, &mut self.aovs, moments, spp);
            (image, guide, now_ms() - started)
        };
        let began = now_ms();
        let queued = filter_input(&image, &guide.variance, &guide.aovs).map_err(|e| e.to_string()).and_then(|input| {
            match (running, gpu_filter) {
                (Runtime::WebGl2(r), _) => r.queue_filter(&input).map(|()| None),
                (Runtime::WebGpu(r), Some(filter)) => gpu::run_filter(&filter, r.renderer().device(), &input).map(Some),
                (Runtime::WebGpu(_), None) => Err("the WebGPU filter pass is not compiled".to_string()),
            }
        });
        match queued {
            Ok(output) => {
                let (generation, variance, aovs) = (self.generation, guide.variance, guide.aovs);
                self.job = Some(Job { generation, spp, image, variance, aovs, output, started_ms: began, guide_ms });
            }
            Err(e) => self.fail(e),
        }
    }

    /// A denoise whose passes are done: remodulated (by `tracer::denoise` itself) and shown,
    /// unless the accumulation restarted meanwhile.
    fn finish_job(&mut self, running: &mut Runtime) -> bool {
        let Some(job) = &self.job else { return false };
        let output = match (&job.output, &mut *running) {
            (Some(slot), _) => slot.borrow_mut().take(),
            (None, Runtime::WebGl2(r)) => r.filter_output(),
            (None, Runtime::WebGpu(_)) => Some(Err("the filter's output was lost".to_string())),
        };
        let Some(output) = output else { return false };
        let job = self.job.take().expect("checked above");
        if job.generation != self.generation {
            return false;
        }
        let mut replay = Replay { packed: running.packed(), output: None };
        let denoised = output.and_then(|output| {
            replay.output = Some(output);
            denoise_on(&mut replay, &job.image, &job.variance, &job.aovs).map_err(|e| e.to_string())
        });
        match denoised {
            Ok(d) => {
                self.show(job.spp, d.image, now_ms() - job.started_ms, job.guide_ms);
                true
            }
            Err(e) => {
                self.fail(e);
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
        let pending = self.job.as_ref().filter(|j| j.generation == self.generation).map(|j| j.spp);
        let mut text = match (self.current(), &self.shown) {
            (Some(_), Some(shown)) => format!("denoised at {} spp", shown.spp),
            _ if self.error.is_some() => "raw".to_string(),
            _ if pending.is_none() && running.frames() < FIRST_SPP => format!("raw (denoised from {FIRST_SPP} spp)"),
            _ => "raw".to_string(),
        };
        if let Some(spp) = pending {
            text.push_str(&format!(", denoising {spp} spp…"));
        }
        if self.current().is_some() && self.moments.is_none() {
            text.push_str(" (variance unknown: frames were not read)");
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
        let pending = self.job.as_ref().filter(|j| j.generation == self.generation).map(|j| j.spp);
        set(&o, "pendingSpp", pending.map_or(JsValue::NULL, JsValue::from));
        set(&o, "filterMs", self.filter_ms.map_or(JsValue::NULL, JsValue::from));
        set(&o, "guideMs", self.guide_ms.map_or(JsValue::NULL, JsValue::from));
        set(&o, "varianceKnown", self.moments.is_some());
        set(&o, "error", self.error.as_deref().map_or(JsValue::NULL, JsValue::from));
        set(&o, "readout", self.readout(running));
        o
    }
}
