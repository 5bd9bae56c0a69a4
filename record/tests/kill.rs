//! Kill: a child process records the simulated rig as fast as it renders,
//! printing each set once it is flushed; it is killed with SIGKILL in the
//! middle. Every set it printed replays bit-identical, and the only fault
//! is the file's tail.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::PathBuf;
use std::process::{Command, Stdio};

use common::{assert_same, Sim};
use rigview_core::image::PixelFormat;
use rigview_record::{Compression, SetStream, SetWriter};

const CHILD: &str = "RIGVIEW_RECORD_KILL_CHILD";
const SEED: u64 = 11;

/// The child: records until killed (does nothing in a normal test run).
#[test]
fn child_records_until_killed() {
    let Some(path) = std::env::var_os(CHILD).map(PathBuf::from) else {
        return;
    };
    let sim = Sim::new(PixelFormat::Mono8, 0.25);
    let out = BufWriter::new(File::create(&path).unwrap());
    let mut w = SetWriter::new(&path, out, &sim.setup(), Compression::None).unwrap();
    let mut stdout = std::io::stdout().lock();
    for k in 0.. {
        let set = sim.set(SEED, k);
        w.write_set(&set, sim.telemetry(&set), 0, 1).unwrap();
        writeln!(stdout, "flushed {k}").unwrap();
        stdout.flush().unwrap();
    }
}

#[test]
fn a_killed_recording_replays_every_set_it_flushed() {
    if std::env::var_os(CHILD).is_some() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("killed.mcap");
    let mut child = Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "child_records_until_killed",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(CHILD, &path)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let mut printed = Vec::new();
    while printed.len() < 25 {
        let line = lines.next().expect("the child ended early").unwrap();
        if let Some(k) = line.strip_prefix("flushed ") {
            printed.push(k.parse::<u64>().unwrap());
        }
    }
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    // Whatever it printed before it died.
    for line in lines {
        if let Some(k) = line.unwrap().strip_prefix("flushed ") {
            printed.push(k.parse::<u64>().unwrap());
        }
    }
    let sim = Sim::new(PixelFormat::Mono8, 0.25);
    let mut stream = SetStream::open(&path, true).unwrap();
    let got: Vec<_> = stream
        .by_ref()
        .map(|s| s.expect("an error before the tail"))
        .collect();
    assert!(
        got.len() >= printed.len(),
        "{} sets replayed, {} printed",
        got.len(),
        printed.len()
    );
    for (k, g) in got.iter().enumerate() {
        assert_same(g, &sim.set(SEED, k as u64), sim.setup().time_offset_ns);
    }
    assert!(
        stream.end().is_none(),
        "a killed recording has no end record"
    );
    assert!(stream.tail().is_some(), "the file ends without its summary");
}
