#[kernel_dsl::kernel]
pub mod k {
    pub fn narrow(x: f64) -> f32 {
        x as f32
    }
}

fn main() {}
