#[kernel_dsl::kernel]
pub mod k {
    pub fn rotate(x: u32, n: u32) -> u32 {
        (x << n) | (x >> 3)
    }
}

fn main() {}
