#[kernel_dsl::kernel]
pub mod camera {
    //! Primary rays: a pinhole camera, or a thin lens when `lens_radius > 0`.

    use glam::{Vec2, Vec3};

    use crate::kernel::sampling::cos_sin_turns;
    use crate::kernel::scene_data::Scene;

    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct Ray {
        pub origin: Vec3,
        pub dir: Vec3,
    }

    /// A uniform point on the unit disk (polar mapping).
    pub fn sample_disk(u1: f32, u2: f32) -> Vec2 {
        // cos_sin_turns, not the trig builtins: SwiftShader's sin/cos are 1.9e-4 off (found by
        // the browser runtimes of the equivalence harness; docs/dsl.md).
        let r = u1.sqrt();
        let cs = cos_sin_turns(u2);
        Vec2::new(r * cs.x, r * cs.y)
    }

    /// The ray through film position `film` (pixel units, origin at the top-left corner) with
    /// lens uniforms `lens`.
    // Inlined into the CPU backend's row loop, which is also compiled for AVX2 (backend/cpu.rs).
    #[inline(always)]
    pub fn camera_ray(scene: &Scene, film: Vec2, lens: Vec2) -> Ray {
        let ndc_x = 2.0 * film.x / scene.width as f32 - 1.0;
        let ndc_y = 1.0 - 2.0 * film.y / scene.height as f32;
        let dir = (scene.camera_forward + scene.camera_right * ndc_x + scene.camera_up * ndc_y).normalize();
        if scene.lens_radius > 0.0 {
            let focus = scene.camera_position + dir * (scene.focus_distance / dir.dot(scene.camera_forward));
            let d = sample_disk(lens.x, lens.y) * scene.lens_radius;
            let origin =
                scene.camera_position + scene.camera_right.normalize() * d.x + scene.camera_up.normalize() * d.y;
            Ray { origin, dir: (focus - origin).normalize() }
        } else {
            Ray { origin: scene.camera_position, dir }
        }
    }
}
