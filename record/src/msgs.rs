//! The messages of a recording: their ROS 2 `.msg` texts (the schemas, in
//! `ros2msg` encoding) and their CDR encoding.
//!
//! `sensor_msgs/msg/Image`, `sensor_msgs/msg/CameraInfo`,
//! `tf2_msgs/msg/TFMessage` and their dependencies are the ROS 2 texts
//! verbatim (`record/msg/`); rigview's own
//! `rigview_msgs/msg/FrameMeta` and `rigview_msgs/msg/SetTelemetry` are
//! defined there too. A schema is the message's text followed, for each
//! type it uses, by a line of 80 `=`, `MSG: pkg/Type` and that type's text,
//! as `ros2 bag record` writes them.

use rigview_calib::{Camera, Distortion};
use rigview_core::image::PixelFormat;
use rigview_core::source::{Frame, FrameStatus};

use crate::cdr::{CdrError, CdrReader, CdrWriter};

/// `builtin_interfaces/msg/Time`.
pub const TIME_MSG: &str = include_str!("../msg/builtin_interfaces_Time.msg");
/// `std_msgs/msg/Header`.
pub const HEADER_MSG: &str = include_str!("../msg/std_msgs_Header.msg");
/// `sensor_msgs/msg/Image`.
pub const IMAGE_MSG: &str = include_str!("../msg/sensor_msgs_Image.msg");
/// `sensor_msgs/msg/CameraInfo`.
pub const CAMERA_INFO_MSG: &str = include_str!("../msg/sensor_msgs_CameraInfo.msg");
/// `sensor_msgs/msg/RegionOfInterest`.
pub const ROI_MSG: &str = include_str!("../msg/sensor_msgs_RegionOfInterest.msg");
/// `rigview_msgs/msg/FrameMeta`.
pub const FRAME_META_MSG: &str = include_str!("../msg/rigview_msgs_FrameMeta.msg");
/// `rigview_msgs/msg/SetTelemetry`.
pub const SET_TELEMETRY_MSG: &str = include_str!("../msg/rigview_msgs_SetTelemetry.msg");

/// `sensor_msgs/msg/CompressedImage` (its fields as ROS 2 defines them).
pub const COMPRESSED_IMAGE_MSG: &str = include_str!("../msg/sensor_msgs_CompressedImage.msg");
/// `tf2_msgs/msg/TFMessage`.
pub const TF_MESSAGE_MSG: &str = include_str!("../msg/tf2_msgs_TFMessage.msg");
/// `geometry_msgs/msg/TransformStamped`.
pub const TRANSFORM_STAMPED_MSG: &str = include_str!("../msg/geometry_msgs_TransformStamped.msg");
/// `geometry_msgs/msg/Transform`.
pub const TRANSFORM_MSG: &str = include_str!("../msg/geometry_msgs_Transform.msg");
/// `geometry_msgs/msg/Vector3`.
pub const VECTOR3_MSG: &str = include_str!("../msg/geometry_msgs_Vector3.msg");
/// `geometry_msgs/msg/Quaternion`.
pub const QUATERNION_MSG: &str = include_str!("../msg/geometry_msgs_Quaternion.msg");

/// The schema names.
pub const IMAGE: &str = "sensor_msgs/msg/Image";
/// See [`IMAGE`].
pub const TF_MESSAGE: &str = "tf2_msgs/msg/TFMessage";
/// See [`IMAGE`].
pub const COMPRESSED_IMAGE: &str = "sensor_msgs/msg/CompressedImage";
/// See [`IMAGE`].
pub const CAMERA_INFO: &str = "sensor_msgs/msg/CameraInfo";
/// See [`IMAGE`].
pub const FRAME_META: &str = "rigview_msgs/msg/FrameMeta";
/// See [`IMAGE`].
pub const SET_TELEMETRY: &str = "rigview_msgs/msg/SetTelemetry";

const SEPARATOR: &str =
    "================================================================================";

fn with_dependencies(text: &str, deps: &[(&str, &str)]) -> String {
    let mut out = text.to_owned();
    for (name, dep) in deps {
        out.push('\n');
        out.push_str(SEPARATOR);
        out.push_str("\nMSG: ");
        out.push_str(name);
        out.push('\n');
        out.push_str(dep);
    }
    out
}

/// The `ros2msg` schema text of one of the recording's schemas (`None`:
/// not one of them).
pub fn schema_text(name: &str) -> Option<String> {
    let header = [
        ("std_msgs/Header", HEADER_MSG),
        ("builtin_interfaces/Time", TIME_MSG),
    ];
    let text = match name {
        IMAGE => IMAGE_MSG,
        CAMERA_INFO => {
            return Some(with_dependencies(
                CAMERA_INFO_MSG,
                &[
                    header[0],
                    header[1],
                    ("sensor_msgs/RegionOfInterest", ROI_MSG),
                ],
            ))
        }
        FRAME_META => FRAME_META_MSG,
        SET_TELEMETRY => SET_TELEMETRY_MSG,
        COMPRESSED_IMAGE => COMPRESSED_IMAGE_MSG,
        TF_MESSAGE => {
            return Some(with_dependencies(
                TF_MESSAGE_MSG,
                &[
                    ("geometry_msgs/TransformStamped", TRANSFORM_STAMPED_MSG),
                    ("geometry_msgs/Transform", TRANSFORM_MSG),
                    ("geometry_msgs/Quaternion", QUATERNION_MSG),
                    ("geometry_msgs/Vector3", VECTOR3_MSG),
                    header[0],
                    header[1],
                ],
            ))
        }
        _ => return None,
    };
    Some(with_dependencies(text, &header))
}

/// The ROS 2 image encoding of a pixel format (Mono12, unpacked in 16
/// bits, is `mono16`, and a 12-bit mosaic `bayer_*16`; the frame meta
/// keeps the exact format).
pub fn encoding(format: PixelFormat) -> &'static str {
    match format {
        PixelFormat::Mono8 => "mono8",
        PixelFormat::Mono12 | PixelFormat::Mono16 => "mono16",
        PixelFormat::Rgb8 => "rgb8",
        PixelFormat::BayerRg8 => "bayer_rggb8",
        PixelFormat::BayerGr8 => "bayer_grbg8",
        PixelFormat::BayerGb8 => "bayer_gbrg8",
        PixelFormat::BayerBg8 => "bayer_bggr8",
        PixelFormat::BayerRg12 | PixelFormat::BayerRg16 => "bayer_rggb16",
        PixelFormat::BayerGr12 | PixelFormat::BayerGr16 => "bayer_grbg16",
        PixelFormat::BayerGb12 | PixelFormat::BayerGb16 => "bayer_gbrg16",
        PixelFormat::BayerBg12 | PixelFormat::BayerBg16 => "bayer_bggr16",
    }
}

/// The pixel format of a GenICam PFNC name.
pub fn pixel_format(genicam: &str) -> Option<PixelFormat> {
    PixelFormat::ALL
        .into_iter()
        .find(|f| f.genicam_name() == genicam)
}

fn header(w: &mut CdrWriter, stamp_ns: u64, frame_id: &str) {
    // ROS time: seconds as int32 (good until 2038, as ROS 2's own).
    let sec = i32::try_from(stamp_ns / 1_000_000_000).unwrap_or(i32::MAX);
    w.i32(sec);
    w.u32((stamp_ns % 1_000_000_000) as u32);
    w.string(frame_id);
}

fn read_header(r: &mut CdrReader<'_>) -> Result<(u64, String), CdrError> {
    let sec = r.i32("header.stamp.sec")?;
    let nanosec = r.u32("header.stamp.nanosec")?;
    let frame_id = r.string("header.frame_id")?;
    let ns = u64::try_from(sec).unwrap_or(0) * 1_000_000_000 + u64::from(nanosec);
    Ok((ns, frame_id))
}

/// The frame id of the vehicle (REP 105's `base_link`): the parent of the
/// cameras' frames in `/tf_static` for a rig in the vehicle frame.
pub const VEHICLE_FRAME: &str = "base_link";

/// One transform of a `tf2_msgs/msg/TFMessage`: the pose of frame `child`
/// in frame `parent` (`p_parent = R·p_child + t`).
#[derive(Clone, Debug, PartialEq)]
pub struct TransformMsg {
    /// `header.frame_id`.
    pub parent: String,
    /// `child_frame_id`.
    pub child: String,
    /// The translation, metres.
    pub translation: [f64; 3],
    /// The rotation as a quaternion (x, y, z, w).
    pub rotation: [f64; 4],
}

/// The static transforms of a rig: for each posed camera, its optical
/// frame in the vehicle frame ([`VEHICLE_FRAME`]) for a vehicle-frame rig,
/// or in the reference camera's optical frame for a rig relative to a
/// camera (the reference camera itself has no transform then).
pub fn rig_transforms(rig: &rigview_calib::rig::Rig) -> Vec<TransformMsg> {
    let parent = match &rig.frame {
        rigview_calib::rig::Frame::Vehicle => VEHICLE_FRAME.to_owned(),
        rigview_calib::rig::Frame::Camera(name) => optical_frame(name),
    };
    rig.cameras
        .iter()
        .filter_map(|c| {
            let pose = c.pose.as_ref()?;
            let child = optical_frame(&c.name);
            if child == parent {
                return None;
            }
            let t = pose.translation();
            let q = pose.quaternion();
            Some(TransformMsg {
                parent: parent.clone(),
                child,
                translation: [t.x, t.y, t.z],
                rotation: [q.i, q.j, q.k, q.w],
            })
        })
        .collect()
}

/// `sensor_msgs/msg/CompressedImage` of `data` in `format` ("jpeg",
/// "png").
pub fn encode_compressed_image(
    stamp_ns: u64,
    frame_id: &str,
    format: &str,
    data: &[u8],
) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(64 + data.len());
    header(&mut w, stamp_ns, frame_id);
    w.string(format);
    w.bytes(data);
    w.finish()
}

/// Reads a `sensor_msgs/msg/CompressedImage`: the header's frame id, the
/// format and the data.
pub fn decode_compressed_image(buf: &[u8]) -> Result<(String, String, &[u8]), CdrError> {
    let mut r = CdrReader::new(buf)?;
    let (_, frame_id) = read_header(&mut r)?;
    let format = r.string("format")?;
    Ok((frame_id, format, r.bytes("data")?))
}

/// `tf2_msgs/msg/TFMessage` of `transforms`, stamped `stamp_ns`.
pub fn encode_tf_message(stamp_ns: u64, transforms: &[TransformMsg]) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(64 + 128 * transforms.len());
    w.u32(transforms.len() as u32);
    for t in transforms {
        header(&mut w, stamp_ns, &t.parent);
        w.string(&t.child);
        for v in t.translation.iter().chain(&t.rotation) {
            w.f64(*v);
        }
    }
    w.finish()
}

/// Reads a `tf2_msgs/msg/TFMessage`.
pub fn decode_tf_message(buf: &[u8]) -> Result<Vec<TransformMsg>, CdrError> {
    let mut r = CdrReader::new(buf)?;
    let n = r.u32("transforms")?;
    let mut out = Vec::new();
    for _ in 0..n {
        let (_, parent) = read_header(&mut r)?;
        let child = r.string("child_frame_id")?;
        let mut v = [0.0; 7];
        for (x, field) in v.iter_mut().zip([
            "transform.translation.x",
            "transform.translation.y",
            "transform.translation.z",
            "transform.rotation.x",
            "transform.rotation.y",
            "transform.rotation.z",
            "transform.rotation.w",
        ]) {
            *x = r.f64(field)?;
        }
        out.push(TransformMsg {
            parent,
            child,
            translation: [v[0], v[1], v[2]],
            rotation: [v[3], v[4], v[5], v[6]],
        });
    }
    Ok(out)
}

/// The frame id of a camera's messages.
pub fn optical_frame(camera: &str) -> String {
    format!("{camera}_optical")
}

/// `sensor_msgs/msg/Image` of one frame.
pub fn encode_image(stamp_ns: u64, frame_id: &str, frame: &Frame) -> Vec<u8> {
    let m = &frame.meta;
    let step = m.width * m.format.bytes_per_pixel();
    let mut w = CdrWriter::with_capacity(frame.data.len() + 96);
    header(&mut w, stamp_ns, frame_id);
    w.u32(u32::try_from(m.height).unwrap_or(u32::MAX));
    w.u32(u32::try_from(m.width).unwrap_or(u32::MAX));
    w.string(encoding(m.format));
    w.u8(0);
    w.u32(u32::try_from(step).unwrap_or(u32::MAX));
    w.bytes(&frame.data);
    w.finish()
}

/// A decoded `sensor_msgs/msg/Image`, its pixels borrowed.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageMsg<'a> {
    /// `header.stamp`, ns.
    pub stamp_ns: u64,
    /// `header.frame_id`.
    pub frame_id: String,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// The ROS encoding.
    pub encoding: String,
    /// Whether the pixels are big-endian.
    pub is_bigendian: u8,
    /// Bytes per row.
    pub step: u32,
    /// The pixels.
    pub data: &'a [u8],
}

/// Reads a `sensor_msgs/msg/Image`.
pub fn decode_image(buf: &[u8]) -> Result<ImageMsg<'_>, CdrError> {
    let mut r = CdrReader::new(buf)?;
    let (stamp_ns, frame_id) = read_header(&mut r)?;
    Ok(ImageMsg {
        stamp_ns,
        frame_id,
        height: r.u32("height")?,
        width: r.u32("width")?,
        encoding: r.string("encoding")?,
        is_bigendian: r.u8("is_bigendian")?,
        step: r.u32("step")?,
        data: r.bytes("data")?,
    })
}

/// `sensor_msgs/msg/CameraInfo` of a calibrated camera.
pub fn encode_camera_info(stamp_ns: u64, frame_id: &str, camera: &Camera) -> Vec<u8> {
    let k = &camera.intrinsics;
    // ROS names no other model; the others carry rigview's model name and
    // its parameters in its order, which tools that do not know it ignore.
    let model = match k.distortion {
        Distortion::Fisheye(_) => "equidistant",
        Distortion::RadTan(_) => "plumb_bob",
        Distortion::Rational(_) => "rational_polynomial",
        other => other.model_name(),
    };
    let km = [k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0];
    let r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    let p = [
        k.fx, 0.0, k.cx, 0.0, 0.0, k.fy, k.cy, 0.0, 0.0, 0.0, 1.0, 0.0,
    ];
    let mut w = CdrWriter::with_capacity(512);
    header(&mut w, stamp_ns, frame_id);
    w.u32(k.height);
    w.u32(k.width);
    w.string(model);
    w.f64_seq(k.distortion.coefficients());
    w.f64_array(&km);
    w.f64_array(&r);
    w.f64_array(&p);
    w.u32(0);
    w.u32(0);
    for _ in 0..4 {
        w.u32(0);
    }
    w.u8(0);
    w.finish()
}

/// The parts of a `sensor_msgs/msg/CameraInfo` rigview reads back.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraInfoMsg {
    /// `header.frame_id`.
    pub frame_id: String,
    /// Calibrated height.
    pub height: u32,
    /// Calibrated width.
    pub width: u32,
    /// The ROS distortion model.
    pub distortion_model: String,
    /// Its coefficients.
    pub d: Vec<f64>,
    /// The camera matrix, row-major.
    pub k: [f64; 9],
}

/// Reads a `sensor_msgs/msg/CameraInfo` (up to `k`).
pub fn decode_camera_info(buf: &[u8]) -> Result<CameraInfoMsg, CdrError> {
    let mut r = CdrReader::new(buf)?;
    let (_, frame_id) = read_header(&mut r)?;
    Ok(CameraInfoMsg {
        frame_id,
        height: r.u32("height")?,
        width: r.u32("width")?,
        distortion_model: r.string("distortion_model")?,
        d: r.f64_seq("d")?,
        k: r.f64_array("k")?,
    })
}

/// `rigview_msgs/msg/FrameMeta`: what a camera said about a frame.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameMetaMsg {
    /// `header.stamp` (the set's trigger time), ns.
    pub stamp_ns: u64,
    /// `header.frame_id`.
    pub frame_id: String,
    /// The set's trigger number.
    pub trigger: u64,
    /// The camera's frame id.
    pub camera_frame_id: u64,
    /// Exposure time taken, µs.
    pub exposure_us: f64,
    /// Gain taken, dB.
    pub gain_db: f64,
    /// The set's trigger time, ns.
    pub trigger_time_ns: u64,
    /// The camera's timestamp, ns.
    pub camera_time_ns: u64,
    /// When the recorder received the set, Unix ns.
    pub host_time_ns: u64,
    /// GenICam PFNC name.
    pub pixel_format: String,
    /// How the frame arrived.
    pub status: FrameStatus,
}

const STATUS_COMPLETE: u8 = 0;
const STATUS_MISSING_PACKETS: u8 = 1;
const STATUS_FAILED: u8 = 2;

/// Writes a `rigview_msgs/msg/FrameMeta`.
pub fn encode_frame_meta(m: &FrameMetaMsg) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(160);
    header(&mut w, m.stamp_ns, &m.frame_id);
    w.u64(m.trigger);
    w.u64(m.camera_frame_id);
    w.f64(m.exposure_us);
    w.f64(m.gain_db);
    w.u64(m.trigger_time_ns);
    w.u64(m.camera_time_ns);
    w.u64(m.host_time_ns);
    w.string(&m.pixel_format);
    let (code, missing, detail) = match &m.status {
        FrameStatus::Complete => (STATUS_COMPLETE, 0, ""),
        FrameStatus::MissingPackets { missing } => (STATUS_MISSING_PACKETS, *missing, ""),
        FrameStatus::Failed(why) => (STATUS_FAILED, 0, why.as_str()),
    };
    w.u8(code);
    w.u32(missing);
    w.string(detail);
    w.finish()
}

/// Reads a `rigview_msgs/msg/FrameMeta`.
pub fn decode_frame_meta(buf: &[u8]) -> Result<FrameMetaMsg, CdrError> {
    let mut r = CdrReader::new(buf)?;
    let (stamp_ns, frame_id) = read_header(&mut r)?;
    let trigger = r.u64("trigger")?;
    let camera_frame_id = r.u64("frame_id")?;
    let exposure_us = r.f64("exposure_us")?;
    let gain_db = r.f64("gain_db")?;
    let trigger_time_ns = r.u64("trigger_time_ns")?;
    let camera_time_ns = r.u64("camera_time_ns")?;
    let host_time_ns = r.u64("host_time_ns")?;
    let pixel_format = r.string("pixel_format")?;
    let code = r.u8("status")?;
    let missing = r.u32("missing_packets")?;
    let detail = r.string("status_detail")?;
    let status = match code {
        STATUS_COMPLETE => FrameStatus::Complete,
        STATUS_MISSING_PACKETS => FrameStatus::MissingPackets { missing },
        _ => FrameStatus::Failed(detail),
    };
    Ok(FrameMetaMsg {
        stamp_ns,
        frame_id,
        trigger,
        camera_frame_id,
        exposure_us,
        gain_db,
        trigger_time_ns,
        camera_time_ns,
        host_time_ns,
        pixel_format,
        status,
    })
}

/// `rigview_msgs/msg/SetTelemetry`: one set's exposure telemetry (NaN
/// where a value was not computed).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SetTelemetryMsg {
    /// `header.stamp` (the set's trigger time), ns.
    pub stamp_ns: u64,
    /// The set's trigger number.
    pub trigger: u64,
    /// Seconds since the first processed set.
    pub time_s: f64,
    /// Whether the set went through processing.
    pub processed: bool,
    /// The strategy's name.
    pub strategy: String,
    /// The law's name.
    pub law: String,
    /// The cameras' names.
    pub camera_names: Vec<String>,
    /// Per camera: a whole frame is in the set.
    pub present: Vec<bool>,
    /// Per camera: shutter taken, µs.
    pub shutter_us: Vec<f64>,
    /// Per camera: gain taken, dB.
    pub gain_db: Vec<f64>,
    /// Per camera: exposure taken.
    pub exposure: Vec<f64>,
    /// Per camera: γ̂.
    pub gamma_hat: Vec<f64>,
    /// Per camera: M.
    pub m: Vec<f64>,
    /// Per camera: mean metered luminance.
    pub mean: Vec<f64>,
    /// Per camera: the exposure commanded after the set.
    pub command: Vec<f64>,
    /// Per camera: a probe frame.
    pub probe: Vec<bool>,
    /// The overlaps' names.
    pub pair_names: Vec<String>,
    /// Per overlap: `log2 r_ij`.
    pub log2_r: Vec<f64>,
    /// Sets per second reaching processing.
    pub set_rate_hz: f64,
    /// Stage times, ms.
    pub stage_ms: Vec<f64>,
    /// Sets the pipeline dropped so far.
    pub dropped_before_processing: u64,
    /// Sets the recorder dropped so far.
    pub dropped_by_recorder: u64,
    /// Sets the recorder dropped right before this one.
    pub dropped_since_last: u64,
}

/// Writes a `rigview_msgs/msg/SetTelemetry`.
pub fn encode_set_telemetry(t: &SetTelemetryMsg) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(1024);
    header(&mut w, t.stamp_ns, "rig");
    w.u64(t.trigger);
    w.f64(t.time_s);
    w.u8(u8::from(t.processed));
    w.string(&t.strategy);
    w.string(&t.law);
    w.string_seq(&t.camera_names);
    w.bool_seq(&t.present);
    for v in [
        &t.shutter_us,
        &t.gain_db,
        &t.exposure,
        &t.gamma_hat,
        &t.m,
        &t.mean,
        &t.command,
    ] {
        w.f64_seq(v);
    }
    w.bool_seq(&t.probe);
    w.string_seq(&t.pair_names);
    w.f64_seq(&t.log2_r);
    w.f64(t.set_rate_hz);
    w.f64_seq(&t.stage_ms);
    w.u64(t.dropped_before_processing);
    w.u64(t.dropped_by_recorder);
    w.u64(t.dropped_since_last);
    w.finish()
}

/// Reads a `rigview_msgs/msg/SetTelemetry`.
pub fn decode_set_telemetry(buf: &[u8]) -> Result<SetTelemetryMsg, CdrError> {
    let mut r = CdrReader::new(buf)?;
    let (stamp_ns, _) = read_header(&mut r)?;
    Ok(SetTelemetryMsg {
        stamp_ns,
        trigger: r.u64("trigger")?,
        time_s: r.f64("time_s")?,
        processed: r.bool("processed")?,
        strategy: r.string("strategy")?,
        law: r.string("law")?,
        camera_names: r.string_seq("camera_names")?,
        present: r.bool_seq("present")?,
        shutter_us: r.f64_seq("shutter_us")?,
        gain_db: r.f64_seq("gain_db")?,
        exposure: r.f64_seq("exposure")?,
        gamma_hat: r.f64_seq("gamma_hat")?,
        m: r.f64_seq("m")?,
        mean: r.f64_seq("mean")?,
        command: r.f64_seq("command")?,
        probe: r.bool_seq("probe")?,
        pair_names: r.string_seq("pair_names")?,
        log2_r: r.f64_seq("log2_r")?,
        set_rate_hz: r.f64("set_rate_hz")?,
        stage_ms: r.f64_seq("stage_ms")?,
        dropped_before_processing: r.u64("dropped_before_processing")?,
        dropped_by_recorder: r.u64("dropped_by_recorder")?,
        dropped_since_last: r.u64("dropped_since_last")?,
    })
}

/// The telemetry of a set from the pipeline's row (`None`: the set was
/// not processed; only what its frames say is filled in).
pub fn telemetry_of(
    set: &rigview_core::source::FrameSet,
    processed: Option<&rigview_core::pipeline::Processed<'_>>,
    camera_names: &[String],
) -> SetTelemetryMsg {
    let nan = f64::NAN;
    let mut t = SetTelemetryMsg {
        trigger: set.trigger,
        camera_names: camera_names.to_vec(),
        present: set
            .frames
            .iter()
            .map(|f| f.as_ref().is_some_and(Frame::is_complete))
            .collect(),
        ..Default::default()
    };
    let taken = |f: &Option<Frame>| f.as_ref().map(|f| f.meta.taken);
    t.shutter_us = set
        .frames
        .iter()
        .map(|f| taken(f).map_or(nan, |s| s.shutter_us))
        .collect();
    t.gain_db = set
        .frames
        .iter()
        .map(|f| taken(f).map_or(nan, |s| s.gain_db))
        .collect();
    t.exposure = set
        .frames
        .iter()
        .map(|f| taken(f).map_or(nan, |s| s.exposure()))
        .collect();
    let n = set.frames.len();
    match processed {
        None => {
            t.gamma_hat = vec![nan; n];
            t.m = vec![nan; n];
            t.mean = vec![nan; n];
            t.command = vec![nan; n];
            t.probe = vec![false; n];
            t.set_rate_hz = nan;
        }
        Some(p) => {
            let row = p.row;
            t.processed = true;
            t.time_s = row.time_s;
            t.strategy = p.settings.strategy.name().to_owned();
            t.law = p.settings.controller.law.kind.name().to_owned();
            t.gamma_hat = row
                .cameras
                .iter()
                .map(|c| c.gamma_hat.unwrap_or(nan))
                .collect();
            t.m = row.cameras.iter().map(|c| c.m.unwrap_or(nan)).collect();
            t.mean = row.cameras.iter().map(|c| c.mean).collect();
            t.command = row
                .cameras
                .iter()
                .map(|c| c.command.unwrap_or(nan))
                .collect();
            t.probe = row.cameras.iter().map(|c| c.probe).collect();
            t.pair_names = p.pair_names.to_vec();
            t.log2_r = row.log2_r.iter().map(|r| r.unwrap_or(nan)).collect();
            t.set_rate_hz = row.set_rate_hz;
            t.stage_ms = row.times.values().to_vec();
            t.dropped_before_processing = row.dropped;
        }
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schemas_follow_their_dependencies_after_a_separator() {
        let image = schema_text(IMAGE).unwrap();
        assert!(image.starts_with("# This message contains an uncompressed image\n"));
        let sep = format!("\n{}\nMSG: std_msgs/Header\n", "=".repeat(80));
        assert!(image.contains(&sep), "{image}");
        assert!(image.ends_with("uint32 nanosec\n"));
        let info = schema_text(CAMERA_INFO).unwrap();
        assert!(info.contains("MSG: sensor_msgs/RegionOfInterest\n"));
        assert!(schema_text("std_msgs/msg/String").is_none());
    }

    #[test]
    fn a_rig_relative_to_a_camera_hangs_its_cameras_from_that_camera() {
        use rigview_calib::pose::Pose;
        use rigview_calib::rig::{Frame, Rig};
        let intrinsics = rigview_calib::Intrinsics {
            width: 640,
            height: 480,
            fx: 400.0,
            fy: 400.0,
            cx: 320.0,
            cy: 240.0,
            distortion: Distortion::Fisheye([0.0; 4]),
        };
        let mut left = Camera::new("left", intrinsics);
        left.pose = Some(Pose::identity());
        let mut right = Camera::new("right", intrinsics);
        let t = nalgebra::Vector3::new(0.12, 0.0, 0.0);
        right.pose = Some(Pose::new(nalgebra::Matrix3::identity(), t).unwrap());
        let rig = Rig::new(
            Frame::Camera("left".into()),
            vec![left, right],
            vec![(0, 1)],
        )
        .unwrap();
        let tf = rig_transforms(&rig);
        assert_eq!(tf.len(), 1);
        assert_eq!(
            (tf[0].parent.as_str(), tf[0].child.as_str()),
            ("left_optical", "right_optical")
        );
        assert_eq!(
            tf[0].translation.map(f64::to_bits),
            [0.12, 0.0, 0.0].map(f64::to_bits)
        );
        assert_eq!(
            tf[0].rotation.map(f64::to_bits),
            [0.0, 0.0, 0.0, 1.0].map(f64::to_bits)
        );
        assert_eq!(decode_tf_message(&encode_tf_message(7, &tf)).unwrap(), tf);
    }

    #[test]
    fn camera_info_reads_back_with_the_rig_calibration() {
        let intrinsics = rigview_calib::Intrinsics {
            width: 1288,
            height: 964,
            fx: 410.5,
            fy: 409.25,
            cx: 644.0,
            cy: 481.5,
            distortion: Distortion::Fisheye([0.02, -0.005, 0.001, 0.0]),
        };
        let camera = Camera::new("front", intrinsics);
        let m = decode_camera_info(&encode_camera_info(5, "front_optical", &camera)).unwrap();
        assert_eq!(m.frame_id, "front_optical");
        assert_eq!((m.width, m.height), (1288, 964));
        assert_eq!(m.distortion_model, "equidistant");
        assert_eq!(m.d, vec![0.02, -0.005, 0.001, 0.0]);
        let k = [410.5, 0.0, 644.0, 0.0, 409.25, 481.5, 0.0, 0.0, 1.0];
        assert_eq!(m.k.map(f64::to_bits), k.map(f64::to_bits));
    }

    #[test]
    fn frame_meta_and_telemetry_read_back() {
        let m = FrameMetaMsg {
            stamp_ns: 1_700_000_000_123_456_789,
            frame_id: "front_optical".into(),
            trigger: 9,
            camera_frame_id: 1234,
            exposure_us: 812.5,
            gain_db: 3.25,
            trigger_time_ns: 1_700_000_000_123_456_789,
            camera_time_ns: 55,
            host_time_ns: 66,
            pixel_format: "BayerRG8".into(),
            status: FrameStatus::MissingPackets { missing: 3 },
        };
        assert_eq!(decode_frame_meta(&encode_frame_meta(&m)).unwrap(), m);
        let t = SetTelemetryMsg {
            trigger: 3,
            camera_names: vec!["a".into(), "b".into()],
            present: vec![true, false],
            gamma_hat: vec![1.25, 0.5],
            pair_names: vec!["a-b".into()],
            log2_r: vec![0.125],
            stage_ms: vec![1.0; 6],
            dropped_since_last: 2,
            ..Default::default()
        };
        assert_eq!(decode_set_telemetry(&encode_set_telemetry(&t)).unwrap(), t);
    }
}
