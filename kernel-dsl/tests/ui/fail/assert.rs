#[kernel_dsl::kernel]
pub mod k {
    pub fn checked(x: f32) -> f32 {
        assert!(x >= 0.0);
        x
    }
}

fn main() {}
