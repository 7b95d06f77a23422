#[kernel_dsl::kernel]
pub mod k {
    pub fn traced(x: f32) -> f32 {
        println!("{x}");
        x
    }
}

fn main() {}
