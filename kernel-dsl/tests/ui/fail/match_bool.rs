#[kernel_dsl::kernel]
pub mod k {
    pub fn choose(flag: bool) -> u32 {
        match flag {
            true => 1,
            false => 0,
        }
    }
}

fn main() {}
