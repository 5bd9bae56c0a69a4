//! Recording and replay throughput: the set writer against a plain file
//! write of the same bytes (both into a tmpfs, on this thread), decoding a
//! recording back to frame sets, and seeking in a 10-minute recording.
//!
//! The frames are the simulated rig's, rendered once (4 × 1288×964 Mono8,
//! 4.97 MB a set) and shared by every set, as the pipeline shares them.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use rigview_core::exposure::ExposureSetting;
use rigview_core::image::PixelFormat;
use rigview_core::sim::{FillRequest, SimConfig, SimRender};
use rigview_core::source::{CameraInfo, Frame, FrameMeta, FrameSet};
use rigview_record::msgs;
use rigview_record::{Compression, IndexedRecording, RecordingSetup, SetStream, SetWriter};

/// Where the files go: a tmpfs, so that the figures are the writer's and
/// not the disk's.
fn scratch() -> PathBuf {
    let dir = Path::new("/dev/shm").join(format!("rigview-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

struct Rig {
    setup: RecordingSetup,
    frames: Vec<Frame>,
    names: Vec<String>,
}

fn full_size_rig() -> Rig {
    let config = SimConfig::named("reference").unwrap();
    let render = SimRender::new(&config).unwrap();
    let cameras: Vec<CameraInfo> = render.cameras().to_vec();
    let setting = ExposureSetting {
        shutter_us: 4000.0,
        gain_db: 0.0,
    };
    let frames = cameras
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let req = FillRequest::new(i, 0, setting, PixelFormat::Mono8, c.width, c.height);
            let mut buf = vec![0u8; req.buffer_len()];
            let meta = render.fill(&req, &mut buf).unwrap();
            Frame::new(meta, Arc::from(buf)).unwrap()
        })
        .collect();
    Rig {
        names: cameras.iter().map(|c| c.name.clone()).collect(),
        setup: RecordingSetup {
            cameras,
            rig: Some(render.rig().clone()),
            source: "bench".into(),
            time_offset_ns: 1_700_000_000_000_000_000,
        },
        frames,
    }
}

fn set_of(frames: &[Frame], k: u64) -> FrameSet {
    FrameSet {
        trigger: k,
        timestamp_ns: k * 50_000_000,
        frames: frames
            .iter()
            .map(|f| {
                let mut f = f.clone();
                f.meta.frame_id = k;
                Some(f)
            })
            .collect(),
    }
}

/// Sets per file before a new one is started (keeps the tmpfs small).
const PER_FILE: u64 = 40;

/// The time to write `iters` sets, a new file every [`PER_FILE`] sets.
fn write_sets(path: &Path, rig: &Rig, compression: Compression, iters: u64) -> Duration {
    let mut spent = Duration::ZERO;
    let mut k = 0;
    while k < iters {
        let t = Instant::now();
        let out = BufWriter::with_capacity(1 << 22, File::create(path).unwrap());
        let mut w = SetWriter::new(path, out, &rig.setup, compression).unwrap();
        let n = PER_FILE.min(iters - k);
        for j in 0..n {
            let set = set_of(&rig.frames, k + j);
            let t = msgs::telemetry_of(&set, None, &rig.names);
            w.write_set(&set, t, 0, 0).unwrap();
        }
        w.finish("bench").unwrap();
        spent += t.elapsed();
        k += n;
    }
    spent
}

fn bench_write(c: &mut Criterion) {
    let rig = full_size_rig();
    let dir = scratch();
    let bytes: u64 = rig.frames.iter().map(|f| f.data.len() as u64).sum();
    let mut g = c.benchmark_group("write_set");
    g.throughput(Throughput::Bytes(bytes));
    g.sample_size(20);
    g.measurement_time(Duration::from_secs(10));
    let path = dir.join("w.mcap");
    g.bench_function("rigview_mcap", |b| {
        b.iter_custom(|iters| write_sets(&path, &rig, Compression::None, iters));
    });
    g.bench_function("plain_file_write", |b| {
        b.iter_custom(|iters| {
            let mut spent = Duration::ZERO;
            let mut k = 0;
            while k < iters {
                let t = Instant::now();
                let mut out = BufWriter::with_capacity(1 << 22, File::create(&path).unwrap());
                let n = PER_FILE.min(iters - k);
                for _ in 0..n {
                    for f in &rig.frames {
                        out.write_all(&f.data).unwrap();
                    }
                    out.flush().unwrap();
                }
                spent += t.elapsed();
                k += n;
            }
            spent
        });
    });
    for compression in [Compression::Lz4, Compression::Zstd] {
        g.bench_function(BenchmarkId::new("rigview_mcap", compression.name()), |b| {
            b.iter_custom(|iters| write_sets(&path, &rig, compression, iters));
        });
    }
    g.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

fn record(path: &Path, setup: &RecordingSetup, frames: &[Frame], names: &[String], sets: u64) {
    let out = BufWriter::with_capacity(1 << 22, File::create(path).unwrap());
    let mut w = SetWriter::new(path, out, setup, Compression::None).unwrap();
    for k in 0..sets {
        let set = set_of(frames, k);
        let t = msgs::telemetry_of(&set, None, names);
        w.write_set(&set, t, 0, 0).unwrap();
    }
    w.finish("bench").unwrap();
}

fn bench_replay(c: &mut Criterion) {
    let rig = full_size_rig();
    let dir = scratch();
    let path = dir.join("r.mcap");
    const SETS: u64 = 40;
    record(&path, &rig.setup, &rig.frames, &rig.names, SETS);
    let mut g = c.benchmark_group("replay");
    g.throughput(Throughput::Elements(SETS));
    g.sample_size(10);
    g.measurement_time(Duration::from_secs(10));
    g.bench_function("decode_40_sets_streaming", |b| {
        b.iter(|| {
            let n = SetStream::open(&path, false)
                .unwrap()
                .map(|s| s.unwrap().set.frames.len())
                .sum::<usize>();
            assert_eq!(n as u64, SETS * 4);
        });
    });
    g.bench_function("decode_40_sets_streaming_crc", |b| {
        b.iter(|| {
            let n = SetStream::open(&path, true).unwrap().count();
            assert_eq!(n as u64, SETS);
        });
    });
    // The peer: the same file read through a 1 MiB buffer into nothing.
    g.bench_function("read_file_peer", |b| {
        b.iter(|| {
            let mut f = std::io::BufReader::with_capacity(1 << 20, File::open(&path).unwrap());
            std::io::copy(&mut f, &mut std::io::sink()).unwrap()
        });
    });
    g.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

/// A 10-minute recording at 20 Hz (12 000 sets) of four small frames
/// (128×96), for the cost of the index; a full-size set's chunk adds the
/// time to read 5 MB (see `replay`).
fn bench_seek(c: &mut Criterion) {
    let dir = scratch();
    let path = dir.join("ten-minutes.mcap");
    let cameras: Vec<CameraInfo> = ["front", "left", "rear", "right"]
        .iter()
        .map(|n| CameraInfo {
            name: (*n).into(),
            format: PixelFormat::Mono8,
            width: 128,
            height: 96,
            range: Default::default(),
            levels: None,
            tone_curve: None,
        })
        .collect();
    let frames: Vec<Frame> = (0..4)
        .map(|i| {
            let meta = FrameMeta::still(i, PixelFormat::Mono8, 128, 96);
            Frame::new(meta, Arc::from(vec![i as u8; 128 * 96])).unwrap()
        })
        .collect();
    let setup = RecordingSetup {
        cameras,
        rig: None,
        source: "bench".into(),
        time_offset_ns: 1_700_000_000_000_000_000,
    };
    let names: Vec<String> = setup.cameras.iter().map(|c| c.name.clone()).collect();
    const SETS: u64 = 12_000;
    record(&path, &setup, &frames, &names, SETS);
    let mut g = c.benchmark_group("seek_10_minutes");
    g.sample_size(20);
    g.bench_function("open_index_and_read_one_set", |b| {
        let mut k = 0u64;
        b.iter(|| {
            k = (k + 7919) % SETS;
            let mut r = IndexedRecording::open(&path).unwrap();
            let t = r.times()[0] + k * 50_000_000;
            let at = r.position(t);
            r.set(at).unwrap().unwrap().set.trigger
        });
    });
    let mut r = IndexedRecording::open(&path).unwrap();
    assert_eq!(r.len() as u64, SETS);
    g.bench_function("read_one_set_from_open_index", |b| {
        let mut k = 0u64;
        b.iter(|| {
            k = (k + 7919) % SETS;
            let t = r.times()[0] + k * 50_000_000;
            let at = r.position(t);
            r.set(at).unwrap().unwrap().set.trigger
        });
    });
    g.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, bench_write, bench_replay, bench_seek);
criterion_main!(benches);
