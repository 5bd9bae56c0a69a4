//! Which setting a frame was taken with, when the camera does not say it in
//! chunk data: frame ids made monotonic, and a history of commands keyed by
//! the first frame id that shows each.

use std::collections::VecDeque;

use rigview_core::exposure::ExposureSetting;

/// Turns a camera's frame ids (GigE Vision block ids are 16 bit and skip 0)
/// into a monotonic count.
#[derive(Clone, Debug, Default)]
pub struct IdUnwrapper {
    last_raw: Option<u64>,
    offset: u64,
}

impl IdUnwrapper {
    /// The monotonic id of raw id `raw`.
    pub fn unwrap(&mut self, raw: u64) -> u64 {
        if let Some(last) = self.last_raw {
            if raw < last && last - raw > 1 << 15 {
                // Wrapped: 16-bit block ids run 1..=65535, wider ids wrap at
                // their width.
                self.offset += if last <= 0xffff {
                    0xffff
                } else if last <= 0xffff_ffff {
                    1 << 32
                } else {
                    0
                };
            }
        }
        self.last_raw = Some(raw);
        self.offset + raw
    }

    /// Forgets the history (a new acquisition).
    pub fn reset(&mut self) {
        *self = Self::default();
    }
}

/// The settings a camera was commanded, each with the first (monotonic)
/// frame id that shows it.
#[derive(Clone, Debug)]
pub struct SettingTracker {
    history: VecDeque<(u64, ExposureSetting)>,
}

impl SettingTracker {
    /// A tracker whose every frame so far is taken with `initial`.
    pub fn new(initial: ExposureSetting) -> Self {
        Self {
            history: VecDeque::from([(0, initial)]),
        }
    }

    /// Frames from `first_id` on are taken with `setting`.
    pub fn commanded(&mut self, first_id: u64, setting: ExposureSetting) {
        // A later command that shows earlier than one queued replaces it.
        while self.history.len() > 1 && self.history.back().is_some_and(|(id, _)| *id >= first_id) {
            self.history.pop_back();
        }
        self.history.push_back((first_id, setting));
    }

    /// The setting frame `id` was taken with; forgets what older frames no
    /// longer need.
    pub fn taken(&mut self, id: u64) -> ExposureSetting {
        while self.history.len() > 1 && self.history.get(1).is_some_and(|(from, _)| *from <= id) {
            self.history.pop_front();
        }
        self.history
            .iter()
            .rev()
            .find(|(from, _)| *from <= id)
            .or(self.history.front())
            .map(|(_, s)| *s)
            .unwrap_or(ExposureSetting {
                shutter_us: 1.0,
                gain_db: 0.0,
            })
    }

    /// The setting commanded last.
    pub fn latest(&self) -> Option<ExposureSetting> {
        self.history.back().map(|(_, s)| *s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(us: f64) -> ExposureSetting {
        ExposureSetting {
            shutter_us: us,
            gain_db: 0.0,
        }
    }

    #[test]
    fn sixteen_bit_block_ids_unwrap_past_65535() {
        let mut u = IdUnwrapper::default();
        let ids: Vec<u64> = [65533, 65534, 65535, 1, 2, 4]
            .into_iter()
            .map(|r| u.unwrap(r))
            .collect();
        assert_eq!(ids, vec![65533, 65534, 65535, 65536, 65537, 65539]);
        u.reset();
        assert_eq!(u.unwrap(7), 7);
    }

    #[test]
    fn frames_take_the_setting_commanded_for_them() {
        let mut t = SettingTracker::new(s(100.0));
        assert_eq!(t.taken(5), s(100.0));
        t.commanded(8, s(200.0));
        assert_eq!(t.taken(6), s(100.0));
        assert_eq!(t.taken(7), s(100.0));
        assert_eq!(t.taken(8), s(200.0));
        t.commanded(10, s(300.0));
        // A command that will show sooner replaces the queued one.
        t.commanded(9, s(400.0));
        assert_eq!(t.taken(9), s(400.0));
        assert_eq!(t.taken(12), s(400.0));
        assert_eq!(t.latest(), Some(s(400.0)));
    }
}
