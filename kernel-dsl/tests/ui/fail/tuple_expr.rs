#[kernel_dsl::kernel]
pub mod k {
    pub fn span(a: f32, b: f32) -> f32 {
        let _pair = (a, b);
        b - a
    }
}

fn main() {}
