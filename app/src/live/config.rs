//! What live capture configures on each camera, and how it runs.

use std::time::Duration;

use rigview_core::exposure::PixelFormat;

use super::LiveError;

/// How the cameras are triggered.
#[derive(Clone, Debug, PartialEq)]
pub enum TriggerMode {
    /// A trigger box: `TriggerMode` On, `TriggerSource` = `line`,
    /// `TriggerActivation` RisingEdge.
    Hardware {
        /// The input line, e.g. `Line0`.
        line: String,
    },
    /// rigview sends `TriggerSoftware` to every camera at `rate_hz`, for rigs
    /// without a trigger box.
    Software {
        /// Triggers per second.
        rate_hz: f64,
    },
    /// `TriggerMode` Off: each camera runs on its own clock (sets are matched
    /// by timestamp, so they are only as synchronous as the clocks allow).
    FreeRun {
        /// `AcquisitionFrameRate`, where the camera has it.
        rate_hz: Option<f64>,
    },
}

impl TriggerMode {
    /// The trigger period, when rigview knows it.
    pub fn period(&self) -> Option<Duration> {
        match self {
            TriggerMode::Software { rate_hz }
            | TriggerMode::FreeRun {
                rate_hz: Some(rate_hz),
            } => Some(Duration::from_secs_f64(1.0 / rate_hz)),
            _ => None,
        }
    }

    /// A short name for status lines.
    pub fn describe(&self) -> String {
        match self {
            TriggerMode::Hardware { line } => format!("hardware trigger on {line}, rising edge"),
            TriggerMode::Software { rate_hz } => format!("software trigger at {rate_hz} Hz"),
            TriggerMode::FreeRun { rate_hz: Some(r) } => format!("free run at {r} Hz"),
            TriggerMode::FreeRun { rate_hz: None } => "free run".into(),
        }
    }
}

/// A region of interest on the sensor, in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Region {
    /// Left edge.
    pub x: u32,
    /// Top edge.
    pub y: u32,
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
}

impl std::str::FromStr for Region {
    type Err = String;

    /// `WIDTHxHEIGHT` or `WIDTHxHEIGHT+X+Y`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = || {
            format!("region \"{s}\": expected WIDTHxHEIGHT or WIDTHxHEIGHT+X+Y, e.g. 1280x960+0+32")
        };
        let mut parts = s.split('+');
        let size = parts.next().ok_or_else(bad)?;
        let (w, h) = size.split_once(['x', 'X']).ok_or_else(bad)?;
        let num = |t: &str| t.trim().parse::<u32>().map_err(|_| bad());
        let (width, height) = (num(w)?, num(h)?);
        let (x, y) = match (parts.next(), parts.next(), parts.next()) {
            (None, None, None) => (0, 0),
            (Some(x), Some(y), None) => (num(x)?, num(y)?),
            _ => return Err(bad()),
        };
        if width == 0 || height == 0 {
            return Err(bad());
        }
        Ok(Region {
            x,
            y,
            width,
            height,
        })
    }
}

/// How rigview captures from a rig: what it configures on every camera and
/// how it assembles, watches and restores the streams.
#[derive(Clone, Debug, PartialEq)]
pub struct CaptureConfig {
    /// Pixel format (GenICam `PixelFormat`).
    pub pixel_format: PixelFormat,
    /// Region of interest; `None` keeps the camera's current one.
    pub region: Option<Region>,
    /// How the cameras are triggered.
    pub trigger: TriggerMode,
    /// GigE Vision packet size in bytes; `None` lets Aravis find the largest
    /// that gets through (needs jumbo frames on the path for > 1500).
    pub packet_size: Option<u32>,
    /// GigE Vision inter-packet delay in ns (0: none). Raise it when several
    /// cameras share one link and frames arrive with missing packets.
    pub packet_delay_ns: u64,
    /// Receive socket buffer of each GigE Vision stream, bytes (well above one
    /// frame; the kernel caps it at `net.core.rmem_max`).
    pub socket_buffer_bytes: u32,
    /// How long each camera's own auto-exposure runs at start-up before
    /// rigview takes over (Algorithm 1); zero skips it.
    pub auto_settle: Duration,
    /// Frames of one trigger arrive within this much of each other (host
    /// receive time of their first packet).
    pub sync_tolerance: Duration,
    /// How long a frame set waits for a late or missing frame before it is
    /// given out incomplete.
    pub set_timeout: Duration,
    /// With software trigger or free run: a camera that sends no frame for
    /// this long is marked lost.
    pub lost_after: Duration,
    /// First wait before reconnecting a lost camera; it doubles up to
    /// `reconnect_max`.
    pub reconnect_initial: Duration,
    /// Longest wait between reconnection attempts.
    pub reconnect_max: Duration,
    /// How long [`super::LiveSource::open`] keeps trying to open a camera
    /// before it gives up.
    pub open_timeout: Duration,
    /// Frames that still show the old setting after a command is written,
    /// beyond the software triggers already sent (which rigview counts):
    /// raise it for cameras that apply settings a frame late, or whose next
    /// hardware trigger may already have fired. Used when the camera has no
    /// chunk data.
    pub command_latency_frames: u32,
    /// dB per step of `GainRaw`, for cameras that have no `Gain` in dB.
    pub gain_raw_db_per_step: f64,
    /// Read exposure time and gain from chunk data where the camera has it.
    pub use_chunks: bool,
    /// Buffers queued in each stream.
    pub buffers: usize,
}

impl Default for CaptureConfig {
    fn default() -> Self {
        Self {
            pixel_format: PixelFormat::Mono8,
            region: None,
            trigger: TriggerMode::Software { rate_hz: 20.0 },
            packet_size: None,
            packet_delay_ns: 0,
            socket_buffer_bytes: 4 << 20,
            auto_settle: Duration::from_secs(1),
            sync_tolerance: Duration::from_millis(20),
            set_timeout: Duration::from_millis(300),
            lost_after: Duration::from_secs(1),
            reconnect_initial: Duration::from_millis(200),
            reconnect_max: Duration::from_secs(1),
            open_timeout: Duration::from_secs(10),
            command_latency_frames: 0,
            gain_raw_db_per_step: 1.0,
            use_chunks: true,
            buffers: 8,
        }
    }
}

impl CaptureConfig {
    /// Checks the values.
    pub fn validate(&self) -> Result<(), LiveError> {
        let bad = |field: &'static str, expected: &'static str, value: String| {
            Err(LiveError::Config {
                field,
                expected,
                value,
            })
        };
        match &self.trigger {
            TriggerMode::Software { rate_hz }
            | TriggerMode::FreeRun {
                rate_hz: Some(rate_hz),
            } if !(rate_hz.is_finite() && *rate_hz > 0.0 && *rate_hz <= 10_000.0) => {
                return bad(
                    "trigger rate",
                    "a rate in Hz above 0 and at most 10000",
                    rate_hz.to_string(),
                );
            }
            TriggerMode::Hardware { line } if line.trim().is_empty() => {
                return bad("trigger line", "a line name such as Line0", line.clone());
            }
            _ => {}
        }
        if self.sync_tolerance.is_zero() {
            return bad("sync tolerance", "a positive duration", "0".into());
        }
        if self.set_timeout < self.sync_tolerance {
            return bad(
                "set timeout",
                "at least the sync tolerance",
                format!("{:?}", self.set_timeout),
            );
        }
        if self.lost_after.is_zero() || self.reconnect_initial.is_zero() {
            return bad(
                "lost-after / reconnect wait",
                "positive durations",
                format!("{:?} / {:?}", self.lost_after, self.reconnect_initial),
            );
        }
        if !(self.gain_raw_db_per_step.is_finite() && self.gain_raw_db_per_step > 0.0) {
            return bad(
                "gain_raw_db_per_step",
                "a positive number of dB",
                self.gain_raw_db_per_step.to_string(),
            );
        }
        if self.buffers < 2 {
            return bad("buffers", "at least 2", self.buffers.to_string());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_parse_and_bad_ones_are_refused() {
        assert_eq!(
            "640x480".parse::<Region>().unwrap(),
            Region {
                x: 0,
                y: 0,
                width: 640,
                height: 480
            }
        );
        assert_eq!(
            "640x480+8+16".parse::<Region>().unwrap(),
            Region {
                x: 8,
                y: 16,
                width: 640,
                height: 480
            }
        );
        for bad in ["", "640", "0x480", "640x480+1", "axb", "640x480+1+2+3"] {
            assert!(bad.parse::<Region>().is_err(), "{bad}");
        }
    }

    #[test]
    fn the_default_is_valid_and_bad_values_are_named() {
        CaptureConfig::default().validate().unwrap();
        let c = CaptureConfig {
            trigger: TriggerMode::Software { rate_hz: 0.0 },
            ..Default::default()
        };
        assert!(c
            .validate()
            .unwrap_err()
            .to_string()
            .contains("trigger rate"));
    }
}
