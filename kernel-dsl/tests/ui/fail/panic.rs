#[kernel_dsl::kernel]
pub mod k {
    pub fn checked(x: f32) -> f32 {
        if x < 0.0 {
            panic!("negative");
        }
        x
    }
}

fn main() {}
