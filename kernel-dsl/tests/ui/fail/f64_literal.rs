#[kernel_dsl::kernel]
pub mod k {
    pub fn half() -> f32 {
        let _precise = 0.5f64;
        0.5
    }
}

fn main() {}
