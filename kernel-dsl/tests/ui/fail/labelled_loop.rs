#[kernel_dsl::kernel]
pub mod k {
    pub fn find(limit: u32) -> u32 {
        let mut found = 0;
        'outer: for i in 0..limit {
            for j in 0..limit {
                if i * j == 12 {
                    found = i;
                    break 'outer;
                }
            }
        }
        found
    }
}

fn main() {}
