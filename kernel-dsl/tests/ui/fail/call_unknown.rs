fn helper(x: f32) -> f32 {
    x * 2.0
}

#[kernel_dsl::kernel]
mod k {
    pub fn twice(x: f32) -> f32 {
        helper(x)
    }
}

fn main() {}
