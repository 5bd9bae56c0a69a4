//! Frame sets of the simulated rig for the recording tests: rendered in any
//! pixel format, with seeded exposure settings, and a frame that arrived
//! broken now and then.

#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;
use std::sync::Arc;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rigview_calib::Rig;
use rigview_core::exposure::ExposureSetting;
use rigview_core::image::PixelFormat;
use rigview_core::sim::{FillRequest, SimConfig, SimRender};
use rigview_core::source::{CameraInfo, Frame, FrameSet, FrameStatus};
use rigview_record::msgs::{self, SetTelemetryMsg};
use rigview_record::{RecordedSet, RecordingSetup};

/// The simulated rig rendered in one format.
pub struct Sim {
    pub render: SimRender,
    pub format: PixelFormat,
    pub cameras: Vec<CameraInfo>,
}

impl Sim {
    pub fn new(format: PixelFormat, scale: f64) -> Self {
        let mut config = SimConfig::named("reference").unwrap();
        config.scale = scale;
        let render = SimRender::new(&config).unwrap();
        let cameras = render
            .cameras()
            .iter()
            .map(|c| CameraInfo {
                format,
                ..c.clone()
            })
            .collect();
        Self {
            render,
            format,
            cameras,
        }
    }

    pub fn rig(&self) -> Rig {
        self.render.rig().clone()
    }

    pub fn setup(&self) -> RecordingSetup {
        RecordingSetup {
            cameras: self.cameras.clone(),
            rig: Some(self.rig()),
            source: "the simulated rig (tests)".into(),
            time_offset_ns: 1_700_000_000_000_000_000,
        }
    }

    /// Set `k` of a run seeded by `seed`: every camera at its own random
    /// setting; in every fifth set one frame lost packets.
    pub fn set(&self, seed: u64, k: u64) -> FrameSet {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ (k * 0x9e37_79b9));
        let frames = self
            .cameras
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let setting = ExposureSetting {
                    shutter_us: rng.gen_range(200.0..20_000.0),
                    gain_db: rng.gen_range(0.0..6.0),
                };
                let req = FillRequest::new(i, k, setting, self.format, c.width, c.height);
                let mut buf = vec![0u8; req.buffer_len()];
                let mut meta = self.render.fill(&req, &mut buf).unwrap();
                if k % 5 == 3 && i == 1 {
                    meta.status = FrameStatus::MissingPackets { missing: 7 };
                }
                Some(Frame::new(meta, Arc::from(buf)).unwrap())
            })
            .collect();
        FrameSet {
            trigger: k,
            timestamp_ns: (self.render.time_of(k) * 1e9).round() as u64,
            frames,
        }
    }

    pub fn names(&self) -> Vec<String> {
        self.cameras.iter().map(|c| c.name.clone()).collect()
    }

    pub fn telemetry(&self, set: &FrameSet) -> SetTelemetryMsg {
        msgs::telemetry_of(set, None, &self.names())
    }
}

/// Asserts that a recorded set is `want`, byte for byte and field for
/// field.
pub fn assert_same(got: &RecordedSet, want: &FrameSet, offset_ns: u64) {
    let g = &got.set;
    assert_eq!(g.trigger, want.trigger);
    assert_eq!(g.timestamp_ns, want.timestamp_ns);
    assert_eq!(got.log_time, want.timestamp_ns + offset_ns);
    assert_eq!(got.telemetry.trigger, want.trigger);
    assert_eq!(g.frames.len(), want.frames.len());
    for (a, b) in g.frames.iter().zip(&want.frames) {
        match (a, b) {
            (Some(a), Some(b)) => {
                assert_eq!(a.meta, b.meta, "set {}", want.trigger);
                assert!(a.data[..] == b.data[..], "pixels of set {}", want.trigger);
            }
            (None, None) => {}
            _ => panic!("set {}: a frame is missing", want.trigger),
        }
    }
}

pub fn file_len(p: &Path) -> u64 {
    std::fs::metadata(p).unwrap().len()
}
