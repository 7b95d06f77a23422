#[kernel_dsl::kernel]
pub mod k {
    pub struct Size {
        pub w: u32,
        pub h: u32,
    }

    pub fn area(s: Size) -> u32 {
        let Size { w, h } = s;
        w * h
    }
}

fn main() {}
