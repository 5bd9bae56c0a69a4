//! Frame-set assembly: the frames of one trigger, one per camera, matched by
//! a time key within a tolerance. With software triggers the key is the
//! trigger's tick (each camera's thread pairs its frames with its triggers
//! in order, using frame-id gaps to skip frames lost whole); otherwise it is
//! the host time the frame's first packet arrived. Frame ids tell when a
//! camera skipped a trigger.

use std::collections::VecDeque;

pub use rigview_core::source::SetCounters;
use rigview_core::source::{Frame, FrameSet};

/// A frame waiting for its set.
#[derive(Clone, Debug)]
pub struct Arrived {
    /// Its matching key, ns since the Unix epoch: the software trigger's tick,
    /// or the host time its first packet arrived.
    pub host_ns: u64,
    /// The camera's monotonic frame id.
    pub id: u64,
    /// The frame.
    pub frame: Frame,
}

/// Matches frames into sets.
#[derive(Clone, Debug)]
pub struct Assembler {
    queues: Vec<VecDeque<Arrived>>,
    last_id: Vec<Option<u64>>,
    tolerance_ns: u64,
    timeout_ns: u64,
    next_trigger: u64,
    emitted_until_ns: u64,
    counters: SetCounters,
}

impl Assembler {
    /// An assembler for `cameras` cameras.
    pub fn new(cameras: usize, tolerance_ns: u64, timeout_ns: u64) -> Self {
        Self {
            queues: vec![VecDeque::new(); cameras],
            last_id: vec![None; cameras],
            tolerance_ns,
            timeout_ns: timeout_ns.max(tolerance_ns),
            next_trigger: 0,
            emitted_until_ns: 0,
            counters: SetCounters::default(),
        }
    }

    /// The counters so far.
    pub fn counters(&self) -> &SetCounters {
        &self.counters
    }

    /// A camera's frame ids restart (it reconnected).
    pub fn restart_ids(&mut self, camera: usize) {
        if let Some(l) = self.last_id.get_mut(camera) {
            *l = None;
        }
    }

    /// Frames of `camera` that wait (a lost camera's are dropped).
    pub fn drop_camera(&mut self, camera: usize) {
        if let Some(q) = self.queues.get_mut(camera) {
            q.clear();
        }
        self.restart_ids(camera);
    }

    /// Adds a frame of camera `frame.frame.meta.camera`.
    pub fn push(&mut self, arrived: Arrived) {
        let camera = arrived.frame.meta.camera;
        if arrived.host_ns + self.tolerance_ns < self.emitted_until_ns {
            // Its set was given out already.
            self.counters.late_frames += 1;
            return;
        }
        let Some(q) = self.queues.get_mut(camera) else {
            return;
        };
        let at = q.partition_point(|a| a.host_ns <= arrived.host_ns);
        q.insert(at, arrived);
    }

    /// The next set, if it is ready at host time `now_ns`: every camera in
    /// `active` has its frame, or has moved past it, or the set has waited
    /// its timeout. Cameras not in `active` (lost) get an empty slot without
    /// being waited for.
    pub fn pop(&mut self, now_ns: u64, active: &[bool]) -> Option<FrameSet> {
        let anchor = self
            .queues
            .iter()
            .filter_map(|q| q.front().map(|a| a.host_ns))
            .min()?;
        let window_end = anchor + self.tolerance_ns;
        let mut ready = true;
        for (c, q) in self.queues.iter().enumerate() {
            let has_candidate = q.front().is_some_and(|a| a.host_ns <= window_end);
            let moved_past = q.front().is_some_and(|a| a.host_ns > window_end);
            let waited_for = active.get(c).copied().unwrap_or(false);
            if waited_for && !has_candidate && !moved_past {
                ready = false;
            }
        }
        if !ready && now_ns < anchor + self.timeout_ns {
            return None;
        }
        let mut frames = Vec::with_capacity(self.queues.len());
        let mut arrivals = Vec::new();
        for (c, q) in self.queues.iter_mut().enumerate() {
            let take = q.front().is_some_and(|a| a.host_ns <= window_end);
            let slot = if take { q.pop_front() } else { None };
            if let Some(a) = &slot {
                arrivals.push(a.host_ns);
                if let Some(prev) = self.last_id[c] {
                    // A gap in the ids: frames the camera made that never
                    // reached a set.
                    self.counters.id_gaps += a.id.saturating_sub(prev + 1);
                }
                self.last_id[c] = Some(a.id);
            }
            frames.push(slot.map(|a| a.frame));
        }
        self.emitted_until_ns = window_end;
        let set = FrameSet {
            trigger: self.next_trigger,
            timestamp_ns: anchor,
            frames,
        };
        self.next_trigger += 1;
        let k = &mut self.counters;
        if set.is_complete() {
            k.complete += 1;
        } else {
            k.incomplete += 1;
        }
        for f in &set.frames {
            match f {
                None => k.missing_frames += 1,
                Some(f) if !f.is_complete() => k.broken_frames += 1,
                Some(_) => {}
            }
        }
        if set.frames.iter().flatten().count() >= 2 {
            k.last_skew_ns = set.timestamp_skew_ns();
            if set.is_complete() {
                k.max_skew_ns = k.max_skew_ns.max(k.last_skew_ns);
            }
        }
        let (lo, hi) = arrivals
            .iter()
            .fold((u64::MAX, 0), |(lo, hi), &t| (lo.min(t), hi.max(t)));
        k.last_arrival_spread_ns = hi.saturating_sub(lo.min(hi));
        Some(set)
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use rigview_core::exposure::{ExposureSetting, PixelFormat};
    use rigview_core::source::{FrameMeta, FrameStatus};

    use super::*;

    const MS: u64 = 1_000_000;

    fn arrived(camera: usize, host_ms: u64, id: u64, status: FrameStatus) -> Arrived {
        let meta = FrameMeta {
            camera,
            format: PixelFormat::Mono8,
            width: 2,
            height: 2,
            taken: ExposureSetting {
                shutter_us: 100.0,
                gain_db: 0.0,
            },
            timestamp_ns: host_ms * MS,
            frame_id: id,
            status,
        };
        Arrived {
            host_ns: host_ms * MS,
            id,
            frame: Frame::new(meta, Arc::from(vec![0u8; 4])).unwrap(),
        }
    }

    #[test]
    fn frames_of_one_trigger_make_one_set() {
        let mut a = Assembler::new(3, 10 * MS, 100 * MS);
        let all = [true; 3];
        a.push(arrived(0, 1000, 1, FrameStatus::Complete));
        a.push(arrived(1, 1003, 7, FrameStatus::Complete));
        assert!(a.pop(1005 * MS, &all).is_none(), "camera 2 is awaited");
        a.push(arrived(2, 1002, 3, FrameStatus::Complete));
        a.push(arrived(0, 1050, 2, FrameStatus::Complete));
        let set = a.pop(1006 * MS, &all).unwrap();
        assert!(set.is_complete());
        assert_eq!(set.timestamp_skew_ns(), 3 * MS);
        assert_eq!(a.counters().complete, 1);
        // Camera 0's next frame waits for the others.
        assert!(a.pop(1051 * MS, &all).is_none());
    }

    #[test]
    fn a_missing_or_broken_frame_makes_an_incomplete_set() {
        let mut a = Assembler::new(2, 10 * MS, 100 * MS);
        let all = [true; 2];
        a.push(arrived(0, 1000, 1, FrameStatus::Complete));
        // Camera 1 has moved past: no need to wait.
        a.push(arrived(1, 1050, 2, FrameStatus::Complete));
        let set = a.pop(1051 * MS, &all).unwrap();
        assert!(!set.is_complete());
        assert!(set.frames[1].is_none());
        a.push(arrived(
            0,
            1049,
            2,
            FrameStatus::MissingPackets { missing: 3 },
        ));
        let set = a.pop(1052 * MS, &all).unwrap();
        assert!(!set.is_complete());
        let k = a.counters();
        assert_eq!((k.complete, k.incomplete), (0, 2));
        assert_eq!((k.missing_frames, k.broken_frames), (1, 1));
    }

    #[test]
    fn a_silent_camera_is_waited_for_until_the_timeout_and_a_lost_one_not_at_all() {
        let mut a = Assembler::new(2, 10 * MS, 100 * MS);
        a.push(arrived(0, 1000, 1, FrameStatus::Complete));
        assert!(a.pop(1050 * MS, &[true, true]).is_none());
        assert!(a.pop(1101 * MS, &[true, true]).is_some());
        a.push(arrived(0, 1150, 2, FrameStatus::Complete));
        let set = a.pop(1150 * MS, &[true, false]).unwrap();
        assert!(set.frames[1].is_none());
        // A frame for a set already given out is dropped and counted.
        a.push(arrived(1, 1140, 9, FrameStatus::Complete));
        assert_eq!(a.counters().late_frames, 1);
    }
}
