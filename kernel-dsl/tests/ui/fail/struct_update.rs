#[kernel_dsl::kernel]
pub mod k {
    pub struct Size {
        pub w: u32,
        pub h: u32,
    }

    pub fn square(s: Size) -> Size {
        Size { h: s.w, ..s }
    }
}

fn main() {}
