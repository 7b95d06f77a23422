#[kernel_dsl::kernel]
pub mod k {
    pub static SAMPLES: u32 = 16;
}

fn main() {}
