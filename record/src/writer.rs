//! Writing a recording, synchronously: [`SetWriter`] puts each frame set
//! in a chunk of its own (the chunk is closed and the file flushed after
//! every set, so that a killed process loses at most the set being
//! written). [`crate::Recorder`] runs one on a thread of its own.
//!
//! Layout (MCAP, ROS 2 profile, CDR messages with `ros2msg` schemas):
//! - a metadata record `rigview` (version, cameras, pixel formats, sizes,
//!   the source's clock offset) and the rig as the attachment `rig.yaml`;
//! - per set, in one chunk: per camera `/rig/<camera>/frame_meta` then
//!   `/rig/<camera>/image_raw`, about once a second `/rig/<camera>/camera_info`,
//!   and last `/rig/telemetry`, which closes the set; with the first set of
//!   a calibrated rig, `/tf_static` (`tf2_msgs/msg/TFMessage`, transient
//!   local): each posed camera's optical frame `<camera>_optical` in
//!   `base_link` (a rig in the vehicle frame) or in the first camera's
//!   optical frame (a rig relative to a camera);
//! - at the end a metadata record `rigview.end` (sets, drops, why it
//!   stopped) and the summary with its indexes.
//!
//! Every message's `log_time` = `publish_time` = `header.stamp` = the set's
//! trigger time plus the recording's clock offset (Unix ns); `sequence` is
//! the camera's frame id (the trigger number for the telemetry), modulo 2³².

use std::collections::BTreeMap;
use std::io::{Seek, Write};
use std::path::{Path, PathBuf};

use mcap::records::MessageHeader;
use rigview_calib::Rig;
use rigview_core::source::{CameraInfo, FrameSet};

use crate::error::{RecordError, Result};
use crate::msgs::{self, FrameMetaMsg, SetTelemetryMsg};

/// How chunks are compressed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Compression {
    /// Stored as they are (the default: rig frames compress by a sixth at
    /// best, at a third of a core).
    #[default]
    None,
    /// LZ4 (fast, about 11 % smaller).
    Lz4,
    /// Zstandard level 1 (about 17 % smaller).
    Zstd,
}

impl Compression {
    /// Every choice.
    pub const ALL: [Compression; 3] = [Self::None, Self::Lz4, Self::Zstd];

    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Lz4 => "lz4",
            Self::Zstd => "zstd",
        }
    }

    fn mcap(self) -> Option<mcap::Compression> {
        match self {
            Self::None => None,
            Self::Lz4 => Some(mcap::Compression::Lz4),
            Self::Zstd => Some(mcap::Compression::Zstd),
        }
    }
}

impl std::str::FromStr for Compression {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|c| c.name() == s)
            .ok_or_else(|| format!("unknown compression \"{s}\" (known: none, lz4, zstd)"))
    }
}

/// What a recording is of: written once, at its start.
#[derive(Clone, Debug)]
pub struct RecordingSetup {
    /// The source's cameras, in rig order.
    pub cameras: Vec<CameraInfo>,
    /// The rig's calibration (the `rig.yaml` attachment and the
    /// `camera_info` topics); `None`: uncalibrated.
    pub rig: Option<Rig>,
    /// The source, in words.
    pub source: String,
    /// Added to the sets' timestamps to make Unix time (0 for a source
    /// whose clock is Unix time, such as live cameras; the start's wall
    /// clock for the simulator, whose clock starts at 0).
    pub time_offset_ns: u64,
}

/// The metadata record that describes the recording.
pub const METADATA: &str = "rigview";
/// The metadata record written when the recording ends.
pub const END_METADATA: &str = "rigview.end";
/// The attachment that holds the rig.
pub const RIG_ATTACHMENT: &str = "rig.yaml";
/// The telemetry topic (closes each set).
pub const TELEMETRY_TOPIC: &str = "/rig/telemetry";

/// The topic of a camera's stream (`image_raw`, `camera_info`, `frame_meta`).
pub fn topic(camera: &str, stream: &str) -> String {
    format!("/rig/{camera}/{stream}")
}

/// What `ros2 bag record` offers by default (reliable, volatile, keep
/// last), which `ros2 bag play` needs on every channel.
const QOS: &str = "- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n  deadline:\n    sec: 2147483647\n    nsec: 4294967295\n  lifespan:\n    sec: 2147483647\n    nsec: 4294967295\n  liveliness: 1\n  liveliness_lease_duration:\n    sec: 2147483647\n    nsec: 4294967295\n  avoid_ros_namespace_conventions: false\n";

/// `/tf_static`'s QoS as ROS 2 offers it: reliable, transient local
/// (a late subscriber of a replay still gets the rig), keep last 1.
const TF_STATIC_QOS: &str = "- history: 1\n  depth: 1\n  reliability: 1\n  durability: 1\n  deadline:\n    sec: 2147483647\n    nsec: 4294967295\n  lifespan:\n    sec: 2147483647\n    nsec: 4294967295\n  liveliness: 1\n  liveliness_lease_duration:\n    sec: 2147483647\n    nsec: 4294967295\n  avoid_ros_namespace_conventions: false\n";

/// The topic of the rig's static transforms.
pub const TF_STATIC_TOPIC: &str = "/tf_static";

#[derive(Debug)]
struct CameraChannels {
    image: u16,
    info: u16,
    meta: u16,
    frame_id: String,
}

/// Writes frame sets into an MCAP file (see the module documentation).
pub struct SetWriter<W: Write + Seek> {
    file: PathBuf,
    mcap: mcap::Writer<W>,
    channels: Vec<CameraChannels>,
    telemetry: u16,
    /// `/tf_static` (a calibrated rig only), until its message is written
    /// with the first set.
    tf_static: Option<u16>,
    names: Vec<String>,
    rig: Option<Rig>,
    offset_ns: u64,
    last_info_ns: Option<u64>,
    sets: u64,
    dropped: u64,
}

impl<W: Write + Seek> std::fmt::Debug for SetWriter<W> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SetWriter")
            .field("file", &self.file)
            .field("sets", &self.sets)
            .field("dropped", &self.dropped)
            .finish_non_exhaustive()
    }
}

/// The wall clock, Unix ns.
pub fn unix_now_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
}

impl<W: Write + Seek> SetWriter<W> {
    /// Starts a recording named `file` (for messages) into `out`: the
    /// header, schemas, channels, the rig attachment and the metadata.
    pub fn new(
        file: &Path,
        out: W,
        setup: &RecordingSetup,
        compression: Compression,
    ) -> Result<Self> {
        let e = |err| RecordError::mcap(file, err);
        if let Some(rig) = &setup.rig {
            check_rig(file, rig, &setup.cameras)?;
        }
        let mut mcap = mcap::WriteOptions::new()
            .profile("ros2")
            .library(format!("rigview-record {}", env!("CARGO_PKG_VERSION")))
            .compression(compression.mcap())
            .compression_level(1)
            // A set's chunk is closed by hand after the set.
            .chunk_size(None)
            .create(out)
            .map_err(e)?;
        let mut schema = |name: &str| -> Result<u16> {
            let text = msgs::schema_text(name)
                .ok_or_else(|| RecordError::format(file, format!("no schema {name}")))?;
            mcap.add_schema(name, "ros2msg", text.as_bytes()).map_err(e)
        };
        let image = schema(msgs::IMAGE)?;
        let info = schema(msgs::CAMERA_INFO)?;
        let meta = schema(msgs::FRAME_META)?;
        let telemetry = schema(msgs::SET_TELEMETRY)?;
        let tf = match setup.rig {
            Some(_) => Some(schema(msgs::TF_MESSAGE)?),
            None => None,
        };
        let qos = BTreeMap::from([("offered_qos_profiles".to_owned(), QOS.to_owned())]);
        let mut channels = Vec::new();
        for c in &setup.cameras {
            let mut channel = |stream: &str, schema: u16| {
                mcap.add_channel(schema, &topic(&c.name, stream), "cdr", &qos)
                    .map_err(e)
            };
            channels.push(CameraChannels {
                image: channel("image_raw", image)?,
                info: channel("camera_info", info)?,
                meta: channel("frame_meta", meta)?,
                frame_id: msgs::optical_frame(&c.name),
            });
        }
        let telemetry = mcap
            .add_channel(telemetry, TELEMETRY_TOPIC, "cdr", &qos)
            .map_err(e)?;
        let tf_static = match tf {
            Some(tf) => {
                let qos =
                    BTreeMap::from([("offered_qos_profiles".to_owned(), TF_STATIC_QOS.to_owned())]);
                Some(
                    mcap.add_channel(tf, TF_STATIC_TOPIC, "cdr", &qos)
                        .map_err(e)?,
                )
            }
            None => None,
        };
        let now = unix_now_ns();
        let cameras_yaml = serde_norway::to_string(&setup.cameras)
            .map_err(|err| RecordError::format(file, format!("the cameras as YAML: {err}")))?;
        let list = |f: &dyn Fn(&CameraInfo) -> String| {
            setup.cameras.iter().map(f).collect::<Vec<_>>().join(",")
        };
        let metadata = BTreeMap::from([
            ("version".to_owned(), env!("CARGO_PKG_VERSION").to_owned()),
            ("cameras".to_owned(), list(&|c| c.name.clone())),
            (
                "pixel_format".to_owned(),
                list(&|c| c.format.genicam_name().to_owned()),
            ),
            (
                "size".to_owned(),
                list(&|c| format!("{}x{}", c.width, c.height)),
            ),
            ("source".to_owned(), setup.source.clone()),
            (
                "time_offset_ns".to_owned(),
                setup.time_offset_ns.to_string(),
            ),
            ("cameras_yaml".to_owned(), cameras_yaml),
        ]);
        mcap.write_metadata(&mcap::records::Metadata {
            name: METADATA.to_owned(),
            metadata,
        })
        .map_err(e)?;
        if let Some(rig) = &setup.rig {
            let text = rigview_calib::formats::rig_yaml::to_string(rig)
                .map_err(|err| RecordError::format(file, format!("the rig as rig YAML: {err}")))?;
            mcap.attach(&mcap::Attachment {
                log_time: now,
                create_time: now,
                name: RIG_ATTACHMENT.to_owned(),
                media_type: "application/yaml".to_owned(),
                data: text.into_bytes().into(),
            })
            .map_err(e)?;
        }
        mcap.flush().map_err(e)?;
        Ok(Self {
            file: file.to_owned(),
            mcap,
            channels,
            telemetry,
            tf_static,
            names: setup.cameras.iter().map(|c| c.name.clone()).collect(),
            rig: setup.rig.clone(),
            offset_ns: setup.time_offset_ns,
            last_info_ns: None,
            sets: 0,
            dropped: 0,
        })
    }

    /// The cameras' names, in rig order.
    pub fn camera_names(&self) -> &[String] {
        &self.names
    }

    /// Sets written.
    pub fn sets(&self) -> u64 {
        self.sets
    }

    /// Sets counted as dropped.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    fn message(&mut self, channel: u16, sequence: u64, time: u64, data: &[u8]) -> Result<()> {
        self.mcap
            .write_to_known_channel(
                &MessageHeader {
                    channel_id: channel,
                    sequence: sequence as u32,
                    log_time: time,
                    publish_time: time,
                },
                data,
            )
            .map_err(|e| RecordError::mcap(&self.file, e))
    }

    /// Writes one set (its frames, about once a second the cameras'
    /// calibration, and `telemetry` last), `dropped_before` sets after the
    /// last one written were dropped, and closes the set's chunk. `host_ns`
    /// is when the set reached the recorder.
    pub fn write_set(
        &mut self,
        set: &FrameSet,
        mut telemetry: SetTelemetryMsg,
        dropped_before: u64,
        host_ns: u64,
    ) -> Result<()> {
        if set.frames.len() != self.channels.len() {
            return Err(RecordError::Unsupported {
                file: self.file.clone(),
                what: format!(
                    "set {} has {} camera slots, the recording {} cameras",
                    set.trigger,
                    set.frames.len(),
                    self.channels.len()
                ),
            });
        }
        let time = set.timestamp_ns.saturating_add(self.offset_ns);
        for (c, frame) in set.frames.iter().enumerate() {
            let Some(frame) = frame else { continue };
            let m = &frame.meta;
            let ch = &self.channels[c];
            let (image, meta, frame_id) = (ch.image, ch.meta, ch.frame_id.clone());
            let meta_msg = msgs::encode_frame_meta(&FrameMetaMsg {
                stamp_ns: time,
                frame_id: frame_id.clone(),
                trigger: set.trigger,
                camera_frame_id: m.frame_id,
                exposure_us: m.taken.shutter_us,
                gain_db: m.taken.gain_db,
                trigger_time_ns: time,
                camera_time_ns: m.timestamp_ns,
                host_time_ns: host_ns,
                pixel_format: m.format.genicam_name().to_owned(),
                status: m.status.clone(),
            });
            self.message(meta, m.frame_id, time, &meta_msg)?;
            let image_msg = msgs::encode_image(time, &frame_id, frame);
            self.message(image, m.frame_id, time, &image_msg)?;
        }
        let info_due = self
            .last_info_ns
            .is_none_or(|t| time.saturating_sub(t) >= 1_000_000_000 || time < t);
        if let (Some(channel), Some(rig)) = (self.tf_static.take(), &self.rig) {
            let transforms = msgs::rig_transforms(rig);
            self.message(
                channel,
                0,
                time,
                &msgs::encode_tf_message(time, &transforms),
            )?;
        }
        if info_due {
            if let Some(rig) = self.rig.take() {
                let written = self.camera_infos(&rig, time);
                self.rig = Some(rig);
                written?;
                self.last_info_ns = Some(time);
            }
        }
        self.dropped += dropped_before;
        telemetry.stamp_ns = time;
        telemetry.dropped_by_recorder = self.dropped;
        telemetry.dropped_since_last = dropped_before;
        let t = msgs::encode_set_telemetry(&telemetry);
        self.message(self.telemetry, set.trigger, time, &t)?;
        self.mcap
            .flush()
            .map_err(|e| RecordError::mcap(&self.file, e))?;
        self.sets += 1;
        Ok(())
    }

    fn camera_infos(&mut self, rig: &Rig, time: u64) -> Result<()> {
        for (c, cam) in rig.cameras.iter().enumerate() {
            let (info, frame_id) = (self.channels[c].info, self.channels[c].frame_id.clone());
            let data = msgs::encode_camera_info(time, &frame_id, cam);
            self.message(info, 0, time, &data)?;
        }
        Ok(())
    }

    /// Counts sets dropped after the last one written, when no set follows
    /// (they are marked in the end record).
    pub fn note_dropped(&mut self, n: u64) {
        self.dropped += n;
    }

    /// Ends the recording: the end record (sets, drops, `reason` it stopped)
    /// and the summary with its indexes. Returns the output.
    pub fn finish(mut self, reason: &str) -> Result<W> {
        let e = |err| RecordError::mcap(&self.file, err);
        let end = BTreeMap::from([
            ("sets".to_owned(), self.sets.to_string()),
            ("dropped_sets".to_owned(), self.dropped.to_string()),
            ("stopped".to_owned(), reason.to_owned()),
        ]);
        self.mcap
            .write_metadata(&mcap::records::Metadata {
                name: END_METADATA.to_owned(),
                metadata: end,
            })
            .map_err(e)?;
        self.mcap.finish().map_err(e)?;
        Ok(self.mcap.into_inner())
    }
}

/// Checks that a rig fits the cameras (count, names' order and image
/// sizes).
pub(crate) fn check_rig(file: &Path, rig: &Rig, cameras: &[CameraInfo]) -> Result<()> {
    if rig.cameras.len() != cameras.len() {
        return Err(RecordError::format(
            file,
            format!(
                "the rig has {} cameras, the source {}",
                rig.cameras.len(),
                cameras.len()
            ),
        ));
    }
    for (r, c) in rig.cameras.iter().zip(cameras) {
        let (w, h) = (r.intrinsics.width as usize, r.intrinsics.height as usize);
        if (w, h) != (c.width, c.height) {
            return Err(RecordError::format(
                file,
                format!(
                    "camera \"{}\" is calibrated at {w}×{h}, the source's \"{}\" gives {}×{}",
                    r.name, c.name, c.width, c.height
                ),
            ));
        }
    }
    Ok(())
}
