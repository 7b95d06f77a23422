#[kernel_dsl::kernel]
pub mod k {
    pub mod inner {
        pub fn one() -> u32 {
            1
        }
    }
}

fn main() {}
