#[kernel_dsl::kernel]
mod k {
    pub fn biggest(a: u32, b: u32) -> u32 {
        std::cmp::max(a, b)
    }
}

fn main() {}
