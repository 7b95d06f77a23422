#[kernel_dsl::kernel]
pub mod k {
    use glam::Vec3;

    pub fn luminance(c: &Vec3) -> f32 {
        c.x * 0.2126 + c.y * 0.7152 + c.z * 0.0722
    }
}

fn main() {}
