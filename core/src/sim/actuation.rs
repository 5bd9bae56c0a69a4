//! Actuation latency: exposure commands that a camera applies some frame
//! sets after they are sent, as a hardware-triggered camera does (a
//! command sent while set `n` is the next to be taken shows from set
//! `n + latency` on).
//!
//! The one latency model of the simulated cameras: the simulated rig and
//! the test harnesses that drive a controller without one share it.

use crate::exposure::ExposureSetting;
use crate::source::ExposureCommand;

/// Exposure commands in flight, with the latency they take to show.
#[derive(Clone, Debug, Default)]
pub struct Actuation {
    latency: u64,
    queued: Vec<(u64, ExposureCommand)>,
}

impl Actuation {
    /// No command in flight; each command shows `latency` sets after the
    /// set that is next when it is sent.
    pub fn new(latency: u64) -> Self {
        Self {
            latency,
            queued: Vec::new(),
        }
    }

    /// The latency, frame sets.
    pub fn latency(&self) -> u64 {
        self.latency
    }

    /// Sends `command` while set `next` is the next to be taken.
    pub fn send(&mut self, next: u64, command: ExposureCommand) {
        self.queued.push((next + self.latency, command));
    }

    /// Applies to `settings` (one per camera) every command due by set
    /// `trigger`, in the order they were sent, and forgets them. A command
    /// for a camera beyond `settings` is dropped.
    pub fn apply_due(&mut self, trigger: u64, settings: &mut [ExposureSetting]) {
        self.queued.retain(|(at, c)| {
            if *at > trigger {
                return true;
            }
            if let Some(s) = settings.get_mut(c.camera) {
                *s = c.setting;
            }
            false
        });
    }

    /// The setting last sent to camera `camera` and not yet shown.
    pub fn pending(&self, camera: usize) -> Option<ExposureSetting> {
        self.queued
            .iter()
            .rev()
            .find(|(_, c)| c.camera == camera)
            .map(|(_, c)| c.setting)
    }

    /// Forgets every command in flight.
    pub fn clear(&mut self) {
        self.queued.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(shutter_us: f64) -> ExposureSetting {
        ExposureSetting {
            shutter_us,
            gain_db: 0.0,
        }
    }

    fn command(camera: usize, shutter_us: f64) -> ExposureCommand {
        ExposureCommand {
            camera,
            setting: at(shutter_us),
        }
    }

    #[test]
    fn a_command_shows_after_the_latency_and_later_ones_win() {
        for latency in 0..=2 {
            let mut a = Actuation::new(latency);
            let mut settings = vec![at(100.0); 2];
            a.send(5, command(1, 200.0));
            a.send(5, command(1, 300.0));
            assert_eq!(a.pending(1), Some(at(300.0)));
            assert_eq!(a.pending(0), None);
            for trigger in 5..5 + latency {
                a.apply_due(trigger, &mut settings);
                assert_eq!(settings[1], at(100.0), "latency {latency}, set {trigger}");
            }
            a.apply_due(5 + latency, &mut settings);
            assert_eq!(settings, [at(100.0), at(300.0)], "latency {latency}");
            assert_eq!(a.pending(1), None);
        }
    }

    #[test]
    fn commands_for_unknown_cameras_are_dropped_and_clear_forgets() {
        let mut a = Actuation::new(1);
        let mut settings = vec![at(100.0)];
        a.send(0, command(3, 200.0));
        a.send(0, command(0, 400.0));
        a.clear();
        a.apply_due(10, &mut settings);
        assert_eq!(settings, [at(100.0)]);
        a.send(0, command(3, 200.0));
        a.apply_due(1, &mut settings);
        assert_eq!(settings, [at(100.0)]);
        assert_eq!(a.pending(3), None);
    }
}
