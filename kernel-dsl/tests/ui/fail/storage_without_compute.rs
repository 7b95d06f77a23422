#[kernel_dsl::kernel]
pub mod k {
    use glam::Vec4;
    use kernel_dsl::Storage;

    #[resources]
    pub struct Pool {
        pub rays: Storage<Vec4>,
        pub count: u32,
    }

    pub fn first(pool: &Pool) -> u32 {
        pool.count
    }
}

fn main() {}
