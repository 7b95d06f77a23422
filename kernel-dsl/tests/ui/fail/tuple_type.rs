#[kernel_dsl::kernel]
pub mod k {
    pub struct Interval {
        pub range: (f32, f32),
    }
}

fn main() {}
