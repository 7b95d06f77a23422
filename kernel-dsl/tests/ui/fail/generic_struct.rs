#[kernel_dsl::kernel]
pub mod k {
    pub struct Pair<T> {
        pub a: T,
        pub b: T,
    }
}

fn main() {}
