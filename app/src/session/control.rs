//! The window's hold on a replay (`ReplayControl`): what it asks (pause,
//! steps, seeks, speed) and where the replay is; the replayed source
//! (`replay::Controlled`) carries the requests out.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};

/// What the window asks of a replay, and where the replay is.
#[derive(Debug, Default)]
pub(super) struct ControlState {
    pub(super) paused: bool,
    /// Sets to step from the last one given (negative: back).
    pub(super) steps: i64,
    pub(super) seek: Option<usize>,
    /// A new speed (`Some(None)`: as fast as possible).
    pub(super) speed: Option<Option<f64>>,
    /// The speed in use.
    pub(super) current_speed: Option<f64>,
    /// The number of the last set given.
    pub(super) shown: Option<usize>,
    /// The last sets given: their triggers and numbers.
    pub(super) given: std::collections::VecDeque<(u64, usize)>,
    pub(super) at_end: bool,
}

/// Sets given that a [`ReplayControl`] can still number by their trigger
/// (more than the pipeline holds between the source and the window).
pub(super) const GIVEN_KEPT: usize = 64;

/// The window's hold on a replay: play and pause, steps, seeks, speed,
/// and where the replay is. Requests take effect when the capture thread
/// next asks the replay for a set.
#[derive(Clone, Debug)]
pub struct ReplayControl {
    state: Arc<Mutex<ControlState>>,
    /// The sets' log times (`None`: the file has no index).
    times: Option<Arc<[u64]>>,
    file: PathBuf,
}

impl ReplayControl {
    /// A control of the replay of `file` (the sets' log times `times`,
    /// if it has its index) at `speed`.
    pub(super) fn new(file: PathBuf, times: Option<Arc<[u64]>>, speed: Option<f64>) -> Self {
        Self {
            state: Arc::new(Mutex::new(ControlState {
                current_speed: speed,
                ..Default::default()
            })),
            times,
            file,
        }
    }

    pub(super) fn lock(&self) -> std::sync::MutexGuard<'_, ControlState> {
        // Plain fields: no update leaves them half done.
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The recording.
    pub fn file(&self) -> &Path {
        &self.file
    }

    /// The sets' log times (Unix ns), if the file has its index (without
    /// one it can be played and stepped forward, not sought).
    pub fn times(&self) -> Option<&[u64]> {
        self.times.as_deref()
    }

    /// Pauses or plays (playing at the end starts again from the first
    /// set).
    pub fn set_paused(&self, paused: bool) {
        let mut s = self.lock();
        if !paused && s.at_end && self.times.is_some() {
            s.seek = Some(0);
            s.steps = 0;
        }
        s.paused = paused;
    }

    /// Whether the replay is paused (also at the end of an interactive
    /// replay).
    pub fn is_paused(&self) -> bool {
        self.lock().paused
    }

    /// Pauses and steps `n` sets from the last one given (negative: back,
    /// which needs the index).
    pub fn step(&self, n: i64) {
        let mut s = self.lock();
        s.paused = true;
        s.steps += n;
    }

    /// Goes to set number `k` (shown at once, even when paused).
    pub fn seek(&self, k: usize) {
        let mut s = self.lock();
        s.seek = Some(k);
        s.steps = 0;
    }

    /// The number of the set nearest to `log_time`, if the file has its
    /// index (and a set).
    pub fn set_at(&self, log_time: u64) -> Option<usize> {
        let times = self.times()?;
        let after = times.partition_point(|&t| t < log_time);
        let before = after.checked_sub(1);
        match (before, times.get(after)) {
            (Some(b), Some(&ta)) if log_time - times[b] < ta - log_time => Some(b),
            (_, Some(_)) => Some(after),
            (b, None) => b,
        }
    }

    /// Replays at `speed` times the recorded rate (`None`: as fast as
    /// possible).
    pub fn set_speed(&self, speed: Option<f64>) {
        let mut s = self.lock();
        s.speed = Some(speed);
        s.current_speed = speed;
    }

    /// The speed asked for.
    pub fn speed(&self) -> Option<f64> {
        self.lock().current_speed
    }

    /// The number of the last set given to processing.
    pub fn shown(&self) -> Option<usize> {
        self.lock().shown
    }

    /// The number of the set with `trigger` among the last sets given
    /// (the set the window shows lags the last one given while playing).
    pub fn number_of(&self, trigger: u64) -> Option<usize> {
        let s = self.lock();
        s.given.iter().rev().find(|g| g.0 == trigger).map(|g| g.1)
    }

    /// Whether the replay has given its last set.
    pub fn at_end(&self) -> bool {
        self.lock().at_end
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn control(times: Option<Vec<u64>>) -> ReplayControl {
        ReplayControl {
            state: Arc::default(),
            times: times.map(Arc::from),
            file: PathBuf::from("drive.mcap"),
        }
    }

    #[test]
    fn a_seek_by_time_goes_to_the_nearest_set() {
        let c = control(Some(vec![100, 200, 300]));
        assert_eq!(c.set_at(0), Some(0));
        assert_eq!(c.set_at(149), Some(0));
        assert_eq!(c.set_at(151), Some(1));
        assert_eq!(c.set_at(300), Some(2));
        assert_eq!(c.set_at(10_000), Some(2));
        assert_eq!(control(Some(Vec::new())).set_at(5), None);
        // Without the index there is nothing to seek by.
        assert_eq!(control(None).set_at(5), None);
    }

    #[test]
    fn steps_pause_and_playing_at_the_end_starts_again() {
        let c = control(Some(vec![100, 200, 300]));
        c.step(1);
        c.step(-2);
        assert!(c.is_paused());
        assert_eq!(c.lock().steps, -1);
        c.lock().at_end = true;
        c.set_paused(false);
        assert!(!c.is_paused());
        let s = c.lock();
        assert_eq!((s.seek, s.steps), (Some(0), 0));
    }
}
