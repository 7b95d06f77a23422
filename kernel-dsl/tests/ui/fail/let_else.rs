#[kernel_dsl::kernel]
pub mod k {
    pub fn non_zero(x: u32) -> u32 {
        let 1 = x else {
            return 0;
        };
        x
    }
}

fn main() {}
