// A compute module: stages over `Storage` and `Atomics` that run on the CPU from many rayon
// threads at once, as they would as WGSL invocations.

#[kernel_dsl::kernel(compute)]
pub mod k {
    use glam::{UVec4, Vec4};
    use kernel_dsl::{Atomics, Storage};

    pub const QUEUE_HEAD: u32 = 0;
    pub const TOTAL: u32 = 1;

    #[resources(group = 0)]
    pub struct Pool {
        pub items: Storage<u32>,
        pub weights: Storage<f32>,
        pub colours: Storage<Vec4>,
        pub keys: Storage<UVec4>,
        pub counters: Atomics,
        pub count: u32,
    }

    #[resources(group = 1)]
    pub struct Queue {
        pub entries: Storage<u32>,
        pub head: Atomics,
    }

    /// Invocations with an even item append it to the queue.
    pub fn enqueue_even(pool: &Pool, queue: &Queue, invocation: u32) {
        if invocation >= pool.count {
            return;
        }
        let item = pool.items.load(invocation);
        pool.counters.atomic_add(TOTAL, 1);
        if item % 2 == 0 {
            let slot = queue.head.atomic_add(QUEUE_HEAD, 1);
            queue.entries.store(slot, item);
        }
        let w = pool.weights.load(invocation) * 2.0;
        pool.weights.store(invocation, w);
        pool.colours.store(invocation, Vec4::splat(w));
        pool.keys.store(invocation, UVec4::new(item, slot_or_zero(item), 0, 1));
        pool.counters.atomic_max(2, item);
        pool.counters.atomic_min(3, item);
        let old = pool.counters.atomic_exchange(4, item);
        pool.counters.atomic_sub(5, old.wrapping_sub(old));
        if pool.counters.atomic_load(6) == 0 {
            pool.counters.atomic_store(7, 1);
        }
    }

    pub fn slot_or_zero(item: u32) -> u32 {
        item / 2
    }
}

use kernel_dsl::{Atomics, Storage};
use rayon::prelude::*;

fn main() {
    let n = 20_000u32;
    let pool = k::Pool {
        items: Storage::from_slice(&(0..n).collect::<Vec<_>>()),
        weights: Storage::from_slice(&vec![1.5; n as usize]),
        colours: Storage::new(n as usize),
        keys: Storage::new(n as usize),
        counters: Atomics::from_slice(&[0, 0, 0, u32::MAX, 0, 0, 0, 0]),
        count: n,
    };
    let queue = k::Queue { entries: Storage::new(n as usize), head: Atomics::new(1) };
    // More invocations than items: the stage checks its own bound.
    (0..n + 100).into_par_iter().for_each(|i| k::enqueue_even(&pool, &queue, i));
    let head = queue.head.to_vec()[0];
    let mut queued = queue.entries.to_vec()[..head as usize].to_vec();
    queued.sort_unstable();
    assert_eq!(queued, (0..n).filter(|i| i % 2 == 0).collect::<Vec<_>>(), "no item lost or duplicated");
    let counters = pool.counters.to_vec();
    assert_eq!((counters[1], counters[2], counters[3], counters[7]), (n, n - 1, 0, 1));
    assert!(pool.weights.to_vec().iter().all(|w| *w == 3.0));
    assert_eq!(pool.colours.load(5), glam::Vec4::splat(3.0));
    assert_eq!(pool.keys.load(6), glam::UVec4::new(6, 3, 0, 1));

    let ir = k::kernel_ir();
    assert!(ir.compute);
    let groups: Vec<u32> = ir
        .items
        .iter()
        .filter_map(|i| match i {
            kernel_dsl::ir::Item::Struct(s) if s.resources => Some(s.group),
            _ => None,
        })
        .collect();
    assert_eq!(groups, vec![0, 1]);
}
