#[kernel_dsl::kernel]
pub mod k {
    pub fn double(x: f32) -> f32 {
        let twice = |y: f32| y * 2.0;
        twice(x)
    }
}

fn main() {}
