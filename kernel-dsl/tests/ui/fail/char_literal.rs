#[kernel_dsl::kernel]
pub mod k {
    pub fn code() -> u32 {
        'a' as u32
    }
}

fn main() {}
