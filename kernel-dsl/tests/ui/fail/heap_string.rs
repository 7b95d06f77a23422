#[kernel_dsl::kernel]
pub mod k {
    pub fn label(id: u32) -> u32 {
        let _name: String = String::new();
        id
    }
}

fn main() {}
