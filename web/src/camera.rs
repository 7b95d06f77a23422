//! The interactive camera: orbit around a target, or fly (look around from the eye and move
//! it), written into the kernel's camera uniforms exactly as `tracer::pack` lays them out.
//!
//! It starts from the packed uniforms themselves (a served bundle carries no glTF camera, only
//! the uniforms), so the first frames render the scene's own view unchanged; only input moves it.
//! Orbiting turns about world +Y (glTF's up).

use glam::Vec3;
use tracer::kernel::scene_data::Scene;

/// Pitch stays this far from straight up/down, where "right" (forward x +Y) is undefined.
const MAX_PITCH: f32 = 89.0 * std::f32::consts::PI / 180.0;

/// An orbit / fly camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrbitCamera {
    /// The point orbited around (and kept in focus by a thin lens).
    pub target: Vec3,
    /// Eye-to-target distance (> 0).
    pub distance: f32,
    /// Rotation about +Y, radians; 0 looks down -Z, positive turns towards +X.
    pub yaw: f32,
    /// Elevation of the view direction, radians, within ±89°.
    pub pitch: f32,
    /// tan(vertical field of view / 2).
    pub tan_half_fov: f32,
    /// The scene's size (largest absolute coordinate), to scale movement and distance limits.
    pub scene_scale: f32,
}

impl OrbitCamera {
    /// The camera the packed uniforms describe: eye, view direction and field of view; the
    /// target lies on the view direction at the focus distance (`pack` focuses on the glTF or
    /// framing camera's target).
    pub fn from_uniforms(scene: &Scene) -> Self {
        let forward = scene.camera_forward.normalize_or(Vec3::NEG_Z);
        let distance =
            if scene.focus_distance.is_finite() && scene.focus_distance > 0.0 { scene.focus_distance } else { 1.0 };
        let tan_half_fov = scene.camera_up.length();
        let scene_scale =
            if scene.scene_scale.is_finite() && scene.scene_scale > 0.0 { scene.scene_scale } else { 1.0 };
        OrbitCamera {
            target: scene.camera_position + forward * distance,
            distance,
            yaw: forward.x.atan2(-forward.z),
            pitch: forward.y.clamp(-1.0, 1.0).asin().clamp(-MAX_PITCH, MAX_PITCH),
            tan_half_fov: if tan_half_fov.is_finite() && tan_half_fov > 0.0 { tan_half_fov } else { 0.414_213_57 },
            scene_scale,
        }
    }

    /// Unit view direction.
    pub fn forward(&self) -> Vec3 {
        let (sin_yaw, cos_yaw) = self.yaw.sin_cos();
        let (sin_pitch, cos_pitch) = self.pitch.sin_cos();
        Vec3::new(cos_pitch * sin_yaw, sin_pitch, -cos_pitch * cos_yaw)
    }

    /// The eye position.
    pub fn position(&self) -> Vec3 {
        self.target - self.forward() * self.distance
    }

    /// Unit right and up vectors of the view.
    fn basis(&self) -> (Vec3, Vec3) {
        let forward = self.forward();
        let right = forward.cross(Vec3::Y).normalize_or(Vec3::X);
        (right, right.cross(forward))
    }

    /// Writes the camera into the kernel's uniforms, for the scene's image size (as `pack` does:
    /// right and up scaled by the half-field-of-view tangent, right also by the aspect ratio).
    /// A thin lens stays focused on the target.
    pub fn apply(&self, scene: &mut Scene) {
        let (right, up) = self.basis();
        let aspect = scene.width.max(1) as f32 / scene.height.max(1) as f32;
        scene.camera_position = self.position();
        scene.camera_forward = self.forward();
        scene.camera_right = right * self.tan_half_fov * aspect;
        scene.camera_up = up * self.tan_half_fov;
        scene.focus_distance = self.distance;
    }

    /// Turns the eye around the target by `yaw` and `pitch` radians.
    pub fn orbit(&mut self, yaw: f32, pitch: f32) {
        self.turn(yaw, pitch);
    }

    /// Turns the view around the eye (fly mode): the eye stays, the target moves.
    pub fn look(&mut self, yaw: f32, pitch: f32) {
        let eye = self.position();
        self.turn(yaw, pitch);
        self.target = eye + self.forward() * self.distance;
    }

    fn turn(&mut self, yaw: f32, pitch: f32) {
        if yaw.is_finite() {
            self.yaw = (self.yaw + yaw).rem_euclid(std::f32::consts::TAU);
        }
        if pitch.is_finite() {
            self.pitch = (self.pitch + pitch).clamp(-MAX_PITCH, MAX_PITCH);
        }
    }

    /// Moves eye and target sideways: `dx`, `dy` are fractions of the view's height at the
    /// target (dragging by the canvas height moves the scene by one view height).
    pub fn pan(&mut self, dx: f32, dy: f32) {
        if !(dx.is_finite() && dy.is_finite()) {
            return;
        }
        let (right, up) = self.basis();
        let view_height = 2.0 * self.distance * self.tan_half_fov;
        self.target += (right * dx + up * dy) * view_height;
    }

    /// Moves the eye towards (factor < 1) or away from (factor > 1) the target.
    pub fn dolly(&mut self, factor: f32) {
        if !(factor.is_finite() && factor > 0.0) {
            return;
        }
        let (min, max) = (1e-4 * self.scene_scale, 1e3 * self.scene_scale);
        self.distance = (self.distance * factor).clamp(min.min(self.distance), max.max(self.distance));
    }

    /// Moves eye and target together (fly mode): `forward` along the view, `right` sideways,
    /// `up` along +Y, each in units of the scene's size.
    pub fn fly(&mut self, forward: f32, right: f32, up: f32) {
        if !(forward.is_finite() && right.is_finite() && up.is_finite()) {
            return;
        }
        let (right_dir, _) = self.basis();
        self.target += (self.forward() * forward + right_dir * right + Vec3::Y * up) * self.scene_scale;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tracer::kernel::{RenderSettings, Strategy};
    use tracer::pack::pack;

    fn packed_cornell(width: u32, height: u32) -> tracer::pack::Packed {
        let scene = tracer::scene::cornell_box();
        let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
        pack(&scene, &bvh, &RenderSettings { width, height, strategy: Strategy::Mis, max_depth: 4 }).expect("pack")
    }

    fn assert_close(a: Vec3, b: Vec3, what: &str) {
        assert!((a - b).abs().max_element() < 1e-5, "{what}: {a} vs {b}");
    }

    /// Reading the camera from the uniforms and writing it back changes nothing: the first
    /// frames show the scene's own view, and `apply` lays the uniforms out as `pack` does.
    #[test]
    fn uniforms_round_trip() {
        for (w, h) in [(64, 64), (640, 480), (300, 500)] {
            let packed = packed_cornell(w, h);
            let mut scene = packed.scene.clone();
            scene.camera_position += Vec3::ONE; // must be rewritten
            scene.camera_right = Vec3::ZERO;
            OrbitCamera::from_uniforms(&packed.scene).apply(&mut scene);
            let s = &packed.scene;
            assert_close(scene.camera_position, s.camera_position, "position");
            assert_close(scene.camera_forward, s.camera_forward, "forward");
            assert_close(scene.camera_right, s.camera_right, "right");
            assert_close(scene.camera_up, s.camera_up, "up");
            assert!((scene.focus_distance - s.focus_distance).abs() < 1e-5);
        }
    }

    #[test]
    fn orbiting_keeps_the_target_and_distance() {
        let mut camera = OrbitCamera::from_uniforms(&packed_cornell(64, 64).scene);
        let (target, distance) = (camera.target, camera.distance);
        camera.orbit(1.0, 0.3);
        assert_close(camera.target, target, "target");
        assert!(((camera.position() - target).length() - distance).abs() < 1e-4);
        assert!((camera.forward() - (target - camera.position()).normalize()).length() < 1e-5);
        // Pitch is clamped short of the pole, so the basis stays defined.
        camera.orbit(0.0, 10.0);
        assert!(camera.pitch < std::f32::consts::FRAC_PI_2);
        let mut scene = packed_cornell(64, 64).scene;
        camera.apply(&mut scene);
        assert!(scene.camera_right.is_finite() && scene.camera_right.length() > 0.1);
    }

    #[test]
    fn looking_keeps_the_eye() {
        let mut camera = OrbitCamera::from_uniforms(&packed_cornell(64, 64).scene);
        let eye = camera.position();
        camera.look(-0.5, 0.2);
        assert_close(camera.position(), eye, "eye");
        assert!((camera.yaw - OrbitCamera::from_uniforms(&packed_cornell(64, 64).scene).yaw).abs() > 0.4);
    }

    #[test]
    fn pan_fly_and_dolly_move_the_view() {
        let start = OrbitCamera::from_uniforms(&packed_cornell(64, 64).scene);
        let mut camera = start;
        camera.pan(0.5, 0.0);
        let (right, _) = start.basis();
        let moved = camera.target - start.target;
        assert!((moved.normalize() - right).length() < 1e-5 && moved.length() > 0.0);
        let mut camera = start;
        camera.fly(0.1, 0.0, 0.0);
        assert_close(camera.position() - start.position(), start.forward() * 0.1 * start.scene_scale, "fly");
        let mut camera = start;
        camera.dolly(0.5);
        assert!((camera.distance - 0.5 * start.distance).abs() < 1e-6);
        // Bad input leaves the camera as it was.
        let mut camera = start;
        camera.dolly(f32::NAN);
        camera.dolly(-1.0);
        camera.pan(f32::INFINITY, 0.0);
        camera.orbit(f32::NAN, f32::NAN);
        camera.fly(f32::NAN, 0.0, 0.0);
        assert_eq!(camera, start);
    }
}
