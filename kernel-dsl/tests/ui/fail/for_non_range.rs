#[kernel_dsl::kernel]
pub mod k {
    pub fn sum(values: [u32; 4]) -> u32 {
        let mut s = 0;
        for v in values {
            s += v;
        }
        s
    }
}

fn main() {}
