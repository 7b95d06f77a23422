//! Scenes that move, in the page: a dropped glTF whose animation moves something is loaded
//! with its motion kept (`tracer::pack::MovingScene`), and a served bundle with a motion
//! section poses from its arrays and moving parts (`MovingScene::from_bundle`); either plays
//! by default. While it plays,
//! each frame the loop starts shows the scene posed at the page's clock (times the speed,
//! wrapped over the animation's length): the renderer takes the pose's geometry
//! (`Renderer::take_geometry`, no recompile) and the accumulation restarts; paused, the pose
//! stays and samples accumulate. A static scene has no playback and behaves as before.

use js_sys::Object;
use tracer::backend::RenderError;
use tracer::pack::{MovingScene, PackError, Packed};
use wasm_bindgen::prelude::*;

use super::Viewer;
use crate::js::{js_error, set};

/// The animation of the loaded scene and where it is.
pub struct Playback {
    moving: MovingScene,
    /// Seconds into the animation of the pose on show.
    time: f32,
    playing: bool,
    speed: f32,
    /// `performance.now()` when the pose on show was taken while playing (`None`: not yet).
    clock_ms: Option<f64>,
    /// Milliseconds the last pose took: posing, packing and the renderer taking it.
    pose_ms: f64,
    /// Poses shown since the scene was loaded (a soak test's count of what it exercised).
    poses: u64,
    /// What posing warned about since the load (a placement a pose cannot place is dropped,
    /// once each): also on the console.
    warnings: Vec<String>,
}

impl Playback {
    pub fn new(moving: MovingScene) -> Self {
        let warnings = Vec::new();
        Playback { moving, time: 0.0, playing: true, speed: 1.0, clock_ms: None, pose_ms: 0.0, poses: 0, warnings }
    }

    /// Whether the animation plays (each pose restarting the accumulation).
    pub fn playing(&self) -> bool {
        self.playing
    }

    /// The time at `now_ms` while playing: the shown time advanced by the page's clock times
    /// the speed, wrapped over the animation's length.
    fn time_at(&mut self, now_ms: f64) -> Option<f32> {
        if !self.playing {
            self.clock_ms = None;
            return None;
        }
        let Some(last) = self.clock_ms.replace(now_ms) else { return Some(self.time) };
        let duration = self.moving.duration();
        let t = self.time + ((now_ms - last) / 1e3) as f32 * self.speed;
        Some(if duration > 0.0 { t.rem_euclid(duration) } else { 0.0 })
    }

    /// `sceneInfo().animation`: { duration, time, playing, speed, moving (what moves, in
    /// words), poseMs, poses (shown since the load), warnings (posing's, joined) }.
    pub fn describe(&self) -> Object {
        let info = Object::new();
        set(&info, "duration", self.moving.duration());
        set(&info, "time", self.time);
        set(&info, "playing", self.playing);
        set(&info, "speed", self.speed);
        let moving = self.moving.scene().motion.as_ref().map_or(String::new(), |m| m.describe());
        set(&info, "moving", moving);
        set(&info, "poseMs", self.pose_ms);
        set(&info, "poses", self.poses as f64);
        set(&info, "warnings", self.warnings.join("; "));
        info
    }
}

#[wasm_bindgen]
impl Viewer {
    /// Plays (true, the default) or pauses the animation of a moving scene; paused, the pose
    /// stays and samples accumulate.
    #[wasm_bindgen(js_name = setPlaying)]
    pub fn set_playing(&mut self, on: bool) {
        if let Some(p) = self.playback_mut() {
            p.playing = on;
        }
    }

    /// Shows the pose at `seconds` into the animation (clamped to it) now, restarting the
    /// accumulation.
    #[wasm_bindgen(js_name = setAnimationTime)]
    pub fn set_animation_time(&mut self, seconds: f32) -> Result<(), JsError> {
        if !seconds.is_finite() {
            return Err(JsError::new("the animation time must be a finite number of seconds"));
        }
        let Some(p) = self.playback_mut() else { return Ok(()) };
        p.clock_ms = None;
        let time = seconds.clamp(0.0, p.moving.duration());
        self.show_pose(time)
    }

    /// Plays at `speed` times real time (0 < speed <= 100).
    #[wasm_bindgen(js_name = setAnimationSpeed)]
    pub fn set_animation_speed(&mut self, speed: f32) -> Result<(), JsError> {
        if !(speed > 0.0 && speed <= 100.0) {
            return Err(JsError::new("the animation speed must be above 0 and at most 100"));
        }
        if let Some(p) = self.playback_mut() {
            p.speed = speed;
        }
        Ok(())
    }
}

impl Viewer {
    fn playback_mut(&mut self) -> Option<&mut Playback> {
        self.playback.as_mut()
    }

    /// Whether no frame is half rendered in bands (a new pose may be shown).
    fn between_frames(&self) -> bool {
        self.running.as_ref().is_some_and(|r| r.renderer().rows_left() == r.packed().scene.height)
    }

    /// A moved scene's geometry into the master copy and the renderer, restarting the
    /// accumulation (`crate::playback`).
    fn take_geometry(&mut self, moved: Packed) -> Result<(), RenderError> {
        let Some(loaded) = &mut self.loaded else { return Ok(()) };
        loaded.packed.take_geometry(moved.clone())?;
        let halted = self.halted();
        if let Some(running) = self.running.as_mut().filter(|_| !halted) {
            running.take_geometry(moved)?;
        }
        self.denoiser.restart();
        Ok(())
    }

    /// The scene packed again for a new kernel variant, in place of the master copy (its
    /// view and settings kept), with a new renderer.
    fn replace_packed(&mut self, packed: Packed) -> Result<(), JsError> {
        if let Some(loaded) = &mut self.loaded {
            loaded.packed = packed;
        }
        self.rebuild()
    }

    /// Before the frame loop's step: while playing, between frames (no frame half rendered in
    /// bands) and with nothing on the GPU (a preview in flight would otherwise be followed by a
    /// pose per animation frame that no image shows), the pose at `now_ms`.
    pub(super) fn advance_animation(&mut self, now_ms: f64) -> Result<(), JsError> {
        let playing = self.playback.as_ref().is_some_and(|p| p.playing);
        if playing && !self.between_frames() {
            return Ok(());
        }
        let halted = self.halted();
        if playing && self.running.as_mut().is_some_and(|r| !halted && !r.poll(now_ms)) {
            return Ok(());
        }
        let Some(p) = self.playback_mut() else { return Ok(()) };
        match p.time_at(now_ms) {
            Some(time) => self.show_pose(time),
            None => Ok(()),
        }
    }

    /// Poses the scene at `time`, hands the geometry to the master copy and the renderer and
    /// restarts the accumulation; a pose needing another kernel variant recreates the renderer.
    fn show_pose(&mut self, time: f32) -> Result<(), JsError> {
        let start = crate::js::now_ms();
        let Some(p) = self.playback_mut() else { return Ok(()) };
        p.time = time;
        let known = p.moving.scene().warnings.len();
        p.moving.pose(time).map_err(js_error)?;
        for warning in p.moving.scene().warnings.iter().skip(known) {
            web_sys::console::warn_1(&warning.into());
            p.warnings.push(warning.clone());
        }
        let moved = p.moving.pack().map_err(js_error)?;
        let taken = self.take_geometry(moved);
        let result = match taken {
            Err(RenderError::Pack(PackError::KernelChanged { .. })) => {
                let p = self.playback_mut().expect("checked above");
                let packed = p.moving.pack_for_kernel().map_err(js_error)?;
                self.replace_packed(packed)
            }
            Err(e) => Err(js_error(e)),
            Ok(()) => Ok(()),
        };
        if let Some(p) = self.playback_mut() {
            p.pose_ms = crate::js::now_ms() - start;
            p.poses += 1;
        }
        result
    }
}
