//! Triggers: how a camera is set up to be triggered, when rigview's
//! software triggers fire, and which tick an arriving frame answers.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use aravis::prelude::*;
use aravis::Camera;

use super::config::TriggerMode;
use super::error::{CameraError, Named};

/// Sets `camera` up for `mode`: a hardware line, software triggers, or
/// free run at a frame rate.
pub(crate) fn configure(
    camera: &Camera,
    named: Named<'_>,
    mode: &TriggerMode,
) -> Result<(), CameraError> {
    match mode {
        TriggerMode::Hardware { line } => camera
            .set_trigger(line)
            .map_err(named.set("TriggerSource", line)),
        TriggerMode::Software { .. } => camera
            .set_trigger("Software")
            .map_err(named.set("TriggerSource", "Software")),
        TriggerMode::FreeRun { rate_hz } => {
            camera
                .clear_triggers()
                .map_err(named.set("TriggerMode", "Off"))?;
            match rate_hz {
                Some(r) => camera
                    .set_frame_rate(*r)
                    .map_err(named.set("AcquisitionFrameRate", format!("{r} Hz"))),
                None => Ok(()),
            }
        }
    }
}

/// When software triggers fire: every camera fires at the same ticks, so a
/// tick's index names the frame set its frames belong to.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Schedule {
    epoch: Instant,
    /// The epoch on the host's wall clock, ns since the Unix epoch.
    epoch_wall_ns: u64,
    period: Duration,
}

impl Schedule {
    /// Ticks every `period` from now.
    pub fn starting_now(period: Duration) -> Self {
        Self {
            epoch: Instant::now(),
            epoch_wall_ns: super::clock::host_now_ns(),
            period,
        }
    }

    fn period_ns(&self) -> u64 {
        u64::try_from(self.period.as_nanos())
            .unwrap_or(u64::MAX)
            .max(1)
    }

    /// The index and instant of the first tick after `now`.
    pub fn next_after(&self, now: Instant) -> (u64, Instant) {
        let p = self.period_ns();
        let since =
            u64::try_from(now.saturating_duration_since(self.epoch).as_nanos()).unwrap_or(u64::MAX);
        let k = since / p + 1;
        (k, self.epoch + Duration::from_nanos(k.saturating_mul(p)))
    }

    /// Tick `k` on the host's wall clock: the key its frames are matched by.
    pub fn wall_ns(&self, k: u64) -> u64 {
        self.epoch_wall_ns + k.saturating_mul(self.period_ns())
    }
}

/// Software triggers sent whose frame has not arrived yet, oldest first.
#[derive(Clone, Debug, Default)]
pub(crate) struct Outstanding {
    sent: VecDeque<(u64, Instant)>,
}

impl Outstanding {
    /// Tick `k`'s trigger was sent at `at`.
    pub fn sent(&mut self, k: u64, at: Instant) {
        self.sent.push_back((k, at));
    }

    /// Triggers waiting for their frame.
    pub fn len(&self) -> u64 {
        self.sent.len() as u64
    }

    /// Forgets triggers sent more than `timeout` before `now`: their frames
    /// are not coming.
    pub fn expire(&mut self, now: Instant, timeout: Duration) {
        while self
            .sent
            .front()
            .is_some_and(|(_, t)| now.duration_since(*t) > timeout)
        {
            self.sent.pop_front();
        }
    }

    /// The tick of a frame that arrived after `lost` frames were lost whole
    /// (a gap in the frame ids): each trigger makes one frame, so the oldest
    /// trigger still waiting after those of the lost frames is this frame's.
    pub fn arrived(&mut self, lost: u64) -> Option<u64> {
        let lost = usize::try_from(lost).unwrap_or(usize::MAX);
        self.sent.drain(..lost.min(self.sent.len()));
        self.sent.pop_front().map(|(k, _)| k)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_follow_the_period_from_the_epoch() {
        let s = Schedule {
            epoch: Instant::now(),
            epoch_wall_ns: 1_000,
            period: Duration::from_millis(50),
        };
        let (k, at) = s.next_after(s.epoch);
        assert_eq!((k, at - s.epoch), (1, Duration::from_millis(50)));
        let (k, at) = s.next_after(s.epoch + Duration::from_millis(120));
        assert_eq!((k, at - s.epoch), (3, Duration::from_millis(150)));
        assert_eq!(s.wall_ns(3), 1_000 + 150_000_000);
    }

    #[test]
    fn a_frame_answers_the_oldest_trigger_after_those_of_lost_frames() {
        let t0 = Instant::now();
        let mut o = Outstanding::default();
        for k in 1..=5 {
            o.sent(k, t0 + Duration::from_millis(50 * k));
        }
        assert_eq!(o.arrived(0), Some(1));
        // Frames 2 and 3 were lost whole.
        assert_eq!(o.arrived(2), Some(4));
        assert_eq!(o.len(), 1);
        // A trigger whose frame never comes is forgotten after the timeout.
        o.expire(t0 + Duration::from_millis(400), Duration::from_millis(100));
        assert_eq!(o.len(), 0);
        assert_eq!(o.arrived(3), None);
    }
}
