#[kernel_dsl::kernel]
pub mod k {
    pub fn clamp_kind(kind: u32) -> u32 {
        match kind {
            0 => 0,
            other => other - 1,
        }
    }
}

fn main() {}
