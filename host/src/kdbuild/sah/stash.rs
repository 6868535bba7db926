//! The build's buffers and their reuse. The work of the build (Wald & Havran 2006, "On building
//! fast kd-Trees for Ray Tracing, and on doing that in O(N log N)") is a few passes over each
//! node's lists, and the deep tail of the tree is millions of nodes of a few references each:
//! allocating and freeing their lists would cost more than the passes. So lists go back to
//! pools bucketed by capacity (`Pool`), a task keeps its pools and working buffers together
//! (`Scratch`), and the parallel tasks hand those sets on to each other (`Stash`), so memory freed
//! anywhere in the tree serves later nodes.
use super::event::Event;
use super::Node;
use crate::kdbuild::clip::ClipBuffers;

/// Lists kept for reuse, bucketed by capacity: bucket b holds lists whose capacity lies in
/// [2^b, 2^(b+1)). A list is handed out only to a need it covers within a factor of eight, so a
/// big list freed near the root is not held (with all its pages) by a small node deep in the
/// tree: with one unsorted pool, every pending sibling ended up holding a root-sized list and the
/// conference room's build peaked at 400 MiB.
pub(super) struct Pool<T> {
    buckets: Vec<Vec<Vec<T>>>,
}

impl<T> Default for Pool<T> {
    fn default() -> Self {
        Self { buckets: (0..usize::BITS).map(|_| Vec::new()).collect() }
    }
}

impl<T> Pool<T> {
    /// An empty list with room for at least `need` items.
    pub(super) fn take(&mut self, need: usize) -> Vec<T> {
        if need == 0 {
            return Vec::new();
        }
        let class = need.next_power_of_two().trailing_zeros() as usize;
        for bucket in self.buckets.iter_mut().skip(class).take(3) {
            if let Some(list) = bucket.pop() {
                return list;
            }
        }
        Vec::with_capacity(need.next_power_of_two())
    }

    pub(super) fn give(&mut self, mut list: Vec<T>) {
        if list.capacity() == 0 {
            return;
        }
        list.clear();
        self.buckets[list.capacity().ilog2() as usize].push(list);
    }
}

/// Buffers a task reuses from node to node: its pools, the partition's codes and fresh events,
/// the sort's second buffer and the clipper's. Allocating and freeing a dozen lists per split
/// would cost more than the split itself in the deep tail of the tree; lists freed by a node go
/// back to the pools and serve the next.
#[derive(Default)]
pub(super) struct Scratch {
    event_lists: Pool<Event>,
    pub(super) triangle_lists: Pool<u32>,
    pub(super) code: Vec<u32>,
    pub(super) fresh: [[Vec<Event>; 3]; 2],
    /// The radix sort's second buffer.
    pub(super) sort: Vec<Event>,
    pub(super) clip: ClipBuffers,
}

impl Scratch {
    #[inline]
    pub(super) fn events(&mut self, need: usize) -> Vec<Event> {
        self.event_lists.take(need)
    }

    #[inline]
    pub(super) fn triangles(&mut self, need: usize) -> Vec<u32> {
        self.triangle_lists.take(need)
    }

    #[inline]
    pub(super) fn recycle_events(&mut self, list: Vec<Event>) {
        self.event_lists.give(list);
    }

    pub(super) fn recycle(&mut self, node: Node) {
        let Node { triangles, events, .. } = node;
        self.triangle_lists.give(triangles);
        for list in events {
            self.recycle_events(list);
        }
    }
}

/// Buffers between tasks: a task takes one set and gives it back when done, so lists freed
/// anywhere in the tree serve later nodes (memory the build has touched already, where fresh
/// pages cost a fault and zeroing each), and all of it is freed with the build. Kept apart
/// from `Sah`, which holds only the settings and the scene, so no lock sits among them.
#[derive(Default)]
pub(super) struct Stash(std::sync::Mutex<Vec<Scratch>>);

impl Stash {
    /// A set of buffers from the stash, or a new one.
    pub(super) fn take(&self) -> Scratch {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).pop().unwrap_or_default()
    }

    pub(super) fn keep(&self, scratch: Scratch) {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).push(scratch);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pool hands out a list that covers the need, never one more than eight times too big
    /// (the bound that keeps root-sized lists away from deep nodes), and reuses what it got.
    #[test]
    fn pool_hands_out_lists_that_fit_the_need() {
        let mut pool: Pool<u32> = Pool::default();
        assert_eq!(pool.take(0).capacity(), 0, "an empty need allocates nothing");
        let big: Vec<u32> = Vec::with_capacity(1 << 20);
        let big_ptr = big.as_ptr();
        pool.give(big);
        for need in [1usize, 100, 5000, (1 << 16) + 1] {
            let list = pool.take(need);
            assert!(list.capacity() >= need && list.is_empty());
            assert!(list.capacity() <= 16 * need.next_power_of_two(), "need {need} got a list of {}", list.capacity());
            assert_ne!(list.as_ptr(), big_ptr, "need {need} was given the root-sized list");
        }
        // Within a factor of eight the big list is reused, not a new one allocated.
        let reused = pool.take((1 << 18) + 1);
        assert_eq!(reused.as_ptr(), big_ptr);
        let mut small = pool.take(10);
        small.extend([1, 2, 3]);
        let small_ptr = small.as_ptr();
        pool.give(small);
        let again = pool.take(9);
        assert_eq!((again.as_ptr(), again.len()), (small_ptr, 0), "a given list comes back cleared");
    }
}
