//! A recording under faults: cut at any byte, a disk that fills, a writer
//! that falls behind. Each time the file replays exactly its complete sets
//! and the one offering sets never waits.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::fs::File;
use std::io::{self, BufWriter, Cursor, Seek, SeekFrom, Write};
use std::path::Path;
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use common::{assert_same, Sim};
use rigview_core::image::PixelFormat;
use rigview_core::source::FrameSet;
use rigview_record::{Compression, Recorder, RecorderOptions, SetStream, SetWriter};

fn record(sim: &Sim, sets: &[FrameSet], path: &Path) {
    let out = BufWriter::new(File::create(path).unwrap());
    let mut w = SetWriter::new(path, out, &sim.setup(), Compression::None).unwrap();
    for s in sets {
        w.write_set(s, sim.telemetry(s), 0, 1).unwrap();
    }
    w.finish("finished").unwrap();
}

/// A recording of `n` sets of a run seeded by `seed`, and its bytes.
struct Recorded {
    sim: Sim,
    sets: Vec<FrameSet>,
    dir: tempfile::TempDir,
    path: std::path::PathBuf,
    bytes: Vec<u8>,
}

impl Recorded {
    fn new(seed: u64, n: u64) -> Self {
        let sim = Sim::new(PixelFormat::Mono8, 0.25);
        let sets: Vec<_> = (0..n).map(|k| sim.set(seed, k)).collect();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.mcap");
        record(&sim, &sets, &path);
        let bytes = std::fs::read(&path).unwrap();
        Self {
            sim,
            sets,
            dir,
            path,
            bytes,
        }
    }
}

/// Reads every set of `bytes`; an error at open (cut before the recording's
/// metadata) counts as no set.
fn replay(path: &Path, bytes: &[u8]) -> Vec<rigview_record::RecordedSet> {
    let Ok(stream) = SetStream::new(path, Cursor::new(bytes), false) else {
        return Vec::new();
    };
    stream.map(|s| s.unwrap()).collect()
}

#[test]
fn a_recording_cut_at_any_of_200_offsets_replays_an_exact_prefix() {
    let r = Recorded::new(7, 8);
    let (sets, path, bytes) = (&r.sets, &r.path, &r.bytes);
    let offset = r.sim.setup().time_offset_ns;
    let mut last = 0;
    for i in 0..200u64 {
        let cut = (bytes.len() as u64 * i / 200) as usize;
        let got = replay(path, &bytes[..cut]);
        assert!(
            got.len() >= last,
            "cut at {cut}: fewer sets than a shorter cut"
        );
        last = got.len();
        for (g, w) in got.iter().zip(sets) {
            assert_same(g, w, offset);
        }
    }
    assert!(
        last >= sets.len() - 1,
        "the last cuts keep all but the last set"
    );
    assert_eq!(replay(path, bytes).len(), sets.len());
}

/// A file that takes `left` bytes, then fails as a full disk does.
struct FillsUp {
    inner: File,
    left: u64,
}

impl Write for FillsUp {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if self.left == 0 {
            return Err(io::Error::new(
                io::ErrorKind::StorageFull,
                "No space left on device (simulated)",
            ));
        }
        let n = buf.len().min(usize::try_from(self.left).unwrap());
        let n = self.inner.write(&buf[..n])?;
        self.left -= n as u64;
        Ok(n)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

impl Seek for FillsUp {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.inner.seek(pos)
    }
}

/// Offers sets until the recorder stops (at most `limit` sets); returns how
/// many were offered. The offers never wait, so the loop goes on after the
/// recording has stopped.
fn offer_until_stopped(rec: &Recorder, sim: &Sim, limit: u64) -> u64 {
    let mut k = 0;
    while k < limit {
        rec.offer(&sim.set(3, k), None);
        k += 1;
        if rec.is_stopped() {
            break;
        }
        // Gives the writer time to take each set (no set is meant to be
        // dropped here); not a measurement.
        let t = Instant::now();
        while rec.stats().sets + rec.stats().dropped < k && t.elapsed() < Duration::from_secs(10) {
            std::thread::sleep(Duration::from_millis(1));
        }
    }
    assert!(
        rec.is_stopped(),
        "{k} sets offered and the recording goes on"
    );
    // The pipeline keeps producing after the stop.
    for j in 0..5 {
        assert!(
            !rec.offer(&sim.set(3, k + j), None),
            "a stopped recording takes no set"
        );
    }
    k
}

fn check_replays_to_last_complete(path: &Path, sim: &Sim, written: u64) {
    let got = replay(path, &std::fs::read(path).unwrap());
    assert_eq!(
        got.len() as u64,
        written,
        "every set written, and only those"
    );
    for (k, g) in got.iter().enumerate() {
        assert_same(g, &sim.set(3, k as u64), sim.setup().time_offset_ns);
    }
}

#[test]
fn a_full_disk_stops_the_recording_which_replays_to_its_last_set() {
    let sim = Sim::new(PixelFormat::Mono8, 0.25);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("full.mcap");
    let out = FillsUp {
        inner: File::create(&path).unwrap(),
        left: 2_000_000,
    };
    let rec = Recorder::start(
        &path,
        out,
        &sim.setup(),
        RecorderOptions::default(),
        Box::new(|| Ok(u64::MAX)),
    )
    .unwrap();
    offer_until_stopped(&rec, &sim, 100);
    let stats = rec.finish();
    let why = stats.stopped.clone().unwrap();
    assert!(
        why.contains("write error") && why.contains("No space left"),
        "{why}"
    );
    assert!(!stats.finished);
    assert!(stats.sets >= 3, "{stats:?}");
    check_replays_to_last_complete(&path, &sim, stats.sets);
}

#[test]
fn the_reserve_stops_the_recording_cleanly() {
    let sim = Sim::new(PixelFormat::Mono8, 0.25);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("reserve.mcap");
    // Plenty of space at the first look, below the reserve at the next.
    let mut looks = 0;
    let rec = Recorder::start(
        &path,
        BufWriter::new(File::create(&path).unwrap()),
        &sim.setup(),
        RecorderOptions::default(),
        Box::new(move || {
            looks += 1;
            Ok(if looks == 1 { 10 << 30 } else { 1 << 30 })
        }),
    )
    .unwrap();
    // The free space is asked about once a second.
    offer_until_stopped(&rec, &sim, 1_000_000);
    let stats = rec.finish();
    let why = stats.stopped.clone().unwrap();
    assert!(why.contains("below the reserve of 2048 MiB"), "{why}");
    assert!(
        stats.finished,
        "a clean stop closes the file with its summary"
    );
    check_replays_to_last_complete(&path, &sim, stats.sets);
    assert!(rigview_record::IndexedRecording::open(&path).is_ok());
}

#[test]
fn a_real_small_filesystem_fills_up() {
    let is_root = std::process::Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| o.stdout.starts_with(b"0\n"));
    if !is_root {
        eprintln!("skipped: mounting a small tmpfs needs root");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let mounted = std::process::Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=4m", "tmpfs"])
        .arg(dir.path())
        .status()
        .is_ok_and(|s| s.success());
    if !mounted {
        eprintln!("skipped: this machine refuses to mount a tmpfs");
        return;
    }
    let sim = Sim::new(PixelFormat::Mono8, 0.25);
    let path = dir.path().join("tmpfs.mcap");
    let rec = Recorder::create(
        &path,
        &sim.setup(),
        RecorderOptions {
            reserve_bytes: 0,
            ..Default::default()
        },
    )
    .unwrap();
    offer_until_stopped(&rec, &sim, 100);
    let stats = rec.finish();
    let why = stats.stopped.clone().unwrap_or_default();
    let ok = why.contains("No space left on device");
    if ok {
        check_replays_to_last_complete(&path, &sim, stats.sets);
    }
    let _ = std::process::Command::new("umount")
        .arg(dir.path())
        .status();
    assert!(ok, "{stats:?}");
}

/// A disk that takes nothing until the gate opens.
struct Gated {
    inner: Cursor<Vec<u8>>,
    gate: Arc<(Mutex<bool>, Condvar)>,
    out: Arc<Mutex<Vec<u8>>>,
}

impl Write for Gated {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let (open, cv) = &*self.gate;
        let mut g = open.lock().unwrap();
        while !*g {
            g = cv.wait(g).unwrap();
        }
        self.inner.write(buf)
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

impl Drop for Gated {
    fn drop(&mut self) {
        *self.out.lock().unwrap() = std::mem::take(self.inner.get_mut());
    }
}

impl Seek for Gated {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.inner.seek(pos)
    }
}

#[test]
fn a_stalled_writer_never_blocks_capture_and_dropped_sets_are_counted_and_marked() {
    let sim = Sim::new(PixelFormat::Mono8, 0.25);
    let gate = Arc::new((Mutex::new(true), Condvar::new()));
    let out = Arc::new(Mutex::new(Vec::new()));
    let path = Path::new("stalled.mcap");
    let rec = Recorder::start(
        path,
        Gated {
            inner: Cursor::new(Vec::new()),
            gate: gate.clone(),
            out: out.clone(),
        },
        &sim.setup(),
        RecorderOptions {
            queue: 4,
            ..Default::default()
        },
        Box::new(|| Ok(u64::MAX)),
    )
    .unwrap();
    *gate.0.lock().unwrap() = false;
    // With the disk stalled, 40 offers return (if one waited for the disk,
    // this loop would never end); at most the queue and the set being
    // written get through.
    let sets: Vec<_> = (0..40).map(|k| sim.set(5, k)).collect();
    let accepted: Vec<bool> = sets.iter().map(|s| rec.offer(s, None)).collect();
    let taken = accepted.iter().filter(|&&a| a).count() as u64;
    // Each set written carries the sets refused since the one before it;
    // the set after the stall carries those refused after the last one.
    let mut want = Vec::new();
    let mut refused = 0;
    for a in &accepted {
        if *a {
            want.push(refused);
            refused = 0;
        } else {
            refused += 1;
        }
    }
    want.push(refused);
    assert!(taken <= 5, "{taken} sets queued behind a stalled disk");
    assert_eq!(rec.stats().dropped, 40 - taken);
    *gate.0.lock().unwrap() = true;
    gate.1.notify_all();
    // After the disk is back and the queue is written, the next set goes
    // through and carries the count of the sets dropped before it.
    while rec.stats().sets < taken {
        std::thread::sleep(Duration::from_millis(1));
    }
    assert!(rec.offer(&sim.set(5, 40), None));
    let stats = rec.finish();
    assert!(stats.finished);
    assert_eq!(stats.dropped, 40 - taken);
    let bytes = out.lock().unwrap().clone();
    let mut stream = SetStream::new(path, Cursor::new(&bytes[..]), true).unwrap();
    let got: Vec<_> = stream.by_ref().map(|s| s.unwrap()).collect();
    assert_eq!(got.len() as u64, taken + 1);
    let marked: u64 = got.iter().map(|g| g.telemetry.dropped_since_last).sum();
    assert_eq!(marked, 40 - taken, "the drops are marked in the file");
    let marks: Vec<_> = got.iter().map(|g| g.telemetry.dropped_since_last).collect();
    assert_eq!(marks, want, "each set carries the drops right before it");
    assert_eq!(
        got.last().unwrap().telemetry.dropped_by_recorder,
        40 - taken
    );
    assert_eq!(stream.end().unwrap().dropped, 40 - taken);
}

#[test]
fn a_recording_is_never_overwritten() {
    let sim = Sim::new(PixelFormat::Mono8, 0.25);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("drive.mcap");
    std::fs::write(&path, b"a drive recorded before").unwrap();
    let e = Recorder::create(&path, &sim.setup(), RecorderOptions::default()).unwrap_err();
    assert!(e.to_string().contains("drive.mcap"), "{e}");
    assert_eq!(std::fs::read(&path).unwrap(), b"a drive recorded before");
    let copy = dir.path().join("copy.mcap");
    std::fs::write(&copy, b"kept").unwrap();
    assert!(rigview_record::repair(&path, &copy).is_err());
    assert_eq!(std::fs::read(&copy).unwrap(), b"kept");
}

#[test]
fn a_damaged_recording_read_with_crcs_gives_an_exact_prefix_and_no_panic() {
    let r = Recorded::new(13, 6);
    let (sets, path, good) = (&r.sets, &r.path, &r.bytes);
    let offset = r.sim.setup().time_offset_ns;
    for i in 0..100u64 {
        // Eight bytes of all ones (what a kill leaves in a chunk's length)
        // anywhere in the file.
        let at = (good.len() as u64 * i / 100) as usize;
        let mut bytes = good.clone();
        let end = (at + 8).min(bytes.len());
        bytes[at..end].fill(0xff);
        // Through the index, set by set: a damaged set is an error, the
        // others are whole.
        let copy = r.dir.path().join("damaged.mcap");
        std::fs::write(&copy, &bytes).unwrap();
        if let Ok(mut indexed) = rigview_record::IndexedRecording::open(&copy) {
            for (k, want) in sets.iter().enumerate().take(indexed.len()) {
                if let Ok(Some(got)) = indexed.set(k) {
                    assert_same(&got, want, offset);
                }
            }
        }
        std::fs::remove_file(&copy).unwrap();
        let Ok(stream) = SetStream::new(path, Cursor::new(&bytes[..]), true) else {
            continue;
        };
        for (k, got) in stream.enumerate() {
            let Ok(got) = got else { break };
            assert_same(&got, &sets[k], offset);
        }
    }
}
