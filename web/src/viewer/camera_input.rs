//! The viewer's camera input (`orbit`, `look`, `pan`, `dolly`, `fly`, `resetCamera`): each
//! moves the loaded scene's [`OrbitCamera`] and restarts the accumulation.

use wasm_bindgen::prelude::*;

use super::Viewer;
use crate::camera::OrbitCamera;

#[wasm_bindgen]
impl Viewer {
    /// Orbit: turns the eye around the target (radians). Restarts the accumulation.
    pub fn orbit(&mut self, yaw: f32, pitch: f32) -> Result<(), JsError> {
        self.move_camera(|c| c.orbit(yaw, pitch))
    }

    /// Fly: turns the view around the eye (radians). Restarts the accumulation.
    pub fn look(&mut self, yaw: f32, pitch: f32) -> Result<(), JsError> {
        self.move_camera(|c| c.look(yaw, pitch))
    }

    /// Moves eye and target sideways by fractions of the view height. Restarts the accumulation.
    pub fn pan(&mut self, dx: f32, dy: f32) -> Result<(), JsError> {
        self.move_camera(|c| c.pan(dx, dy))
    }

    /// Scales the eye's distance to the target. Restarts the accumulation.
    pub fn dolly(&mut self, factor: f32) -> Result<(), JsError> {
        self.move_camera(|c| c.dolly(factor))
    }

    /// Moves eye and target (scene-size units) along the view, right and +Y. Restarts.
    pub fn fly(&mut self, forward: f32, right: f32, up: f32) -> Result<(), JsError> {
        self.move_camera(|c| c.fly(forward, right, up))
    }

    /// The scene's own camera again. Restarts the accumulation.
    #[wasm_bindgen(js_name = resetCamera)]
    pub fn reset_camera(&mut self) -> Result<(), JsError> {
        let Some(home) = self.loaded.as_ref().map(|l| l.home) else { return Ok(()) };
        self.move_camera(|c| *c = home)
    }

    fn move_camera(&mut self, change: impl FnOnce(&mut OrbitCamera)) -> Result<(), JsError> {
        let Some(loaded) = &mut self.loaded else { return Ok(()) };
        change(&mut loaded.camera);
        self.update_uniforms()
    }
}
