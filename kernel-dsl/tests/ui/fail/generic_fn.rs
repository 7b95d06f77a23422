#[kernel_dsl::kernel]
pub mod k {
    pub fn first<T: Copy>(a: T, _b: T) -> T {
        a
    }
}

fn main() {}
