#[kernel_dsl::kernel]
pub mod k {
    pub fn total(values: Vec<f32>) -> f32 {
        values[0]
    }
}

fn main() {}
