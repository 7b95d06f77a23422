//! The camera: the kernel's pinhole basis, scaled by the field of view and the image's aspect,
//! and the thin lens.

use glam::Vec3;

use crate::scene::Camera;

/// The kernel's camera uniforms.
pub(super) struct PackedCamera {
    pub position: Vec3,
    /// Right, scaled by `tan(yfov / 2) * aspect`.
    pub right: Vec3,
    /// Up, scaled by `tan(yfov / 2)`.
    pub up: Vec3,
    pub forward: Vec3,
    pub lens_radius: f32,
    pub focus_distance: f32,
}

impl PackedCamera {
    pub fn new(cam: &Camera, width: u32, height: u32) -> Self {
        let forward = (cam.target - cam.position).normalize_or(Vec3::NEG_Z);
        let tan_half = (0.5 * cam.yfov).tan();
        let aspect = width as f32 / height as f32;
        let right = forward.cross(cam.up).normalize_or(Vec3::X);
        let up = right.cross(forward).normalize_or(Vec3::Y);
        PackedCamera {
            position: cam.position,
            right: right * tan_half * aspect,
            up: up * tan_half,
            forward,
            lens_radius: cam.aperture_radius,
            focus_distance: cam.focus_distance,
        }
    }
}
