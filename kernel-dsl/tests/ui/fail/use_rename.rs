#[kernel_dsl::kernel]
pub mod k {
    use glam::Vec3 as V3;

    pub fn up() -> V3 {
        V3::new(0.0, 1.0, 0.0)
    }
}

fn main() {}
