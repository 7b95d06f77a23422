#[kernel_dsl::kernel]
pub mod k {
    pub struct Scene {
        pub count: u32,
    }

    pub fn count<'a>(scene: &'a Scene) -> u32 {
        scene.count
    }
}

fn main() {}
