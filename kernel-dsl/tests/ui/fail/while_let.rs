#[kernel_dsl::kernel]
pub mod k {
    pub fn count_up(start: u32) -> u32 {
        let mut x = start;
        while let 0 = x {
            x += 1;
        }
        x
    }
}

fn main() {}
