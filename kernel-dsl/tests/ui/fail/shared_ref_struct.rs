#[kernel_dsl::kernel]
pub mod k {
    use glam::Vec3;

    pub struct Ray {
        pub origin: Vec3,
        pub dir: Vec3,
    }

    pub fn at(ray: &Ray, t: f32) -> Vec3 {
        ray.origin + ray.dir * t
    }
}

fn main() {}
