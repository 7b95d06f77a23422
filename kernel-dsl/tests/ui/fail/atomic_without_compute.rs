#[kernel_dsl::kernel]
pub mod k {
    use kernel_dsl::Atomics;

    #[resources]
    pub struct Queue {
        pub head: Atomics,
    }

    pub fn push(queue: &Queue) -> u32 {
        queue.head.atomic_add(0, 1)
    }
}

fn main() {}
