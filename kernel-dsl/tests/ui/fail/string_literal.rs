#[kernel_dsl::kernel]
pub mod k {
    pub fn label(id: u32) -> u32 {
        let _name = "lamp";
        id
    }
}

fn main() {}
