#[kernel_dsl::kernel]
pub mod k {
    pub fn is_zero(x: u32) -> bool {
        if let 0 = x {
            true
        } else {
            false
        }
    }
}

fn main() {}
