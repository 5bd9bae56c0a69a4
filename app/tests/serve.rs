#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! The live remote view end to end: `rigview run --headless --serve` on
//! the simulated rig, and a WebSocket client (tungstenite) that speaks
//! Foxglove's protocol to it: it subscribes to a camera's pictures and
//! calibration, its exposure state, the composed view and the rig's
//! transforms, and decodes them.

use std::io::{BufRead, BufReader};
use std::net::TcpStream;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use rigview_record::msgs;
use tungstenite::client::IntoClientRequest;
use tungstenite::stream::MaybeTlsStream;
use tungstenite::{Message, WebSocket};

type Ws = WebSocket<MaybeTlsStream<TcpStream>>;

fn text(ws: &mut Ws) -> serde_json::Value {
    loop {
        match ws.read().unwrap() {
            Message::Text(t) => return serde_json::from_str(t.as_str()).unwrap(),
            Message::Binary(_) | Message::Ping(_) | Message::Pong(_) => {}
            other => panic!("{other:?}"),
        }
    }
}

#[test]
fn a_foxglove_client_gets_the_cameras_the_view_and_the_transforms() {
    let dir = tempfile::tempdir().unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_rigview"))
        .args([
            "run",
            "--headless",
            "--realtime",
            "--frames",
            "120",
            "--scale",
            "0.5",
        ])
        .args(["--serve", "127.0.0.1:0", "--out"])
        .arg(dir.path())
        .arg("--settings")
        .arg(dir.path().join("settings.yaml"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = child.stderr.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    let addr = loop {
        let line = rx
            .recv_timeout(Duration::from_secs(60))
            .expect("the run says where it serves");
        if let Some((_, rest)) = line.split_once("remote view on ws://") {
            break rest.split_whitespace().next().unwrap().to_owned();
        }
    };
    let mut req = format!("ws://{addr}").into_client_request().unwrap();
    req.headers_mut().insert(
        "Sec-WebSocket-Protocol",
        "foxglove.websocket.v1".parse().unwrap(),
    );
    let (mut ws, resp) = tungstenite::connect(req).unwrap();
    assert_eq!(
        resp.headers().get("Sec-WebSocket-Protocol").unwrap(),
        "foxglove.websocket.v1"
    );
    assert_eq!(text(&mut ws)["op"], "serverInfo");
    let adv = text(&mut ws);
    assert_eq!(adv["op"], "advertise");
    let channels = adv["channels"].as_array().unwrap();
    let id = |topic: &str| {
        channels
            .iter()
            .find(|c| c["topic"] == topic)
            .unwrap_or_else(|| panic!("no {topic} in {channels:?}"))["id"]
            .as_u64()
            .unwrap()
    };
    // Every topic the Foxglove layout in assets/ opens is one the server
    // advertises.
    let layout: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/foxglove-layout.json"),
        )
        .unwrap(),
    )
    .unwrap();
    let mut used = Vec::new();
    for panel in layout["configById"].as_object().unwrap().values() {
        for key in ["imageTopic", "calibrationTopic"] {
            if let Some(t) = panel["imageMode"][key].as_str() {
                used.push(t.to_owned());
            }
        }
        for p in panel["paths"].as_array().into_iter().flatten() {
            let path = p["value"].as_str().unwrap();
            used.push(path.split('.').next().unwrap().to_owned());
        }
        for t in panel["topics"]
            .as_object()
            .into_iter()
            .flat_map(|o| o.keys())
        {
            used.push(t.clone());
        }
    }
    assert!(used.len() > 10, "{used:?}");
    for topic in &used {
        id(topic);
    }
    let wanted = [
        (1, "/rig/front/image_raw/compressed"),
        (2, "/rig/front/camera_info"),
        (3, "/rig/front/exposure"),
        (4, "/rig/view/compressed"),
        (5, "/tf_static"),
        (6, "/rig/telemetry"),
    ];
    let subs: Vec<_> = wanted
        .iter()
        .map(|(sub, topic)| serde_json::json!({"id": sub, "channelId": id(topic)}))
        .collect();
    ws.send(Message::text(
        serde_json::json!({"op": "subscribe", "subscriptions": subs}).to_string(),
    ))
    .unwrap();
    let mut got: std::collections::HashMap<u32, Vec<u8>> = Default::default();
    let t0 = Instant::now();
    while got.len() < wanted.len() && t0.elapsed() < Duration::from_secs(60) {
        if let Message::Binary(b) = ws.read().unwrap() {
            assert_eq!(b[0], 1, "message data");
            let sub = u32::from_le_bytes(b[1..5].try_into().unwrap());
            got.entry(sub).or_insert_with(|| b[13..].to_vec());
        }
    }
    assert_eq!(got.len(), wanted.len(), "got {:?}", got.keys());
    // The client's log (docs/remote-view.md shows one).
    for (sub, topic) in wanted {
        eprintln!("client: {topic}: first message {} bytes", got[&sub].len());
    }
    // The front camera: 1288×964 rendered at half scale (644×482), served
    // at half that.
    let (frame_id, format, jpeg) = msgs::decode_compressed_image(&got[&1]).unwrap();
    assert_eq!(
        (frame_id.as_str(), format.as_str()),
        ("front_optical", "jpeg")
    );
    let picture = image::load_from_memory(jpeg).unwrap();
    assert_eq!((picture.width(), picture.height()), (322, 241));
    let info = msgs::decode_camera_info(&got[&2]).unwrap();
    assert_eq!((info.width, info.height), (322, 241));
    assert_eq!(info.distortion_model, "equidistant");
    let state: serde_json::Value = serde_json::from_slice(&got[&3]).unwrap();
    assert!(state["shutter_us"].as_f64().unwrap() > 0.0, "{state}");
    for key in [
        "gain_db",
        "gamma_hat",
        "m",
        "mean",
        "saturated",
        "probe_frame",
        "last_probe",
    ] {
        assert!(state.get(key).is_some(), "{key} missing: {state}");
    }
    let (_, _, view) = msgs::decode_compressed_image(&got[&4]).unwrap();
    let view = image::load_from_memory(view).unwrap();
    assert!(view.width() > 100 && view.height() > 100);
    let telemetry: serde_json::Value = serde_json::from_slice(&got[&6]).unwrap();
    assert_eq!(
        telemetry["pairs"].as_array().unwrap().len(),
        4,
        "{telemetry}"
    );
    let streams = telemetry["streams"].as_array().unwrap();
    assert_eq!(streams.len(), 4, "{telemetry}");
    assert!(
        streams.iter().all(|s| s["state"] == "Streaming"),
        "{telemetry}"
    );
    assert!(
        telemetry["times_ms"]["meter"].as_f64().unwrap() > 0.0,
        "{telemetry}"
    );
    // The transforms are the simulated rig's poses.
    let rig = rigview_core::sim::reference_rig().unwrap();
    let tf = msgs::decode_tf_message(&got[&5]).unwrap();
    assert_eq!(tf, msgs::rig_transforms(&rig));
    eprintln!(
        "client: front picture {}×{} JPEG; camera_info {}×{} {}; view {}×{}; {} transforms from {}",
        picture.width(),
        picture.height(),
        info.width,
        info.height,
        info.distortion_model,
        view.width(),
        view.height(),
        tf.len(),
        tf[0].parent
    );
    drop(ws);
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success());
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains(&format!("remote view {addr}")), "{stdout}");
}

/// A port in use stops the run before it starts, saying where and what
/// to add; with `--serve-optional` the run goes on without the remote
/// view.
#[test]
fn a_port_in_use_stops_the_run_unless_the_view_is_optional() {
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = taken.local_addr().unwrap().port().to_string();
    let dir = tempfile::tempdir().unwrap();
    let run = |extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_rigview"))
            .args([
                "run",
                "--headless",
                "--frames",
                "3",
                "--scale",
                "0.25",
                "--serve",
                &port,
            ])
            .args(extra)
            .arg("--out")
            .arg(dir.path())
            .arg("--settings")
            .arg(dir.path().join("settings.yaml"))
            .output()
            .unwrap()
    };
    let out = run(&[]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains(&format!("--serve 127.0.0.1:{port}"))
            && stderr.contains("--serve-optional"),
        "{stderr}"
    );
    assert!(
        !dir.path().join("telemetry.csv").exists(),
        "it stopped before starting"
    );
    let out = run(&["--serve-optional"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("going on without the remote view"),
        "{stderr}"
    );
    assert!(dir.path().join("telemetry.csv").exists());
}
