//! Replay reproduces: a lock-step headless run of the simulated rig,
//! recorded with `--record`, replayed headless with `--source replay:FILE`;
//! the replay's telemetry measures (γ̂, M, r_ij, and the exposures the
//! frames were taken with) equal the live run's, set by set, and equal the
//! telemetry recorded in the file. Also: `rigview recording info` and
//! `repair` on a cut copy, and a calibration that does not fit.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::path::Path;

use common::{csv, rigview};

use rigview::commands::recording;
use rigview::commands::run::{self as headless, HeadlessRun};
use rigview::logging::LogBuffer;
use rigview::session::{RecordSpec, ReplaySpec};
use rigview::session::{SimSpec, SourceSpec};
use rigview_core::pipeline::ProcessingSettings;

fn measured(header: &[String]) -> Vec<usize> {
    header
        .iter()
        .enumerate()
        .filter(|(_, h)| {
            h.ends_with(".gamma_hat")
                || h.ends_with(".m")
                || h.starts_with("log2_r.")
                || h.ends_with(".exposure")
                || h.ends_with(".mean")
        })
        .map(|(i, _)| i)
        .collect()
}

#[test]
fn a_replayed_recording_measures_what_the_run_measured() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("drive.mcap");
    let settings = ProcessingSettings::default();
    let log = LogBuffer::default();
    let live = HeadlessRun {
        source: SourceSpec::Sim(SimSpec {
            scenario: "steps".into(),
            scale: 0.25,
            realtime: false,
            frames: Some(40),
        }),
        frames: 40,
        out: dir.path().join("live"),
        every: 1000,
        record: Some(RecordSpec::new(file.clone())),
        serve: None,
    };
    let summary = headless::run(&live, &settings, &log, false).unwrap();
    assert!(summary.contains("40 sets"), "{summary}");
    assert!(summary.contains("0 dropped"), "{summary}");

    let replay = HeadlessRun {
        source: SourceSpec::Replay(ReplaySpec {
            file: file.clone(),
            rig: None,
            interactive: false,
        }),
        frames: u64::MAX,
        out: dir.path().join("replay"),
        every: 1000,
        record: None,
        serve: None,
    };
    headless::run(&replay, &settings, &log, false).unwrap();
    let (h1, live_rows) = csv(&dir.path().join("live/telemetry.csv"));
    let (h2, replay_rows) = csv(&dir.path().join("replay/telemetry.csv"));
    assert_eq!(h1, h2);
    assert_eq!(live_rows.len(), 40);
    assert_eq!(replay_rows.len(), 40);
    let cols = measured(&h1);
    assert!(cols.len() >= 4 * 4 + 4, "{h1:?}");
    let mut gammas = 0;
    for (a, b) in live_rows.iter().zip(&replay_rows) {
        for &c in &cols {
            assert_eq!(a[c], b[c], "set {}, column {}", a[0], h1[c]);
            gammas += usize::from(h1[c].ends_with(".gamma_hat") && !a[c].is_empty());
        }
    }
    assert!(gammas > 100, "estimates were compared ({gammas})");
    // The recorder's drops, per set: none in the recorded run, and the
    // replay recorded nothing.
    let d = h1.iter().position(|h| h == "recorder_dropped").unwrap();
    assert_eq!(d, h1.len() - 1);
    assert!(live_rows.iter().all(|r| r[d] == "0"), "{live_rows:?}");
    assert!(replay_rows.iter().all(|r| r[d].is_empty()));

    // The telemetry in the file is the run's.
    let stream = rigview_record::SetStream::open(&file, true).unwrap();
    let recorded: Vec<_> = stream.map(|s| s.unwrap().telemetry).collect();
    let g = h1.iter().position(|h| h.ends_with(".gamma_hat")).unwrap();
    for (t, row) in recorded.iter().zip(&live_rows) {
        assert!(t.processed);
        let v = t.gamma_hat[0];
        let want = row[g].parse::<f64>().unwrap_or(f64::NAN);
        assert!(v.to_bits() == want.to_bits() || (v.is_nan() && want.is_nan()));
    }

    // info, and repair of a copy cut in its last set.
    let info = recording::info(&file).unwrap();
    assert!(info.contains("40 complete sets"), "{info}");
    assert!(info.contains("calibration: attached (rig.yaml)"), "{info}");
    assert!(info.contains("/rig/telemetry"), "{info}");
    let bytes = std::fs::read(&file).unwrap();
    let cut = dir.path().join("cut.mcap");
    let summary_start = bytes.len() * 97 / 100;
    std::fs::write(&cut, &bytes[..summary_start]).unwrap();
    let info = recording::info(&cut).unwrap();
    assert!(info.contains("NOT CLOSED"), "{info}");
    assert!(info.contains("calibration: attached (rig.yaml)"), "{info}");
    let fixed = dir.path().join("fixed.mcap");
    let report = recording::repair(&cut, &fixed).unwrap();
    assert!(report.contains("complete sets"), "{report}");
    let indexed = rigview_record::IndexedRecording::open(&fixed).unwrap();
    let cut_sets = rigview_record::SetStream::open(&cut, false)
        .unwrap()
        .count();
    assert_eq!(indexed.len(), cut_sets);
    assert!(cut_sets >= 38, "{cut_sets}");
    assert!(
        indexed.meta().rig_yaml.is_some(),
        "the repaired file keeps the rig"
    );

    // A calibration that does not fit the recording names both files.
    let other = dir.path().join("one-camera.yaml");
    let loaded = rigview_calib::formats::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/reference.rig.yaml"),
        None,
        None,
    )
    .unwrap();
    let mut one = loaded.rig.clone();
    one.cameras.truncate(1);
    one.neighbours.clear();
    rigview_calib::formats::save(&one, &other, None).unwrap();
    let bad = HeadlessRun {
        source: SourceSpec::Replay(ReplaySpec {
            file: file.clone(),
            rig: Some(other.clone()),
            interactive: false,
        }),
        frames: 5,
        out: dir.path().join("bad"),
        every: 1000,
        record: None,
        serve: None,
    };
    let e = format!(
        "{:#}",
        headless::run(&bad, &settings, &log, false).unwrap_err()
    );
    assert!(
        e.contains("one-camera.yaml") && e.contains("drive.mcap"),
        "{e}"
    );
}

#[test]
fn the_command_line_records_replays_and_describes_recordings() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let file = d.join("run.mcap");
    let f = file.to_str().unwrap();
    let out = |name: &str| d.join(name).to_str().unwrap().to_owned();
    let summary = rigview(
        &[
            "run",
            "--headless",
            "--scale",
            "0.25",
            "--frames",
            "12",
            "--out",
            &out("a"),
            "--record",
            f,
            "--compression",
            "lz4",
        ],
        d,
    );
    assert!(
        summary.contains(&format!("recording {f}: 12 sets")),
        "{summary}"
    );
    let replay = format!("replay:{f}");
    let summary = rigview(
        &["run", "--headless", "--source", &replay, "--out", &out("b")],
        d,
    );
    assert!(summary.contains("12 of all sets processed"), "{summary}");
    let (_, rows) = csv(&d.join("b/telemetry.csv"));
    assert_eq!(rows.len(), 12);
    // The replay's plot has the panel of the commands the strategy would
    // have sent under the recorded exposures.
    let live = image::image_dimensions(d.join("a/exposure.png")).unwrap();
    let replayed = image::image_dimensions(d.join("b/exposure.png")).unwrap();
    assert_eq!(replayed.1 * 5, live.1 * 6, "{live:?} {replayed:?}");
    let info = rigview(&["recording", "info", f], d);
    assert!(info.contains("12 complete sets"), "{info}");
    assert!(
        info.contains("image_raw  sensor_msgs/msg/Image  12 messages"),
        "{info}"
    );
    assert!(info.contains("0 sets dropped"), "{info}");

    let sim = out("sim.mcap");
    let summary = rigview(
        &[
            "record",
            "--sim",
            "--scale",
            "0.25",
            "--seconds",
            "1",
            "--out",
            &sim,
        ],
        d,
    );
    assert!(summary.contains("0 dropped"), "{summary}");
    let info = rigview(&["recording", "info", &sim], d);
    assert!(info.contains("ended: finished"), "{info}");
    let fixed = out("fixed.mcap");
    let report = rigview(&["recording", "repair", &sim, &fixed], d);
    assert!(report.contains("complete sets"), "{report}");

    // Capture without processing from Aravis's fake cameras.
    let fake = out("fake.mcap");
    let summary = rigview(
        &[
            "record",
            "--fake",
            "--scale",
            "0.25",
            "--seconds",
            "2",
            "--out",
            &fake,
        ],
        d,
    );
    assert!(
        summary.contains(&format!("recording {fake}: ")),
        "{summary}"
    );
    let sets: Vec<_> = rigview_record::SetStream::open(Path::new(&fake), true)
        .unwrap()
        .map(|s| s.unwrap())
        .collect();
    assert!(sets.len() >= 5, "{} sets in 2 s at 20 Hz", sets.len());
    assert!(sets.iter().all(|s| !s.telemetry.processed));
}

#[test]
fn live_fake_cameras_are_recorded_and_replayed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let file = d.join("live.mcap");
    let f = file.to_str().unwrap();
    let printed = rigview(
        &[
            "live",
            "--fake",
            "--headless",
            "--scale",
            "0.25",
            "--seconds",
            "3",
            "--record",
            f,
        ],
        d,
    );
    assert!(printed.contains(&format!("recording {f}: ")), "{printed}");
    let info = rigview(&["recording", "info", f], d);
    assert!(info.contains("ended: finished"), "{info}");
    let sets = rigview_record::SetStream::open(&file, true)
        .unwrap()
        .map(|s| s.unwrap())
        .filter(|s| s.set.is_complete())
        .count();
    assert!(sets >= 5, "{sets} complete sets in 3 s of 20 Hz: {printed}");
    let out = d.join("replay");
    let replay = format!("replay:{f}");
    let summary = rigview(
        &[
            "run",
            "--headless",
            "--source",
            &replay,
            "--out",
            out.to_str().unwrap(),
        ],
        d,
    );
    assert!(
        summary.contains(&format!("{sets} of all sets processed")),
        "{summary}"
    );
}
