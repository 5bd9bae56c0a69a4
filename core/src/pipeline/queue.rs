//! A bounded queue between two pipeline threads that never blocks its
//! producer: when it is full, a push drops the oldest item and counts it.
//! A lock-step mode (for offline sources only) makes the producer wait for
//! room instead, so that nothing is dropped.

use std::collections::VecDeque;
use std::sync::{Condvar, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

/// What a queue has seen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct QueueStats {
    /// Items pushed.
    pub pushed: u64,
    /// Items dropped because the queue was full (the oldest each time).
    pub dropped: u64,
    /// Items taken by the consumer.
    pub popped: u64,
    /// The most items it held at once.
    pub high_water: usize,
}

#[derive(Debug)]
struct Inner<T> {
    items: VecDeque<T>,
    stats: QueueStats,
    closed: bool,
}

/// A bounded queue that drops its oldest item when full (see the module
/// documentation).
#[derive(Debug)]
pub struct DropOldest<T> {
    capacity: usize,
    inner: Mutex<Inner<T>>,
    changed: Condvar,
}

impl<T> DropOldest<T> {
    /// A queue holding at most `capacity` items (at least 1).
    pub fn new(capacity: usize) -> Self {
        let capacity = capacity.max(1);
        Self {
            capacity,
            inner: Mutex::new(Inner {
                items: VecDeque::with_capacity(capacity),
                stats: QueueStats::default(),
                closed: false,
            }),
            changed: Condvar::new(),
        }
    }

    /// The capacity.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    fn lock(&self) -> MutexGuard<'_, Inner<T>> {
        // A thread that panicked while holding the lock left the queue in a
        // consistent state (every change is a single push or pop), so the
        // data is still good.
        self.inner.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Adds an item without waiting; when full, the oldest item is dropped
    /// and returned.
    pub fn push(&self, item: T) -> Option<T> {
        let mut g = self.lock();
        let dropped = if g.items.len() >= self.capacity {
            g.stats.dropped += 1;
            g.items.pop_front()
        } else {
            None
        };
        g.items.push_back(item);
        g.stats.pushed += 1;
        g.stats.high_water = g.stats.high_water.max(g.items.len());
        drop(g);
        self.changed.notify_all();
        dropped
    }

    /// Adds an item, waiting up to `timeout` for room (lock-step mode). Gives
    /// the item back when there was no room in time or the queue is closed.
    pub fn push_wait(&self, item: T, timeout: Duration) -> Result<(), T> {
        let deadline = Instant::now() + timeout;
        let mut g = self.lock();
        while g.items.len() >= self.capacity && !g.closed {
            let now = Instant::now();
            if now >= deadline {
                return Err(item);
            }
            g = self
                .changed
                .wait_timeout(g, deadline - now)
                .unwrap_or_else(PoisonError::into_inner)
                .0;
        }
        if g.closed {
            return Err(item);
        }
        g.items.push_back(item);
        g.stats.pushed += 1;
        g.stats.high_water = g.stats.high_water.max(g.items.len());
        drop(g);
        self.changed.notify_all();
        Ok(())
    }

    /// Takes the oldest item, waiting up to `timeout`; `None` when none came
    /// (or the queue is closed and empty).
    pub fn pop(&self, timeout: Duration) -> Option<T> {
        let deadline = Instant::now() + timeout;
        let mut g = self.lock();
        loop {
            if let Some(item) = g.items.pop_front() {
                g.stats.popped += 1;
                drop(g);
                self.changed.notify_all();
                return Some(item);
            }
            let now = Instant::now();
            if g.closed || now >= deadline {
                return None;
            }
            g = self
                .changed
                .wait_timeout(g, deadline - now)
                .unwrap_or_else(PoisonError::into_inner)
                .0;
        }
    }

    /// Takes the newest item without waiting and drops the older ones (they
    /// count as dropped): what a display wants.
    pub fn take_latest(&self) -> Option<T> {
        let mut g = self.lock();
        let n = g.items.len();
        if n == 0 {
            return None;
        }
        g.stats.dropped += (n - 1) as u64;
        g.stats.popped += 1;
        let last = g.items.pop_back();
        g.items.clear();
        drop(g);
        self.changed.notify_all();
        last
    }

    /// Items waiting.
    pub fn len(&self) -> usize {
        self.lock().items.len()
    }

    /// Whether no item is waiting.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// What the queue has seen.
    pub fn stats(&self) -> QueueStats {
        self.lock().stats
    }

    /// Closes the queue: waiting pushers and poppers return, later pushes
    /// with [`DropOldest::push_wait`] fail; items already in it can still be
    /// taken.
    pub fn close(&self) {
        self.lock().closed = true;
        self.changed.notify_all();
    }

    /// Whether the queue is closed.
    pub fn is_closed(&self) -> bool {
        self.lock().closed
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    #[test]
    fn a_full_queue_drops_its_oldest_item_and_counts_it() {
        let q = DropOldest::new(2);
        assert_eq!(q.push(1), None);
        assert_eq!(q.push(2), None);
        assert_eq!(q.push(3), Some(1));
        assert_eq!(q.pop(Duration::ZERO), Some(2));
        assert_eq!(q.pop(Duration::ZERO), Some(3));
        assert_eq!(q.pop(Duration::ZERO), None);
        let s = q.stats();
        assert_eq!((s.pushed, s.dropped, s.popped, s.high_water), (3, 1, 2, 2));
    }

    #[test]
    fn take_latest_keeps_the_newest_and_counts_the_rest_as_dropped() {
        let q = DropOldest::new(4);
        for i in 0..3 {
            q.push(i);
        }
        assert_eq!(q.take_latest(), Some(2));
        assert!(q.is_empty());
        assert_eq!(q.stats().dropped, 2);
        assert_eq!(q.take_latest(), None);
    }

    #[test]
    fn push_wait_waits_for_room_instead_of_dropping() {
        let q = Arc::new(DropOldest::new(1));
        q.push(0);
        let consumer = {
            let q = q.clone();
            std::thread::spawn(move || {
                let mut got = Vec::new();
                while got.len() < 3 {
                    if let Some(v) = q.pop(Duration::from_secs(5)) {
                        got.push(v);
                    }
                }
                got
            })
        };
        for i in 1..3 {
            assert!(q.push_wait(i, Duration::from_secs(5)).is_ok());
        }
        let got = consumer.join().unwrap_or_default();
        assert_eq!(got, vec![0, 1, 2]);
        assert_eq!(q.stats().dropped, 0);
    }

    #[test]
    fn push_wait_gives_the_item_back_when_no_room_comes() {
        let q = DropOldest::new(1);
        q.push(0);
        assert_eq!(q.push_wait(1, Duration::from_millis(1)), Err(1));
        q.close();
        assert_eq!(q.push_wait(2, Duration::from_secs(1)), Err(2));
        // What was queued before the close can still be taken.
        assert_eq!(q.pop(Duration::ZERO), Some(0));
        assert_eq!(q.pop(Duration::from_secs(1)), None);
    }
}
