#[kernel_dsl::kernel]
pub mod k {
    pub trait Shape {
        fn area(&self) -> f32;
    }
}

fn main() {}
