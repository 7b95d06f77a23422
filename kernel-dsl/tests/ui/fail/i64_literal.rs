#[kernel_dsl::kernel]
pub mod k {
    pub fn big() -> u32 {
        let _wide = 1i64;
        1
    }
}

fn main() {}
