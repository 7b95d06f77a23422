#[kernel_dsl::kernel]
pub mod k {
    pub struct Node {
        pub value: Box<f32>,
    }
}

fn main() {}
