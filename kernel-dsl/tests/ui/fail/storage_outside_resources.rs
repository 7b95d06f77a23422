#[kernel_dsl::kernel(compute)]
pub mod k {
    use kernel_dsl::{Atomics, Storage};

    #[resources]
    pub struct Pool {
        pub count: u32,
    }

    /// A value type: `Storage` and `Atomics` belong to the `#[resources]` struct.
    pub struct Queue {
        pub entries: Storage<u32>,
        pub length: Atomics,
        pub first: u32,
    }

    pub fn size(pool: &Pool, invocation: u32) -> u32 {
        pool.count + invocation
    }
}

fn main() {}
