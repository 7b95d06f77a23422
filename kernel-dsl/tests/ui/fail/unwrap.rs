#[kernel_dsl::kernel]
pub mod k {
    pub fn next(x: u32) -> u32 {
        x.checked_add(1).unwrap()
    }
}

fn main() {}
