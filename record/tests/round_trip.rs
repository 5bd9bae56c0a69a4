//! Round trip: seeded runs of the simulated rig in Mono8, RGB8 and
//! BayerRG8, at full and quarter size, read back identically through the
//! streaming and the indexed reader; the file passes the mcap crate's
//! strict reading with CRCs, carries the exact ROS 2 schemas, and its
//! images decode with an independent CDR decoder (the `cdr` crate).

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::fs::File;
use std::io::BufWriter;

use common::{assert_same, Sim};
use rigview_core::image::PixelFormat;
use rigview_record::msgs;
use rigview_record::{Compression, IndexedRecording, SetStream, SetWriter};
use serde::Deserialize;

const SETS: u64 = 6;

#[derive(Debug, Deserialize)]
struct Time {
    sec: i32,
    nanosec: u32,
}

#[derive(Debug, Deserialize)]
struct Header {
    stamp: Time,
    frame_id: String,
}

#[derive(Debug, Deserialize)]
struct Image {
    header: Header,
    height: u32,
    width: u32,
    encoding: String,
    is_bigendian: u8,
    step: u32,
    #[serde(with = "serde_bytes")]
    data: Vec<u8>,
}

#[derive(Debug, Deserialize)]
struct TransformStamped {
    header: Header,
    child_frame_id: String,
    translation: [f64; 3],
    rotation: [f64; 4],
}

#[derive(Debug, Deserialize)]
struct TfMessage {
    transforms: Vec<TransformStamped>,
}

fn round_trip(format: PixelFormat, scale: f64, compression: Compression) {
    let sim = Sim::new(format, scale);
    let setup = sim.setup();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.mcap");
    let sets: Vec<_> = (0..SETS).map(|k| sim.set(42, k)).collect();
    {
        let out = BufWriter::new(File::create(&path).unwrap());
        let mut w = SetWriter::new(&path, out, &setup, compression).unwrap();
        for s in &sets {
            w.write_set(s, sim.telemetry(s), 0, 1).unwrap();
        }
        w.finish("finished").unwrap();
    }
    let what = format!("{format:?} at scale {scale}, {compression:?}");

    // Streaming, with CRCs checked.
    let mut stream = SetStream::open(&path, true).unwrap();
    let got: Vec<_> = stream.by_ref().map(|s| s.unwrap()).collect();
    assert_eq!(got.len(), sets.len(), "{what}");
    for (g, w) in got.iter().zip(&sets) {
        assert_same(g, w, setup.time_offset_ns);
    }
    assert_eq!(stream.tail(), None, "{what}: the file ends properly");
    assert_eq!(stream.end().unwrap().sets, SETS);
    let meta = stream.meta().unwrap();
    assert_eq!(meta.cameras, sim.cameras);
    assert!(meta
        .rig_yaml
        .as_deref()
        .unwrap()
        .contains(&sim.cameras[0].name));

    // Indexed, set by set and by time.
    let mut indexed = IndexedRecording::open(&path).unwrap();
    assert_eq!(indexed.len(), sets.len());
    let got: Vec<_> = indexed.sets().map(|s| s.unwrap()).collect();
    for (g, w) in got.iter().zip(&sets) {
        assert_same(g, w, setup.time_offset_ns);
    }
    let t3 = indexed.times()[3];
    assert_eq!(indexed.position(t3), 3);
    assert_eq!(indexed.position(t3 - 1), 3);
    assert_eq!(indexed.position(t3 + 1), 4);
    assert_same(
        &indexed.set(3).unwrap().unwrap(),
        &sets[3],
        setup.time_offset_ns,
    );

    // The mcap crate's own strict reading: CRCs, log and publish time,
    // sequence = frame id, exact schemas, and an independent CDR decoder.
    let bytes = std::fs::read(&path).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    assert_eq!(
        u64::from(summary.stats.as_ref().unwrap().chunk_count),
        SETS + 1,
        "a chunk per set, and the first for the schemas and channels"
    );
    let (mut images, mut tf) = (0, 0);
    let rig = sim.rig();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        assert_eq!(m.log_time, m.publish_time);
        let schema = m.channel.schema.as_ref().unwrap();
        assert_eq!(schema.encoding, "ros2msg");
        assert_eq!(m.channel.message_encoding, "cdr");
        assert!(m.channel.metadata.contains_key("offered_qos_profiles"));
        assert_eq!(
            std::str::from_utf8(&schema.data).unwrap(),
            msgs::schema_text(&schema.name).unwrap()
        );
        if schema.name == msgs::IMAGE {
            let img: Image = cdr::deserialize(&m.data).unwrap();
            let stamp = u64::try_from(img.header.stamp.sec).unwrap() * 1_000_000_000
                + u64::from(img.header.stamp.nanosec);
            assert_eq!(stamp, m.log_time, "header.stamp = log_time");
            let k = sets
                .iter()
                .position(|s| s.timestamp_ns + setup.time_offset_ns == m.log_time)
                .unwrap();
            let cam = sim
                .cameras
                .iter()
                .position(|c| m.channel.topic == format!("/rig/{}/image_raw", c.name))
                .unwrap();
            let frame = sets[k].frames[cam].as_ref().unwrap();
            assert_eq!(u64::from(m.sequence), frame.meta.frame_id % (1 << 32));
            assert_eq!(
                img.header.frame_id,
                format!("{}_optical", sim.cameras[cam].name)
            );
            assert_eq!(
                (img.width as usize, img.height as usize),
                (frame.meta.width, frame.meta.height)
            );
            assert_eq!(img.encoding, msgs::encoding(format));
            assert_eq!(img.is_bigendian, 0);
            assert_eq!(
                img.step as usize,
                frame.meta.width * format.bytes_per_pixel()
            );
            assert!(img.data[..] == frame.data[..]);
            images += 1;
        }
        if schema.name == msgs::TF_MESSAGE {
            // The rig's cameras in the vehicle frame, decoded by the `cdr`
            // crate: transient local, so that a late subscriber of a
            // replay still gets them.
            assert_eq!(m.channel.topic, "/tf_static");
            let qos = &m.channel.metadata["offered_qos_profiles"];
            assert!(qos.contains("durability: 1"), "{qos}");
            assert_eq!(m.log_time, sets[0].timestamp_ns + setup.time_offset_ns);
            let msg: TfMessage = cdr::deserialize(&m.data).unwrap();
            assert_eq!(msg.transforms.len(), rig.cameras.len());
            for (t, cam) in msg.transforms.iter().zip(&rig.cameras) {
                let pose = cam.pose.as_ref().unwrap();
                assert_eq!(t.header.frame_id, "base_link");
                assert_eq!(t.child_frame_id, format!("{}_optical", cam.name));
                let q = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                    t.rotation[3],
                    t.rotation[0],
                    t.rotation[1],
                    t.rotation[2],
                ));
                // A point of the camera frame lands where the rig's pose
                // puts it.
                let p = nalgebra::Vector3::new(0.3, -0.2, 1.0);
                let via_tf = q * p + nalgebra::Vector3::from(t.translation);
                assert!((via_tf - pose.to_rig(&p)).norm() < 1e-9, "{}", cam.name);
            }
            tf += 1;
        }
    }
    assert_eq!(images, SETS as usize * sim.cameras.len(), "{what}");
    assert_eq!(tf, 1, "{what}: one /tf_static message");
}

#[test]
fn mono8_full_and_quarter_size_read_back_identically() {
    round_trip(PixelFormat::Mono8, 1.0, Compression::None);
    round_trip(PixelFormat::Mono8, 0.25, Compression::None);
}

#[test]
fn rgb8_full_and_quarter_size_read_back_identically() {
    round_trip(PixelFormat::Rgb8, 1.0, Compression::None);
    round_trip(PixelFormat::Rgb8, 0.25, Compression::None);
}

#[test]
fn bayer_rggb8_full_and_quarter_size_read_back_identically() {
    round_trip(PixelFormat::BayerRg8, 1.0, Compression::None);
    round_trip(PixelFormat::BayerRg8, 0.25, Compression::None);
}

#[test]
fn compressed_chunks_read_back_identically() {
    round_trip(PixelFormat::Mono8, 0.25, Compression::Lz4);
    round_trip(PixelFormat::Mono8, 0.25, Compression::Zstd);
}

/// A 2×2 mono8 image as `ros2` serialises it, byte by byte from the CDR
/// rules (not from rigview's encoder), decoded by rigview and by the `cdr`
/// crate.
#[test]
fn cdr_golden_image() {
    let golden: Vec<u8> = [
        &[0x00, 0x01, 0x00, 0x00][..], // encapsulation: CDR little-endian
        &[0x01, 0x00, 0x00, 0x00],     // stamp.sec = 1
        &[0x02, 0x00, 0x00, 0x00],     // stamp.nanosec = 2
        &[0x04, 0x00, 0x00, 0x00],
        b"cam\0",                  // frame_id "cam" (length counts NUL)
        &[0x02, 0x00, 0x00, 0x00], // height 2
        &[0x02, 0x00, 0x00, 0x00], // width 2
        &[0x06, 0x00, 0x00, 0x00],
        b"mono8\0",                // encoding
        &[0x00],                   // is_bigendian
        &[0x00],                   // padding to 4
        &[0x02, 0x00, 0x00, 0x00], // step
        &[0x04, 0x00, 0x00, 0x00],
        &[9, 8, 7, 6], // data
    ]
    .concat();
    let ours = msgs::decode_image(&golden).unwrap();
    assert_eq!(ours.stamp_ns, 1_000_000_002);
    assert_eq!(
        (ours.frame_id.as_str(), ours.encoding.as_str()),
        ("cam", "mono8")
    );
    assert_eq!((ours.width, ours.height, ours.step), (2, 2, 2));
    assert_eq!(ours.data, &[9, 8, 7, 6]);
    let theirs: Image = cdr::deserialize(&golden).unwrap();
    assert_eq!(
        (theirs.header.stamp.sec, theirs.header.stamp.nanosec),
        (1, 2)
    );
    assert_eq!(theirs.header.frame_id, "cam");
    assert_eq!(theirs.data, vec![9, 8, 7, 6]);
    // And rigview's encoder writes exactly these bytes.
    let meta = rigview_core::source::FrameMeta {
        camera: 0,
        format: PixelFormat::Mono8,
        width: 2,
        height: 2,
        taken: rigview_core::exposure::ExposureSetting {
            shutter_us: 1.0,
            gain_db: 0.0,
        },
        timestamp_ns: 0,
        frame_id: 0,
        status: rigview_core::source::FrameStatus::Complete,
    };
    let frame = rigview_core::source::Frame::new(meta, vec![9u8, 8, 7, 6].into()).unwrap();
    assert_eq!(msgs::encode_image(1_000_000_002, "cam", &frame), golden);
}

/// The schemas are the ROS 2 message texts as `ros2 bag record` stores
/// them: the copies in tests/data were taken from ros2/common_interfaces
/// and ros2/rcl_interfaces.
#[test]
fn schemas_are_the_ros2_texts() {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/ros2-msgs");
    let read = |f: &str| std::fs::read_to_string(data.join(f)).unwrap();
    let sep = format!("\n{}\n", "=".repeat(80));
    let image = format!(
        "{}{sep}MSG: std_msgs/Header\n{}{sep}MSG: builtin_interfaces/Time\n{}",
        read("sensor_msgs/msg/Image.msg"),
        read("std_msgs/msg/Header.msg"),
        read("builtin_interfaces/msg/Time.msg")
    );
    assert_eq!(msgs::schema_text(msgs::IMAGE).unwrap(), image);
    let info = msgs::schema_text(msgs::CAMERA_INFO).unwrap();
    assert!(info.starts_with(&read("sensor_msgs/msg/CameraInfo.msg")));
    assert!(info.ends_with(&format!(
        "MSG: sensor_msgs/RegionOfInterest\n{}",
        read("sensor_msgs/msg/RegionOfInterest.msg")
    )));
    let tf = msgs::schema_text(msgs::TF_MESSAGE).unwrap();
    assert!(tf.starts_with(&read("tf2_msgs/msg/TFMessage.msg")));
    for (name, file) in [
        (
            "geometry_msgs/TransformStamped",
            "geometry_msgs/msg/TransformStamped.msg",
        ),
        ("geometry_msgs/Transform", "geometry_msgs/msg/Transform.msg"),
        (
            "geometry_msgs/Quaternion",
            "geometry_msgs/msg/Quaternion.msg",
        ),
        ("geometry_msgs/Vector3", "geometry_msgs/msg/Vector3.msg"),
        ("std_msgs/Header", "std_msgs/msg/Header.msg"),
        ("builtin_interfaces/Time", "builtin_interfaces/msg/Time.msg"),
    ] {
        assert!(
            tf.contains(&format!("{sep}MSG: {name}\n{}", read(file))),
            "{name}"
        );
    }
}
