#[kernel_dsl::kernel]
pub mod k {
    pub fn first(values: [u32; 4]) -> u32 {
        let _it = values.iter();
        values[0]
    }
}

fn main() {}
