#[kernel_dsl::kernel]
pub mod k {
    pub fn sign(x: i32, strict: bool) -> i32 {
        match x {
            0 if strict => 0,
            _ => 1,
        }
    }
}

fn main() {}
