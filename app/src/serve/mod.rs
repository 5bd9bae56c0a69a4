//! The live remote view: a Foxglove WebSocket server ([`server`]) fed from
//! the pipeline's newest output ([`rigview_core::pipeline::OutputWatch`])
//! on a thread of its own, so that encoding never runs on the processing
//! thread and a slow client costs the pipeline nothing.
//!
//! What it publishes (topics in ROS 2's conventions, messages in CDR with
//! their ROS 2 schemas, or JSON with a JSON Schema):
//!
//! | topic | message | when |
//! | --- | --- | --- |
//! | `/rig/<camera>/image_raw/compressed` | `sensor_msgs/msg/CompressedImage` (JPEG, scaled) | at the serving rate |
//! | `/rig/<camera>/camera_info` | `sensor_msgs/msg/CameraInfo` (scaled to the image) | once a second, and to each new subscriber |
//! | `/rig/<camera>/exposure` | JSON: shutter, gain, γ̂, M, mean, saturation, the probe frame and the latest probe, command | at the serving rate |
//! | `/rig/view/compressed` | `sensor_msgs/msg/CompressedImage` (JPEG, scaled as the cameras): the composed view | at the serving rate |
//! | `/tf_static` | `tf2_msgs/msg/TFMessage`: each camera's optical frame in `base_link` | to each new subscriber |
//! | `/rig/telemetry` | JSON: r_ij, stage times, the server's own counts | at the serving rate |

pub mod preview;
pub mod server;

use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use rigview_calib::Rig;
use rigview_core::pipeline::{Output, OutputWatch};
use rigview_core::source::CameraInfo;
use rigview_record::msgs;

use server::{Channel, Server, ServerStats};

/// The default address: loopback, Foxglove's port.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8765";

/// How the remote view is served.
#[derive(Clone, Debug, PartialEq)]
pub struct ServeOptions {
    pub addr: SocketAddr,
    /// Pictures a second, at most.
    pub rate_hz: f64,
    /// Each picture is shrunk by this factor (2: half size).
    pub shrink: usize,
    /// JPEG quality, 1–100.
    pub quality: u8,
}

impl Default for ServeOptions {
    fn default() -> Self {
        Self {
            addr: SocketAddr::from(([127, 0, 0, 1], 8765)),
            rate_hz: 10.0,
            shrink: 2,
            quality: 80,
        }
    }
}

/// Parses `--serve`'s `[ADDR:]PORT` (a port alone: loopback).
pub fn parse_addr(text: &str) -> Result<SocketAddr, String> {
    let text = text.trim();
    if let Ok(port) = text.parse::<u16>() {
        return Ok(SocketAddr::from(([127, 0, 0, 1], port)));
    }
    text.parse::<SocketAddr>().map_err(|_| {
        format!("--serve: expected [ADDR:]PORT (e.g. 8765, 127.0.0.1:8765 or 0.0.0.0:8765); got {text:?}")
    })
}

/// What the publishing thread has done.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PublishStats {
    /// Sets published.
    pub published: u64,
    /// Milliseconds the latest set took to encode and publish.
    pub encode_ms: f64,
}

/// The running remote view; dropping it stops it.
#[derive(Debug)]
pub struct Serving {
    server: Arc<Server>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    stats: Arc<Mutex<PublishStats>>,
}

/// Channel ids: per camera four, then the view's, the transforms' and the
/// telemetry's.
fn image_id(k: usize) -> u32 {
    1 + 4 * k as u32
}
fn info_id(k: usize) -> u32 {
    2 + 4 * k as u32
}
fn exposure_id(k: usize) -> u32 {
    3 + 4 * k as u32
}
const VIEW_ID: u32 = 1000;
const TF_ID: u32 = 1001;
const TELEMETRY_ID: u32 = 1002;

const EXPOSURE_SCHEMA: &str = r#"{"type":"object","title":"rigview exposure state","properties":{"shutter_us":{"type":"number"},"gain_db":{"type":"number"},"exposure_log2":{"type":"number"},"gamma_hat":{"type":["number","null"]},"m":{"type":["number","null"]},"mean":{"type":"number"},"saturated":{"type":"number"},"probe_frame":{"type":"boolean"},"last_probe":{"description":"the latest probe, darker or brighter: Sent {from, to}, Taken {gain} or Rejected","type":["object","string","null"]},"last_probe_brighter":{"description":"whether that probe was brighter (most of the frame dark)","type":"boolean"},"command_shutter_us":{"type":["number","null"]},"command_gain_db":{"type":["number","null"]}}}"#;
const TELEMETRY_SCHEMA: &str = r#"{"type":"object","title":"rigview set telemetry","properties":{"trigger":{"type":"integer"},"times_ms":{"type":"object"},"pairs":{"type":"array","items":{"type":"object","properties":{"pair":{"type":"string"},"log2_r":{"type":["number","null"]}}}},"clients":{"type":"integer"},"sent":{"type":"integer"},"dropped_for_clients":{"type":"integer"},"processed":{"type":["integer","null"]},"incomplete":{"type":["integer","null"]},"dropped_before_processing":{"type":["integer","null"]},"set_rate_hz":{"type":["number","null"]},"streams":{"type":["array","null"],"items":{"type":"object","properties":{"camera":{"type":"string"},"state":{"type":"string"},"fps":{"type":"number"},"failed":{"type":"integer"},"missing_packets":{"type":"integer"}}}}}}"#;

fn cdr_channel(id: u32, topic: String, schema: &str, latched: bool) -> Channel {
    Channel {
        id,
        topic,
        encoding: "cdr".into(),
        schema_name: schema.into(),
        schema: msgs::schema_text(schema).unwrap_or_default(),
        schema_encoding: "ros2msg".into(),
        latched,
    }
}

fn json_channel(id: u32, topic: String, title: &str, schema: &str) -> Channel {
    Channel {
        id,
        topic,
        encoding: "json".into(),
        schema_name: title.into(),
        schema: schema.into(),
        schema_encoding: "jsonschema".into(),
        latched: false,
    }
}

impl Serving {
    /// Starts serving `watch`'s outputs of a rig of `cameras` (calibrated
    /// by `rig`, if it is) as `options` say. An address that cannot be
    /// bound is an error that names it.
    pub fn start(
        options: &ServeOptions,
        watch: Arc<OutputWatch>,
        cameras: &[CameraInfo],
        rig: Option<&Rig>,
    ) -> Result<Self, String> {
        let mut channels = Vec::new();
        for (k, c) in cameras.iter().enumerate() {
            channels.push(cdr_channel(
                image_id(k),
                format!("/rig/{}/image_raw/compressed", c.name),
                msgs::COMPRESSED_IMAGE,
                false,
            ));
            if rig.is_some() {
                channels.push(cdr_channel(
                    info_id(k),
                    format!("/rig/{}/camera_info", c.name),
                    msgs::CAMERA_INFO,
                    true,
                ));
            }
            channels.push(json_channel(
                exposure_id(k),
                format!("/rig/{}/exposure", c.name),
                "rigview.ExposureState",
                EXPOSURE_SCHEMA,
            ));
        }
        channels.push(cdr_channel(
            VIEW_ID,
            "/rig/view/compressed".into(),
            msgs::COMPRESSED_IMAGE,
            false,
        ));
        if rig.is_some() {
            channels.push(cdr_channel(
                TF_ID,
                "/tf_static".into(),
                msgs::TF_MESSAGE,
                true,
            ));
        }
        channels.push(json_channel(
            TELEMETRY_ID,
            "/rig/telemetry".into(),
            "rigview.SetTelemetry",
            TELEMETRY_SCHEMA,
        ));
        let server = Arc::new(Server::start(options.addr, "rigview", channels)?);
        if let Some(rig) = rig {
            let now = rigview_record::writer::unix_now_ns();
            let tf = msgs::encode_tf_message(now, &msgs::rig_transforms(rig));
            server.publish(TF_ID, now, &tf);
        }
        let stop = Arc::new(AtomicBool::new(false));
        let stats = Arc::new(Mutex::new(PublishStats::default()));
        let names: Vec<String> = cameras.iter().map(|c| c.name.clone()).collect();
        let job = Publisher {
            server: server.clone(),
            options: options.clone(),
            names,
            rig: rig.cloned(),
            stats: stats.clone(),
        };
        let stopping = stop.clone();
        let thread = std::thread::Builder::new()
            .name("rigview-serve-publish".into())
            .spawn(move || job.run(&watch, &stopping))
            .map_err(|e| format!("cannot start the remote view's thread: {e}"))?;
        Ok(Self {
            server,
            stop,
            thread: Some(thread),
            stats,
        })
    }

    /// Where it listens.
    pub fn addr(&self) -> SocketAddr {
        self.server.addr()
    }

    /// What the server and the publishing thread have done.
    pub fn stats(&self) -> (ServerStats, PublishStats) {
        let p = *self.stats.lock().unwrap_or_else(PoisonError::into_inner);
        (self.server.stats(), p)
    }

    /// A line for a status bar: clients, and messages dropped for slow
    /// ones.
    pub fn status_line(&self) -> String {
        let (s, _) = self.stats();
        format!(
            "remote view {}: {} client{}, {} dropped",
            self.addr(),
            s.clients,
            if s.clients == 1 { "" } else { "s" },
            s.dropped
        )
    }
}

impl Drop for Serving {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

struct Publisher {
    server: Arc<Server>,
    options: ServeOptions,
    names: Vec<String>,
    rig: Option<Rig>,
    stats: Arc<Mutex<PublishStats>>,
}

impl Publisher {
    fn run(&self, watch: &OutputWatch, stop: &AtomicBool) {
        let period = Duration::from_secs_f64(1.0 / self.options.rate_hz.clamp(0.1, 100.0));
        let mut last = None;
        let mut last_info: Option<Instant> = None;
        let mut due = Instant::now();
        while !stop.load(Ordering::Relaxed) {
            let now = Instant::now();
            if now < due {
                std::thread::sleep((due - now).min(Duration::from_millis(50)));
                continue;
            }
            let Some(out) = watch.newer(last, Duration::from_millis(100)) else {
                continue;
            };
            last = Some(out.trigger);
            due = Instant::now() + period;
            let t = Instant::now();
            let info_due = last_info.is_none_or(|t| t.elapsed() >= Duration::from_secs(1));
            if info_due {
                last_info = Some(Instant::now());
            }
            self.publish(&out, watch.status().as_ref(), info_due);
            let mut s = self.stats.lock().unwrap_or_else(PoisonError::into_inner);
            s.published += 1;
            s.encode_ms = t.elapsed().as_secs_f64() * 1e3;
        }
    }

    fn publish(
        &self,
        out: &Output,
        status: Option<&rigview_core::pipeline::PipelineStatus>,
        info_due: bool,
    ) {
        let now = rigview_record::writer::unix_now_ns();
        let n = self.options.shrink.max(1);
        for (k, frame) in out.frames.iter().enumerate() {
            let name = self.names.get(k).map_or("?", String::as_str);
            let frame_id = msgs::optical_frame(name);
            if self.server.wanted(image_id(k)) {
                match preview::shrink(frame, n)
                    .and_then(|s| preview::jpeg(&s, self.options.quality))
                {
                    Ok(jpeg) => {
                        let m = msgs::encode_compressed_image(now, &frame_id, "jpeg", &jpeg);
                        self.server.publish(image_id(k), now, &m);
                    }
                    Err(e) => tracing::debug!("remote view: camera {name}: {e}"),
                }
            }
            if info_due {
                if let Some(cam) = self.rig.as_ref().and_then(|r| r.cameras.get(k)) {
                    let scaled = scaled_camera(cam, n);
                    let m = msgs::encode_camera_info(now, &frame_id, &scaled);
                    self.server.publish(info_id(k), now, &m);
                }
            }
            if let Some(c) = out.cameras.get(k) {
                if self.server.wanted(exposure_id(k)) {
                    let m = c
                        .estimate
                        .as_ref()
                        .and_then(|e| e.anchors.iter().find(|a| (a.x - 1.0).abs() < 1e-9))
                        .map(|a| a.m);
                    let state = serde_json::json!({
                        "shutter_us": c.taken.shutter_us,
                        "gain_db": c.taken.gain_db,
                        "exposure_log2": c.taken.exposure().log2(),
                        "gamma_hat": c.estimate.as_ref().map(|e| e.gamma_hat),
                        "m": m,
                        "mean": c.mean,
                        "saturated": c.saturated,
                        "probe_frame": c.probe_frame,
                        "last_probe": c.last_probe,
                        "last_probe_brighter": c.last_probe_brighter,
                        "command_shutter_us": c.command.map(|s| s.shutter_us),
                        "command_gain_db": c.command.map(|s| s.gain_db),
                    });
                    self.server
                        .publish(exposure_id(k), now, state.to_string().as_bytes());
                }
            }
        }
        if self.server.wanted(VIEW_ID) {
            if let Some(canvas) = &out.canvas {
                let small = preview::shrink_picture(
                    &canvas.data,
                    (canvas.width, canvas.height),
                    canvas.channels,
                    n,
                );
                match preview::jpeg(&small, self.options.quality) {
                    Ok(jpeg) => {
                        let m =
                            msgs::encode_compressed_image(now, msgs::VEHICLE_FRAME, "jpeg", &jpeg);
                        self.server.publish(VIEW_ID, now, &m);
                    }
                    Err(e) => tracing::debug!("remote view: the view: {e}"),
                }
            }
        }
        if self.server.wanted(TELEMETRY_ID) {
            let s = self.server.stats();
            let times = &out.times;
            let pairs: Vec<_> = out
                .pairs
                .iter()
                .map(|p| {
                    let name = |i: usize| self.names.get(i).map_or("?", String::as_str);
                    serde_json::json!({"pair": format!("{}-{}", name(p.i), name(p.j)), "log2_r": p.log2_r})
                })
                .collect();
            let t = serde_json::json!({
                "trigger": out.trigger,
                "times_ms": {
                    "capture": times.capture_ms, "queue": times.queue_ms, "meter": times.meter_ms,
                    "control": times.control_ms, "compose": times.compose_ms, "total": times.total_ms,
                },
                "pairs": pairs,
                "clients": s.clients,
                "sent": s.sent,
                "dropped_for_clients": s.dropped,
                "processed": status.map(|st| st.processed),
                "incomplete": status.map(|st| st.incomplete),
                "dropped_before_processing": status.map(|st| st.capture_queue.dropped),
                "set_rate_hz": status.map(|st| st.set_rate_hz),
                "streams": status.map(|st| {
                    st.health
                        .iter()
                        .zip(&self.names)
                        .map(|(h, name)| serde_json::json!({
                            "camera": name,
                            "state": format!("{:?}", h.state),
                            "fps": h.fps,
                            "failed": h.failed,
                            "missing_packets": h.missing_packets,
                        }))
                        .collect::<Vec<_>>()
                }),
            });
            self.server
                .publish(TELEMETRY_ID, now, t.to_string().as_bytes());
        }
    }
}

/// `cam` as seen in its pictures shrunk `n` times (pixel centres kept).
fn scaled_camera(cam: &rigview_calib::Camera, n: usize) -> rigview_calib::Camera {
    let s = 1.0 / n as f64;
    let mut c = cam.clone();
    let k = &mut c.intrinsics;
    k.width /= n as u32;
    k.height /= n as u32;
    k.fx *= s;
    k.fy *= s;
    k.cx = (k.cx + 0.5) * s - 0.5;
    k.cy = (k.cy + 0.5) * s - 0.5;
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn serve_takes_a_port_or_an_address_and_says_what_it_expected() {
        assert_eq!(
            parse_addr("9000").unwrap(),
            SocketAddr::from(([127, 0, 0, 1], 9000))
        );
        assert_eq!(
            parse_addr("0.0.0.0:8765").unwrap(),
            SocketAddr::from(([0, 0, 0, 0], 8765))
        );
        assert_eq!(
            parse_addr(DEFAULT_ADDR).unwrap(),
            ServeOptions::default().addr
        );
        let e = parse_addr("vehicle").unwrap_err();
        assert!(e.contains("[ADDR:]PORT") && e.contains("vehicle"), "{e}");
    }

    /// A camera's calibration follows its pictures: half the focal length,
    /// and the principal point where the same pixel centre lands.
    #[test]
    fn a_shrunk_camera_keeps_its_pixel_centres() {
        let k = rigview_calib::Intrinsics {
            width: 1288,
            height: 964,
            fx: 400.0,
            fy: 402.0,
            cx: 643.5,
            cy: 481.5,
            distortion: rigview_calib::Distortion::Fisheye([0.0; 4]),
        };
        let c = scaled_camera(&rigview_calib::Camera::new("front", k), 2);
        let s = c.intrinsics;
        assert_eq!((s.width, s.height), (644, 482));
        assert!((s.fx - 200.0).abs() < 1e-12 && (s.fy - 201.0).abs() < 1e-12);
        // The image centre stays the image centre.
        assert!((s.cx - 321.5).abs() < 1e-12 && (s.cy - 240.5).abs() < 1e-12);
    }
}
