#[kernel_dsl::kernel]
pub mod k {
    pub fn next(x: Option<u32>) -> Option<u32> {
        let y = x?;
        Some(y + 1)
    }
}

fn main() {}
