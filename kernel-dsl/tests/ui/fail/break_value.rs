#[kernel_dsl::kernel]
pub mod k {
    pub fn first_square_over(limit: u32) -> u32 {
        let mut i = 0;
        loop {
            if i * i > limit {
                break i;
            }
            i += 1;
        }
    }
}

fn main() {}
