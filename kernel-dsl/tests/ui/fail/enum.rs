#[kernel_dsl::kernel]
pub mod k {
    #[derive(Clone, Copy)]
    pub enum Kind {
        Diffuse,
        Mirror,
    }
}

fn main() {}
