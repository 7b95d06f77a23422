#[kernel_dsl::kernel]
pub mod k {
    pub fn big() -> u32 {
        let _wide = 1u64;
        1
    }
}

fn main() {}
