#[kernel_dsl::kernel]
pub mod k {
    pub fn bucket(x: u32) -> u32 {
        match x {
            0..=9 => 0,
            _ => 1,
        }
    }
}

fn main() {}
